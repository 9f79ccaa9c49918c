"""Tie points' heights held to a reference DEM (DEM with TIE_HEIGHT_SIGMA, core/adjust/tieheights.py, issue 31).

A simulated TH-1 tri-stereo of RPC products (nadir, +-18 deg; 1000 x 1000 px; the preset's trajectory
errors, 300 tie points at 0.3 px, no GCP), adjusted with ties alone, RPC_CORRECTION=drift and RPC_SIGMA
10 px. Without a reference its heights are off the truth by tens of metres and tilted (median -55.5 m,
tilt 50.4 m measured), and the report names the height shift and the tilt along the flight as left to
the priors. With the true DEM plus white noise of 3 m as the reference at TIE_HEIGHT_SIGMA=3 the
heights come within 1.5 sigma of the truth and both directions are named held by the reference DEM; the
constraint's rows count among the equations. About 5 s.
"""
from __future__ import annotations

from dataclasses import fields, replace

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.adjust import AdjustmentSettings
from pushbroom_adjust.core.adjust.block import adjust_block
from pushbroom_adjust.core.adjust.engine import adjust
from pushbroom_adjust.core.adjust.tieheights import TIE_HEIGHT_GROUP, TieHeights
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import geodetic_to_ecef
from pushbroom_adjust.core.observations import tiepoints
from pushbroom_adjust.core.observations.tiepoints import TieTable
from pushbroom_adjust.core.runs.adjustinputs import no_gcps
from pushbroom_adjust.simulation.block import simulate_block
from pushbroom_adjust.simulation.blockmembers import BlockMember
from pushbroom_adjust.simulation.layouts import TRI_STEREO_PITCH
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.presets import PRESETS, ErrorSettings, cut_preset
from pushbroom_adjust.simulation.simulator import simulate
from tests.support.tie_heights import height_change

SIGMA = 3.0  # m: the reference DEM's noise and its stated accuracy
VIEWS = (("nad", 0.0), ("fwd", TRI_STEREO_PITCH), ("bwd", -TRI_STEREO_PITCH))
HELD = ("height shift", "height tilt along the flight direction")


@pytest.fixture(scope="module")
def block(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("tri_stereo")
    spec = cut_preset(PRESETS["th1_tlc"], 1000, 1000)
    spec = replace(spec, name="th1_nad", cameras=spec.cameras[:1])
    errors = ErrorSettings(**{k: getattr(spec.errors, k) for k in ("position_bias", "position_drift",
                                                                   "attitude_bias", "attitude_drift")})
    simulate_block([BlockMember(n, spec, view=(p, 0.0), errors=errors, rpc=True) for n, p in VIEWS], folder, seed=0,
                   n_gcps=10, n_tie_points=300)
    ties = tiepoints.read_csv(folder / "tie_points.csv")
    rows = np.genfromtxt(folder / "tie_points.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    ids, first = np.unique(rows["id"], return_index=True)
    return {"scenes": {n: load_scene(folder / n / f"{n}_RPC.TXT") for n, _ in VIEWS},
            "ties": replace(ties, camera=np.full(len(ties), "")),  # an RPC product's one camera is named after it
            "ids": ids, "truth": np.stack([rows[k][first] for k in ("lon_true", "lat_true", "h_true")], axis=1),
            "noisy": noisy_dem(folder / "dem.tif", folder / "noisy_dem.tif", np.s_[:, :]),
            "half": noisy_dem(folder / "dem.tif", folder / "half_dem.tif", np.s_[:, :200]),
            "folder": folder}


def noisy_dem(true: str, path, keep) -> str:
    """The simulation's DEM (EGM96 heights) plus white noise of SIGMA m, nodata outside the columns
    ``keep`` (a numpy index of rows, columns)."""
    src = gdal.Open(str(true))
    z = src.GetRasterBand(1).ReadAsArray().astype(np.float32)
    out = np.full_like(z, -9999.0)
    out[keep] = (z + np.random.default_rng(1).normal(0.0, SIGMA, z.shape).astype(np.float32))[keep]
    ds = gdal.GetDriverByName("GTiff").CreateCopy(str(path), src)
    band = ds.GetRasterBand(1)
    band.SetNoDataValue(-9999.0)
    band.WriteArray(out)
    ds = None
    return str(path)


def adjusted(block: dict, **reference):
    out = adjust_block(block["scenes"], None, block["ties"],
                       AdjustmentSettings(rpc_correction="drift", rpc_sigma=10.0, **reference))
    h = dict(zip(out.tie_points["id"], out.tie_points["h"]))
    error = np.array([h[i] for i in block["ids"]]) - block["truth"][:, 2]
    return out, error


@pytest.fixture(scope="module")
def free(block):
    return adjusted(block)


@pytest.fixture(scope="module")
def held(block):
    return adjusted(block, dem=block["noisy"], dem_datum="geoid", tie_height_sigma=SIGMA)


def directions(out) -> dict:
    return {d["direction"]: d for d in out.report["datum_directions"]}


def test_without_a_reference_the_priors_alone_hold_the_heights_and_the_report_says_so(block, free):
    out, error = free
    change = height_change(block["truth"], error)
    assert abs(change["median_m"]) > 10 * SIGMA and change["tilt_m"] > 10 * SIGMA  # measured -55.5 m, 50.4 m
    named = directions(out)
    for name in HELD:
        assert named[name]["held_by"] == "priors"
    assert "heights" not in out.report["adjustment"]["tie_points"]
    assert TIE_HEIGHT_GROUP not in out.report["adjustment"]["variance_components"]


def test_a_reference_dem_holds_the_heights_within_its_sigma_and_the_tilt(block, free, held):
    out, error = held
    rms = float(np.sqrt(np.mean(error ** 2)))
    assert rms < 1.5 * SIGMA  # measured 2.23 m
    change = height_change(block["truth"], error)
    # measured -0.56 m and 3.48 m: the priors leave the block shifted 24 m east and 30 m north, where the DEM
    # is sampled on 370 m of relief; without that (the true DEM compared at both places) 1.25 m
    assert abs(change["median_m"]) < 0.5 * SIGMA and change["tilt_m"] < 1.5 * SIGMA
    named = directions(out)
    for name in HELD:  # the ties alone leave them to the priors; the DEM holds them, far tighter
        assert named[name]["held_by"] == "reference DEM"
        assert named[name]["ties_sigma_m"] < 0.1 * named[name]["prior_sigma_m"]
    assert "the reference DEM holds (the ties alone would leave them to the priors) the height shift" in \
        out.report["adjustment"]["datum"]["note"]
    assert "reference DEM (3 m, TIE_HEIGHT_SIGMA)" in out.report["adjustment"]["datum"]["held_by"]


def test_the_constraint_enters_the_statistics_and_the_report(free, held):
    report = held[0].report["adjustment"]
    heights = report["tie_points"]["heights"]
    assert (heights["constrained"], heights["off_dem"], heights["on_holes"]) == (300, 0, 0)
    assert heights["sentence"].startswith("300 tie points held to the reference DEM ")
    # one equation per tie point held: 300 more degrees of freedom than the same block without
    assert report["observations"]["degrees_of_freedom"] - free[0].report["adjustment"]["observations"][
        "degrees_of_freedom"] == 300
    group = report["variance_components"][TIE_HEIGHT_GROUP]
    assert group["observations"] == 300 and 0 < group["redundancy"] < 300
    assert group["apriori_sigma"] == SIGMA and group["unit"] == "m" and group["holds_datum"]
    assert not group["estimated"]  # the DEM's stated accuracy is kept, not rescaled
    # the misfits' sigma is the noise the DEM has at the points (1.85 m RMS after bilinear sampling)
    assert 0.3 * SIGMA < group["estimated_sigma"] < 1.2 * SIGMA


def test_tie_points_off_the_dem_are_left_free_and_counted(block):
    out, error = adjusted(block, dem=block["half"], dem_datum="geoid", tie_height_sigma=SIGMA)
    heights = out.report["adjustment"]["tie_points"]["heights"]
    assert heights["constrained"] + heights["on_holes"] + heights["off_dem"] == 300
    assert heights["on_holes"] > 50 and heights["constrained"] > 50
    assert f"{heights['on_holes']} on its holes left free" in heights["sentence"]
    assert float(np.sqrt(np.mean(error ** 2))) < 1.5 * SIGMA


def test_a_dem_that_covers_no_tie_point_is_refused(block, tmp_path):
    elsewhere = tmp_path / "elsewhere.tif"
    ds = gdal.GetDriverByName("GTiff").CreateCopy(str(elsewhere), gdal.Open(block["noisy"]))
    gt = list(ds.GetGeoTransform())
    gt[0] += 5.0
    ds.SetGeoTransform(gt)
    ds = None
    with pytest.raises(InputError) as err:
        adjusted(block, dem=str(elsewhere), tie_height_sigma=SIGMA)
    assert err.value.parameter == "settings.dem" and "gives no height at any of the 300 tie points" in str(err.value)


@pytest.mark.parametrize("given, parameter, words", [
    ({"tie_height_sigma": 3.0}, "settings.dem", "give the DEM"),
    ({"dem": "x.tif"}, "settings.tie_height_sigma", "needs its stated accuracy TIE_HEIGHT_SIGMA"),
    ({"dem": "x.tif", "tie_height_sigma": 0.001}, "settings.tie_height_sigma", "between 0.01 and 1000 m"),
    ({"dem": "x.tif", "tie_height_sigma": 3.0, "dem_datum": "egm2008"}, "settings.dem_datum", "DEM_DATUM")])
def test_the_reference_settings_are_checked(given, parameter, words):
    with pytest.raises(InputError) as err:
        AdjustmentSettings(**given).validate()
    assert err.value.parameter == parameter and words in str(err.value)


def test_the_constraint_weighs_the_height_only(block):
    reference = TieHeights(Dem(block["noisy"], "geoid"), SIGMA)
    lon, lat = block["truth"][:5, 0], block["truth"][:5, 1]
    dem_h = reference.surface.height(lon, lat)
    ground = geodetic_to_ecef(lon, lat, dem_h + 6.0)
    c = reference.at(ground)
    assert np.allclose(c.dh, 6.0, atol=1e-6) and np.isclose(c.cost, 5 * 4.0)
    e = c.misfit
    assert np.allclose(np.einsum("mi,mij,mj->m", e, c.weight, e), 4.0)
    # a horizontal move weighs nothing: the weight is rank 1 along the local vertical
    assert np.allclose(np.linalg.matrix_rank(c.weight), 1)
    east = np.cross([0.0, 0.0, 1.0], c.up)
    assert np.allclose(np.einsum("mi,mij,mj->m", east, c.weight, east), 0.0, atol=1e-12)


def test_a_three_line_scene_tied_alone_sums_its_redundancy_to_the_degrees_of_freedom(tmp_path):
    """A rigorous TH-1 three-line scene (trajectory errors, 100 tie points at 0.3 px, no GCP, onboard position
    sigma only: its roll is left to nothing but the reference DEM) held by the true DEM at 1 m: the
    redundancy numbers of every group, the tie heights' included, add up to the degrees of freedom, and
    the heights come to the truth (measured: 383.003 of 383; sigma0 0.92; heights 1.16 m RMS from the truth,
    median -0.16 m; the tie heights' group redundancy 12.8 of 100, implied sigma 1.01 m)."""
    errors = {f.name: 0.0 for f in fields(ErrorSettings) if not f.name.startswith(("position", "attitude"))}
    result = simulate("th1_tlc", tmp_path, seed=5, errors=errors,
                      gcp_settings=GcpSettings(n_gcps=10, check_fraction=0.5, image_noise=0.3, n_tie_points=100))
    rows = np.genfromtxt(result.tie_points, delimiter=",", names=True, dtype=None, encoding="utf-8")
    ties = TieTable(rows["id"], rows["camera"], rows["col"].astype(float), rows["row"].astype(float), 0.3, "")
    with pytest.raises(InputError, match="roll"):  # without the DEM nothing holds the roll
        adjust(load_scene(result.onboard_scene), no_gcps(), AdjustmentSettings(position_sigma=100.0), ties=ties)
    out = adjust(load_scene(result.onboard_scene), no_gcps(),
                 AdjustmentSettings(position_sigma=100.0, robust="none", variance_components=False,
                                    dem=str(result.dem), dem_datum="geoid", tie_height_sigma=1.0), ties=ties)
    rep = out.report
    assert rep["tie_points"]["heights"]["constrained"] == 100
    assert "reference DEM (1 m, TIE_HEIGHT_SIGMA)" in rep["datum"]["held_by"]
    total = sum(v["redundancy"] for v in rep["variance_components"].values())
    assert total == pytest.approx(rep["observations"]["degrees_of_freedom"], abs=0.01)  # measured 383.003 of 383
    assert rep["sigma0"] == pytest.approx(1.0, abs=0.2)
    h = dict(zip(out.tie_points["id"], out.tie_points["h"]))
    ids, first = np.unique(rows["id"], return_index=True)
    error = np.array([h[i] for i in ids]) - rows["h_true"][first]
    assert float(np.sqrt(np.mean(error ** 2))) < 1.5 and abs(float(np.median(error))) < 0.5
