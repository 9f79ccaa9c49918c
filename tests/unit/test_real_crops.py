"""Tie points between real satellite images: two crops of a Pleiades 1B stereo pair over Giza
(2013-02-08, 0.55 m, 800 x 801 and 795 x 801 px; tests/data/pleiades_gizeh, source and licence in
tests/data/README.md) with the vendor's RPCs, matched by core.measure.tiematching through the RPCs on a
flat surface, then intersected: each tie's ground point (lon, lat, h) fitted to both images by Gauss-Newton,
its reprojection residuals being how far the two vendor RPCs disagree before any adjustment.

Measured (spacing 40 px, window 31 px, search 60 m, flat at the RPCs' height offset 140 m; about 0.3 s):
198 of the 361 grid points tied; 19 outside img2, 45 low correlation (the pyramid's shadow), 71 ambiguous
peaks (its regular courses of stone), 5 peaks on the search border and 23 inconsistent (the Great Pyramid
stands 138 m above the flat surface: its faces are up to 20 px of parallax off the coarse plane).
Intersected: reprojection RMS 0.249 px per image point, max 0.55 px. The residual is a bias, not noise: the
image columns are off by -0.244 and +0.245 px (0.49 px of y-parallax between the two RPCs, across track)
with a scatter of 0.05 px about it, which bias compensation in the adjustment removes. The ties' heights:
median 75.6 m (ellipsoidal: the Giza plateau, about 60 m above the geoid, which is 15 m above the ellipsoid).
"""
from __future__ import annotations

import re
import time

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.dem import ConstantHeight
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.measure.matching import MatchSettings
from pushbroom_adjust.core.measure.tiematching import OUTSIDE_OTHER, View, match_block_tiepoints

gdal.UseExceptions()

NAMES = ("img1", "img2")
SETTINGS = MatchSettings(spacing=40, window=31, search=60.0)
GRID_POINTS = 19 * 19  # spacing 40 px over 800 px, less the window's margin


@pytest.fixture(scope="module")
def gizeh(shared_data):
    return shared_data / "pleiades_gizeh"


@pytest.fixture(scope="module")
def scenes(gizeh):
    return {n: load_scene(gizeh / f"{n}.tif") for n in NAMES}


@pytest.fixture(scope="module")
def matched(gizeh, scenes):
    """The ties matched in img1's geometry, their rejections and the matching wall time."""
    dem = ConstantHeight(scenes["img1"].rpc.height_off)
    start = time.perf_counter()
    table, rejected = match_block_tiepoints([View(n, scenes[n], 0, gizeh / f"{n}.tif") for n in NAMES], dem,
                                            SETTINGS)
    return table, rejected["img2/img2"], time.perf_counter() - start


def _geom(path) -> dict:
    """The OSSIM keyword list of a .geom file: {key: value text}."""
    return dict(re.match(r"\s*([^:]+):\s*(.*)", line).groups() for line in path.read_text().splitlines()
                if ":" in line)


@pytest.mark.parametrize("name", NAMES)
def test_the_rpc_files_are_the_vendor_geom_moved_to_the_crop(gizeh, name):
    """img*_RPC.TXT hold the numbers of the unchanged img*.geom (the full product's RPC, OSSIM's
    pixel-centre convention, the same as GDAL's RPC metadata), with LINE_OFF/SAMP_OFF moved by the crop's
    origin in the full product (the crop's geotransform). Read the same from the image (GDAL pairs the
    _RPC.TXT with it) and from the _RPC.TXT."""
    geom = _geom(gizeh / f"{name}.geom")
    ds = gdal.Open(str(gizeh / f"{name}.tif"))
    x0, _, _, y0, _, _ = ds.GetGeoTransform()
    assert (x0, y0) == {"img1": (20500, 5000), "img2": (20501, 5476)}[name]
    assert ds.GetRasterBand(1).DataType == gdal.GDT_Float32 and ds.RasterCount == 1
    for scene in (load_scene(gizeh / f"{name}.tif"), load_scene(gizeh / f"{name}_RPC.TXT")):
        rpc = scene.rpc
        assert (scene.camera.cols, scene.camera.rows) == (ds.RasterXSize, ds.RasterYSize)
        assert rpc.origin == 0.0
        assert rpc.samp_off == float(geom["samp_off"]) - x0 and rpc.line_off == float(geom["line_off"]) - y0
        for fld, key in (("lon", "long"), ("lat", "lat"), ("height", "height")):
            assert getattr(rpc, f"{fld}_off") == float(geom[f"{key}_off"])
            assert getattr(rpc, f"{fld}_scale") == float(geom[f"{key}_scale"])
        assert rpc.samp_scale == float(geom["samp_scale"]) and rpc.line_scale == float(geom["line_scale"])
        for fld in ("line_num", "line_den", "samp_num", "samp_den"):
            np.testing.assert_array_equal(getattr(rpc, fld), [float(geom[f"{fld}_coeff_{i:02d}"]) for i in range(20)])


def test_ties_between_the_real_pair(matched):
    """Most grid points tie; the rest are rejected for the reasons a real scene with a pyramid gives."""
    table, rejected, seconds = matched
    n = int((table.scene == "img2").sum())
    assert set(table.scene) == set(NAMES) and len(table) == 2 * n
    assert n + sum(rejected.values()) == GRID_POINTS
    assert 170 <= n <= 230                                   # measured 198 of 361
    assert 12 <= rejected[OUTSIDE_OTHER] <= 26                # measured 19
    assert rejected["near a CCD seam"] == rejected["outside the image"] == rejected["off the DEM"] == 0
    assert 20 <= rejected["low correlation"] <= 70            # measured 45
    assert 40 <= rejected["ambiguous peak"] <= 100            # measured 71
    assert rejected["inconsistent with its neighbours"] <= 40  # measured 23
    assert seconds < 15                                       # measured 0.3 s


def intersect(scenes: list, obs: np.ndarray, start: np.ndarray, iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Ground points (n, 3: lon, lat, h) minimising the reprojection error in all ``scenes`` of the
    observations ``obs`` (n, 2 * len(scenes): col, row per scene), Gauss-Newton from ``start`` with
    finite-difference Jacobians, vectorised over the points; and the residuals obs - projection."""
    def project(p):
        return np.concatenate([np.stack(s.ground_to_image_geodetic(p[:, 0], p[:, 1], p[:, 2]), axis=1)
                               for s in scenes], axis=1)

    steps = np.array([1e-6, 1e-6, 1.0])  # deg, deg, m
    p = start.copy()
    for _ in range(iterations):
        f = project(p)
        jac = np.stack([(project(p + np.eye(3)[k] * steps[k]) - f) / steps[k] for k in range(3)], axis=2)
        p += np.linalg.solve(np.einsum("nik,nil->nkl", jac, jac), np.einsum("nik,ni->nk", jac, obs - f))
    return p, obs - project(p)


def test_intersected_ties_show_the_relative_bias_of_the_vendor_rpcs(matched, scenes):
    """Before any adjustment the two RPCs disagree by about half a pixel across track, nearly the
    same at every tie (a bias that the adjustment's bias compensation removes), and the ties' heights
    are the Giza plateau's."""
    table, _, _ = matched
    obs = []
    for name in NAMES:
        mine = table.scene == name
        order = np.argsort(table.id[mine])
        obs += [table.col[mine][order], table.row[mine][order]]
    obs = np.stack(obs, axis=1)
    lon, lat, h = ecef_to_geodetic(scenes["img1"].image_to_ground(obs[:, 0], obs[:, 1], 140.0))
    ground, res = intersect([scenes[n] for n in NAMES], obs, np.stack([lon, lat, h], axis=1))
    per_point = np.hypot(res[:, 0::2], res[:, 1::2])          # (n, 2): px in img1, img2
    rms = float(np.sqrt(np.mean(per_point ** 2)))
    assert 0.15 < rms < 0.32                                  # measured 0.249 px
    assert per_point.max() < 0.8                              # measured 0.55 px
    bias = res.mean(axis=0)                                   # measured col -0.244, row 0.004, col 0.245, row -0.004
    assert -0.32 < bias[0] < -0.17 and 0.17 < bias[2] < 0.32 and np.all(np.abs(bias[1::2]) < 0.02)
    assert np.all(res.std(axis=0) < 0.1)                      # measured 0.047 px in columns
    assert 68 < np.median(ground[:, 2]) < 84                  # measured 75.6 m
