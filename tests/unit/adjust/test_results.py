"""core.adjust.results: the result built from a solution (:func:`result_of`) on a simulated CBERS-02B HRC
scene with known errors: 200 control and 200 check points, 0.7 px image noise, 3 m / 10 m ground
noise, and 5 % of all image measurements displaced by 5-30 px (the simulation's ``gross`` column:
8 control and 12 check observations). Its figures are recomputed here from the returned per-point
arrays and, for the check points, from the adjusted scene's own ground -> image."""
import numpy as np
import pytest

from pushbroom_adjust.core.adjust.checks import check_inputs
from pushbroom_adjust.core.adjust.estimation import estimate
from pushbroom_adjust.core.adjust.problem import Problem
from pushbroom_adjust.core.adjust.report_types import StageOutcomes
from pushbroom_adjust.core.adjust.results import result_of
from tests.support.cbers_strip import settings, strip


def rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a * a)))


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """(the result, the problem, the checked table, the ids of the displaced rows, the estimate)."""
    sim, scene, table = strip(tmp_path_factory.mktemp("results"), 1, 400, seed=6, gross_fraction=0.05,
                              gross_min=5.0, gross_max=30.0)
    s = settings(interior="HRC-1.*, HRC-3.*", robust="selection")
    table = check_inputs(scene, table, s)
    problem = Problem(scene, table, s)
    est = estimate(problem, lambda *a: None, lambda: False)
    out = result_of(problem, table, problem.params.adjusted_scene(), est,
                    StageOutcomes([], None, None, None, None, None))
    g = np.genfromtxt(sim.gcps, delimiter=",", names=True, dtype=None, encoding=None)
    return out, problem, table, set(g["id"][g["gross"].astype(bool)].astype(str)), est


def test_control_figures_are_those_of_the_returned_residuals_with_the_flagged_left_out_and_counted(built):
    """Measured: 8 control observations flagged (exactly the displaced ones), 192 counted; RMSE
    0.337 / 0.338 px (col / row: the 0.7 px noise times the root of the redundancy, ~0.22)."""
    out, problem, table, displaced, _ = built
    rep, pts = out.report, out.points
    control = pts["role"] == "control"
    flagged = pts["flagged"] & control
    assert rep["observations"]["control_points"] == 200 and rep["observations"]["check_points"] == 200
    assert rep["observations"]["unknowns"] == 30 and rep["observations"]["degrees_of_freedom"] == 382
    assert rep["robust"]["flagged"] == flagged.sum() == 8
    assert set(rep["robust"]["flagged_ids"]) == set(pts["id"][flagged]) == displaced & set(pts["id"][control])
    kept = control & ~pts["flagged"]
    summary = rep["control_residuals"]
    assert summary["count"] == kept.sum() == 192
    assert summary["rmse_col"] == pytest.approx(rms(pts["res_col"][kept]), rel=1e-12)
    assert summary["rmse_row"] == pytest.approx(rms(pts["res_row"][kept]), rel=1e-12)
    assert summary["max"] == pytest.approx(pts["res_px"][kept].max(), rel=1e-12)
    assert 0.25 < summary["rmse_col"] < 0.45 and 0.25 < summary["rmse_row"] < 0.45
    # per chip: the chip that delivers each measured column
    chip = problem.scene.cameras[0].chip_index(pts["col"])
    per_chip = rep["control_residuals_per_chip"]
    assert list(per_chip) == ["HRC/HRC-1", "HRC/HRC-2", "HRC/HRC-3"]
    for k, figures in enumerate(per_chip.values()):
        mine = kept & (chip == k)
        assert figures["count"] == mine.sum() > 40
        assert figures["rmse_col"] == pytest.approx(rms(pts["res_col"][mine]), rel=1e-12)
    assert sum(f["count"] for f in per_chip.values()) == 192


def test_check_figures_are_the_adjusted_scenes_and_their_blunders_the_displaced_points(built):
    """Measured: check RMSE 3.26 / 3.21 px over all 200, 1.50 / 1.54 px over the 189 without the 11
    blunders (the 3 m ground noise is 1.3 px); every blunder is a displaced point (11 of 12: the
    smallest displacement hides in the noise)."""
    out, problem, table, displaced, _ = built
    rep, pts = out.report, out.points
    checks = pts["role"] == "check"
    ground = table.select(np.nonzero(checks)[0]).ecef()
    col, row = out.scene.ground_to_image(ground)
    np.testing.assert_allclose(pts["res_col"][checks], col - pts["col"][checks], atol=1e-6)
    np.testing.assert_allclose(pts["res_row"][checks], row - pts["row"][checks], atol=1e-6)
    figures = rep["check_points"]
    assert figures["observations"] == 200 and figures["not_imaged"] == 0
    assert figures["image"]["rmse_col"] == pytest.approx(rms(pts["res_col"][checks]), rel=1e-9)
    assert figures["image"]["rmse_row"] == pytest.approx(rms(pts["res_row"][checks]), rel=1e-9)
    blunder = checks & pts["flagged"]
    assert figures["blunders"] == blunder.sum()
    assert set(pts["id"][blunder]) <= displaced and blunder.sum() >= 10
    clean = checks & ~pts["flagged"]
    assert figures["without_blunders"]["image"]["rmse_col"] == pytest.approx(rms(pts["res_col"][clean]), rel=1e-9)
    assert figures["without_blunders"]["image"]["rmse"] < 2.5 < figures["image"]["rmse"]
    # before the adjustment: the onboard model, hundreds of pixels off
    assert rep["check_points_before"]["image"]["rmse"] > 50.0


def test_parameters_carry_their_posterior_sigmas(built):
    out, problem, *_, est = built
    rep = out.report
    cofactor = np.diag(est.st.Q)
    params = {p["name"]: p for p in rep["parameters"]}
    assert len(params) == len(problem.params.params)
    free = {problem.params.params[i].name for i in problem.params.free}
    assert {n for n, p in params.items() if p["sigma"] is not None} == free
    for name in ("HRC-1.dy", "HRC-3.theta"):
        p = params[name]
        i = problem.params.index[name]
        assert p["value"] == problem.params.params[i].value
        assert p["sigma"] == pytest.approx(est.st.sigma0 * np.sqrt(cofactor[problem.unknown[i]]), rel=1e-12)
        assert p["significant"] == (abs(p["value"]) > 1.96 * p["sigma"])
    assert params["HRC-3.dy"]["significant"]  # -24 um simulated, sigma ~4 um
    assert out.scene.info["adjustment"]["sigma0"] == rep["sigma0"]
