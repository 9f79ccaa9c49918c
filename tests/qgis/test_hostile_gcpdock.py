"""Hostile use of the GCP dock (ui/digitising/gcpdock.py), driven with mouse events: each mistake
refused with a message naming what is wrong, the dock's points and the files it reads unchanged
(no traceback on stderr: tests/qgis/conftest.py checks every test_hostile_* module)."""
import shutil

import numpy as np
import pytest
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtTest import QTest

from tests.support.digitising import click, click_pixel, zoom_to
from tests.support.gcpblock import NAMES, gcp_block, true_ground, true_pixel  # noqa: F401 (the fixture)
from tests.support.hostile import assert_unchanged, snapshot


@pytest.fixture
def dock(plugin, gcp_block, qgis_iface, qgis_new_project):  # noqa: F811
    """A GCP dock with both scenes, heights constant (no DEM layer needed)."""
    from pushbroom_adjust.ui.digitising.gcpdock import GcpDock
    dock = GcpDock(qgis_iface)
    dock.resize(600, 1000)
    dock.show()
    for name in NAMES:
        assert dock.add_scene(gcp_block["displays"][name]), dock.message_label.text()
    dock.height_combo.setCurrentText("constant")
    yield dock
    dock.dispose()


def measured(dock, block) -> str:
    """One point clicked in nad, its ground set in the core (as a reference layer would)."""
    from pushbroom_adjust.core.measure.gcpmeasure import Ground
    point_id = block["inside"][0]
    dock.scene_list.setCurrentRow(0)
    QTest.mouseClick(dock.new_button, Qt.LeftButton)
    click_pixel(dock, true_pixel(block, point_id, "nad"))
    dock.editor.set_ground(Ground(*true_ground(block, point_id)))
    return point_id


def test_a_click_outside_the_image_is_refused(dock, gcp_block):  # noqa: F811
    dock.scene_list.setCurrentRow(0)
    QTest.mouseClick(dock.new_button, Qt.LeftButton)
    zoom_to(dock.canvas, np.array([[0.0, 0.0], [500.0, 500.0]]), margin=100.0)
    screen = dock.canvas.getCoordinateTransform().transform(-50.0, 250.0)   # col -50: left of the image
    click(dock.canvas, screen.x(), screen.y())
    assert "is outside the image of nad (500 x 500 px): click inside it" in dock.message_label.text()
    assert dock.editor.current().observations == []


def test_undo_with_nothing_to_undo(dock):
    QTest.mouseClick(dock.undo_button, Qt.LeftButton)
    assert dock.message_label.text() == "Nothing to undo" and dock.editor.points == []


@pytest.mark.parametrize("what", ["display copy", "raw image", "scene file"])
def test_saving_over_an_input_is_refused(dock, gcp_block, what):  # noqa: F811
    measured(dock, gcp_block)
    files = {"display copy": gcp_block["displays"]["fwd"],
             "raw image": str(gcp_block["result"].members["fwd"]["images"]["NAD"]),
             "scene file": str(gcp_block["result"].members["fwd"]["onboard_scene"])}
    before = snapshot(*files.values())
    assert not dock.save(files[what])
    assert f"is the file of fwd/NAD ({what})" in dock.message_label.text(), dock.message_label.text()
    assert_unchanged(before, list(files.values()))


def test_saving_a_point_without_ground_writes_nothing(dock, gcp_block, tmp_path):  # noqa: F811
    dock.scene_list.setCurrentRow(1)
    QTest.mouseClick(dock.new_button, Qt.LeftButton)
    click_pixel(dock, np.array([250.0, 250.0]))
    assert not dock.save(str(tmp_path / "gcps.gpkg"))
    assert "point(s) G1 have no ground position" in dock.message_label.text()
    assert list(tmp_path.iterdir()) == []


def test_a_layer_naming_scenes_not_in_the_dock_is_refused_naming_them(dock, gcp_block, qgis_iface,  # noqa: F811
                                                                       tmp_path):
    from pushbroom_adjust.ui.digitising.gcpdock import GcpDock
    measured(dock, gcp_block)
    dock.scene_list.setCurrentRow(1)
    click_pixel(dock, true_pixel(gcp_block, gcp_block["inside"][0], "fwd"))
    assert dock.save(str(tmp_path / "gcps.gpkg")), dock.message_label.text()
    nad_only = GcpDock(qgis_iface)
    try:
        assert nad_only.add_scene(gcp_block["displays"]["nad"])
        assert not nad_only.open_layer(str(tmp_path / "gcps.gpkg"))
        assert "names scene(s) 'fwd' that are not in the block (nad): add those scenes first" in \
            nad_only.message_label.text()
        assert nad_only.editor.points == []
    finally:
        nad_only.dispose()


def test_scenes_that_cannot_join_the_block_are_refused(dock, gcp_block, tmp_path):  # noqa: F811
    assert not dock.add_scene(gcp_block["displays"]["nad"])
    assert dock.message_label.text() == "nad/NAD is in the block already"
    raw = tmp_path / "raw.tif"
    shutil.copy(gcp_block["result"].members["nad"]["images"]["NAD"], raw)
    assert not dock.add_scene(str(raw))
    assert "names no scene file" in dock.message_label.text() and dock.scene_list.count() == 2


def test_snap_without_the_point_in_another_scene_says_so(dock, gcp_block):  # noqa: F811
    point_id = measured(dock, gcp_block)
    QTest.mouseClick(dock.snap_button, Qt.LeftButton)
    assert dock.message_label.text() == (f"point {point_id} is measured in no other scene: measure it there first, "
                                         "or snap to a reference orthoimage")
    dock.snap_combo.setCurrentText("reference orthoimage")
    QTest.mouseClick(dock.snap_button, Qt.LeftButton)
    assert dock.message_label.text() == "choose the reference orthoimage layer to snap to"


def test_a_scene_with_another_image_or_none_is_refused_and_nothing_is_written_beside_it(dock, gcp_block,  # noqa: F811
                                                                                         tmp_path):
    nad = gcp_block["result"].members["nad"]
    folder = tmp_path / "scene"
    folder.mkdir()
    shutil.copy(nad["onboard_scene"], folder / "scene.json")
    before = snapshot(folder, nad["images"]["NAD"].parent)
    assert not dock.add_scene(str(folder / "scene.json"))             # no raster of 500 x 500 px beside it
    assert "no raster of camera NAD's size (500 x 500 px) beside the scene file" in dock.message_label.text()
    assert not dock.add_scene(str(folder / "scene.json"), str(gcp_block["result"].reference))
    assert "692 x 692 pixels but camera NAD of the scene delivers 500 x 500" in dock.message_label.text()
    assert not dock.add_scene(str(folder / "scene.json"), str(nad["images"]["NAD"]), "FWD")
    assert "scene.json: camera 'FWD' is not in this scene" in dock.message_label.text()
    assert dock.add_scene(str(folder / "scene.json"), str(nad["images"]["NAD"]))  # named 'scene': a third view
    assert dock.scene_list.count() == 3
    assert_unchanged(before, [folder, nad["images"]["NAD"].parent])


def test_disposing_twice_warns_of_nothing(plugin, gcp_block, qgis_iface, qgis_new_project, capfd):  # noqa: F811
    """Markers on both canvases, the dock disposed twice (QGIS unloading the plugin after its own
    teardown began): no 'QGraphicsScene::removeItem: item's scene (0x0) is different' on stderr."""
    from pushbroom_adjust.ui.digitising.gcpdock import GcpDock
    dock = GcpDock(qgis_iface)
    dock.show()
    assert dock.add_scene(gcp_block["displays"]["nad"])
    measured(dock, gcp_block)
    dock.redraw()
    assert dock.drawing.items and dock.main_markers.drawing.items
    capfd.readouterr()
    dock.dispose()
    dock.dispose()
    assert "QGraphicsScene" not in capfd.readouterr().err
    assert dock.drawing.items == [] and dock.main_markers.drawing.items == []
