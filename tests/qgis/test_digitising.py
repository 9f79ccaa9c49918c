"""The digitising dock in QGIS, driven with mouse events on real map canvases: prepare the display
copy (pushbroom:preparedigitising), digitise two image lines on the dock's canvas, undo a vertex,
pair each with its ground line on the main canvas, predict the ground lines, save; the saved
layer reads back through core.observations.lines with the clicked pixels and the ids."""
from pathlib import Path

import numpy as np
from osgeo import gdal, ogr
from qgis.core import QgsApplication
from qgis.PyQt.QtCore import QPoint, Qt
from qgis.PyQt.QtTest import QTest

from tests.support.digitising import click, digitise, pick, true_points, zoom_to
from tests.support.digitising import ground_layer, prepared, roads  # noqa: F401 (the fixtures)
from tests.support.polylines import distances_to_polylines
from tests.support.snapping import across_error, clicks_along, render_roads

CLICK_TOLERANCE_PX = 0.5


def test_prepare_writes_the_display_copy_and_an_empty_layer(prepared, roads):  # noqa: F811
    from pushbroom_adjust.core.measure.display import read_display_source
    ds = gdal.Open(prepared["OUTPUT"])
    assert ds.GetGeoTransform() == (0.0, 1.0, 0.0, 0.0, 0.0, -1.0)
    assert (ds.RasterXSize, ds.RasterYSize) == (roads["camera"].cols, roads["camera"].rows)
    source = read_display_source(prepared["OUTPUT"])
    assert (source.scene, source.camera, source.image) == (str(roads["result"].true_scene), "HRC", str(roads["raw"]))
    lines = ogr.Open(prepared["OUTPUT_LINES"])
    assert lines.GetLayerByName("image_lines").GetFeatureCount() == 0
    from qgis.core import QgsRasterLayer
    layer = QgsRasterLayer(prepared["OUTPUT"], "display")
    assert layer.isValid() and "Pushbroom image pixels" in layer.crs().toWkt()
    assert layer.extent().xMaximum() == roads["camera"].cols and layer.extent().yMinimum() == -roads["camera"].rows


def test_dock_digitises_pairs_predicts_and_saves(plugin, prepared, roads, ground_layer, qgis_iface, qgis_canvas,  # noqa: F811
                                                 tmp_path):
    from pushbroom_adjust.core.observations.lines import read_image_lines
    from pushbroom_adjust.ui.digitising.dock import DigitisingDock
    dock = DigitisingDock(qgis_iface)  # the Python reference keeps the widget alive
    dock.resize(600, 900)
    dock.show()
    assert dock.open_image(prepared["OUTPUT"])
    assert dock.scene is not None and dock.source.camera_name == "HRC" and dock.raw_image == str(roads["raw"])
    dock.ground_combo.setLayer(ground_layer)
    dock.id_combo.setField("line_id")
    ground = {f["line_id"]: np.array(f.geometry().asPolyline()) for f in ground_layer.getFeatures()}

    expected = {}
    for line_id in ("R1", "R2"):
        truth = true_points(roads, line_id)[::3]
        zoom_to(dock.canvas, truth)
        clicked = digitise(dock, truth)
        click(dock.canvas, 400, 300)  # a stray vertex ...
        assert len(dock.editor.current) == len(truth) + 1
        QTest.mouseClick(dock.undo_button, Qt.LeftButton)  # ... undone
        click(dock.canvas, 10, 10, Qt.RightButton)  # right click finishes the line
        assert dock.editor.current == [] and dock.editor.selected == len(expected)
        QTest.mouseClick(dock.pair_button, Qt.LeftButton)
        middle = ground[line_id][len(ground[line_id]) // 2]
        pick(qgis_canvas, middle[0], middle[1])
        assert dock.editor.lines[-1].line_id == line_id, dock.message_label.text()
        expected[line_id] = clicked
        # the clicks stand for points within a screen pixel of the road's true image
        assert np.abs(clicked - truth).max() <= dock.canvas.mapUnitsPerPixel()

    dock.height_combo.setCurrentText("z")
    QTest.mouseClick(dock.predict_button, Qt.LeftButton)
    assert len(dock.predicted) == 6 and len(dock.drawing.items) >= 6 + 2
    r1 = next(p for p in dock.predicted if p.line_id == "R1")
    assert distances_to_polylines(true_points(roads, "R1"), r1.runs()).max() < 1.6

    # a third, unpaired line is refused on saving and leaves no file; deleted, the rest saves
    dock.add_vertex(5000.0, 5000.0)
    dock.add_vertex(5100.0, 5050.0)
    QTest.mouseClick(dock.finish_button, Qt.LeftButton)
    assert not dock.save(str(tmp_path / "lines.gpkg")) and "3 are not paired" in dock.message_label.text()
    assert not (tmp_path / "lines.gpkg").exists()
    QTest.mouseClick(dock.delete_button, Qt.LeftButton)
    assert dock.save(str(tmp_path / "lines.gpkg")), dock.message_label.text()

    back = read_image_lines(tmp_path / "lines.gpkg")
    assert back.line_id.tolist() == ["R1", "R2"] and back.camera.tolist() == ["HRC", "HRC"]
    # the scene as bundleadjust with SCENES names the scene file (true_scene.json: its folder)
    assert back.scene.tolist() == [Path(roads["result"].true_scene).parent.name] * 2
    for i, line_id in enumerate(("R1", "R2")):
        sl = slice(back.start[i], back.start[i + 1])
        got = np.c_[back.col[sl], back.row[sl]]
        assert got.shape == expected[line_id].shape
        assert np.abs(got - expected[line_id]).max() < CLICK_TOLERANCE_PX
    moved = QPoint(200, 200)
    QTest.mouseMove(dock.canvas.viewport(), moved)
    at = dock.canvas.getCoordinateTransform().toMapCoordinates(moved)
    assert dock.pixel_label.text() == f"col {at.x():.1f}, row {-at.y():.1f} px"
    _snap_in(dock, tmp_path)
    dock.dispose()


def test_plugin_action_opens_the_dock(plugin_instance, qgis_iface, monkeypatch):
    from unittest.mock import Mock

    from pushbroom_adjust.ui.digitising.dock import DigitisingDock
    from pushbroom_adjust.ui.digitising.gcpdock import GcpDock
    for name in ("removePluginMenu", "removeDockWidget"):  # not in pytest-qgis's interface
        monkeypatch.setattr(qgis_iface, name, Mock(), raising=False)
    plugin_instance.initGui()  # the provider is registered already: only the action is added
    try:
        assert plugin_instance.action.text() == "Digitise control lines on the raw image"
        plugin_instance.action.trigger()
        assert isinstance(plugin_instance.dock, DigitisingDock) and not plugin_instance.dock.isHidden()
        assert plugin_instance.gcp_action.text() == "Measure GCPs on the raw images"
        plugin_instance.gcp_action.trigger()
        assert isinstance(plugin_instance.gcp_dock, GcpDock) and not plugin_instance.gcp_dock.isHidden()
    finally:
        plugin_instance.remove_gui()
    assert plugin_instance.action is None and plugin_instance.dock is None
    assert plugin_instance.gcp_action is None and plugin_instance.gcp_dock is None
    assert qgis_iface.removePluginMenu.call_count == 2 and qgis_iface.removeDockWidget.call_count == 2
    assert QgsApplication.processingRegistry().providerById("pushbroom") is not None


def _snap_in(dock, tmp_path):
    """Clicks 2 px off a rendered road, Snap: within 0.3 px RMS across the road's true image,
    each vertex with its own sigma; Undo restores the clicks; the snapped sigmas are saved.
    (In the dock of the test above, with a second display copy.)"""
    from pushbroom_adjust.core.measure.display import write_display_vrt
    from pushbroom_adjust.core.observations.lines import read_image_lines
    (tmp_path / "snap").mkdir()
    path, scene, truth = render_roads(tmp_path / "snap")  # the scene of the fixture ``rendered``
    write_display_vrt(path, tmp_path / "display.vrt")
    dock.editor.lines.clear()
    dock.editor.selected = None
    assert dock.open_image(str(tmp_path / "display.vrt")) and dock.raw_image == str(path)
    clicks = clicks_along(truth[:1], 40.0, 2.0, np.random.default_rng(3), scene.cameras[0].cols)
    pixels = np.c_[clicks.col, clicks.row]
    zoom_to(dock.canvas, pixels)
    clicked = digitise(dock, pixels)
    click(dock.canvas, 10, 10, Qt.RightButton)
    clicked_lines = type(clicks)(["R0"], "HRC", [0, len(clicked)], clicked[:, 0], clicked[:, 1], 1.0)
    before = across_error(clicked_lines, truth[:1])
    QTest.mouseClick(dock.snap_button, Qt.LeftButton)
    assert "vertices snapped" in dock.message_label.text(), dock.message_label.text()
    line = dock.editor.lines[0]
    snapped = type(clicks)(["R0"], "HRC", [0, len(clicked)], *np.array(line.vertices).T, line.sigmas)
    after = across_error(snapped, truth[:1])
    refined = np.array(line.sigmas) != 1.0
    print(f"dock snap: {refined.sum()} of {len(clicked)} vertices, RMS across {np.sqrt(np.mean(before ** 2)):.2f} "
          f"-> {np.sqrt(np.mean(after[refined] ** 2)):.3f} px")
    assert np.sqrt(np.mean(before ** 2)) > 1.0 and refined.mean() >= 0.9
    assert np.sqrt(np.mean(after[refined] ** 2)) <= 0.3
    QTest.mouseClick(dock.undo_button, Qt.LeftButton)
    assert dock.message_label.text() == "Snap undone" and len(dock.editor.lines) == 1
    assert np.abs(np.array(dock.editor.lines[0].vertices) - clicked).max() < 1e-9
    QTest.mouseClick(dock.snap_button, Qt.LeftButton)
    dock.editor.pair_selected("R0")
    assert dock.save(str(tmp_path / "snapped.gpkg")), dock.message_label.text()
    back = read_image_lines(tmp_path / "snapped.gpkg")
    np.testing.assert_allclose(back.sigma_px, dock.editor.lines[0].sigmas)
    assert np.all((back.sigma_px[refined] >= 0.1) & (back.sigma_px[refined] < 0.5))  # the fit's, per vertex
    assert np.all(back.sigma_px[~refined] == 1.0)
