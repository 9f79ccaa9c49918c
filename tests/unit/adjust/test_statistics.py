"""core.adjust.statistics: the posterior statistics of a simulated CBERS-02B HRC adjustment with known
noise (0.7 px in the image, 3 m / 10 m on the ground, stated as such; 200 control points, 30
parameters), and the correlations worth a look on a constructed correlation matrix."""
from types import SimpleNamespace

import numpy as np
import pytest

from pushbroom_adjust.core.adjust.checks import check_inputs
from pushbroom_adjust.core.adjust.problem import Problem
from pushbroom_adjust.core.adjust.solver import solve
from pushbroom_adjust.core.adjust.statistics import correlated_pairs, normalised, statistics
from tests.support.cbers_strip import settings, strip


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    """(problem, statistics) at the solution; no robust estimation, no variance components: the
    residuals are judged against the stated sigmas, which are the simulated noise."""
    _, scene, table = strip(tmp_path_factory.mktemp("statistics"), 1, 400, seed=5)
    s = settings(interior="HRC-1.*, HRC-3.*", variance_components=False)
    problem = Problem(scene, check_inputs(scene, table, s), s)
    result = solve(problem, lambda *a: None, lambda: False)
    return problem, statistics(problem, result["linearization"], result["system"])


def test_redundancy_numbers_add_up_to_the_degrees_of_freedom(solved):
    """trace(R) = n - u: image rows (measured 88.46), the control points' ground priors (292.79) and
    the position pseudo-observations (0.75) sum to dof 382 (1012 rows, 630 unknowns) to 2e-5."""
    problem, st = solved
    rows, unknowns = problem.counts()
    assert st.dof == rows - unknowns == 382
    total = st.redundancy.sum() + st.ground_redundancy.sum() + sum(r for _, r, _ in st.pseudo.values())
    assert total == pytest.approx(st.dof, abs=1e-3)
    assert ((st.redundancy >= 0) & (st.redundancy <= 1)).all()


def test_normalised_residuals_of_the_stated_noise_have_unit_spread(solved):
    """Measured: sigma0 0.949; RMS of w 0.966 (col), 0.929 (row); the ground's 0.96 (pooled);
    sampling spread of each ~0.05."""
    problem, st = solved
    assert st.sigma0 == pytest.approx(1.0, abs=0.12)
    assert np.sqrt(np.mean(st.w ** 2)) == pytest.approx(1.0, abs=0.12)
    assert np.sqrt(st.ground_pvv.sum() / st.ground_redundancy.sum()) == pytest.approx(1.0, abs=0.15)
    # sigma0 from the weighted squares: sum p v^2 over all groups / dof
    total = st.pvv.sum() + st.ground_pvv.sum() + sum(s for s, _, _ in st.pseudo.values())
    assert np.sqrt(total / st.dof) == pytest.approx(st.sigma0, rel=1e-6)


def test_normalised_uses_the_cameras_variance_factor_and_skips_unchecked_rows(solved):
    problem, st = solved
    labels, _ = problem.image_groups
    redundancy = st.redundancy.copy()
    redundancy[:5] = 0.0  # fully determined rows: no residual to judge them by
    try:
        problem.set_scale({labels[0]: 2.0})
        halved = normalised(problem, st.v, redundancy)
    finally:
        problem.set_scale({})
    w = normalised(problem, st.v, redundancy)
    assert (w[:5] == 0.0).all() and (halved[:5] == 0.0).all()
    np.testing.assert_allclose(w[5:], st.w[5:], rtol=1e-12)
    np.testing.assert_allclose(halved[5:], w[5:] / 2.0, rtol=1e-12)
    np.testing.assert_allclose(w[5:], st.v[5:] / (0.7 * np.sqrt(redundancy[5:])), rtol=1e-12)


def test_correlated_pairs_lists_exactly_the_pairs_above_their_thresholds():
    """Interior pairs above 0.9 (either sign), trajectory pairs only above 0.999, largest first."""
    params = [SimpleNamespace(name=n, block=b) for n, b in (
        ("X1", "position"), ("X2", "position"), ("roll1", "attitude"), ("f", "camera"), ("dx", "chip"),
        ("dy", "chip"))]
    corr = np.eye(6)
    for (i, j), r in {(0, 1): 0.9995,    # trajectory pair above 0.999: listed
                      (0, 2): 0.995,     # trajectory pair below 0.999: not
                      (3, 4): -0.95,     # interior pair: listed by |r|
                      (2, 3): 0.92,      # trajectory with interior: the interior threshold
                      (4, 5): 0.89,      # below 0.9: not
                      (1, 5): 0.5}.items():
        corr[i, j] = corr[j, i] = r
    pairs = correlated_pairs(corr, params)
    assert [(p["a"], p["b"], p["r"], p["trajectory"]) for p in pairs] == [
        ("X1", "X2", 0.9995, True), ("f", "dx", -0.95, False), ("roll1", "f", 0.92, False)]


def test_correlated_pairs_lists_at_most_fifty():
    params = [SimpleNamespace(name=f"p{i}", block="chip") for i in range(12)]
    corr = np.full((12, 12), 0.95) + np.diag(np.full(12, 0.05))
    corr[0, 1] = corr[1, 0] = 0.99
    pairs = correlated_pairs(corr, params)
    assert len(pairs) == 50 and pairs[0]["r"] == 0.99  # 66 pairs above 0.9, the strongest first
