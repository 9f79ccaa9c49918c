"""The analytic derivatives of RPC00B models (core.model.rpc.RpcModel.ground_to_image_jacobian and,
through geodetic coordinates and the image-space correction, core.model.rpcscene.RpcScene.
ground_to_image_jacobian) against central finite differences, on the real vendor RPCs (Pleiades
Global_RFM, WorldView-2 RPB) and on a random full cubic ratio that exercises all 80 coefficients.

Measured (largest difference over 200 points relative to the size of each row): 6e-11 to 2e-8 by (lon,
lat, h) with steps of 1e-4 of the scales; 3e-8 to 5e-8 by ECEF with steps of 0.05 m (the differences'
own truncation and rounding error).
"""
from __future__ import annotations

import numpy as np
import pytest

from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.core.model.rpc import EXPONENTS, RpcModel, rpc_terms
from pushbroom_adjust.core.model.rpcscene import RpcCamera, RpcScene
from tests.support.rpcdata import pleiades_rpc, worldview2_rpc

RELATIVE = 1e-6


def random_cubic(seed: int = 3) -> RpcModel:
    """A full cubic ratio (every coefficient non-zero, denominators near 1) over 0.1 degrees and 1 km."""
    rng = np.random.default_rng(seed)
    num = [rng.normal(0.0, 0.3, 20) for _ in range(2)]
    den = [np.concatenate([[1.0], rng.normal(0.0, 0.02, 19)]) for _ in range(2)]
    return RpcModel(num[0], den[0], num[1], den[1], 5.0, 0.05, 45.0, 0.05, 500.0, 500.0, 5000.0, 5000.0, 5000.0,
                    5000.0, origin=1.0)


@pytest.fixture(params=["pleiades", "worldview2", "random cubic"])
def rpc(request, shared_data) -> RpcModel:
    return {"pleiades": pleiades_rpc, "worldview2": worldview2_rpc}.get(request.param, lambda _: random_cubic())(
        shared_data)


def ground(rpc: RpcModel, n: int = 200, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random (lon, lat deg, h m) (n,) over the RPC's ground domain."""
    rng = np.random.default_rng(seed)
    return tuple(off + scale * rng.uniform(-1.0, 1.0, n) for off, scale in
                 ((rpc.lon_off, rpc.lon_scale), (rpc.lat_off, rpc.lat_scale), (rpc.height_off, rpc.height_scale)))


def agree(jac: np.ndarray, fd: np.ndarray) -> float:
    """The largest difference of two (n, 2, 3) Jacobians relative to the size of each row."""
    return float(np.max(np.abs(jac - fd) / np.linalg.norm(jac, axis=2, keepdims=True)))


def test_the_derivative_by_lon_lat_h_is_the_central_difference(rpc):
    lon, lat, h = ground(rpc)
    col, row, jac = rpc.ground_to_image_jacobian(lon, lat, h)
    np.testing.assert_allclose(np.stack([col, row]), np.stack(rpc.ground_to_image(lon, lat, h)), rtol=0, atol=1e-8)
    steps = 1e-4 * np.array([rpc.lon_scale, rpc.lat_scale, rpc.height_scale])
    fd = np.empty_like(jac)
    for k, e in enumerate(np.eye(3) * steps):
        plus = np.stack(rpc.ground_to_image(lon + e[0], lat + e[1], h + e[2]), axis=1)
        minus = np.stack(rpc.ground_to_image(lon - e[0], lat - e[1], h - e[2]), axis=1)
        fd[:, :, k] = (plus - minus) / (2.0 * steps[k])
    assert np.all(np.abs(jac) < 1e12) and agree(jac, fd) < RELATIVE


def test_the_scene_derivative_by_ecef_is_the_central_difference_with_a_correction(rpc):
    scene = RpcScene(rpc, RpcCamera("scene", 10_000, 10_000), np.array([[4.0, 2e-4, -3e-4], [-6.0, 1e-4, 5e-4]]))
    xyz = geodetic_to_ecef(*ground(rpc, seed=2))
    col, row, own_col, own_row, jac = scene.ground_to_image_jacobian(xyz)
    np.testing.assert_allclose(np.stack([col, row]), np.stack(scene.ground_to_image(xyz)), rtol=0, atol=1e-8)
    np.testing.assert_allclose(np.stack([own_col, own_row]), np.stack(scene.uncorrect(col, row)), atol=1e-8)
    fd = np.empty_like(jac)
    for k, e in enumerate(np.eye(3) * 0.05):
        fd[:, :, k] = (np.stack(scene.ground_to_image(xyz + e), 1) - np.stack(scene.ground_to_image(xyz - e), 1)) / 0.1
    assert agree(jac, fd) < RELATIVE


def test_the_derivative_is_nan_where_the_scene_images_no_point(rpc):
    scene = RpcScene(rpc, RpcCamera("scene", 10_000, 10_000))
    lon, lat, h = ground(rpc, n=2)
    xyz = geodetic_to_ecef(lon + np.array([0.0, 3.0 * rpc.lon_scale]), lat, h)
    col, row, _, _, jac = scene.ground_to_image_jacobian(xyz)
    assert np.isfinite(col[0]) and np.all(np.isfinite(jac[0]))
    assert np.isnan(col[1]) and np.isnan(row[1]) and np.all(np.isnan(jac[1]))
    assert ecef_to_geodetic(xyz)[0].shape == (2,)


def test_the_exponent_table_is_that_of_the_monomials():
    x, y, z = 2.0, 3.0, 5.0
    np.testing.assert_array_equal(rpc_terms(x, y, z), np.prod(np.array([x, y, z]) ** EXPONENTS, axis=1))
