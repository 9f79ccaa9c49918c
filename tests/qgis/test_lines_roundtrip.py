"""The digitising dock's saved image_lines layer round-trips through pushbroom:importlines and
pushbroom:bundleadjust LINES: lines digitised with mouse events on the dock's canvas and paired
on the main canvas (as tests/qgis/test_digitising.py drives them) adjust the scene."""
import json

import numpy as np
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtTest import QTest

import processing

from tests.support.digitising import click, digitise, pick, true_points, zoom_to
from tests.support.digitising import ground_layer, prepared, roads  # noqa: F401 (the fixtures)

LINES = ("R1", "R2", "R3", "R4", "R5", "R6")


def test_dock_lines_round_trip_through_importlines_and_bundleadjust(plugin, prepared, roads, ground_layer,  # noqa: F811
                                                                    qgis_iface, qgis_canvas, tmp_path):
    from pushbroom_adjust.ui.digitising.dock import DigitisingDock
    dock = DigitisingDock(qgis_iface)
    dock.resize(600, 900)
    dock.show()
    assert dock.open_image(prepared["OUTPUT"])
    dock.ground_combo.setLayer(ground_layer)
    dock.id_combo.setField("line_id")
    ground = {f["line_id"]: np.array(f.geometry().asPolyline()) for f in ground_layer.getFeatures()}
    digitised = []
    for line_id in LINES:
        truth = true_points(roads, line_id)
        if truth.shape[0] < 4:
            continue  # a road the camera barely sees
        truth = truth[::2]
        zoom_to(dock.canvas, truth)
        digitise(dock, truth)
        click(dock.canvas, 10, 10, Qt.RightButton)
        QTest.mouseClick(dock.pair_button, Qt.LeftButton)
        middle = ground[line_id][len(ground[line_id]) // 2]
        pick(qgis_canvas, middle[0], middle[1])
        assert dock.editor.lines[-1].line_id == line_id, dock.message_label.text()
        digitised.append(line_id)
    saved = tmp_path / "digitised.gpkg"
    assert dock.save(str(saved)), dock.message_label.text()
    dock.dispose()
    assert len(digitised) >= 4

    result = roads["result"]
    control_lines = tmp_path / "control_lines.gpkg"
    processing.run("pushbroom:importlines", {
        "SCENE": str(result.onboard_scene), "INPUT": f"{result.lines}|layername=ground_lines",
        "IMAGE_LINES": f"{saved}|layername=image_lines", "HEIGHT_SOURCE": "z", "Z_DATUM": "ellipsoid",
        "OUTPUT": str(control_lines)})
    gcps = tmp_path / "gcps.gpkg"
    processing.run("pushbroom:importgcps", {
        "SCENE": str(result.onboard_scene), "INPUT_FILE": str(result.gcps), "Z_FIELD": "h", "HEIGHT_SOURCE": "z",
        "Z_DATUM": "ellipsoid", "OUTPUT": str(gcps)})
    done = processing.run("pushbroom:bundleadjust", {
        "SCENE": str(result.onboard_scene), "GCPS": str(gcps), "LINES": str(control_lines),
        "POSITION_MODEL": "polynomial", "POSITION_ORDER": 1, "ATTITUDE_MODEL": "polynomial", "ATTITUDE_ORDER": 1,
        "OUTPUT_SCENE": str(tmp_path / "adjusted.json"), "OUTPUT_REPORT": str(tmp_path / "report.html"),
        "OUTPUT_LINE_RESIDUALS": str(tmp_path / "line_residuals.gpkg")})
    rep = json.loads(open(done["OUTPUT_REPORT_JSON"]).read())["lines"]
    assert sorted(rep["per_line"]["line_id"]) == sorted(digitised)
    assert rep["flagged_lines"] == 0
    # clicks within a screen pixel of the true image of the road (a few px at this zoom), the
    # map 1 m off: the adjusted rays meet the roads within a few GSD (2.36 m)
    assert rep["across_rmse_m"] < 10.0 < rep["across_rmse_before_m"]
