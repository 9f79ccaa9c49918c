"""Hostile input to pushbroom:importtiepoints: each case one bad tie-point input, refused with a
message naming what is wrong while the input and the output folder stay unchanged, or (a point
seen in one camera only) imported with a warning."""
import csv
import shutil

import pytest

from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.processing import RecordingFeedback


def _rows(three_line):
    return list(csv.DictReader(open(three_line["TIE_POINTS"])))


def _csv(path, rows, columns=("id", "camera", "col", "row")):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        w.writerows([[r.get(c, "") for c in columns] for r in rows])
    return path


def _edit(rows, point, **values):
    return [{**r, **values} if r["id"] == point else r for r in rows]


# Each case: (rows edit, extra parameters, texts in the message).
CASES = {
    "camera the scene lacks": (lambda rows: [{**r, "camera": "PAN"} if r["camera"] == "FWD" else r for r in rows],
                               {}, ["camera 'PAN'", "cameras: NAD, FWD, BWD"]),
    "duplicate observation": (lambda rows: rows + [rows[0]], {}, ["point id(s) T1 occur more than once"]),
    "all in one image corner": (lambda rows: [{**r, "col": float(r["col"]) / 20, "row": float(r["row"]) / 20}
                                              for r in rows], {}, ["one corner", "spread them"]),
    "all on a line": (lambda rows: [{**r, "col": 6000.5} for r in rows], {}, ["lie on a line"]),
    "outside the image": (lambda rows: _edit(rows, "T3", col=-50), {}, ["T3", "outside their camera's image"]),
    "non-numeric col": (lambda rows: _edit(rows, "T4", col="12O5.5"), {}, ["column 'col' is not a number", "T4"]),
    "empty row cell": (lambda rows: _edit(rows, "T6", row=""), {}, ["row is missing or not a number", "T6"]),
    "empty point id": (lambda rows: [{**rows[0], "id": ""}] + rows[1:], {}, ["empty point id in data line(s) 1"]),
    "missing field": (lambda rows: rows, {"COL_FIELD": "sample"}, ["no column 'sample'", "columns: id, camera"]),
    "no camera, three cameras": (lambda rows: [{**r, "camera": ""} for r in rows], {"CAMERA_FIELD": ""},
                                 ["have no camera", "NAD, FWD, BWD"]),
    "absurd image coordinate": (lambda rows: _edit(rows, "T8", col="1e15"), {}, ["T8", "beyond any image"]),
    "sigma field of text": (lambda rows: rows, {"SIGMA_PX_FIELD": "camera"}, ["per-point sigma field 'camera'"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_tie_points_are_refused(three_line, tmp_path, case):
    edit, extra, texts = CASES[case]
    source = _csv(tmp_path / "ties.csv", edit(_rows(three_line)))
    out = tmp_path / "out"
    out.mkdir()
    params = {"SCENE": three_line["ONBOARD_SCENE"], "INPUT_FILE": str(source), "CAMERA_FIELD": "camera",
              "OUTPUT": str(out / "ties.gpkg"), **extra}
    assert_refused("pushbroom:importtiepoints", params, *texts, watch=[source, out])


def test_a_file_without_ids_is_refused_naming_its_columns(three_line, tmp_path):
    """ID_FIELD empty (its default) reads the column id; a file without one is refused, its columns listed."""
    rows = [{**r, "pid": r["id"]} for r in _rows(three_line)]
    source = _csv(tmp_path / "ties.csv", rows, columns=("pid", "camera", "col", "row"))
    out = tmp_path / "out"
    out.mkdir()
    assert_refused("pushbroom:importtiepoints", {"SCENE": three_line["ONBOARD_SCENE"], "INPUT_FILE": str(source),
                                                 "OUTPUT": str(out / "ties.gpkg")},
                   "ties.csv", "no column 'id'", "columns: pid, camera, col, row", watch=[source, out])


def test_an_empty_file_is_refused(three_line, tmp_path):
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    assert_refused("pushbroom:importtiepoints", {"SCENE": three_line["ONBOARD_SCENE"], "INPUT_FILE": str(empty),
                                                 "CAMERA_FIELD": "camera", "OUTPUT": str(tmp_path / "o.gpkg")},
                   "empty.csv", "needs a header line", watch=[tmp_path])


def test_a_header_only_file_is_refused(three_line, tmp_path):
    source = _csv(tmp_path / "ties.csv", [])
    assert_refused("pushbroom:importtiepoints", {"SCENE": three_line["ONBOARD_SCENE"], "INPUT_FILE": str(source),
                                                 "CAMERA_FIELD": "camera", "OUTPUT": str(tmp_path / "o.gpkg")},
                   "ties.csv", "at least one point", watch=[tmp_path])


@pytest.mark.parametrize("both", [True, False])
def test_input_and_input_file_both_or_neither(three_line, tmp_path, both):
    source = _csv(tmp_path / "ties.csv", _rows(three_line))
    params = {"SCENE": three_line["ONBOARD_SCENE"], "CAMERA_FIELD": "camera", "OUTPUT": str(tmp_path / "o.gpkg")}
    if both:
        params.update(INPUT_FILE=str(source), INPUT=str(source))
    assert_refused("pushbroom:importtiepoints", params, "INPUT_FILE", "INPUT", "both" if both else "neither",
                   watch=[tmp_path])


def test_output_onto_the_input_is_refused(three_line, tmp_path):
    source = tmp_path / "ties.gpkg"
    shutil.copy(three_line["TIE_POINTS"], tmp_path / "ties.csv")
    import processing
    processing.run("pushbroom:importtiepoints", {"SCENE": three_line["ONBOARD_SCENE"],
                                                 "INPUT_FILE": str(tmp_path / "ties.csv"), "CAMERA_FIELD": "camera",
                                                 "OUTPUT": str(source)})
    assert_refused("pushbroom:importtiepoints", {"SCENE": three_line["ONBOARD_SCENE"], "INPUT": str(source),
                                                 "CAMERA_FIELD": "camera", "OUTPUT": str(source)},
                   "OUTPUT", watch=[tmp_path])


def test_a_scene_that_is_no_scene(three_line, tmp_path):
    source = _csv(tmp_path / "ties.csv", _rows(three_line))
    assert_refused("pushbroom:importtiepoints", {"SCENE": str(source), "INPUT_FILE": str(source),
                                                 "CAMERA_FIELD": "camera", "OUTPUT": str(tmp_path / "o.gpkg")},
                   "SCENE", watch=[tmp_path])


def test_output_not_a_geopackage(three_line, tmp_path):
    source = _csv(tmp_path / "ties.csv", _rows(three_line))
    assert_refused("pushbroom:importtiepoints", {"SCENE": three_line["ONBOARD_SCENE"], "INPUT_FILE": str(source),
                                                 "CAMERA_FIELD": "camera", "OUTPUT": str(tmp_path / "o.shp")},
                   "OUTPUT", "GeoPackage", watch=[tmp_path])


def test_camera_the_scene_lacks_through_qgis_process(three_line, qgis_process, tmp_path):
    rows = [{**r, "camera": "PAN"} if r["camera"] == "BWD" else r for r in _rows(three_line)]
    source = _csv(tmp_path / "ties.csv", rows)
    assert_refused_cli(qgis_process, "pushbroom:importtiepoints",
                       {"SCENE": three_line["ONBOARD_SCENE"], "INPUT_FILE": source, "CAMERA_FIELD": "camera",
                        "OUTPUT": tmp_path / "o.gpkg"}, "camera 'PAN'", watch=[tmp_path])


def test_a_point_seen_in_one_camera_is_kept_with_a_warning(three_line, tmp_path):
    """Legitimate input (the other cameras' measurements failed): imported, named, not intersected."""
    rows = [r for r in _rows(three_line) if not (r["id"] == "T2" and r["camera"] != "NAD")]
    source = _csv(tmp_path / "ties.csv", rows)
    import processing
    log = RecordingFeedback()
    out = processing.run("pushbroom:importtiepoints", {"SCENE": three_line["ONBOARD_SCENE"],
                                                       "INPUT_FILE": str(source), "CAMERA_FIELD": "camera",
                                                       "OUTPUT": str(tmp_path / "o.gpkg")}, feedback=log)["OUTPUT"]
    assert any("seen in one camera only" in w and "T2" in w for w in log.warnings), log.warnings
    assert any("1 point(s) seen in one camera only" in w and "left out of the adjustment" in w for w in log.warnings)
    from qgis.core import QgsVectorLayer
    layer = QgsVectorLayer(out, "o", "ogr")
    single = [f for f in layer.getFeatures() if f["id"] == "T2"]
    assert len(single) == 1 and single[0]["rays"] == 1 and single[0].geometry().isEmpty()
