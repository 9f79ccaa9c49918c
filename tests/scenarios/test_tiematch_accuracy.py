"""Issue 12, criterion 3: tie points matched between the three cameras of a rendered TH-1 scene
(tests/matchscene.th1_cut: the TH-1 preset's errors, cut to 3000 x 3000 px so it renders in
seconds) lie within 0.2 px of the truth, and the adjustment with them reaches the 3D check-point
accuracy of the same adjustment with exact tie points at the same positions within 10 %.
tests/bench/bench_matchtiepoints.py prints the same figures for larger scenes."""
import numpy as np
import pytest

from pushbroom_adjust.core.adjust import AdjustmentSettings
from pushbroom_adjust.core.measure.matching import MatchSettings
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate
from pushbroom_adjust.core.observations.tiepoints import summary
from tests.support.matchscene import compare_ties, th1_cut

# Self-calibration of every camera (INTERIOR=default) with the automatic removal, 9 control points,
# 30 check points seen in all three cameras, selection weights (the robust default: the tie points'
# variance components apart from the control points', never below their stated sigmas).
ADJUSTMENT = AdjustmentSettings(interior="default")


@pytest.fixture(scope="module")
def comparison(tmp_path_factory):
    sim = simulate(th1_cut(3000, 3000), tmp_path_factory.mktemp("th1cut"), seed=3, render=True,
                   gcp_settings=GcpSettings(n_gcps=60, check_fraction=0.5, image_noise=0.3))
    return compare_ties(sim, 9, MatchSettings(spacing=60, search=300.0), ADJUSTMENT)


def test_tie_points_between_all_camera_pairs_are_accurate(comparison):
    pairs = summary(comparison.matched)["pairs"]
    assert min(pairs.values()) >= 1000, pairs  # measured: NAD-FWD 2104, NAD-BWD 2143, FWD-BWD 1850 (seed 3)
    for name, e in comparison.errors.items():
        # measured: median 0.022 px (FWD), 0.027 px (BWD); largest 0.09 px
        assert np.median(e) <= 0.1 and np.mean(e > 1.0) <= 0.01, (name, np.median(e))


def test_the_adjustment_with_matched_ties_is_as_accurate_as_with_exact_ones(comparison):
    m, x = comparison.with_matched, comparison.with_exact
    assert m["intersected"] == x["intersected"] == 30
    # measured: plan 1.70 / 1.69 m, height 2.87 / 2.87 m (matched / exact); with the tie points' variance
    # components free to go below 1 the matched ties' systematic part bent the heights: 3.82 against 2.99 m
    for key in ("rmse_plan", "rmse_height"):
        assert m[key] <= 1.1 * x[key], (key, m[key], x[key])
    # and both are a few metres (5 m GSD) where the onboard model is tens of metres off
    assert x["rmse_plan"] < 5.0 and x["rmse_height"] < 5.0


def test_the_removal_keeps_the_same_terms_with_matched_and_exact_ties(comparison):
    """The interior terms kept hardly depend on whether the tie points are matched or exact
    (measured: the same 16 terms, the matched run one more, FWD.b3, which the control hardly
    separates from FWD.k1; on the bench's 6000 px scene the same 15 terms, plan 1.88 / 1.90 m;
    an earlier state picked other terms there, plan 4.93 against 2.08 m)."""
    kept = {k: {t["name"] for t in r["interior_selection"]["kept"]} for k, r in comparison.reports.items()}
    assert len(kept["matched"] ^ kept["exact"]) <= 1 and len(kept["exact"]) >= 10, kept
    assert all(r["interior_selection"]["outcome"] == "self-calibration" for r in comparison.reports.values())
