"""pushbroom:bundleadjust's SCENE_SIGMAS (each scene of a block its own onboard or vendor sigmas) as a
user gives it: processing.run (a flat list, row by row), qgis_process (a comma list, or the parameter
repeated once per value) and a graphical model, on the simulated TH-1 tri-stereo
(tests/support/tristereo_block.py: nadir, forward, backward scenes, each its own onboard errors of
about 10 m and 40 arcsec) tied without GCPs, so that nothing but the onboard sigmas holds where the
block lies. Bad values are refused naming SCENE_SIGMAS, the row and what was expected.

The nadir scene is stated far better than its true onboard error (0.5 m, 1 arcsec against ~10 m,
40 arcsec): it must then stay where its onboard model puts it, and the others come to it. That is
what the override does, right or wrong; tests/unit/adjust/test_scenesigmas.py shows a block nearer
the truth when the per-scene sigmas match the scenes' true error levels."""
import json
from pathlib import Path

import pytest
from qgis.core import QgsProcessingException

import processing
from tests.support.qgis_process import run_json
from tests.support.tristereo_block import ADJUST, NAMES, block_model, check_px, simulate_tristereo

HELD = ["nad", 0.5, 1.0, None]  # scene, position_sigma_m, attitude_sigma_arcsec, rpc_sigma_px (empty)


@pytest.fixture(scope="module")
def block(provider, tmp_path_factory) -> dict:
    return simulate_tristereo(tmp_path_factory.mktemp("block"), n_gcps=8)


def params(block, folder, **kw) -> dict:
    return {"SCENES": list(block["SCENES"]), "TIE_POINTS": block["TIE_POINTS"], **ADJUST,
            "OUTPUT_FOLDER": str(folder), **kw}


@pytest.fixture(scope="module")
def held(block, tmp_path_factory) -> dict:
    out = processing.run("pushbroom:bundleadjust", params(block, tmp_path_factory.mktemp("held") / "out",
                                                          SCENE_SIGMAS=HELD))
    return {"out": out, "after": check_px(block, out["ADJUSTED_SCENES"])}


def test_scene_sigmas_by_processing_run(block, held, tmp_path):
    """Measured (SEED 3, 60 tie points, no GCPs), check RMSE against the truth (px): onboard nad
    10.65, fwd 10.17, bwd 9.64; one common sigma (20 m, 60 arcsec) nad 6.82, fwd 10.56, bwd 9.26 (the
    block between the three onboard geolocations); nad with its own 0.5 m, 1 arcsec: nad 10.65 (held
    where its onboard model puts it), fwd 13.52, bwd 11.46 (brought to it). The report states each
    scene's sigmas, the log too."""
    common = check_px(block, processing.run("pushbroom:bundleadjust", params(block, tmp_path / "common"))[
        "ADJUSTED_SCENES"])
    before, after = check_px(block, block["SCENES"]), held["after"]
    assert abs(after["nad"] - before["nad"]) < 0.1 < 2.0 < before["nad"] - common["nad"], (before, after, common)
    assert after["fwd"] > common["fwd"] + 1.0 and after["bwd"] > common["bwd"] + 1.0, (after, common)
    report = json.loads(Path(held["out"]["OUTPUT_REPORT_JSON"]).read_text())
    scenes = report["scenes"]
    assert scenes["nad"]["sigmas"] == pytest.approx({"position_sigma_m": 0.5, "attitude_sigma_arcsec": 1.0,
                                                     "own": ["attitude_sigma", "position_sigma"]})
    for name in ("fwd", "bwd"):
        assert scenes[name]["sigmas"] == pytest.approx({"position_sigma_m": 20.0, "attitude_sigma_arcsec": 60.0,
                                                        "own": []}), name
    assert scenes["nad"]["moved_m"] < scenes["nad"]["onboard_sigma_m"] < 5.0 < 100.0 < scenes["fwd"]["onboard_sigma_m"]
    page = (Path(held["out"]["OUTPUT_FOLDER"]) / "block_report.html").read_text()
    assert "0.5 m (own), 1 arcsec (own)" in page and "20 m, 60 arcsec" in page


def assert_as_processing_run(block, held, out) -> None:
    after = check_px(block, out["ADJUSTED_SCENES"])
    assert all(abs(after[name] - held["after"][name]) < 1e-3 for name in NAMES), (after, held["after"])


def test_scene_sigmas_from_the_command_line(block, held, qgis_process, tmp_path):
    """qgis_process: SCENE_SIGMAS=nad,0.5,1, (one text, which QGIS splits at the commas), and the
    parameter repeated once per value (the empty cell an empty value): both as processing.run."""
    comma = run_json(qgis_process, "pushbroom:bundleadjust", **params(block, tmp_path / "a", SCENE_SIGMAS="nad,0.5,1,"))
    assert_as_processing_run(block, held, comma)
    repeated = run_json(qgis_process, "pushbroom:bundleadjust",
                        **params(block, tmp_path / "b", SCENE_SIGMAS=["nad", "0.5", "1", ""]))
    assert_as_processing_run(block, held, repeated)


def test_scene_sigmas_inside_a_graphical_model(block, held, tmp_path):
    model = block_model({"SCENE_SIGMAS": HELD}, gcps=False)
    valid, problems = model.validate()
    assert valid, problems
    out = processing.run(model, {"scenes": list(block["SCENES"]), "ties": block["TIE_POINTS"],
                                 "adjust:adjusted": str(tmp_path / "model")})
    assert_as_processing_run(block, held, {"ADJUSTED_SCENES": [
        Path(out["adjust:adjusted"]) / f"{name}_adjusted.json" for name in NAMES]})


@pytest.mark.parametrize("change, message", [
    ({"SCENE_SIGMAS": ["nad", "ten", None, None]},
     r"^SCENE_SIGMAS: row 1 \(nad\): position_sigma_m 'ten' is not a positive number; expected a positive number "
     r"or an empty cell"),
    ({"SCENE_SIGMAS": ["fwd", 5, None, None, "nad", None, -2, None]},
     r"^SCENE_SIGMAS: row 2 \(nad\): attitude_sigma_arcsec '-2' is not a positive number"),
    ({"SCENE_SIGMAS": ["nad", 0, None, None]}, r"^SCENE_SIGMAS: row 1 \(nad\): position_sigma_m '0' is not a positive"),
    ({"SCENE_SIGMAS": ["date9", 5, None, None]},
     r"^SCENE_SIGMAS: row 1: scene 'date9' is not in SCENES; expected one of the block's scenes \(nad, fwd, bwd"),
    ({"SCENE_SIGMAS": [None, 5, None, None]}, r"^SCENE_SIGMAS: row 1: no scene is named; expected one of"),
    ({"SCENE_SIGMAS": ["nad", None, None, None]},
     r"^SCENE_SIGMAS: row 1 \(nad\): no value; expected at least one of position_sigma_m, attitude_sigma_arcsec"),
    ({"SCENE_SIGMAS": ["nad", 5, None]}, r"^SCENE_SIGMAS: 3 values are not whole rows; expected rows of 4 values"),
    ({"SCENE_SIGMAS": ["nad", 5, None, None, "nad", 6, None, None]},
     r"^SCENE_SIGMAS: row 2: scene 'nad' is given twice; expected one row per scene"),
    ({"SCENE_SIGMAS": ["nad", 5, None, None], "POSITION_SIGMA": 0.0},
     r"^SCENE_SIGMAS: .*scene 'nad' overrides POSITION_SIGMA, whose global value is not given .*give POSITION_SIGMA "
     r"too; per-scene values override it"),
    ({"SCENE_SIGMAS": ["fwd", None, None, 5]},
     r"^SCENE_SIGMAS: .*scene 'fwd' is a rigorous scene: RPC_SIGMA is the prior of RPC products"),
    ({"SCENE_SIGMAS": ["nad", 2e6, None, None]}, r"^SCENE_SIGMAS: scene 'nad': POSITION_SIGMA must be between"),
])
def test_bad_scene_sigmas_are_refused_naming_the_parameter(block, tmp_path, change, message):
    with pytest.raises(QgsProcessingException, match=message):
        processing.run("pushbroom:bundleadjust", params(block, tmp_path / "out", **change))
    assert not (tmp_path / "out").exists()


def test_scene_sigmas_with_one_scene_are_refused(block, tmp_path):
    with pytest.raises(QgsProcessingException, match=r"^SCENE_SIGMAS: per-scene sigmas are for a block of scenes "
                                                      r"\(SCENES\); one SCENE takes POSITION_SIGMA"):
        processing.run("pushbroom:bundleadjust", {"SCENE": block["SCENES"][0], "TIE_POINTS": block["TIE_POINTS"],
                                                  "SCENE_SIGMAS": HELD, "OUTPUT_SCENE": str(tmp_path / "one.json")})
