"""Simulated regions: the layout's side-lap and forward overlap measured on the products' footprints
(rigorous members of simulate_block, 21 of them: no cap at 20; RPC products without images), the
tie observations of an RPC region consistent with the true models to the noise, the vendor RPCs off
by the drawn bias, and what this machine cannot hold refused before any work, with the estimate."""
import csv
import json

import numpy as np
import pytest
from osgeo import gdal, ogr
from scipy.ndimage import map_coordinates

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.rpcfiles import read_rpc_text
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.simulation.block import simulate_block
from pushbroom_adjust.simulation.geometry import build_scenes
from pushbroom_adjust.simulation.measurements import near_image, observe
from pushbroom_adjust.simulation.memory import GB, refuse_beyond_memory
from pushbroom_adjust.simulation.presets import PRESETS, cut_preset, resolve_errors
from pushbroom_adjust.simulation.region import RegionLayout, region_members
from pushbroom_adjust.simulation.rpcregion import RegionSettings, simulate_region
from pushbroom_adjust.simulation.texture import texture_plane

TH1 = cut_preset(PRESETS["th1_tlc"], 500, 500)
NOISE = 0.3


def _read(path) -> dict:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


def _outline(scene, dem, centre) -> ogr.Geometry:
    """The footprint of a scene's first camera on the DEM: 16 points per image edge, on the plane
    (metres) around ``centre``."""
    cam = scene.cameras[0]
    t = np.linspace(0.0, 1.0, 16, endpoint=False)
    col = np.concatenate([t * cam.cols, np.full(16, cam.cols), (1 - t) * cam.cols, np.zeros(16)])
    row = np.concatenate([np.zeros(16), t * cam.rows, np.full(16, cam.rows), (1 - t) * cam.rows])
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground_dem(col, row, dem, 0))
    x, y = texture_plane(lon, lat, centre)
    ring = ogr.Geometry(ogr.wkbLinearRing)
    for a, b in zip(np.append(x, x[0]), np.append(y, y[0])):
        ring.AddPoint_2D(float(a), float(b))
    poly = ogr.Geometry(ogr.wkbPolygon)
    poly.AddGeometry(ring)
    return poly


def _overlaps(layout: RegionLayout, outlines: dict) -> tuple[list[float], list[float]]:
    """(side-laps, forward overlaps): the share of a product's footprint its neighbour in the next
    strip (same place along track) and the next product of its strip cover."""
    names = layout.names()
    grid = [names[i * layout.products_per_strip:(i + 1) * layout.products_per_strip] for i in range(layout.strips)]

    def share(a, b) -> float:
        return outlines[a].Intersection(outlines[b]).GetArea() / outlines[a].GetArea()
    side = [share(grid[i][j], grid[i + 1][j]) for i in range(layout.strips - 1) for j in range(len(grid[0]))]
    forward = [share(s[j], s[j + 1]) for s in grid for j in range(len(s) - 1)]
    return side, forward


@pytest.fixture(scope="module")
def rigorous(tmp_path_factory) -> dict:
    """21 rigorous TH-1 nadir members (3 strips x 7, 500 x 500 px cuts), not rendered (about 10 s)."""
    layout = RegionLayout(3, 7, side_lap=0.2, forward_overlap=0.15, dates=2)
    result = simulate_block(region_members(layout, TH1, rpc=False), tmp_path_factory.mktemp("region21"), seed=2,
                            n_gcps=10, n_tie_points=60)
    return {"layout": layout, "result": result, "manifest": json.loads(result.manifest.read_text())}


def test_21_members_are_simulated_with_the_side_lap_and_forward_overlap_asked(rigorous):
    layout, result = rigorous["layout"], rigorous["result"]
    assert list(result.members) == layout.names() and len(result.members) == 21
    dem = Dem(result.dem, datum="geoid")
    centre = tuple(TH1.centre)
    outlines = {n: _outline(load_scene(f["true_scene"]), dem, centre) for n, f in result.members.items()}
    side, forward = _overlaps(layout, outlines)
    # Measured: side-lap 0.194-0.200, forward overlap 0.140-0.150 (the terrain's relief)
    assert np.allclose(side, 0.2, atol=0.02) and np.allclose(forward, 0.15, atol=0.02), (side, forward)
    # strips alternate dates; a strip's products are imaged one after the other
    members = rigorous["manifest"]["members"]
    assert [m["date"] for m in members[::7]] == ["2012-03-01", "2012-04-12", "2012-03-01"]
    epochs = [m["epoch"] for m in members[:7]]
    assert epochs == sorted(epochs) or epochs == sorted(epochs, reverse=True)
    # tie points join neighbouring strips
    ties = _read(result.tie_points)
    strips = {s: {n[:3] for n in ties["scene"][ties["id"] == s]} for s in np.unique(ties["id"])}
    assert any(len(v) > 1 for v in strips.values())


@pytest.fixture(scope="module")
def rpc_region(tmp_path_factory) -> dict:
    """6 ZY-3-like RPC products (2 strips x 3), no images, 500 tie observations each (about 8 s)."""
    layout = RegionLayout(2, 3, side_lap=0.25, forward_overlap=0.1)
    settings = RegionSettings(ties_per_product=500, n_gcps=30, corner_gcps=True, image_noise=NOISE)
    result = simulate_region(layout, tmp_path_factory.mktemp("rpcregion"), seed=5, settings=settings)
    return {"layout": layout, "settings": settings, "result": result,
            "manifest": json.loads(result.manifest.read_text()), "ties": _read(result.tie_points),
            "gcps": _read(result.gcps), "truth": {n: load_scene(p) for n, p in result.truth.items()},
            "dem": Dem(result.dem, datum="geoid")}


def test_rpc_region_footprints_have_the_overlaps_asked(rpc_region):
    centre = (rpc_region["truth"]["s1p1"].rpc.lon_off, rpc_region["truth"]["s1p1"].rpc.lat_off)
    outlines = {n: _outline(s, rpc_region["dem"], centre) for n, s in rpc_region["truth"].items()}
    side, forward = _overlaps(rpc_region["layout"], outlines)
    # Measured: side-lap 0.2495-0.2497, forward overlap 0.0987-0.1006
    assert np.allclose(side, 0.25, atol=0.02) and np.allclose(forward, 0.1, atol=0.02), (side, forward)


def test_rpc_region_ties_are_the_true_models_images_plus_the_noise(rpc_region):
    ties, truth, dem = rpc_region["ties"], rpc_region["truth"], rpc_region["dem"]
    lon, lat, h, col_t, row_t, col, row = (ties[k].astype(float) for k in
                                           ("lon_true", "lat_true", "h_true", "col_true", "row_true", "col", "row"))
    assert (ties["camera"] == ties["scene"]).all()
    for name, scene in truth.items():
        m = ties["scene"] == name
        c, r = scene.ground_to_image_geodetic(lon[m], lat[m], h[m])
        assert np.abs(c - col_t[m]).max() < 1e-4 and np.abs(r - row_t[m]).max() < 1e-4, name
        assert m.sum() > 300, (name, m.sum())  # fewer in the corners, where fewer products overlap
    assert abs(len(col) / len(truth) - 500) < 5  # 500 observations per product on average
    # the ground points lie on the DEM (its bilinear surface, ellipsoidal heights)
    assert np.abs(dem.height(lon, lat) - h).max() < 1e-3
    # every tie point is seen by two products or more, once in each
    ids, count = np.unique(ties["id"], return_counts=True)
    assert count.min() >= 2 and len(set(zip(ties["id"], ties["scene"]))) == len(ties["id"])
    # the noise: Gaussian of NOISE px
    d = np.concatenate([col - col_t, row - row_t])
    assert abs(d.std() - NOISE) < 0.02 and abs(d.mean()) < 0.01


def test_rpc_region_vendor_rpcs_miss_the_truth_by_the_drawn_bias(rpc_region):
    result, manifest = rpc_region["result"], rpc_region["manifest"]
    gcps = rpc_region["gcps"]
    for product in manifest["products"]:
        name = product["name"]
        vendor = read_rpc_text(result.folder / product["rpc"])
        true = rpc_region["truth"][name]
        assert np.allclose(true.correction, [product["true_correction"]["col"], product["true_correction"]["row"]])
        m = gcps["scene"] == name
        lon, lat, h = (gcps[k][m].astype(float) for k in ("lon_true", "lat_true", "h_true"))
        vc, vr = vendor.ground_to_image_geodetic(lon, lat, h)
        tc, tr = true.ground_to_image_geodetic(lon, lat, h)
        miss_m = np.hypot(vc - tc, vr - tr) * 2.1  # ZY-3 nadir: 2.1 m pixels
        # the drawn shift (5-20 m) and drift (up to 2 m per axis at the last row); measured 10.5-19.6 m
        assert 5.0 - 2.9 < miss_m.min() and miss_m.max() < 20.0 + 2.9, (name, miss_m)
    roles = dict(zip(*np.unique(gcps["role"][np.unique(gcps["id"], return_index=True)[1]], return_counts=True)))
    assert roles == {"control": 4, "check": 26}


def test_memory_refusals_name_the_parameter_and_the_estimate(tmp_path):
    refuse_beyond_memory(1 * GB, "members", "a test", available=4 * GB)
    with pytest.raises(InputError, match=r"members: a test needs about 10.0 GB.*4.0 GB available") as info:
        refuse_beyond_memory(10 * GB, "members", "a test", available=4 * GB)
    assert info.value.parameter == "members"
    with pytest.raises(InputError, match="a region of 1000000 products x 2000 tie observations.*needs about") as info:
        simulate_region(RegionLayout(1000, 1000), tmp_path / "huge")
    assert info.value.parameter == "products_per_strip" and not (tmp_path / "huge").exists()
    members = region_members(RegionLayout(2, 2), TH1)
    with pytest.raises(InputError, match=r"a block of 4 members with 100000010 ground points.*needs about") as info:
        simulate_block(members, tmp_path / "block", n_gcps=10, n_tie_points=100_000_000)
    assert info.value.parameter == "members" and not (tmp_path / "block").exists()


@pytest.mark.parametrize("layout, field", [
    (RegionLayout(0, 4), "strips"), (RegionLayout(1, 1), "products_per_strip"),
    (RegionLayout(2, 2, side_lap=0.9), "side_lap"), (RegionLayout(2, 2, forward_overlap=-0.1), "forward_overlap"),
    (RegionLayout(2, 2, dates=9), "dates"), (RegionLayout(2.5, 2), "strips"),
])
def test_bad_layouts_are_refused_naming_the_field(tmp_path, layout, field):
    with pytest.raises(InputError) as info:
        simulate_region(layout, tmp_path / "r")
    assert info.value.parameter == field and field in str(info.value)
    assert not (tmp_path / "r").exists()


def test_a_rendered_region_of_12_products_in_3_strips_images_one_ground(tmp_path):
    """The region regionmatch matches: 3 strips x 4 TH-1 RPC products of 500 x 500 px, rendered (about
    10 s); the images of two products agree at the true positions of the tie points they share."""
    layout = RegionLayout(3, 4)
    result = simulate_block(region_members(layout, TH1), tmp_path / "region", seed=3, n_gcps=10, n_tie_points=150,
                            render=True)
    assert list(result.members) == layout.names()
    assert all(len(f["images"]) == 1 and len(f["rpc"]) == 1 for f in result.members.values())
    ties = _read(result.tie_points)
    images = {n: gdal.Open(str(next(iter(f["images"].values())))).ReadAsArray().astype(float)
              for n, f in result.members.items()}
    # mode nearest: a tie within half a pixel of an image's edge takes its edge pixel (not 0 beyond it)
    values = np.array([map_coordinates(images[s], [[float(r) - 0.5], [float(c) - 0.5]], order=1, mode="nearest")[0]
                       for s, c, r in zip(ties["scene"], ties["col_true"], ties["row_true"])])
    ids = ties["id"]
    pairs = [(values[ids == i][0], values[ids == i][1]) for i in np.unique(ids) if (ids == i).sum() >= 2]
    a, b = np.array(pairs).T
    assert len(pairs) >= 100 and np.corrcoef(a, b)[0, 1] > 0.95, (len(pairs), np.corrcoef(a, b)[0, 1])
    strips_tied = {frozenset(n[:2] for n in ties["scene"][ids == i]) for i in np.unique(ids)}
    assert frozenset({"s1", "s2"}) in strips_tied and frozenset({"s2", "s3"}) in strips_tied
    # the products' camera is calibrated: each vendor RPC misses its truth by what a drift correction
    # (a shift of col and row, each drifting along the rows) follows. Measured: up to 0.024 px left
    # beyond a drift (the yaw: rows across the line), 5-10 px before; with the lens errors of seed 001 left
    # in, 0.22-0.69 px (measured on 600 px cuts)
    dem = Dem(result.dem, datum="geoid")
    col, row = (v.ravel() for v in np.meshgrid(np.linspace(0, 500, 11), np.linspace(0, 500, 11)))
    drift = np.column_stack([np.ones_like(col), row])
    for name, files in result.members.items():
        ground = load_scene(files["true_scene"]).image_to_ground_dem(col, row, dem, 0)
        vc, vr = load_scene(next(iter(files["rpc"].values()))).ground_to_image(ground, 0)
        error = np.column_stack([vc - col, vr - row])
        left = error - drift @ np.linalg.lstsq(drift, error, rcond=None)[0]
        assert np.abs(left).max() < 0.05 and np.abs(error).max() > 1.0, (name, np.abs(left).max())


def test_three_line_members_keep_every_camera_and_only_near_points_are_projected():
    """region_members(all_cameras=True): the preset's three cameras, laid out as the one-camera
    members are; observe() projects into a camera only the points in its image's box, and finds the
    same points at the same positions as projecting every point does (most of the candidates lie
    far from the scene: the ground of a 3 x 3 region of it)."""
    one = region_members(RegionLayout(2, 2), TH1, rpc=False)
    three = region_members(RegionLayout(2, 2), TH1, rpc=False, all_cameras=True)
    assert [len(m.preset.cameras) for m in one] == [1] * 4 and [len(m.preset.cameras) for m in three] == [3] * 4
    assert [(m.orbit_offset_km, m.along_track_km) for m in three] == [(m.orbit_offset_km, m.along_track_km)
                                                                       for m in one]
    scene = build_scenes(TH1, 1, resolve_errors(TH1, None), np.random.default_rng(4)).true
    rng = np.random.default_rng(5)
    centres = [ecef_to_geodetic(scene.image_to_ground([250.0], [250.0], 600.0, k)) for k in range(3)]
    # 1,500 points within 0.1 deg (11 km) of each camera's image centre: its image is 2.5 km wide
    lon, lat = (np.concatenate([c[i] + rng.uniform(-0.1, 0.1, 1500) for c in centres]) for i in (0, 1))
    ground = geodetic_to_ecef(lon, lat, rng.uniform(0.0, 1200.0, lon.size))
    near = [near_image(scene, k, lon, lat, ecef_to_geodetic(ground)[2]) for k in range(3)]
    assert all(0 < n.size < 1000 for n in near)  # a small share of the 4,500 points is projected
    for k, idx, col, row in observe(scene, ground):
        c, r = scene.ground_to_image(ground, k)
        every = np.nonzero(scene.cameras[k].in_image(c, r))[0]
        assert every.size > 10 and np.array_equal(idx, every)
        np.testing.assert_allclose(col, c[every], atol=1e-6)
        np.testing.assert_allclose(row, r[every], atol=1e-6)
