"""Bias compensation of RPC scenes (core.adjust.rpcbias, Grodecki & Dial 2003) on the real vendor
RPCs: the Pleiades Global_RFM and the WorldView-2 RPB, with a known image shift and drift added
to simulated measurements (noise 0.3 px): the bias is recovered within its sigma, check points
reach the noise, the refined RPC read by gdal.Transformer reproduces the adjusted scene; the
Pleiades rigorous model adjusted to the same GCPs gives the same check figures.

Measured (seed 5, 30 control + 50 check points, drift mode): see docs/accuracy.md, "RPC scenes".
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.formats.rpcfiles import rpc_metadata, write_rpc
from pushbroom_adjust.core.products.rpcfit import refined_rpc
from pushbroom_adjust.core.formats import load_scene
from tests.support.rpc_bias import BIAS, NOISE, biased_gcps
from tests.support.rpcdata import PLEIADES, pleiades_rpc, worldview2_rpc

gdal.UseExceptions()


@pytest.fixture(scope="module", params=["pleiades", "worldview2"])
def vendor(request, shared_data, tmp_path_factory):
    rpc = pleiades_rpc(shared_data) if request.param == "pleiades" else worldview2_rpc(shared_data)
    return load_scene(write_rpc(rpc, tmp_path_factory.mktemp("rpc") / f"{request.param}_RPC.TXT"))


@pytest.fixture(scope="module")
def drift(vendor):
    table, _, _ = biased_gcps(vendor, BIAS)
    return adjust(vendor, table, AdjustmentSettings(rpc_correction="drift")), table


def test_shift_and_drift_are_recovered_within_their_sigma(drift):
    result, _ = drift
    values = {p["name"].split(".")[-1]: (p["value"], p["sigma"], p["mode"]) for p in result.report["parameters"]}
    assert {k for k, v in values.items() if v[2] == "free"} == {"a0", "a2", "b0", "b2"}
    for term, truth in zip(("a0", "a1", "a2", "b0", "b1", "b2"), BIAS.ravel()):
        value, sigma, mode = values[term]
        if mode == "free":
            assert abs(value - truth) < 2.0 * sigma, (term, value, truth, sigma)
            assert sigma < 0.2 if term in ("a0", "b0") else sigma < 1e-5
        else:
            assert value == 0.0


def test_check_points_reach_the_noise(drift):
    result, _ = drift
    after, before = result.report["check_points"]["image"], result.report["check_points_before"]["image"]
    assert before["rmse"] > 3.0
    assert 0.8 * NOISE < after["rmse_col"] < 1.25 * NOISE and 0.8 * NOISE < after["rmse_row"] < 1.25 * NOISE
    assert 0.7 < result.report["sigma0"] < 1.3


def test_the_refined_rpc_is_the_adjusted_scene_for_gdal(drift):
    result, _ = drift
    scene = result.scene
    rpc, how = refined_rpc(scene)
    assert how == "refitted"  # a drift of the columns along the rows mixes the two
    rng = np.random.default_rng(9)
    col, row = rng.uniform(0, scene.camera.cols, 2000), rng.uniform(0, scene.camera.rows, 2000)
    lo, hi = scene.height_range
    lon, lat, h = ecef_to_geodetic(scene.image_to_ground(col, row, rng.uniform(lo, hi, 2000)))
    ds = gdal.GetDriverByName("MEM").Create("", scene.camera.cols, scene.camera.rows, 1)
    ds.SetMetadata(rpc_metadata(rpc), "RPC")
    pts, _ = gdal.Transformer(ds, None, ["METHOD=RPC"]).TransformPoints(1, np.c_[lon, lat, h].tolist())
    pts = np.array(pts)
    assert np.max(np.hypot(pts[:, 0] - col, pts[:, 1] - row)) < 0.01


def test_a_correction_of_each_coordinate_alone_is_folded_exactly(vendor):
    scene = load_scene(vendor.info["source"])
    scene.correction = np.array([[2.5, 1e-5, 0.0], [-1.2, 0.0, 3e-5]])
    rpc, how = refined_rpc(scene)
    assert how == "folded"
    lo, hi = scene.height_range
    xyz = scene.image_to_ground([10.0, 5000.0, 9000.0], [20.0, 7000.0, 300.0], 0.5 * (lo + hi))
    lon, lat, h = ecef_to_geodetic(xyz)
    c, r = scene.ground_to_image(xyz)
    c2, r2 = rpc.ground_to_image(lon, lat, h)
    assert np.max(np.hypot(c2 - c, r2 - r)) < 1e-6


@pytest.mark.parametrize("mode, free", [("shift", {"a0", "b0"}), ("affine", {"a0", "a1", "a2", "b0", "b1", "b2"})])
def test_other_modes(vendor, mode, free):
    table, _, _ = biased_gcps(vendor, BIAS)
    result = adjust(vendor, table, AdjustmentSettings(rpc_correction=mode))
    assert {p["name"].split(".")[-1] for p in result.report["parameters"] if p["mode"] == "free"} == free
    rmse = result.report["check_points"]["image"]["rmse"]
    # a shift alone leaves the drift (up to 0.4-0.6 px at the ends); affine reaches the noise
    assert rmse < (1.0 if mode == "shift" else 1.25 * np.sqrt(2) * NOISE)


def test_rigorous_and_rpc_adjustments_agree_on_pleiades(shared_data, tmp_path):
    rpc_scene = load_scene(write_rpc(pleiades_rpc(shared_data), tmp_path / "phr_RPC.TXT"))
    table, _, _ = biased_gcps(rpc_scene, BIAS)
    by_rpc = adjust(rpc_scene, table, AdjustmentSettings(rpc_correction="drift"))
    rigorous = load_scene(shared_data / PLEIADES)
    by_model = adjust(rigorous, replace(table, camera=np.full(len(table), rigorous.cameras[0].name)),
                      AdjustmentSettings())
    a, b = by_rpc.report["check_points"]["image"]["rmse"], by_model.report["check_points"]["image"]["rmse"]
    print(f"check RMSE: RPC {a:.4f} px, rigorous {b:.4f} px")
    assert abs(a - b) < 0.05 * b, (a, b)
