"""Tie points whose rays meet at too small an angle to fix their height (core.model.intersection
MIN_CONVERGENCE; core.adjust.ties.start_from_height; issue 31).

A simulated region of 2 strips x 2 RPC products (simulation.rpcregion: ZY-3-like nadir products,
vendor biases of 5-20 m, 0.3 px noise, 300 tie observations per product), its tie points seen only
by the two consecutive products of one strip included: those products see them along one line of
one pass (coincident rays). Their closed-form meeting point lies kilometres along the rays (it sent
the 100-product bench's adjustment towards the Earth's centre); they now start on their first ray
at the reference DEM's height, or without one at the intersected points' median height, and stay
in the adjustment, counted in the report. About 10 s.
"""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from pushbroom_adjust.core.adjust import AdjustmentSettings
from pushbroom_adjust.core.adjust.block import adjust_block
from pushbroom_adjust.core.adjust.report import tie_point_lines
from pushbroom_adjust.core.adjust.ties import set_up_ties
from pushbroom_adjust.core.adjust.tieheights import TieHeights
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.core.model.intersection import MIN_CONVERGENCE, intersect
from pushbroom_adjust.core.model.mixedblock import compose_mixed
from pushbroom_adjust.core.observations import tiepoints
from pushbroom_adjust.simulation.region import RegionLayout
from pushbroom_adjust.simulation.rpcregion import RegionSettings, simulate_region

SIGMA = 3.0  # m: TIE_HEIGHT_SIGMA of the simulation's (true) DEM


@pytest.fixture(scope="module")
def region(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("weak_region")
    simulate_region(RegionLayout(2, 2, dates=2), folder, seed=31,
                    settings=RegionSettings(ties_per_product=300, forward_ties=True))
    products = json.loads((folder / "region.json").read_text())["products"]
    scenes = {p["name"]: load_scene(folder / p["rpc"]) for p in products}
    ties = tiepoints.read_csv(folder / "tie_points.csv")
    rows = np.genfromtxt(folder / "tie_points.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    ids, first, point = np.unique(rows["id"], return_index=True, return_inverse=True)
    strip = np.array([s.split("p")[0] for s in rows["scene"]])
    strips = np.array([np.unique(strip[point == p]).size for p in range(ids.size)])
    truth = geodetic_to_ecef(rows["lon_true"][first], rows["lat_true"][first], rows["h_true"][first])
    return {"folder": folder, "scenes": scenes, "ties": ties, "ids": ids, "one_strip": strips == 1,
            "truth": truth, "h_true": rows["h_true"][first]}


def block_ties(region: dict):
    """(block scene, ties naming its cameras 'product/camera') of the region's products."""
    scenes = region["scenes"]
    ties = region["ties"]
    names = np.array([f"{s}/{scenes[s].cameras[0].name}" for s in ties.scene])
    return compose_mixed(scenes), replace(ties, camera=names)


def adjusted(region: dict, **reference):
    ties = replace(region["ties"], camera=np.full(len(region["ties"]), ""))
    out = adjust_block(region["scenes"], None, ties, AdjustmentSettings(rpc_correction="shift", rpc_sigma=10.0,
                                                                        **reference))
    h = dict(zip(out.tie_points["id"], out.tie_points["h"]))
    return out, np.array([h[i] for i in region["ids"]]) - region["h_true"]


def test_coincident_rays_are_weak_and_the_others_keep_their_intersection_to_the_bit(region):
    scene, ties = block_ties(region)
    ids, point = ties.points()
    camera = np.array([[c.name for c in scene.cameras].index(n) for n in ties.camera])
    out = intersect(scene, camera, ties.col, ties.row, point, ids.size)
    assert region["one_strip"].any() and (~region["one_strip"]).any()
    assert np.array_equal(out.weak, region["one_strip"])  # one strip: one line of one pass
    assert np.all(out.convergence[out.weak] < 0.05 * MIN_CONVERGENCE)  # measured 2.0e-4 to 2.6e-4 rad
    assert np.all(out.convergence[~out.weak] > 2.0 * MIN_CONVERGENCE)  # across strips: 4.6 degrees
    assert np.isnan(out.ground[out.weak]).all() and np.isinf(out.condition[out.weak]).all()
    well = ~out.weak[point]
    alone = intersect(scene, camera[well], ties.col[well], ties.row[well], np.unique(point[well],
                      return_inverse=True)[1])
    assert np.array_equal(alone.ground, out.ground[~out.weak])  # the weak points change nothing of the others


def test_coincident_rays_start_on_the_dem_to_its_accuracy(region):
    scene, ties = block_ties(region)
    weak = region["one_strip"]
    held = set_up_ties(scene, ties, TieHeights(Dem(str(region["folder"] / "dem.tif"), "geoid"), SIGMA))
    assert held.from_height[0].tolist() == region["ids"][weak].tolist() and "reference DEM" in held.from_height[1]
    dh = ecef_to_geodetic(held.ground[weak])[2] - region["h_true"][weak]
    assert np.sqrt(np.mean(dh ** 2)) < SIGMA
    plan = np.linalg.norm(held.ground[weak] - region["truth"][weak], axis=1)
    assert np.percentile(plan, 90) < 40.0  # the vendor RPC's bias (5-20 m per axis) on a near-vertical ray
    free = set_up_ties(scene, ties)
    h = ecef_to_geodetic(free.ground[weak])[2]
    median = np.median(ecef_to_geodetic(free.ground[~weak])[2])
    assert np.allclose(h, median, atol=0.01) and "median height" in free.from_height[1]
    assert np.array_equal(free.ground[~weak], held.ground[~weak])


def test_with_a_reference_dem_the_adjustment_converges_and_holds_their_heights(region):
    out, error = adjusted(region, dem=str(region["folder"] / "dem.tif"), dem_datum="geoid", tie_height_sigma=SIGMA)
    weak = region["one_strip"]
    report = out.report["adjustment"]
    assert len(report["iterations"]) < 10
    assert np.sqrt(np.mean(error[weak] ** 2)) < SIGMA  # measured 0.06 m on the true DEM
    assert np.sqrt(np.mean(error[~weak] ** 2)) < SIGMA
    counted = report["tie_points"]["from_height"]
    assert counted["points"] == int(weak.sum()) and counted["held_by_dem"]
    sentence = [s for s, warn in tie_point_lines(report["tie_points"]) if "started from a height" in s]
    assert len(sentence) == 1 and f"{int(weak.sum())} whose rays meet at less than 1°" in sentence[0]


def test_without_a_reference_they_stay_in_and_the_report_says_nothing_holds_their_heights(region):
    out, _ = adjusted(region)
    report = out.report["adjustment"]
    assert len(report["iterations"]) < 10 and np.isfinite(report["sigma0"])
    assert report["tie_points"]["points"] == region["ids"].size
    sentence = [s for s, warn in tie_point_lines(report["tie_points"]) if "started from a height" in s]
    assert "nothing holds their heights" in sentence[0] and "median height" in sentence[0]


def test_a_tie_layer_checked_against_the_block_names_them_and_gives_them_no_height(region, caplog):
    scene, ties = block_ties(region)
    checked = tiepoints.check_against_scene(ties, scene)
    weak = np.isin(checked.id, region["ids"][region["one_strip"]])
    assert np.isnan(checked.apriori.h[weak]).all() and np.isfinite(checked.apriori.h[~weak]).all()
    assert f"{int(region['one_strip'].sum())} tie point(s) whose rays meet at less than 1°" in caplog.text
