"""Per-scene onboard and vendor sigmas of a block (settings.scene_sigmas, :mod:`core.adjust.scenesigmas`).

The block: tests/support/simulated_block.py (three TH-1 three-line simulations cut to 500 x 500 px,
seeds 1-3, tie points only, 0.3 px noise) with scene S1 an accurate product (onboard errors of 1 m
and 0.002 m/s in position, 1e-5 rad (2 arcsec) and 2.5e-8 rad/s in attitude) and S2, S3 older ones
(30 m, 0.06 m/s, 6e-4 rad (124 arcsec), 1.5e-6 rad/s): each magnitude drawn times U(1/3, 1) with a
random sign. Without GCPs nothing but the onboard pseudo-observations holds where the block lies.
Check figures: 49 true ground points through each adjusted and true camera (px RMS).
"""
from dataclasses import replace

import numpy as np
import pytest

from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.adjust.block import adjust_block
from pushbroom_adjust.core.adjust.report_html import block_section
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.model.rpcscene import RpcCamera, RpcScene
from pushbroom_adjust.core.observations.gcps import GcpTable
from pushbroom_adjust.core.rotations import ARCSEC
from pushbroom_adjust.simulation.presets import ErrorSettings
from tests.support.mixed_block import MixedBlock
from tests.support.rpcdata import pleiades_rpc
from tests.support.simulated_block import SimulatedBlock

ACCURATE = ErrorSettings(position_bias=1.0, position_drift=0.002, attitude_bias=1e-5, attitude_drift=2.5e-8)
OLDER = ErrorSettings(position_bias=30.0, position_drift=0.06, attitude_bias=6e-4, attitude_drift=1.5e-6)
# one sigma for every scene: the older scenes' error level (a user without per-scene values states the worst)
COMMON = AdjustmentSettings(position_order=1, attitude_order=1, position_sigma=30.0, attitude_sigma=6e-4)
# S1's own sigmas as its true error level; S2 and S3 keep the global ones
OWN = replace(COMMON, scene_sigmas={"S1": {"position_sigma": 1.0, "attitude_sigma": 1e-5}})


@pytest.fixture(scope="module")
def block(tmp_path_factory) -> SimulatedBlock:
    return SimulatedBlock(tmp_path_factory.mktemp("sigmas"), {"S1": ACCURATE, "S2": OLDER, "S3": OLDER})


@pytest.fixture(scope="module")
def runs(block) -> dict:
    return {label: adjust_block(block.onboard, None, block.ties, settings)
            for label, settings in (("common", COMMON), ("own", OWN))}


def block_px(block, out) -> dict:
    px = {name: block.check_px(name, scene) for name, scene in out.scenes.items()}
    return {**px, "block": float(np.sqrt(np.mean(np.square(list(px.values())))))}


def test_own_sigmas_keep_the_accurate_scene_and_the_block_near_the_truth(block, runs):
    """Measured, check RMSE (px): onboard S1 1.12, S2 70.0, S3 72.5; one common sigma (30 m, 124
    arcsec) S1 9.45, S2 9.51, S3 9.54, block 9.50 (the ties pull the accurate scene to the mean
    of the three onboard geolocations); S1 with its own (1 m, 2 arcsec) S1 1.09, S2 1.11, S3 1.16,
    block 1.12: S1 stays at its onboard accuracy and holds the other two. S1 moved 94 m from its
    onboard geolocation with the common sigma, 1.8 m with its own (its onboard sigma 5.6 m).
    Tie RMS 0.33 px and sigma0 0.92 in both: the ties fit either way, only the datum differs."""
    onboard = {name: block.check_px(name, scene) for name, scene in block.onboard.items()}
    common, own = block_px(block, runs["common"]), block_px(block, runs["own"])
    assert onboard["S1"] < 1.5 and min(onboard["S2"], onboard["S3"]) > 50.0, onboard
    assert common["S1"] > 6.0 and common["block"] > 6.0, common
    assert own["S1"] < 1.5 and own["block"] < 1.6, own
    assert own["block"] < 0.25 * common["block"], (own, common)
    for out in runs.values():
        assert out.report["block"]["tie_rmse_px"] < 0.5 and 0.7 < out.report["block"]["sigma0"] < 1.3
    s1 = {label: out.report["scenes"]["S1"] for label, out in runs.items()}
    assert s1["own"]["moved_m"] < s1["own"]["onboard_sigma_m"] < 10.0 < 50.0 < s1["common"]["moved_m"], s1


def test_the_report_says_each_scenes_sigmas(runs):
    scenes = runs["own"].report["scenes"]
    assert scenes["S1"]["sigmas"] == pytest.approx({"position_sigma_m": 1.0, "attitude_sigma_arcsec": 1e-5 / ARCSEC,
                                                   "own": ["attitude_sigma", "position_sigma"]})
    assert scenes["S2"]["sigmas"] == pytest.approx({"position_sigma_m": 30.0, "attitude_sigma_arcsec": 6e-4 / ARCSEC,
                                                   "own": []})
    # the onboard sigma on the ground follows the scene's own: 1 m and 2.06 arcsec at ~560 km range
    assert 5.0 < scenes["S1"]["onboard_sigma_m"] < 7.0 and scenes["S2"]["onboard_sigma_m"] > 300.0
    page = block_section(runs["own"].report)
    assert "1 m (own), 2.063 arcsec (own)" in page and "30 m, 123.8 arcsec" in page
    # one factor per pseudo-observation group, as without overrides: here they hold the datum
    components = runs["own"].adjustment.report["variance_components"]
    assert components["position pseudo-observations"]["holds_datum"]
    # their stated sigma: the median over the scenes' corrections (S1 1 m, S2 and S3 30 m)
    assert components["position pseudo-observations"]["apriori_sigma"] == 30.0


def test_the_pseudo_observation_groups_state_the_median_of_the_scenes_sigmas(block):
    """S1 1 m, S2 2 m, S3 the global 30 m: the position group's stated sigma is 2 m (not 30)."""
    settings = replace(COMMON, scene_sigmas={"S1": {"position_sigma": 1.0}, "S2": {"position_sigma": 2.0}})
    out = adjust_block(block.onboard, None, block.ties, settings)
    assert out.adjustment.report["variance_components"]["position pseudo-observations"]["apriori_sigma"] == 2.0


def test_an_rpc_products_own_stated_accuracy(tmp_path):
    """Three RPC products tied without GCPs (tests/support/mixed_block.py: R, S1's nadir, S2's
    forward; image biases 2-4 px), RPC_SIGMA 5 px; R stating 0.5 px of its own. Measured: R moved
    6.0 m from its vendor geolocation with the common 5 px (its stated 11.1 m), 0.23 m with its own
    0.5 px (stated 1.11 m); its shift a0 -1.72 -> -0.02 px. S1 and S2 keep 5 px (25.0, 27.8 m)."""
    block = MixedBlock(tmp_path)
    ties, _, _ = block.tables(block.rpc_true)
    settings = AdjustmentSettings(rpc_sigma=5.0)
    common = adjust_block(block.rpc_vendor, None, ties, settings).report["scenes"]
    own = adjust_block(block.rpc_vendor, None, ties, replace(settings, scene_sigmas={"R": {"rpc_sigma": 0.5}}))
    own = own.report["scenes"]
    assert own["R"]["sigmas"] == {"rpc_sigma_px": 0.5, "own": ["rpc_sigma"]}
    assert own["S1"]["sigmas"] == {"rpc_sigma_px": 5.0, "own": []}
    assert own["R"]["vendor_sigma_m"] == pytest.approx(common["R"]["vendor_sigma_m"] / 10.0)
    assert own["R"]["moved_m"] < 0.5 < 3.0 < common["R"]["moved_m"], (own["R"], common["R"])
    assert abs(own["R"]["correction"]["a0"]["value"]) < 0.1 < 1.0 < abs(common["R"]["correction"]["a0"]["value"])


# --- refusals ------------------------------------------------------------------------------
@pytest.mark.parametrize("sigmas, message", [
    ({"S1": {"position_sgima": 1.0}}, r"scene 'S1' has unknown key\(s\) 'position_sgima'"),
    ({"S1": {"position_sigma": 1e7}}, r"scene 'S1': POSITION_SIGMA must be between 0.0001 and 1e\+06 m"),
    ({"S1": {"attitude_sigma": 1.0}}, r"scene 'S1': ATTITUDE_SIGMA must be between .* rad"),
    ({"S1": {"rpc_sigma": 0.0}}, r"scene 'S1': RPC_SIGMA must be between 0.001 and 100000 px"),
    ({"S1": {"position_sigma": "1 m"}}, r"scene 'S1': POSITION_SIGMA must be between .*got '1 m'"),
    ({"S1": {"position_sigma": None}}, r"scene 'S1': POSITION_SIGMA must be between .*got None"),
    ({"S1": {}}, r"scene 'S1' needs a name and at least one of POSITION_SIGMA"),
    ({"": {"position_sigma": 1.0}}, r"scene '' needs a name"),
])
def test_bad_scene_sigmas_are_refused_by_the_settings(sigmas, message):
    with pytest.raises(InputError, match=message) as err:
        replace(OWN, scene_sigmas=sigmas).validate()
    assert err.value.parameter == "settings.scene_sigmas"


def test_scene_sigmas_the_block_cannot_take_are_refused(block, shared_data):
    rpc = {**block.onboard, "P": RpcScene(pleiades_rpc(shared_data), RpcCamera("PAN", 1000, 1000))}
    for scenes, settings, message in [
        (block.onboard, replace(OWN, scene_sigmas={"S9": {"position_sigma": 1.0}}),
         r"scene 'S9' is not in the block \(scenes: S1, S2, S3\)"),
        (block.onboard, replace(OWN, attitude_sigma=None),
         r"scene 'S1' overrides ATTITUDE_SIGMA, whose global value is not given .*: give ATTITUDE_SIGMA too; "
         "per-scene values override it"),
        (block.onboard, replace(OWN, scene_sigmas={"S2": {"rpc_sigma": 5.0}}, rpc_sigma=10.0),
         r"scene 'S2' is a rigorous scene: RPC_SIGMA is the prior of RPC products .*remove its RPC_SIGMA"),
        (rpc, replace(OWN, scene_sigmas={"P": {"attitude_sigma": 1e-5}}),
         r"scene 'P' is an RPC product: it has no onboard trajectory .*remove its ATTITUDE_SIGMA"),
        (rpc, replace(OWN, scene_sigmas={"P": {"rpc_sigma": 5.0}}),
         r"scene 'P' overrides RPC_SIGMA, whose global value is not given .*give RPC_SIGMA too"),
    ]:
        with pytest.raises(InputError, match=message) as err:
            adjust_block(scenes, None, block.ties, settings)
        assert err.value.parameter == "settings.scene_sigmas"


def test_scene_sigmas_for_one_scene_are_refused(block):
    one = block.onboard["S1"]
    none = np.zeros(0)
    with pytest.raises(InputError, match=r"per-scene sigmas are for a block of scenes") as err:
        adjust(one, GcpTable(*(np.zeros(0, str),) * 3, *(none,) * 8), OWN)
    assert err.value.parameter == "settings.scene_sigmas"
