"""The demo's chain (scripts/demo.sh) on a small rendered scene with known truth: matched GCPs, the
self-calibrating adjustment, the residual plot and the sensor-corrected RPC read clean — sigma0
passes its test, the robust loop converges, no systematic-error warning, no cluster of flags or
biased matches at the CCD seam, an RPC the run's own check calls good, check points at the
matching's own error — and the variance components of image and ground, which points seen in one
image cannot tell apart, are estimated as one and said to be (tests/support/matchscene.py)."""
import re

import numpy as np
import pytest
from pyproj import Transformer

from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.adjust.report import log_lines
from pushbroom_adjust.core.adjust.report_plots import residual_vector_figure
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.measure import matching
from pushbroom_adjust.core.measure.matching import MatchSettings, match_gcps
from pushbroom_adjust.core.measure.reference import ImageReference
from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.products.rpcfit import fit_rpc
from pushbroom_adjust.core.products.sensorcorrect import rpc_height_range, sensor_correct
from tests.support.matchscene import SEARCH, manifest, mini_scene, true_errors

SPACING = 40.0
NEAR_SEAM = 60.0  # px either side of the seam column


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    return mini_scene(tmp_path_factory.mktemp("mini"))


@pytest.fixture(scope="module")
def inputs(mini):
    return load_scene(mini.onboard_scene), Dem(mini.dem, "geoid")


@pytest.fixture(scope="module")
def matched(mini, inputs):
    scene, dem = inputs
    result = match_gcps(scene, 0, mini.images["HRC"], mini.reference, dem, MatchSettings(spacing=SPACING, search=SEARCH))
    return result, G.assign_check_points(result.table, 0.2)


@pytest.fixture(scope="module")
def fixed(inputs, matched):
    """The demo's adjustment: the simulated reference and DEM are exact, so the ground is fixed."""
    return adjust(inputs[0], matched[1], AdjustmentSettings(interior="HRC-1.*", position_order=0, ground="fixed"))


@pytest.fixture(scope="module")
def weighted(inputs, matched):
    """matchgcps's ground sigmas as written (half a reference pixel, 5 m): the GCPs are seen once."""
    return adjust(inputs[0], matched[1], AdjustmentSettings(interior="HRC-1.*", position_order=0))


def _seam(scene) -> float:
    return scene.cameras[0].chip_range(1)[0]


def test_no_match_straddles_the_seam_and_the_matches_beside_it_are_unbiased(mini, inputs, matched, monkeypatch):
    """A chip whose raw search area straddles the seam mixes two chips' views of different ground:
    measured on this scene with the old matcher (search areas not checked), the 40 matches within
    60 px of the seam err by a median 0.17 px, 10 of them by more than 0.3 px; now they are
    counted as 'near a CCD seam' and those left err as the others."""
    scene, dem = inputs
    result, _ = matched
    e = true_errors(mini.folder, result.table)
    near = np.abs(result.table.col - _seam(scene)) < NEAR_SEAM
    assert near.sum() >= 10  # measured 20
    assert np.max(e[near]) < 0.3 and np.median(e[near]) < 1.3 * np.median(e)  # measured 0.088 against 0.083
    assert result.rejected["near a CCD seam"] > 40  # measured 58: the grid points' windows and the search areas
    # the old matcher on the same scene: the test above would fail
    monkeypatch.setattr(matching, "within_one_chip", lambda cam, first, last: np.ones(np.size(first), bool))
    old = match_gcps(scene, 0, mini.images["HRC"], mini.reference, dem, MatchSettings(spacing=SPACING, search=SEARCH))
    old_near = np.abs(old.table.col - _seam(scene)) < NEAR_SEAM
    assert np.sum(true_errors(mini.folder, old.table)[old_near] > 0.3) >= 5  # measured 10


def under_a_cloud(mini, table) -> np.ndarray:
    """(n,) the distance of each GCP's ground from the nearest of the reference's cloud discs, in radii of
    that disc (< 1: under its soft fade)."""
    discs = np.array(manifest(mini.folder)["texture"]["reference"]["cloud_discs_utm_m"])
    x, y = Transformer.from_crs("EPSG:4326", "EPSG:32650", always_xy=True).transform(table.lon, table.lat)
    return np.min(np.hypot(x[:, None] - discs[None, :, 0], y[:, None] - discs[None, :, 1]) / discs[None, :, 2], axis=1)


def test_matches_that_disagree_with_their_neighbours_are_rejected(mini, matched):
    """A match a pixel or more off found other ground (repeated texture): rejected and counted
    (measured: 1 here; 4 with the matcher of issue 12, which left 3 matches more than 1 px off).
    What stays off lies under a cloud of the reference (measured: every one of the 9 matches more than
    0.5 px off, 0.51 to 1.04 px, at 0.64 to 0.89 of a cloud's radius): the cloud's fade, a brightness
    and contrast that change across the window, which the least-squares fit's one gain and offset do
    not model; outside the clouds no match is 0.5 px off."""
    result, _ = matched
    assert result.rejected["inconsistent with its neighbours"] >= 1
    e = true_errors(mini.folder, result.table)
    cloud = under_a_cloud(mini, result.table) < 1.0
    assert np.all(e[~cloud] < 0.5), np.sort(e[~cloud])[-5:]
    assert np.sum(e > 1.0) <= 1 and e.max() < 1.5                 # measured 1 match, 1.04 px


def test_the_demo_adjustment_reads_clean(mini, inputs, fixed):
    rep = fixed.report
    # sigma0 of the matching's stated sigma_px (its bench-measured floor): measured 0.915 in [0.84, 1.24]
    assert rep["sigma0_test"]["passed"] and 0.8 < rep["sigma0"] < 1.2
    assert not rep["robust"]["stopped_at_limit"] and len(rep["robust"]["passes"]) <= 4
    assert rep["reliability"]["reliable"] and not rep["reliability"]["problems"]  # no systematic-error warning
    texts = [line.text for line in log_lines(rep)]
    assert not any("systematic" in t or "stopped at its limit" in t for t in texts)
    # the image variance component is the matching's real error (truth: 0.083 px per axis, 0.072 px
    # over the inliers the robust estimation keeps)
    image = rep["variance_components"]["image HRC"]
    assert image["estimated"] and not image["joint_with"] and 0.06 < image["estimated_sigma"] < 0.085
    # flags: no cluster at the seam (measured 0 of 31 within 60 px of it; the old matcher: 9 of 40)
    flagged = np.asarray(fixed.points["flagged"], bool)
    near = np.abs(np.asarray(fixed.points["col"]) - _seam(inputs[0])) < NEAR_SEAM
    assert flagged.sum() > 0 and flagged[near].mean() <= 2 * flagged.mean() + 0.02
    # check points at the matching's own error: measured 0.140 px over all, 0.098 px without blunders
    check = rep["check_points"]
    assert check["image"]["rmse"] < 0.2 and check["without_blunders"]["image"]["rmse"] < 0.12
    assert not check["model_error"]


def test_the_adjusted_model_meets_the_truth(mini, inputs, fixed):
    true = load_scene(mini.true_scene)
    cam = true.cameras[0]
    cc, rr = np.meshgrid(np.linspace(20, cam.cols - 20, 15), np.linspace(20, cam.rows - 20, 15))
    ground = true.image_to_ground_dem(cc.ravel(), rr.ravel(), inputs[1], 0)
    col, row = fixed.scene.ground_to_image(ground, 0)
    e = np.hypot(col - cc.ravel(), row - rr.ravel())
    assert np.sqrt(np.mean(e ** 2)) < 0.03 and e.max() < 0.08


def test_image_and_ground_seen_once_share_one_factor_and_say_so(mini, weighted):
    """Each GCP seen in one image: its misfit is split between the image residual and the ground
    shift in the ratio of the stated sigmas (0.08 px against 2.5 m), so their factors are not
    separable. Before: estimated apart, the image's at 0.007 px from a redundancy of ~50, the loop
    creeping to its pass limit; now one factor, the split as stated, said in the log, and the
    control figures say what the ground unknowns took."""
    rep = weighted.report
    vc = rep["variance_components"]
    assert vc["image HRC"]["joint_with"] == ["ground_xy"] and vc["ground_xy"]["joint_with"] == ["image HRC"]
    assert vc["image HRC"]["sigma0"] == vc["ground_xy"]["sigma0"]
    assert not rep["robust"]["stopped_at_limit"] and len(rep["robust"]["passes"]) <= 5
    texts = [line.text for line in log_lines(rep)]
    assert any("cannot be told apart" in t and "image HRC" in t for t in texts)
    assert any(t.startswith("control points: their ground unknowns took") for t in texts)
    # the ground took nearly all of the misfit: the image residuals say nothing of the matching ...
    ground = rep["control_ground"]
    assert rep["control_residuals"]["rmse_col"] < 0.01 and ground["ground_share"] > 0.99
    # ... the residuals at the stated ground do: the matching's true error (0.070 / 0.072 px measured,
    # 0.072 px per axis over the fixed-ground run's inliers)
    at = ground["at_stated_ground"]
    assert 0.06 < at["rmse_col"] < 0.085 and 0.06 < at["rmse_row"] < 0.085
    # the stated ground sigmas are far too pessimistic for this exact reference: the test says so
    assert not rep["sigma0_test"]["passed"] and rep["sigma0"] < 0.3
    # the flags and check figures are the fixed-ground run's
    assert rep["check_points"]["without_blunders"]["image"]["rmse"] < 0.12
    assert rep["reliability"]["reliable"] and not rep["reliability"]["problems"]


def test_the_residual_plot_shows_control_and_check_points_at_their_own_scale(weighted):
    """Before: one factor from the control residuals (0.001 px: the ground took the rest) drew the
    check points' 0.1 px vectors 1.7e5 times too long; now a panel each, both at the misfit of
    the stated points."""
    figure = residual_vector_figure(weighted.points)
    factors = {name: float(value) for name, value in
               re.findall(r"(control points|check points) ([0-9.e+]+) times", figure)}
    assert set(factors) == {"control points", "check points"}
    assert all(f < 1e4 for f in factors.values())
    assert 0.3 < factors["control points"] / factors["check points"] < 3.0


def test_the_sensor_corrected_rpc_is_good_where_the_raw_images_is_not(mini, inputs, fixed, tmp_path):
    """The demo's RPC: one RPC of the raw two-chip image misses the adjusted model at the seam (the
    export warns); that of the sensor-corrected image (one straight virtual line) fits its model
    to a hundredth of a pixel, its own independent check."""
    scene, dem = inputs
    heights = rpc_height_range(fixed.scene, 0, dem)
    _, raw = fit_rpc(fixed.scene, 0, heights)
    assert raw["check"]["seams"]["max_px"] > 0.1  # what exportrpc's warning names
    figures = sensor_correct(fixed.scene, 0, mini.images["HRC"], dem, tmp_path / "corrected.tif",
                             tmp_path / "corrected_scene.json")
    virtual = load_scene(tmp_path / "corrected_scene.json")
    assert len(virtual.cameras[0].chips) == 1
    assert figures["rpc_check_rms_px"] < 0.01 and figures["rpc_check_max_px"] < 0.02


def test_an_other_cameras_window_across_its_seam_is_named(inputs, mini):
    """Tie points: the other camera's window (its cubic taps included) must lie in one of its chips."""
    scene, _ = inputs
    ref = ImageReference(scene, 0, mini.images["HRC"], 2.36)
    seam = _seam(scene)
    x = np.arange(31.0)[None, None, :] + np.array([seam - 40, seam - 15, seam + 5])[:, None, None] - 0.5
    assert ref.straddles_seam(np.broadcast_to(x, (3, 31, 31))).tolist() == [False, True, False]
