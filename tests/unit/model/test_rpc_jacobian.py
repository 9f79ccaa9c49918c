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


def newton_by_differences(rpc: RpcModel, col, row, h, tol: float = 1e-10) -> tuple[np.ndarray, np.ndarray]:
    """(lon, lat) deg of image points at heights h by Newton with forward-difference derivatives (steps of
    1e-6 of the scales): the inversion RpcModel.image_to_ground made before it used the analytic ones."""
    lon, lat = np.full(col.shape, rpc.lon_off), np.full(col.shape, rpc.lat_off)
    e_lon, e_lat = 1e-6 * rpc.lon_scale, 1e-6 * rpc.lat_scale
    for _ in range(30):
        c0, r0 = rpc.ground_to_image(lon, lat, h)
        c1, r1 = rpc.ground_to_image(lon + e_lon, lat, h)
        c2, r2 = rpc.ground_to_image(lon, lat + e_lat, h)
        a, b, c, d = (c1 - c0) / e_lon, (c2 - c0) / e_lat, (r1 - r0) / e_lon, (r2 - r0) / e_lat
        dc, dr = col - c0, row - r0
        dlon, dlat = (d * dc - b * dr) / (a * d - b * c), (a * dr - c * dc) / (a * d - b * c)
        lon, lat = lon + dlon, lat + dlat
        if max(np.max(np.abs(dlon)) / rpc.lon_scale, np.max(np.abs(dlat)) / rpc.lat_scale) < tol:
            break
    return lon, lat


@pytest.mark.parametrize("vendor", [pleiades_rpc, worldview2_rpc], ids=["pleiades", "worldview2"])
def test_the_inversion_with_analytic_derivatives_is_the_one_by_differences(vendor, shared_data):
    """image_to_ground (Newton on the analytic derivatives) against Newton on finite differences, on the
    vendor RPCs (the random cubic folds: no inversion from its centre over all its domain): the same ground
    to 1e-6 m, and back onto the image points to 1e-6 px."""
    rpc = vendor(shared_data)
    lon, lat, h = ground(rpc)
    col, row = rpc.ground_to_image(lon, lat, h)
    got_lon, got_lat = rpc.image_to_ground(col, row, h)
    ref_lon, ref_lat = newton_by_differences(rpc, col, row, h)
    apart = np.linalg.norm(geodetic_to_ecef(got_lon, got_lat, h) - geodetic_to_ecef(ref_lon, ref_lat, h), axis=1)
    back = np.hypot(*(np.subtract(rpc.ground_to_image(got_lon, got_lat, h), (col, row))))
    assert np.max(apart) < 1e-6 and np.max(back) < 1e-6
    assert np.max(np.linalg.norm(geodetic_to_ecef(got_lon, got_lat, h) - geodetic_to_ecef(lon, lat, h), axis=1)) < 1e-6
    grid_lon, grid_lat = rpc.image_to_ground(col.reshape(20, 10), row.reshape(20, 10), h.reshape(20, 10))
    assert grid_lon.shape == (20, 10) and np.array_equal(grid_lon.ravel(), got_lon)
