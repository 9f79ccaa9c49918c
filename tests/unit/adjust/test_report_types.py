"""The report types (core/adjust/report_types.py): a report reads as its JSON, in its keys' order,
with the sections a run lacks left out; it cannot be changed once built; its warnings, datum
sentence and block summary follow from its figures."""
import dataclasses
import json

import pytest

from pushbroom_adjust.core.adjust.report import log_lines, report_to_json
from pushbroom_adjust.core.adjust.report_types import AdjustmentReport, BlockReport

KEYS = ["settings", "observations", "iterations", "robust", "reliability", "sigma0", "sigma0_adjusted", "sigma0_test",
        "variance_components", "determinability", "parameters", "high_correlations", "control_residuals",
        "control_ground", "control_residuals_per_chip", "check_points", "check_points_before", "trajectory"]
STAGES = ["interior_selection", "rpc_correction", "trajectory_prior", "written_vs_fitted"]
HELD = {"held_by": "onboard pseudo-observations", "note": "no control points", "directions": []}


def report(**kw) -> AdjustmentReport:
    """A small report of 3 control points, none flagged, the robust loop done in 2 passes."""
    fields = {
        "settings": {"robust": "selection_weights", "position_sigma": 10.0, "attitude_sigma": None},
        "observations": {"control_points": 3, "tie_points": {"points": 7}},
        "iterations": [{"rms": 1.0}], "robust": {"passes": [1, 2], "stopped_at_limit": False, "flagged": 0},
        "reliability": {"reliable": True, "problems": []}, "sigma0": 0.9, "sigma0_adjusted": 0.9,
        "sigma0_test": {"passed": True}, "variance_components": {}, "determinability": [], "parameters": [],
        "high_correlations": [], "control_residuals": {"count": 3, "rmse_col": 0.1, "rmse_row": 0.2},
        "control_ground": None, "control_residuals_per_chip": {}, "check_points": {}, "check_points_before": {},
        "trajectory": None, "tie_points": None, "lines": None, "interior_selection": None, "rpc_correction": None,
        "trajectory_prior": None, "written_vs_fitted": {"max_px": 0.0}, "datum": None}
    return AdjustmentReport(**{**fields, **kw})


def test_the_json_keeps_its_keys_order_and_leaves_out_what_a_run_lacks():
    assert list(report()) == KEYS + STAGES + ["warnings"]
    with_all = report(tie_points={"points": 7}, lines={"lines": 2}, datum=HELD)
    assert list(with_all) == KEYS + ["tie_points", "lines"] + STAGES + ["datum", "warnings"]
    assert "datum" not in report() and report().get("lines") is None
    with pytest.raises(KeyError):
        report()["datum"]
    assert json.loads(report_to_json(with_all)) == json.loads(json.dumps(with_all.as_dict()))


def test_a_built_report_cannot_be_changed():
    rep = report()
    with pytest.raises(TypeError):
        rep["warnings"] = []
    with pytest.raises(dataclasses.FrozenInstanceError):
        rep.datum = HELD


def test_warnings_follow_from_the_robust_loop_the_reliability_and_the_datum():
    assert report().warnings == []
    problem = {"message": "camera B is held by 2 points", "reliable": False}
    rep = report(robust={"passes": [1, 2, 3], "stopped_at_limit": True, "flagged": 0},
                 reliability={"reliable": False, "problems": [problem]})
    assert rep["warnings"] == ["robust estimation stopped at its limit of 3 passes; the flags may be incomplete",
                               "camera B is held by 2 points; the result is not reliable"]


def test_one_datum_sentence_for_the_log_and_the_block():
    rep = report(datum=HELD)
    said = [line.text for line in log_lines(rep, 20)]
    assert "datum held by onboard pseudo-observations: no control points" in said
    block = BlockReport({"scenes": 2, "sigma0": 0.9, "tie_rmse_px": 0.31, "tie_rmse_before_px": None}, {}, [], rep)
    assert block["datum"] == "datum held by the onboard pseudo-observations: no control points"
    assert BlockReport({}, {}, [], report())["datum"] == "datum held by the control points (no tie points)"
    lines = report(lines={"lines": 2}, observations={"control_points": 0, "tie_points": {"points": 0}})
    assert BlockReport({}, {}, [], lines)["datum"] == "datum held by the control lines (no tie points)"
    assert block.summary_sentence() == ("block of 2 scenes: sigma0 0.900, tie RMS - before, 0.310 px after; datum "
                                        "held by the onboard pseudo-observations: no control points")


def test_the_scene_record_keeps_what_the_adjusted_scene_carries():
    rep = report(datum={**HELD, "yaw": {"sigma_arcsec": 5.7}, "extra": 1},
                 parameters=[{"name": "a", "value": 0.0, "sigma": None, "unit": "px", "mode": "fixed"},
                             {"name": "b", "value": 0.5, "sigma": 0.1, "unit": "px", "mode": "free", "block": "x"}])
    record = rep.scene_record()
    assert [p["name"] for p in record["parameters"]] == ["b"] and "block" not in record["parameters"][0]
    assert record["datum"] == {**HELD, "yaw": {"sigma_arcsec": 5.7}} and record["tie_points"] == 7
    assert "lines" not in record and "datum" not in report().scene_record()
