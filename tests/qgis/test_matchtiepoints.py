"""pushbroom:matchtiepoints through processing.run and qgis_process on the small rendered
three-line scene (tests/matchscene.py): accuracy against the truth, the layer importtiepoints
writes, the log summary and the chain matchtiepoints -> bundleadjust."""
import numpy as np
import pytest

import processing
from pushbroom_adjust.core.observations import tiepoints
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.measure.finepass import SIGMA_FLOOR
from tests.support.matchscene import mini_tlc_scene
from tests.support.processing import RecordingFeedback

FIELDS = ["id", "camera", "col", "row", "sigma_px", "scene", "rays", "res_col", "res_row", "res_px"]


@pytest.fixture(scope="module")
def tlc(provider, tmp_path_factory):
    return mini_tlc_scene(tmp_path_factory.mktemp("mini_tlc_match"))


def params(sim, output, **kw) -> dict:
    return {"SCENE": str(sim.onboard_scene), "INPUTS": [str(sim.images[c]) for c in ("NAD", "FWD", "BWD")],
            "DEM": str(sim.dem), "DEM_DATUM": "geoid", "SPACING": 50, "SEARCH_RANGE": 300, "OUTPUT": str(output),
            **kw}


def truth_errors(sim, table) -> dict:
    """{camera: distances (px)} between each FWD/BWD observation and the true scene's projection of
    the true ground its NAD observation sees."""
    true, dem = load_scene(sim.true_scene), Dem(sim.dem, "geoid")
    base = table.camera == "NAD"
    where = {i: k for k, i in enumerate(table.id[base])}
    out = {}
    for k, name in ((1, "FWD"), (2, "BWD")):
        sel = table.camera == name
        b = np.array([where[i] for i in table.id[sel]])
        ground = true.image_to_ground_dem(table.col[base][b], table.row[base][b], dem, 0)
        col, row = true.ground_to_image(ground, k)
        out[name] = np.hypot(col - table.col[sel], row - table.row[sel])
    return out


@pytest.fixture(scope="module")
def matched(tlc, tmp_path_factory):
    log = RecordingFeedback()
    out = processing.run("pushbroom:matchtiepoints", params(tlc, tmp_path_factory.mktemp("m") / "ties.gpkg"),
                         feedback=log)
    return out["OUTPUT"], log


def test_matched_tie_points_are_accurate_and_tie_every_camera_pair(tlc, matched):
    out, _ = matched
    table = tiepoints.read_gpkg(out)
    assert table.apriori is not None and table.scene_path == str(tlc.onboard_scene)
    for name, e in truth_errors(tlc, table).items():
        assert e.size >= 400 and np.median(e) <= 0.1 and np.mean(e > 1) <= 0.03, (name, np.median(e))
    s = tiepoints.summary(table)
    assert s["pairs"]["NAD-FWD"] >= 400 and s["pairs"]["NAD-BWD"] >= 400 and s["pairs"]["FWD-BWD"] >= 250  # measured 483, 484, 300 (a short strip)
    assert s["single"] == 0 and set(s["cameras"]) == {"NAD", "FWD", "BWD"}
    assert np.all(table.sigma_px >= SIGMA_FLOOR)


def test_the_layer_and_the_log(tlc, matched):
    from qgis.core import QgsVectorLayer
    out, log = matched
    layer = QgsVectorLayer(out, "ties", "ogr")
    assert layer.isValid() and layer.fields().names()[1:] == FIELDS and layer.crs().authid() == "EPSG:4979"
    text = "\n".join(log.lines)
    # every grid point (23 x 29) of each pair matched or counted under a reason
    for name in ("FWD", "BWD"):
        line = next(x for x in log.lines if x.startswith(f"NAD-{name}: matched"))
        assert " of 667 grid points; rejected: " in line and "outside the other camera's image" in line
    assert "tie points per camera pair: NAD-FWD" in text and "FWD-BWD" in text
    assert f"camera FWD: {tlc.images['FWD']}" in text
    assert "a-priori intersection residuals" in text


def test_matched_tie_points_adjust_with_the_gcps(tlc, matched, tmp_path):
    """matchtiepoints -> bundleadjust: the matched layer is read directly as TIE_POINTS."""
    out, _ = matched
    gcps = processing.run("pushbroom:importgcps", {
        "SCENE": str(tlc.onboard_scene), "INPUT_FILE": str(tlc.gcps), "X_FIELD": "lon", "Y_FIELD": "lat",
        "Z_FIELD": "h", "Z_DATUM": "ellipsoid", "CAMERA_FIELD": "camera", "OUTPUT": str(tmp_path / "g.gpkg")})
    done = processing.run("pushbroom:bundleadjust", {"SCENE": str(tlc.onboard_scene), "GCPS": gcps["OUTPUT"],
                                                     "TIE_POINTS": out, "INTERIOR": "default",
                                                     "OUTPUT_SCENE": str(tmp_path / "adjusted.json")})
    true, adjusted, dem = load_scene(tlc.true_scene), load_scene(done["OUTPUT_SCENE"]), Dem(tlc.dem, "geoid")
    onboard = load_scene(tlc.onboard_scene)
    cc, rr = (a.ravel() for a in np.meshgrid(np.linspace(50, 1450, 8), np.linspace(50, 1150, 8)))
    ground = true.image_to_ground_dem(cc, rr, dem, 0)
    # measured: median 15.0 px before, 0.75 px after for BWD (the rest is what 20 GCPs with the
    # default INTERIOR leave of the simulated focal-length and installation errors)
    for k in (1, 2):  # the forward and backward cameras now agree with the truth where nadir sees
        col, row = true.ground_to_image(ground, k)
        before = np.hypot(*(np.subtract(onboard.ground_to_image(ground, k), (col, row))))
        after = np.hypot(*(np.subtract(adjusted.ground_to_image(ground, k), (col, row))))
        assert np.median(after) < min(1.0, 0.1 * np.median(before)), (k, np.median(before), np.median(after))


def test_matchtiepoints_through_qgis_process(tlc, tmp_path, qgis_process):
    output = tmp_path / "cli.gpkg"
    p = params(tlc, output, N_POINTS=200)
    images = p.pop("INPUTS")
    done = qgis_process("run", "pushbroom:matchtiepoints", "--", *(f"INPUTS={i}" for i in images),
                        *(f"{k}={v}" for k, v in p.items()))
    assert done.returncode == 0, done.stderr + done.stdout
    assert "rejected:" in done.stdout + done.stderr
    table = tiepoints.read_gpkg(output)
    assert 130 <= tiepoints.summary(table)["points"] <= 230
