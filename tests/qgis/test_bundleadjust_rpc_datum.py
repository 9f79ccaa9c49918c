"""pushbroom:bundleadjust on the real Pleiades pair over Giza tied without GCPs (issue 28), through
processing.run as a user runs it: the RPC correction chosen by default and said so, the datum directions
the ties leave to the priors in the log and block_report.json, no 'nan' and no internal names in what a
user reads, and a robust loop stopped at its pass limit named in the log, block_report.json and
block_report.html (the single-scene report JSON: tests/qgis/test_hostile_adjust.py). The tie sets:
matched by pushbroom:matchtiepoints (40 px grid, 31 px window, 60 m search), and
tests/data/pleiades_gizeh/ties_swinging.csv (a loose set on which the loop once swung, see
tests/scenarios/test_robust_convergence.py). About 10 s."""
import json
import math

import pytest
from qgis.core import QgsProcessingException

import processing
from tests.support.processing import RecordingFeedback
from pushbroom_adjust.core.observations import tiepoints

NAMES = ("img1", "img2")
LIMIT = "robust estimation stopped at its limit of 1 passes; the flags may be incomplete"


@pytest.fixture(scope="module")
def giza(provider, shared_data, tmp_path_factory) -> dict:
    gizeh = shared_data / "pleiades_gizeh"
    folder = tmp_path_factory.mktemp("giza")
    scenes = [str(gizeh / f"{n}_RPC.TXT") for n in NAMES]
    matched = processing.run("pushbroom:matchtiepoints", {
        "SCENES": scenes, "INPUTS": [str(gizeh / f"{n}.tif") for n in NAMES], "HEIGHT": 75.0,
        "SPACING": 40.0, "WINDOW": 31, "SEARCH_RANGE": 60.0, "OUTPUT": str(folder / "ties.gpkg")})
    swinging = folder / "swinging.gpkg"
    tiepoints.write_gpkg(tiepoints.read_csv(gizeh / "ties_swinging.csv", tiepoints.CsvMapping(sigma_px="sigma_px")),
                         swinging)
    return {"SCENES": scenes, "matched": matched["OUTPUT"], "swinging": str(swinging)}


def strict_json(path) -> dict:
    """The JSON file, refusing NaN and infinities (which strict JSON has not)."""
    def refuse(constant):
        raise AssertionError(f"{path}: {constant} in the JSON")
    return json.loads(path.read_text(), parse_constant=refuse)


def test_a_ties_only_block_says_which_correction_and_what_the_priors_hold(giza, tmp_path):
    log = RecordingFeedback()
    processing.run("pushbroom:bundleadjust", {"SCENES": giza["SCENES"], "TIE_POINTS": giza["matched"],
                                              "RPC_SIGMA": 10.0, "OUTPUT_FOLDER": str(tmp_path)}, feedback=log)
    assert "RPC_CORRECTION: shift, the default for a block with fewer than 3 control points: its tie points do not " \
           "determine the height tilt drift terms would let in" in log.lines
    assert not [line for line in log.lines if "nan" in line.split() or "settings." in line]
    assert any(line.startswith("sigma0 ") and "control residuals: no control points" in line for line in log.lines)
    held = [line for line in log.lines if line.startswith("block of 2 scenes")]
    assert len(held) == 1 and "the ties leave to the priors the height shift (the priors' sigma" in held[0]
    report = strict_json(tmp_path / "block_report.json")
    assert report["adjustment"]["settings"]["rpc_correction"] == "shift"
    height = {d["direction"]: d for d in report["datum_directions"]}["height shift"]
    assert height["held_by"] == "priors" and abs(height["moved_m"]) < height["prior_sigma_m"]
    assert report["block"]["control_rmse_px"] is None and report["warnings"] == []
    assert "Control residuals: no control points" in (tmp_path / "block_report.html").read_text()


def test_without_rpc_sigma_the_refusal_names_the_parameter(giza, tmp_path):
    with pytest.raises(QgsProcessingException) as err:
        processing.run("pushbroom:bundleadjust", {"SCENES": giza["SCENES"], "TIE_POINTS": giza["matched"],
                                                  "OUTPUT_FOLDER": str(tmp_path / "out")})
    text = str(err.value)
    assert text.startswith("RPC_SIGMA: datum defect") and "Give RPC_SIGMA (the vendor's stated accuracy" in text
    assert "settings." not in text and not (tmp_path / "out").exists()


def test_the_swinging_tie_set_converges_and_a_loop_at_its_limit_says_so_everywhere(giza, tmp_path):
    run = {"SCENES": giza["SCENES"], "TIE_POINTS": giza["swinging"], "RPC_SIGMA": 10.0, "RPC_CORRECTION": "drift"}
    log = RecordingFeedback()
    processing.run("pushbroom:bundleadjust", {**run, "OUTPUT_FOLDER": str(tmp_path / "all")}, feedback=log)
    robust = strict_json(tmp_path / "all" / "block_report.json")["adjustment"]["robust"]
    assert not robust["stopped_at_limit"] and robust["held_flagged"] > 0
    assert not [w for w in log.warnings if "stopped at its limit" in w]
    log = RecordingFeedback()
    processing.run("pushbroom:bundleadjust", {**run, "MAX_ROBUST_PASSES": 1, "OUTPUT_FOLDER": str(tmp_path / "one")},
                   feedback=log)
    assert log.warnings.count(LIMIT) == 1
    report = strict_json(tmp_path / "one" / "block_report.json")
    assert LIMIT in report["warnings"] and LIMIT in report["adjustment"]["warnings"]
    assert (tmp_path / "one" / "block_report.html").read_text().count(LIMIT) == 1
    assert not math.isnan(report["block"]["sigma0"])
