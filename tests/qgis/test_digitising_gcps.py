"""The GCP dock in QGIS, driven with mouse events on real map canvases (issue 23): a rendered block
of two scenes (tests/support/gcpblock.py) added by their display copies; GCPs measured by clicks
on each scene's raw image at their true pixels, their ground picked on the main canvas (heights from
the DEM); one click 2 px off snapped to the other scene; predictions drawn; saved, reopened in a
new dock (points and scenes identical) and adjusted with core.adjust.block.adjust_block: the check
points' error against the truth falls from the onboard models' 7.5 px to 0.28 px."""
import numpy as np
import pytest
from qgis.core import QgsCoordinateReferenceSystem, QgsProject, QgsRasterLayer
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtTest import QTest

from tests.support.digitising import click_pixel, pick_ground
from tests.support.gcpblock import NAMES, gcp_block, true_ground, true_pixel  # noqa: F401 (the fixture)

SNAPPED = "G1"                       # clicked 2.5 px off in fwd, then snapped to nad
OFF_PX = np.array([2.0, -1.5])


def dock_for(block, qgis_iface):
    """A GCP dock with both scenes of the block, heights from its DEM (a layer of the project)."""
    from pushbroom_adjust.ui.digitising.gcpdock import GcpDock
    dock = GcpDock(qgis_iface)
    dock.resize(600, 1000)
    dock.show()
    for name in NAMES:
        assert dock.add_scene(block["displays"][name]), dock.message_label.text()
    dem = QgsRasterLayer(str(block["result"].dem), "dem")
    QgsProject.instance().addMapLayer(dem)
    dock.dem_combo.setLayer(dem)
    dock.height_combo.setCurrentText("dem")
    dock.datum_combo.setCurrentText("geoid")
    return dock


def measure_point(dock, block, main, point_id: str) -> dict:
    """New point, a click at its true pixel in each scene (OFF_PX off in fwd for SNAPPED), its
    ground picked on the main canvas; {scene: clicked (col, row)}."""
    QTest.mouseClick(dock.new_button, Qt.LeftButton)
    dock.id_edit.setText(point_id)
    dock.id_edit.editingFinished.emit()
    clicked = {}
    for k, name in enumerate(NAMES):
        dock.scene_list.setCurrentRow(k)
        offset = OFF_PX if (point_id, name) == (SNAPPED, "fwd") else 0.0
        clicked[name] = click_pixel(dock, true_pixel(block, point_id, name) + offset)
        assert f"Point {point_id} measured in {name}/NAD" in dock.message_label.text(), dock.message_label.text()
    QTest.mouseClick(dock.ground_button, Qt.LeftButton)
    pick_ground(main, *true_ground(block, point_id)[:2])
    assert f"Point {point_id}: ground lon" in dock.message_label.text(), dock.message_label.text()
    return clicked


def test_dock_measures_snaps_saves_reopens_and_the_block_adjusts(plugin, gcp_block, qgis_iface, qgis_canvas,  # noqa: F811
                                                                 qgis_new_project, tmp_path):
    from pushbroom_adjust.core.adjust import AdjustmentSettings
    from pushbroom_adjust.core.adjust.block import adjust_block
    from pushbroom_adjust.core.observations.gcps import read_gpkg
    qgis_canvas.resize(800, 800)
    qgis_canvas.setDestinationCrs(QgsCoordinateReferenceSystem("EPSG:4326"))
    dock = dock_for(gcp_block, qgis_iface)
    assert [dock.scene_list.item(k).text() for k in range(2)] == ["nad/NAD", "fwd/NAD"]
    control = gcp_block["inside"][:5]
    clicks = {i: measure_point(dock, gcp_block, qgis_canvas, i) for i in control}

    # every click stands for a point within a hundredth of a pixel of the true image
    errors = [np.hypot(*(clicks[i][n] - true_pixel(gcp_block, i, n))) for i in control for n in NAMES
              if (i, n) != (SNAPPED, "fwd")]
    print(f"clicks: {len(errors)}, max {max(errors):.4f} px from the truth")
    assert max(errors) < 0.02
    # ground picked on the main canvas (a few cm per screen pixel), heights from the DEM
    for point in dock.editor.points:
        lon, lat, h = true_ground(gcp_block, point.id)
        assert point.ground.source == "canvas" and abs(point.ground.h - h) < 0.5, (point.ground.h, h)
        assert np.hypot((point.ground.lon - lon) * np.cos(np.radians(lat)), point.ground.lat - lat) * 1.11e5 < 0.1

    # predictions of the selected point in fwd: from its ground and from its nad observation,
    # through the onboard models (a marker each), several px from the truth
    dock.select_point(0)
    dock.scene_list.setCurrentRow(1)
    assert {p.source for p in dock.predictions} == {"ground", "nad"}
    off = [np.hypot(p.col - true_pixel(gcp_block, SNAPPED, "fwd")[0], p.row - true_pixel(gcp_block, SNAPPED, "fwd")[1])
           for p in dock.predictions]
    assert len(dock.drawing.items) >= 2 + len(control) and 2.0 < min(off) < 20.0

    # Snap the click 2.5 px off in fwd to the nad image: back on the truth; Undo restores the click
    QTest.mouseClick(dock.snap_button, Qt.LeftButton)
    assert dock.message_label.text().startswith("Snapped by") and " px to nad/NAD (" in dock.message_label.text(), \
        dock.message_label.text()
    seen = dock.editor.current().observation("fwd", "NAD")
    snap_error = np.hypot(seen.col - true_pixel(gcp_block, SNAPPED, "fwd")[0],
                          seen.row - true_pixel(gcp_block, SNAPPED, "fwd")[1])
    print(f"snap: {dock.message_label.text()}; {snap_error:.3f} px from the truth")
    assert snap_error < 0.05 and seen.sigma_px < 0.1
    QTest.mouseClick(dock.undo_button, Qt.LeftButton)
    assert dock.message_label.text() == "Undone: snap"
    restored = dock.editor.current().observation("fwd", "NAD")
    assert (restored.col, restored.row) == tuple(clicks[SNAPPED]["fwd"]) and restored.sigma_px == 0.5
    QTest.mouseClick(dock.snap_button, Qt.LeftButton)

    # save, reopen in a new dock: the same points in the same scenes
    path = str(tmp_path / "gcps.gpkg")
    assert dock.save(path), dock.message_label.text()
    saved = dock.editor.table()
    again = dock_for(gcp_block, qgis_iface)
    assert again.open_layer(path), again.message_label.text()
    back = again.editor.table()
    for field in ("id", "role", "camera", "scene"):
        assert getattr(back, field).tolist() == getattr(saved, field).tolist()
    for field in ("col", "row", "lon", "lat", "h", "sigma_px", "sigma_xy", "sigma_z"):
        np.testing.assert_allclose(getattr(back, field), getattr(saved, field), rtol=0, atol=1e-9)
    assert sorted(set(back.scene)) == ["fwd", "nad"] and len(back) == 2 * len(control)

    # adjust the block to the saved layer: check points against the truth
    result = adjust_block(gcp_block["onboard"], read_gpkg(path), None,
                          AdjustmentSettings(position_order=0, attitude_order=0, position_sigma=None))
    before, after = check_rmse(gcp_block, gcp_block["onboard"], control), check_rmse(gcp_block, result.scenes, control)
    print(f"check points: RMSE {before:.2f} px onboard -> {after:.3f} px adjusted")
    # measured 7.52 -> 0.279 px: what bias corrections fitted to 5 GCPs leave of the simulated
    # drifts (the same points measured at the truth without the dock: 0.278 px)
    assert before > 5.0 and after < 0.4
    for d in (dock, again):
        d.dispose()


def check_rmse(block, scenes: dict, control) -> float:
    """RMS (px) over both scenes of the GCPs not in ``control`` (true ground through ``scenes``
    against their true pixels)."""
    from pushbroom_adjust.core.geodesy import geodetic_to_ecef
    d = []
    for (point_id, name), row in block["rows"].items():
        if point_id in control:
            continue
        ground = geodetic_to_ecef(*(np.array([float(row[k])]) for k in ("lon_true", "lat_true", "h_true")))
        col, r = scenes[name].ground_to_image(ground, 0)
        d.append(np.hypot(col[0] - float(row["col_true"]), r[0] - float(row["row_true"])))
    return float(np.sqrt(np.mean(np.square(d))))


def test_ground_from_a_reference_point_layer_and_sigmas_edited(plugin, gcp_block, qgis_iface, qgis_canvas,  # noqa: F811
                                                               qgis_new_project):
    """A click near a reference point (PointZ, ellipsoidal Z) takes its position and Z; the sigma
    boxes change the point's ground sigmas and its image sigma in the shown scene (undoable)."""
    from qgis.core import QgsFeature, QgsGeometry, QgsPoint, QgsVectorLayer
    qgis_canvas.resize(800, 800)
    qgis_canvas.setDestinationCrs(QgsCoordinateReferenceSystem("EPSG:4326"))
    point_id = gcp_block["inside"][1]
    lon, lat, h = true_ground(gcp_block, point_id)
    layer = QgsVectorLayer("PointZ?crs=EPSG:4326", "reference", "memory")
    feature = QgsFeature()
    feature.setGeometry(QgsGeometry(QgsPoint(lon, lat, h)))
    layer.dataProvider().addFeatures([feature])
    QgsProject.instance().addMapLayer(layer)
    dock = dock_for(gcp_block, qgis_iface)
    dock.reference_combo.setLayer(layer)
    dock.height_combo.setCurrentText("z")
    dock.datum_combo.setCurrentText("ellipsoid")
    QTest.mouseClick(dock.new_button, Qt.LeftButton)
    click_pixel(dock, true_pixel(gcp_block, point_id, "nad"))
    QTest.mouseClick(dock.ground_button, Qt.LeftButton)
    pick_ground(qgis_canvas, lon + 3e-6, lat - 2e-6)             # 0.3 m beside the reference point
    ground = dock.editor.current().ground
    assert (ground.lon, ground.lat, ground.h, ground.source) == (lon, lat, h, "reference"), dock.message_label.text()
    # the ground is marked on the main canvas (EPSG:4326 here), the selected point highlighted
    marker = dock.main_markers.selected.point
    assert dock.main_markers.selected.isVisible() and (marker.x(), marker.y()) == pytest.approx((lon, lat), abs=1e-12)
    # a click far from every reference point (tens of screen px) takes none of them
    QTest.mouseClick(dock.ground_button, Qt.LeftButton)
    pick_ground(qgis_canvas, lon + 2e-4, lat)                    # 20 m east, the canvas +-0.5 m wide
    assert dock.message_label.text().startswith("No point of the reference layer reference within 20 screen px"), \
        dock.message_label.text()
    assert dock.editor.current().ground == ground
    for spin, value in ((dock.sigma_px_spin, 0.25), (dock.sigma_xy_spin, 0.4), (dock.sigma_z_spin, 0.8)):
        spin.setValue(value)
        spin.editingFinished.emit()
    table = dock.editor.table()
    assert (table.sigma_px[0], table.sigma_xy[0], table.sigma_z[0]) == (0.25, 0.4, 0.8)
    QTest.mouseClick(dock.undo_button, Qt.LeftButton)
    assert dock.message_label.text() == "Undone: edit"
    dock.dispose()


def test_the_table_map_markers_and_adjusted_residuals(plugin, gcp_block, qgis_iface, qgis_canvas,  # noqa: F811
                                                      qgis_new_project, tmp_path):
    """Three points measured: all marked on the main map (the selected one highlighted); the table
    sorts by height as numbers and a click selects the point and zooms to it; an adjusted layer opened
    back shows each measurement's residual in the scene shown, gone when the point is moved there
    (Ctrl+Z brings it back)."""
    from pushbroom_adjust.core.observations.gcps import Residuals, read_gpkg, write_gpkg
    from pushbroom_adjust.ui.digitising.canvas import ZOOM_TO_POINT_PX
    qgis_canvas.resize(800, 800)
    qgis_canvas.setDestinationCrs(QgsCoordinateReferenceSystem("EPSG:4326"))
    dock = dock_for(gcp_block, qgis_iface)
    ids = gcp_block["inside"][1:4]
    for point_id in ids:
        measure_point(dock, gcp_block, qgis_canvas, point_id)
    markers = dock.main_markers.drawing.items
    assert sorted(m.label for m in markers) == sorted(ids) and dock.main_markers.selected.label == ids[-1]
    assert [m.style.legend for m in markers].count("selected point") == 1

    table = dock.table
    table.sortByColumn(4, Qt.DescendingOrder)                       # h (m), highest first
    heights = [float(table.item(r, 4).text()) for r in range(table.rowCount())]
    assert heights == sorted(heights, reverse=True) and len(heights) == 3
    top = table.item(0, 0).text()
    dock.scene_list.setCurrentRow(0)                                # the whole image shown
    QTest.mouseClick(table.viewport(), Qt.LeftButton, Qt.NoModifier, table.visualItemRect(table.item(0, 0)).center())
    assert dock.editor.current().id == top
    seen = dock.editor.current().observation("nad", "NAD")
    centre = dock.canvas.extent().center()
    assert (centre.x(), -centre.y()) == pytest.approx((seen.col, seen.row), abs=1e-6)
    shown = dock.canvas.extent()                                    # +-40 px along the canvas's shorter side
    assert min(shown.width(), shown.height()) == pytest.approx(2 * ZOOM_TO_POINT_PX)

    saved = tmp_path / "gcps.gpkg"
    assert dock.save(str(saved)), dock.message_label.text()
    adjusted = read_gpkg(saved)
    n = len(adjusted)
    adjusted.residuals = Residuals(np.full(n, 0.3), np.full(n, -0.4), np.full(n, 0.5), np.full(n, 1.0), np.ones(n, bool))
    write_gpkg(adjusted, tmp_path / "adjusted_gcps.gpkg")
    assert dock.open_layer(str(tmp_path / "adjusted_gcps.gpkg"))
    assert dock.message_label.text().endswith(f", {n} observations with their residuals")
    assert [table.item(r, 3).text() for r in range(3)] == ["0.50"] * 3
    assert {table.item(r, 5).text() for r in range(3)} == {"the layer adjusted_gcps.gpkg"}
    dock.select_point(0)
    moved = dock.editor.current().observation("nad", "NAD")
    dock.image_clicked(moved.col + 1.0, moved.row, Qt.LeftButton)
    row = next(r for r in range(3) if table.item(r, 0).text() == dock.editor.current().id)
    assert table.item(row, 3).text() == ""
    dock.undo_action.trigger()
    assert table.item(row, 3).text() == "0.50" and dock.message_label.text() == "Undone: move"
    dock.tools.zoom_image.trigger()
    assert dock.canvas.extent().contains(dock.canvas.layer.extent())
    dock.dispose()
    assert dock.main_markers.drawing.items == []
