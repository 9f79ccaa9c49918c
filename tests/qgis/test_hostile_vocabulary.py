"""Hostile input to the parameter vocabulary (issue 15): option numbers from old scripts,
unknown or miscased value names, lists, data-defined numbers and Z values of unstated datum
are refused with the parameter's value names, before anything is written; Z values whose
datum the layer's CRS states are read in that datum."""
import numpy as np
import pytest
from qgis.core import (QgsFeature, QgsGeometry, QgsPoint, QgsProcessingException, QgsProcessingModelAlgorithm, QgsProcessingModelChildAlgorithm,
                       QgsProcessingModelChildParameterSource, QgsProcessingModelOutput, QgsProperty, QgsVectorLayer)

import processing
from pushbroom_adjust.core.dem import to_ellipsoidal
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.core.formats import load_scene

from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.processing import RecordingFeedback

DATUMS = "geoid, ellipsoid"


def _points_z(crs: str, lon, lat, h) -> QgsVectorLayer:
    layer = QgsVectorLayer(f"PointZ?crs={crs}&field=name:string", "points", "memory")
    features = []
    for i, (x, y, z) in enumerate(zip(lon, lat, h)):
        f = QgsFeature(layer.fields())
        f.setGeometry(QgsGeometry(QgsPoint(float(x), float(y), float(z))))
        f.setAttributes([f"p{i}"])
        features.append(f)
    layer.dataProvider().addFeatures(features)
    return layer


@pytest.fixture(scope="module")
def truth(simulated):
    """Image points of the true scene and their ground points (lon, lat, ellipsoidal h)."""
    scene = load_scene(simulated["TRUE_SCENE"])
    cam = scene.cameras[0]
    col, row = np.array([0.3, 0.5, 0.7]) * cam.cols, np.array([0.2, 0.5, 0.8]) * cam.rows
    lon, lat, h = ecef_to_geodetic(scene.image_to_ground(col, row, np.full(3, 250.0)))
    return col, row, lon, lat, h


# (algorithm, the bad parameters, texts the message must hold); SCENE etc. are added below.
CASES = {
    "old DEM_DATUM index of importgcps": (
        "importgcps", {"DEM_DATUM": 1}, ["DEM_DATUM", "option number", DATUMS]),
    "old Z_DATUM index (0 was ellipsoid here, geoid in DEM_DATUM)": (
        "groundtoimage", {"Z_DATUM": 0}, ["Z_DATUM: 0 is an option number", DATUMS]),
    "index given as text": (
        "bundleadjust", {"POSITION_MODEL": "1"}, ["POSITION_MODEL: 1", "polynomial, lagrange, spline"]),
    "old preset index": (
        "simulatescene", {"PRESET": 2}, ["PRESET", "cbers02b_hrc, th1_tlc, zy3_tlc"]),
    "index out of range": (
        "orthorectify", {"RESAMPLING": 5}, ["RESAMPLING: 5 is an option number", "nearest, bilinear, cubic"]),
    "index as a float": (
        "importgcps", {"HEIGHT_SOURCE": 1.0}, ["HEIGHT_SOURCE: 1.0 is an option number", "z, dem, constant"]),
    "value name in another case": (
        "orthorectify", {"RESAMPLING": "Bilinear"}, ["RESAMPLING", "did you mean 'bilinear'"]),
    "the old readable label": (
        "footprint", {"DEM_DATUM": "Ellipsoid (WGS84)"}, ["DEM_DATUM: 'Ellipsoid (WGS84)' is not a value", DATUMS]),
    "unknown method": (
        "bundleadjust", {"ROBUST": "huber"}, ["ROBUST: 'huber'", "none, selection, snooping"]),
    "a list for a single choice": (
        "bundleadjust", {"ON_SINGULAR": ["fix", "stop"]}, ["ON_SINGULAR: takes one value, not a list", "fix, stop"]),
}


def _base_parameters(alg: str, simulated, out) -> dict:
    scene = {"SCENE": simulated["ONBOARD_SCENE"]}
    return {
        "importgcps": {**scene, "INPUT_FILE": simulated["GCPS"], "Z_FIELD": "h", "OUTPUT": str(out / "g.gpkg")},
        "groundtoimage": {**scene, "INPUT": simulated["GCPS"], "OUTPUT": str(out / "p.gpkg")},
        "bundleadjust": {**scene, "OUTPUT_SCENE": str(out / "a.json"), "OUTPUT_REPORT": str(out / "r.html")},
        "simulatescene": {"N_GCPS": 10, "OUTPUT_FOLDER": str(out / "sim")},
        "orthorectify": {**scene, "INPUT": simulated["DEM"], "OUTPUT": str(out / "o.tif")},
        "footprint": {**scene, "OUTPUT": str(out / "f.gpkg")},
    }[alg]


@pytest.mark.parametrize("case", list(CASES))
def test_a_bad_choice_is_refused_with_the_names(simulated, tmp_path, case):
    alg, bad, texts = CASES[case]
    params = {**_base_parameters(alg, simulated, tmp_path), **bad}
    assert_refused(f"pushbroom:{alg}", params, *texts, watch=[tmp_path, simulated["OUTPUT_FOLDER"]])


def test_a_data_defined_option_number_is_refused(simulated, tmp_path):
    """A model's data-defined value passes QGIS's check; the algorithm refuses its number."""
    params = {"SCENE": simulated["TRUE_SCENE"], "DEM": simulated["DEM"], "SAMPLES": 8,
              "DEM_DATUM": QgsProperty.fromValue(1), "OUTPUT": str(tmp_path / "f.gpkg")}
    assert_refused("pushbroom:footprint", params, "DEM_DATUM: 1 is an option number", DATUMS, watch=[tmp_path])


def test_z_values_of_unstated_datum_are_refused_by_importgcps(simulated, tmp_path):
    """An old command line (DEM_DATUM=ellipsoid for the GCP file's Z) no longer states the Z
    values' datum: refused, never read with the DEM's datum or a default."""
    params = {"SCENE": simulated["ONBOARD_SCENE"], "INPUT_FILE": simulated["GCPS"], "Z_FIELD": "h",
              "DEM_DATUM": "ellipsoid", "OUTPUT": str(tmp_path / "g.gpkg")}
    assert_refused("pushbroom:importgcps", params, "Z_DATUM: HEIGHT_SOURCE is z", "EPSG:4326",
                   "Z_DATUM=geoid or Z_DATUM=ellipsoid", "DEM_DATUM is the DEM's datum only",
                   watch=[tmp_path, simulated["OUTPUT_FOLDER"]])


def test_z_values_of_unstated_datum_are_refused_by_groundtoimage(simulated, truth, tmp_path):
    _, _, lon, lat, h = truth
    params = {"SCENE": simulated["TRUE_SCENE"], "INPUT": _points_z("EPSG:4326", lon, lat, h),
              "OUTPUT": str(tmp_path / "p.gpkg")}
    assert_refused("pushbroom:groundtoimage", params, "Z_DATUM: 3 points have Z values", "EPSG:4326",
                   "Z_DATUM=geoid or Z_DATUM=ellipsoid", "USE_Z=false", watch=[tmp_path])


def test_z_values_in_epsg_4979_are_read_as_ellipsoidal(simulated, truth):
    """Legitimate: a 3D geographic CRS says its heights are ellipsoidal; the points land on the
    pixels they came from. Z_DATUM, when given, wins over the CRS."""
    col, row, lon, lat, h = truth
    layer = _points_z("EPSG:4979", lon, lat, h)
    got = {}
    for datum in (None, "ellipsoid", "geoid"):
        params = {"SCENE": simulated["TRUE_SCENE"], "INPUT": layer, "OUTPUT": "memory:"}
        if datum:
            params["Z_DATUM"] = datum
        out = processing.run("pushbroom:groundtoimage", params)["OUTPUT"]
        got[datum] = np.array([[f["col"], f["row"]] for f in out.getFeatures()])
    assert np.abs(got[None] - np.stack([col, row], axis=1)).max() < 1e-3
    assert np.array_equal(got[None], got["ellipsoid"])
    # Z_DATUM=geoid overrides the CRS: the heights are raised by the undulation (about -20 m here)
    h_from_geoid = to_ellipsoidal(lon, lat, h, "geoid")
    assert -40 < np.mean(h_from_geoid - h) < -5
    scene = load_scene(simulated["TRUE_SCENE"])
    expected = np.stack(scene.ground_to_image(geodetic_to_ecef(lon, lat, h_from_geoid), 0), axis=1)
    assert np.abs(got["geoid"] - expected).max() < 1e-3 < np.abs(got["geoid"] - got[None]).max()


@pytest.mark.parametrize("bad, texts", [
    ("DEM_DATUM=1", ["DEM_DATUM: 1 is an option number", DATUMS]),
    ("DEM_DATUM=GEOID", ["DEM_DATUM: 'GEOID'", "did you mean 'geoid'"]),
    ("DEM_DATUM=egm96", ["DEM_DATUM: 'egm96' is not a value", DATUMS]),
])
def test_a_bad_choice_on_the_command_line_is_refused(qgis_process, simulated, tmp_path, bad, texts):
    name, value = bad.split("=")
    params = {"SCENE": simulated["TRUE_SCENE"], "DEM": simulated["DEM"], name: value,
              "OUTPUT": str(tmp_path / "f.gpkg")}
    assert_refused_cli(qgis_process, "pushbroom:footprint", params, *texts, watch=[tmp_path])


def test_a_saved_model_with_an_option_number_is_refused(simulated, tmp_path):
    """A model saved before the names (static value 1 for DEM_DATUM, once 'ellipsoid'): the modeler
    marks the step, and a run stops there with the names in the log instead of reading a datum."""
    model = QgsProcessingModelAlgorithm("old model", "tests")
    child = QgsProcessingModelChildAlgorithm("pushbroom:footprint")
    child.setChildId("footprint")
    for name, value in (("SCENE", simulated["TRUE_SCENE"]), ("DEM", simulated["DEM"]), ("DEM_DATUM", 1),
                        ("SAMPLES", 8), ("HEIGHT", 0.0)):
        child.addParameterSources(name, [QgsProcessingModelChildParameterSource.fromStaticValue(value)])
    output = QgsProcessingModelOutput("footprints")
    output.setChildOutputName("OUTPUT")
    child.setModelOutputs({"footprints": output})
    model.addChildAlgorithm(child)
    model.updateDestinationParameters()
    valid, problems = model.validate()  # the modeler marks the step
    assert not valid and "Value for <i>DEM_DATUM</i> is not acceptable" in problems[0]
    feedback = RecordingFeedback()
    with pytest.raises(QgsProcessingException, match="Error encountered while running"):
        processing.run(model, {"footprint:footprints": str(tmp_path / "f.gpkg")}, feedback=feedback)
    assert any(e.startswith("DEM_DATUM: 1 is an option number") and e.endswith(DATUMS) for e in feedback.errors)
    assert list(tmp_path.iterdir()) == []
