"""What tie points alone leave to the priors, on the real Pleiades pair over Giza (issue 28, Done-when 4).

The two crops (tests/data/pleiades_gizeh) tied as tests/scenarios/test_real_crops.py ties them (40 px grid,
31 px window, 60 m search, flat at the RPCs' height offset) and adjusted as a block of their vendor RPCs
without GCPs, RPC_SIGMA 10 px (RPC_CORRECTION left at auto: shift, the block having no control point).
The ties fix the pair's relative orientation; where the block lies is the priors' alone. The report
names the directions the ties leave to them: the height shift (the priors' sigma 86 m: the pair's
base-to-height ratio is about 0.08, so 10 px per image holds the height only that well), the shifts
east (30 m) and north (3.8 m), and how far the tie points moved along each (measured: -0.7, -0.2 and
0.0 m). Triangulated through the vendor RPCs and through the adjusted ones, the tie heights move by a
median -0.66 m and do not tilt (0.00 m across the ties' extent): within the priors' sigma.

With RPC_CORRECTION=drift the row drift of each image could follow a height tilt along the flight
direction; the ties then determine it only through the 2.3 % of its image displacement the drift cannot
follow (the ties' sigma 1.6 m, the priors' 9.5 m), and the heights tilt by 1.2 m across the ties' 354 m
along it (measured; the report names the tilt and the move). About 8 s.
"""
from __future__ import annotations

import numpy as np
import pytest

from pushbroom_adjust.core.adjust import AdjustmentSettings
from pushbroom_adjust.core.adjust.block import adjust_block
from pushbroom_adjust.core.adjust.datumdirections import flight_direction
from pushbroom_adjust.core.adjust.report import log_lines
from pushbroom_adjust.core.dem import ConstantHeight
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.measure.matching import MatchSettings
from pushbroom_adjust.core.measure.tiematching import View, match_block_tiepoints
from tests.support.tie_heights import height_change, tie_heights

NAMES = ("img1", "img2")
SIGMA = 10.0  # px: RPC_SIGMA


@pytest.fixture(scope="module")
def scenes(shared_data) -> dict:
    return {n: load_scene(shared_data / "pleiades_gizeh" / f"{n}.tif") for n in NAMES}


@pytest.fixture(scope="module")
def ties(shared_data, scenes):
    folder = shared_data / "pleiades_gizeh"
    table, _ = match_block_tiepoints([View(n, scenes[n], 0, folder / f"{n}.tif") for n in NAMES],
                                     ConstantHeight(scenes["img1"].rpc.height_off),
                                     MatchSettings(spacing=40, window=31, search=60.0))
    return table


@pytest.fixture(scope="module")
def before(scenes, ties) -> np.ndarray:
    """The tie points (lon, lat, h) triangulated through the vendor RPCs."""
    return tie_heights(scenes, ties)[1]


def moved(scenes: dict, ties, before: np.ndarray, out) -> dict:
    """How the triangulated tie heights changed from the vendor RPCs to the adjusted ones (m)."""
    after = tie_heights(out.scenes, ties)[1]
    along = flight_direction(scenes["img1"], float(np.median(before[:, 2])))
    return height_change(before, after[:, 2] - before[:, 2], along)


def directions(out) -> dict:
    return {d["direction"]: d for d in out.report["datum_directions"]}


def test_a_ties_only_block_names_what_the_priors_hold_and_its_heights_stay_within_them(scenes, ties, before):
    out = adjust_block(scenes, None, ties, AdjustmentSettings(rpc_sigma=SIGMA))
    rep = out.adjustment.report
    assert rep["settings"]["rpc_correction"] == "shift"
    assert rep["rpc_correction"]["sentence"].startswith("RPC_CORRECTION: shift, the default for a block with fewer "
                                                        "than 3 control points")
    assert rep["rpc_correction"]["sentence"] in [line.text for line in log_lines(rep, len(ties))]
    named = directions(out)
    assert set(named) == {"height shift", "shift east", "shift north"}             # no tilt: shifts cannot follow one
    height = named["height shift"]
    assert height["held_by"] == "priors"
    assert 50 < height["prior_sigma_m"] < 130                                       # measured 86.1 m
    assert 5 < height["prior_sigma_px"] < 1.5 * SIGMA                               # measured 7.1 px
    assert "the ties leave to the priors the height shift (the priors' sigma" in out.report["datum"]
    change = moved(scenes, ties, before, out)
    # the tie points' heights, triangulated through the vendor and the adjusted RPCs, move as the report says
    assert abs(change["median_m"] - height["moved_m"]) < 0.2                        # measured -0.66, -0.66 m
    assert abs(change["median_m"]) < height["prior_sigma_m"]
    assert abs(change["tilt_m"]) < 0.1                                              # measured 0.00 m
    assert not out.report["warnings"]


def test_drift_lets_the_heights_tilt_along_the_flight_and_the_report_says_how_far(scenes, ties, before):
    out = adjust_block(scenes, None, ties, AdjustmentSettings(rpc_correction="drift", rpc_sigma=SIGMA))
    tilt = directions(out)["height tilt along the flight direction"]
    assert tilt["held_by"] == "ties" and 0.005 < tilt["unfollowed_share"] < 0.1     # measured 0.023
    assert tilt["ties_sigma_m"] < tilt["prior_sigma_m"]                             # measured 1.6 and 9.5 m
    change = moved(scenes, ties, before, out)
    assert abs(change["along_m"] - tilt["moved_m"]) < 0.3                           # measured -1.2 m both
    assert 0.3 < abs(change["along_m"]) < tilt["prior_sigma_m"]
    assert "the ties determine only through what the corrections cannot follow the height tilt along the flight " \
           "direction" in out.report["datum"]
