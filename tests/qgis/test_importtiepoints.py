"""pushbroom:importtiepoints in real QGIS: the simulator's tie_points.csv through processing.run
and qgis_process, a table layer, the log summary and the style."""
import csv
import importlib

import numpy as np
import pytest
from qgis.core import (QgsFeature, QgsField, QgsRenderContext, QgsVectorLayer)
from qgis.PyQt.QtCore import QVariant

from tests.support.paths import PLUGIN
from tests.support.processing import RecordingFeedback

FIELDS = ["id", "camera", "col", "row", "sigma_px", "scene", "rays", "res_col", "res_row", "res_px"]


@pytest.fixture(scope="module")
def tiepoints(plugin):
    return importlib.import_module(f"{PLUGIN}.core.observations.tiepoints")


def _run(params, feedback=None):
    import processing
    return processing.run("pushbroom:importtiepoints", params, feedback=feedback)


def test_the_simulators_tie_points_import_as_they_are(three_line, tiepoints, tmp_path):
    """No field parameter: the columns id and camera are read under their own names."""
    rows = list(csv.DictReader(open(three_line["TIE_POINTS"])))
    log = RecordingFeedback()
    out = _run({"SCENE": three_line["ONBOARD_SCENE"], "INPUT_FILE": three_line["TIE_POINTS"], "SIGMA_PX": 0.3,
                "OUTPUT": str(tmp_path / "ties.gpkg")}, log)["OUTPUT"]
    layer = QgsVectorLayer(out, "ties", "ogr")
    assert layer.isValid() and layer.featureCount() == len(rows)
    assert layer.fields().names()[1:] == FIELDS and layer.crs().authid() == "EPSG:4979"
    table = tiepoints.read_gpkg(out)
    assert table.id.tolist() == [r["id"] for r in rows] and (table.sigma_px == 0.3).all()
    assert table.camera.tolist() == [r["camera"] for r in rows] and len(set(table.camera)) == 3
    assert table.scene_path == three_line["ONBOARD_SCENE"]
    s = tiepoints.summary(table)
    assert s["points"] == 40 and s["single"] == 0 and 1.0 < s["rms_px"] < 10.0
    histogram = ", ".join(f"{v} in {k} cameras" for k, v in sorted(s["cameras_per_point"].items()))
    assert f"40 tie points, {len(rows)} observations" in log.lines[0] and histogram in log.lines[0]
    assert any(f"RMS {s['rms_px']:.2f} px" in line for line in log.lines)


def test_the_plugins_own_layer_imports_as_it_is(three_line, tiepoints, tmp_path):
    """The layer importtiepoints wrote, imported again without field parameters (its fields id and
    camera read under their own names): the same observations."""
    first = _run({"SCENE": three_line["ONBOARD_SCENE"], "INPUT_FILE": three_line["TIE_POINTS"],
                  "OUTPUT": str(tmp_path / "a.gpkg")})["OUTPUT"]
    again = _run({"SCENE": three_line["ONBOARD_SCENE"], "INPUT": first, "OUTPUT": str(tmp_path / "b.gpkg")})["OUTPUT"]
    a, b = tiepoints.read_gpkg(first), tiepoints.read_gpkg(again)
    assert b.id.tolist() == a.id.tolist() and b.camera.tolist() == a.camera.tolist() and len(set(b.camera)) == 3
    assert (b.col == a.col).all() and (b.row == a.row).all()


def test_a_table_layer_with_other_field_names(three_line, tiepoints, tmp_path):
    rows = list(csv.DictReader(open(three_line["TIE_POINTS"])))
    layer = QgsVectorLayer("None", "ties", "memory")
    layer.dataProvider().addAttributes([QgsField("pid", QVariant.String), QgsField("cam", QVariant.String),
                                        QgsField("x", QVariant.Double), QgsField("y", QVariant.Double),
                                        QgsField("s", QVariant.Double)])
    layer.updateFields()
    features = []
    for k, r in enumerate(rows):
        f = QgsFeature(layer.fields())
        f.setAttributes([r["id"], r["camera"], float(r["col"]), float(r["row"]), 0.2 if k % 2 else None])
        features.append(f)
    layer.dataProvider().addFeatures(features)
    out = _run({"SCENE": three_line["ONBOARD_SCENE"], "INPUT": layer, "ID_FIELD": "pid", "CAMERA_FIELD": "cam",
                "COL_FIELD": "x", "ROW_FIELD": "y", "SIGMA_PX_FIELD": "s", "SIGMA_PX": 0.7,
                "OUTPUT": str(tmp_path / "ties.gpkg")})["OUTPUT"]
    table = tiepoints.read_gpkg(out)
    assert np.allclose(table.col, [float(r["col"]) for r in rows], atol=1e-9)
    assert table.sigma_px.tolist() == [0.2 if k % 2 else 0.7 for k in range(len(rows))]


def test_the_style_draws_intersected_points(three_line, tmp_path):
    from pathlib import Path
    out = _run({"SCENE": three_line["ONBOARD_SCENE"], "INPUT_FILE": three_line["TIE_POINTS"],
                "CAMERA_FIELD": "camera", "OUTPUT": str(tmp_path / "ties.gpkg")})["OUTPUT"]
    layer = QgsVectorLayer(out, "ties", "ogr")
    message, ok = layer.loadNamedStyle(str(Path(__file__).resolve().parents[2] / "resources/styles/tie_points.qml"))
    assert ok, message
    renderer = layer.renderer()
    labels = [r.label() for r in renderer.rootRule().children()]
    assert labels[0] == "Point seen in 3 or more cameras" and labels[1] == "Point seen in 2 cameras"
    context = QgsRenderContext()
    renderer.startRender(context, layer.fields())
    drawn = [bool(renderer.symbolsForFeature(f, context)) for f in layer.getFeatures()]
    renderer.stopRender(context)
    assert all(drawn)


def test_qgis_process_runs_it(three_line, qgis_process, tiepoints, tmp_path):
    out = tmp_path / "ties.gpkg"
    done = qgis_process("run", "pushbroom:importtiepoints", "--", f"SCENE={three_line['ONBOARD_SCENE']}",
                        f"INPUT_FILE={three_line['TIE_POINTS']}", f"OUTPUT={out}")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "40 tie points" in done.stdout + done.stderr
    assert tiepoints.summary(tiepoints.read_gpkg(out))["points"] == 40
