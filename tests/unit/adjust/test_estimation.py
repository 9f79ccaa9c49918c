"""core.adjust.estimation on a simulated CBERS-02B HRC scene with known errors: 200 control points,
0.7 px image noise (stated as such), chip errors of HRC-1 and HRC-3, and 8 of the control points'
image measurements displaced by 5-30 px (the simulation's ``gross`` column)."""
import json

import numpy as np
import pytest

from pushbroom_adjust.core.adjust.checks import check_inputs
from pushbroom_adjust.core.adjust.estimation import estimate
from pushbroom_adjust.core.adjust.problem import Problem
from pushbroom_adjust.core.errors import Cancelled
from tests.support.cbers_strip import settings, strip

CHIP_TERMS = {"dx": "dx_m", "dy": "dy_m", "theta": "dtheta_rad"}


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """(simulation result, scene, GCP table checked, settings: HRC-1 and HRC-3 free, robust 'selection'
    with variance components)."""
    result, scene, table = strip(tmp_path_factory.mktemp("estimation"), 1, 400, seed=6, gross_fraction=0.05,
                                 gross_min=5.0, gross_max=30.0)
    s = settings(interior="HRC-1.*, HRC-3.*", robust="selection")
    return result, scene, check_inputs(scene, table, s), s


@pytest.fixture(scope="module")
def estimated(scene):
    """(problem, estimate, the progress reported: (fraction, message) in order)."""
    _, sc, table, s = scene
    problem = Problem(sc, table, s)
    reported = []
    est = estimate(problem, lambda fraction, message=None: reported.append((fraction, message)), lambda: False)
    return problem, est, reported


def test_gross_errors_are_flagged_exactly_and_the_rest_keeps_its_noise(scene, estimated):
    """Measured: the 8 displaced control observations flagged, no other; 3 passes; sigma0 0.986;
    the image group's variance factor 1.03 (89.4 / 84.8 with the stated 0.7 px)."""
    result, _, table, _ = scene
    problem, est, _ = estimated
    g = np.genfromtxt(result.gcps, delimiter=",", names=True, dtype=None, encoding=None)
    gross_ids = set(g["id"][g["gross"].astype(bool) & (g["role"] == "control")].astype(str))
    ids = table.id[problem.rows].astype(str)
    displaced = np.isin(ids, list(gross_ids))
    assert displaced.sum() == 8
    np.testing.assert_array_equal(~est.inlier, displaced)
    np.testing.assert_array_equal(problem.factor[:, 0] < 1.0, displaced)
    assert not est.at_limit and len(est.passes) >= 2
    assert est.passes[-1]["down_weighted"] == 8
    assert est.st.sigma0 == pytest.approx(1.0, abs=0.1)
    pvv, redundancy, count = est.components["image HRC"]
    assert count == 2 * 192  # the inliers' rows
    assert np.sqrt(pvv / redundancy) == pytest.approx(1.0, abs=0.1)


def test_chip_errors_are_recovered_within_three_sigma(scene, estimated):
    """Measured (value / truth / sigma): HRC-1.dy -11.7 / -11.2 / 4.0 um, HRC-1.theta -1.11 / -0.85 /
    0.24 mrad, HRC-3.dy -26.2 / -23.9 / 3.9 um; the dx terms, which trade with the trajectory,
    within 2.2 sigma."""
    result, *_ = scene
    problem, est, _ = estimated
    truth = {c["chip"]: c for c in json.loads(result.manifest.read_text())["truth"]["interior"][0]["chips"]}
    values = problem.params.values()
    sigma = est.st.sigma0 * np.sqrt(np.diag(est.st.Q))
    for chip in ("HRC-1", "HRC-3"):
        for term, key in CHIP_TERMS.items():
            i = problem.params.index[f"{chip}.{term}"]
            assert abs(values[i] - truth[chip][key]) < 3.0 * sigma[problem.unknown[i]], (chip, term)
    # the simulated errors are large against their sigmas: recovering them is no accident of zero
    i = problem.params.index["HRC-3.dy"]
    assert abs(truth["HRC-3"]["dy_m"]) > 5.0 * sigma[problem.unknown[i]]


def test_progress_is_reported_per_pass_and_iteration(estimated):
    _, est, reported = estimated
    fractions = [f for f, _ in reported]
    assert reported and all(0.1 < f <= 0.9 for f in fractions)
    for k in range(1, len(est.passes) + 1):
        mine = [m for _, m in reported if m.startswith(f"robust pass {k}: iteration ")]
        assert mine, k
    assert reported[0][1].startswith("robust pass 1: iteration 1: cost ")


def test_without_robust_estimation_or_components_one_pass_is_made(scene):
    _, sc, table, s = scene
    problem = Problem(sc, table, settings(interior=s.interior, robust="none", variance_components=False))
    reported = []
    est = estimate(problem, lambda fraction, message=None: reported.append(message), lambda: False)
    assert len(est.passes) == 1 and not est.at_limit and est.inlier.all()
    assert (problem.factor == 1.0).all()
    assert all(m.startswith("iteration ") for m in reported)
    assert est.st.sigma0 > 2.0  # the 8 gross errors, kept, inflate it (measured 2.54; 0.99 flagged)


def test_a_cancel_request_raises_cancelled_and_changes_nothing(scene):
    _, sc, table, s = scene
    problem = Problem(sc, table, s)
    values, factor = problem.params.values().copy(), problem.factor.copy()
    with pytest.raises(Cancelled):
        estimate(problem, lambda *a: None, lambda: True)
    np.testing.assert_array_equal(problem.params.values(), values)
    np.testing.assert_array_equal(problem.factor, factor)


def test_a_cancel_request_in_a_later_pass_raises_cancelled(scene):
    _, sc, table, s = scene
    problem = Problem(sc, table, s)
    reported = []

    def is_cancelled() -> bool:  # once the second pass has made an iteration
        return any(m.startswith("robust pass 2: ") for m in reported)

    with pytest.raises(Cancelled):
        estimate(problem, lambda fraction, message=None: reported.append(message), is_cancelled)
    assert reported[-1].startswith("robust pass 2: iteration 1: ")
