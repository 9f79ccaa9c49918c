"""Sensor-corrected images of staggered multi-CCD cameras (CBERS-02B HRC true camera, ZY-3 nadir
with 3 CCDs): the RPC written with the image reproduces the virtual rigorous model to hundredths
of a pixel also at the former seams, the image lies on the known texture through its own model,
and gdalwarp -rpc of it agrees with our rigorous orthoimage of the raw image."""

import json
import math

import numpy as np
import pytest
from osgeo import gdal
from pyproj import Transformer

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import Cancelled, InputError
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.products.mapping import OrthoGrid
from pushbroom_adjust.core.products.ortho import default_grid, orthorectify
from pushbroom_adjust.simulation.texture import texture_at
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.products.sensorcorrect import output_files, sensor_correct, virtual_camera
from tests.support.ortho_compare import gdalwarp_rpc, image_difference, rendered_cut

CASES = {"cbers02b_hrc": 700, "zy3_tlc": 400}  # preset: rows of the cut


@pytest.fixture(scope="module", params=list(CASES))
def corrected(request, tmp_path_factory):
    """The cut's true scene, its raw image, the ellipsoidal DEM, the texture frame and the
    sensor-corrected image with its RPC, VRT and virtual scene."""
    folder = tmp_path_factory.mktemp(request.param)
    scene, _, geoid_dem, frame = rendered_cut(folder, seed=3, rows=CASES[request.param], preset=request.param)
    dem_path = geoid_dem.write_ellipsoidal(folder / "dem_ellipsoid.tif")
    dem = Dem(dem_path, datum="ellipsoid")
    figures = sensor_correct(scene, 0, folder / "raw.tif", dem, folder / "corrected.tif",
                             folder / "corrected_scene.json")
    return {"scene": scene, "dem": dem, "dem_path": dem_path, "frame": frame, "folder": folder,
            "figures": figures, "virtual": load_scene(folder / "corrected_scene.json")}


def seams(cam) -> np.ndarray:
    """Columns of the chip boundaries of a camera."""
    return np.array([c.col_offset for c in cam.chips[1:]])


def rpc_errors(case, col, row, h) -> np.ndarray:
    """|GDAL's RPC transformer on the corrected image - the virtual rigorous model| (px) at
    virtual image points (col, row) on heights h (one GDAL transformer per height)."""
    ds = gdal.Open(str(case["folder"] / "corrected.tif"))  # its RPC: the _RPC.TXT beside it
    errors = []
    for height in np.unique(h):
        sel = h == height
        lon, lat, _ = ecef_to_geodetic(case["virtual"].image_to_ground(col[sel], row[sel], height, 0))
        tr = gdal.Transformer(ds, None, ["METHOD=RPC", f"RPC_HEIGHT={height}"])
        pts = np.array(tr.TransformPoints(1, np.stack([lon, lat, np.zeros_like(lon)], axis=1).tolist())[0])
        errors.append(np.hypot(pts[:, 0] - col[sel], pts[:, 1] - row[sel]))
    return np.concatenate(errors)


def test_virtual_camera_is_one_straight_line_over_the_same_span(corrected):
    cam, virtual = corrected["scene"].cameras[0], corrected["virtual"].cameras[0]
    assert len(cam.chips) == 3 and len(virtual.chips) == 1 and virtual.distortion == {}
    assert (virtual.cols, virtual.rows, virtual.name) == (cam.cols, cam.rows, cam.name)
    assert virtual.timing.time(0.5) == pytest.approx(cam.timing.time(0.5), abs=1e-9)
    assert virtual.timing.time(cam.rows - 0.5) == pytest.approx(cam.timing.time(cam.rows - 0.5), abs=1e-9)
    # the line runs where the real detectors look: within a few pixels across the whole array
    cols = np.linspace(0.5, cam.cols - 0.5, 500)
    uy_real, uy_virtual = cam.image_plane(cols)[1], virtual.image_plane(cols)[1]
    pixel = virtual.chips[0].pitch / virtual.focal_length
    assert np.max(np.abs(uy_real - uy_virtual)) / pixel < 5.0
    info = corrected["virtual"].info["sensor_corrected"]
    assert info["camera"] == cam.name and info["chips"] == 3 and "DEM" in info["surface"]
    # its source is its own file (load_scene's), not the real scene's
    assert corrected["virtual"].info["source"] == str(corrected["folder"] / "corrected_scene.json")
    assert virtual_camera(virtual).to_dict()["chips"][0]["pitch"] == pytest.approx(virtual.chips[0].pitch)


def test_rpc_reproduces_the_virtual_model_within_hundredths_of_a_pixel_at_the_seams_too(corrected):
    cam = corrected["scene"].cameras[0]
    lo, hi = corrected["figures"]["height_range"]
    rng = np.random.default_rng(0)
    n = 3000
    everywhere = rng.uniform(0, cam.cols, n)
    at_seams = (seams(cam)[:, None] + np.arange(-5.0, 5.5, 0.5)[None, :]).ravel()
    for cols in (everywhere, at_seams):
        col = np.repeat(cols, 9)
        row = rng.uniform(0, cam.rows, col.size)
        h = np.tile(np.linspace(lo, hi, 9), cols.size)
        err = rpc_errors(corrected, col, row, h)
        rms = float(np.sqrt(np.mean(err ** 2)))
        assert rms <= 0.02 and err.max() <= 0.05, (rms, err.max())
    assert corrected["figures"]["rpc_check_max_px"] < 0.01
    report = json.loads(output_files(corrected["folder"] / "corrected.tif")["report"].read_text())
    assert report["check"]["max_px"] == corrected["figures"]["rpc_check_max_px"]


def texture_shift(case, mask_cols=None, n: int = 200_000) -> tuple[np.ndarray, int]:
    """(dx, dy) px of the corrected image against the texture seen through its own (virtual)
    model: least squares on the texture's gradient at up to n valid pixels, only in columns
    where ``mask_cols(col)`` is true if given."""
    ds = gdal.Open(str(case["folder"] / "corrected.tif"))
    img = ds.GetRasterBand(1).ReadAsArray().astype(float)
    ok = img > 0
    ok[[0, -1], :] = ok[:, [0, -1]] = False
    i, j = np.nonzero(ok)
    if mask_cols is not None:
        keep = mask_cols(j + 0.5)
        i, j = i[keep], j[keep]
    pick = np.random.default_rng(0).choice(i.size, min(n, i.size), replace=False)
    i, j = i[pick], j[pick]
    frame = case["frame"]

    def truth(di=0.0, dj=0.0):
        ground = case["virtual"].image_to_ground_dem(j + 0.5 + dj, i + 0.5 + di, case["dem"], 0)
        lon, lat, _ = ecef_to_geodetic(ground)
        return 20.0 + 215.0 * texture_at(lon, lat, tuple(frame["centre"]), frame["gsd_m"], frame["seed"])

    t0 = truth()
    g = np.stack([truth(dj=0.5) - truth(dj=-0.5), truth(di=0.5) - truth(di=-0.5)], axis=1)
    d, *_ = np.linalg.lstsq(g, img[i, j] - t0, rcond=None)
    return -d, int(i.size)


def test_corrected_image_lies_on_the_texture_without_seams(corrected):
    d, n = texture_shift(corrected)
    assert n == 200_000 and np.hypot(*d) <= 0.05, d
    for seam in seams(corrected["scene"].cameras[0]):
        d, n = texture_shift(corrected, lambda c, s=seam: np.abs(c - s) < 12.0)
        assert n > 5000 and np.hypot(*d) <= 0.05, (seam, d)


def test_gdalwarp_rpc_of_corrected_image_matches_our_rigorous_orthoimage(corrected, tmp_path):
    """A window of the map around the first former seam: gdalwarp -rpc of the corrected image
    against our orthorectification of the raw image with the rigorous model."""
    scene, dem, folder = corrected["scene"], corrected["dem"], corrected["folder"]
    cam = scene.cameras[0]
    full = default_grid(scene, 0, dem)
    seam = seams(cam)[0]
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground_dem(np.array([seam]), np.array([cam.rows / 2]), dem, 0))
    x, y = Transformer.from_crs("EPSG:4326", full.crs, always_xy=True).transform(lon[0], lat[0])
    size = 384
    x0 = full.x0 + math.floor((x - full.x0) / full.resolution - size / 2) * full.resolution
    y0 = full.y0 - math.floor((full.y0 - y) / full.resolution - size / 2) * full.resolution
    grid = OrthoGrid(full.crs, x0, y0, full.resolution, 2 * size, size)
    orthorectify(scene, folder / "raw.tif", dem, tmp_path / "ours.tif", grid=grid, resampling="bilinear")
    gdalwarp_rpc(folder / "corrected.tif", corrected["dem_path"], grid, tmp_path / "gdalwarp.tif")
    diff = image_difference(str(tmp_path / "ours.tif"), str(tmp_path / "gdalwarp.tif"), blocks=2)
    assert diff["pixels"] > 100_000
    assert np.hypot(*diff["shift_px"]) <= 0.1 and diff["worst_block_shift_px"] <= 0.1, diff


def test_refusals_and_cancel_leave_no_file(corrected, tmp_path):
    scene, dem, folder = corrected["scene"], corrected["dem"], corrected["folder"]
    out = tmp_path / "c.tif"
    with pytest.raises(InputError, match="raster is"):
        sensor_correct(scene, 0, folder / "dem_ellipsoid.tif", dem, out)
    with pytest.raises(InputError, match="resampling"):
        sensor_correct(scene, 0, folder / "raw.tif", dem, out, resampling="lanczos")
    with pytest.raises(InputError, match="not in this scene"):
        sensor_correct(scene, "PAN", folder / "raw.tif", dem, out)
    calls = []

    def cancel_after_two():
        calls.append(1)
        return len(calls) > 2

    with pytest.raises(Cancelled):
        sensor_correct(scene, 0, folder / "raw.tif", dem, out, tile=256, is_cancelled=cancel_after_two)
    assert list(tmp_path.iterdir()) == []
