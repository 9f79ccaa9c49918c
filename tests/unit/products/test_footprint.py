"""Footprints: outline sampling, ring geometry against the exact sensor model, DEM coverage."""
import numpy as np
import pytest
from osgeo import gdal, osr
from pyproj import Geod

from pushbroom_adjust.core.model.camera import Camera, Chip, LineTiming
from pushbroom_adjust.core.dem import ConstantHeight, Dem
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.products.footprint import footprints, image_outline
from pushbroom_adjust.core.model.sensor import SceneModel
from pushbroom_adjust.core.model.trajectory import Ephemeris, Platform, QuaternionPolynomial

COLS, ROWS = 2000, 3000


def _staggered_scene() -> SceneModel:
    """Satellite 622 km up over (0°, ~0°) flying north; two look-angle chips 1000 px each, the
    second imaging every row 0.05 s (~350 m) later; ~12 m pixels."""
    t = np.arange(-20.0, 21.0, 5.0)
    pos = np.stack([7.0e6 + 0 * t, 0 * t, 7000.0 * t], 1)
    # body z toward -x ECEF (down), x toward +z ECEF (north), y toward +y ECEF (east): -90° about y
    c = 0.5 ** 0.5
    att = QuaternionPolynomial(0.0, 1.0, np.array([[c, 0.0], [0.0, 0.0], [-c, 0.0], [0.0, 0.0]]))
    chips = [Chip(col_offset=0, n_pixels=1000, kind="look_angle", ux_poly=[0.0], uy_poly=[-0.02, 2e-5]),
             Chip(col_offset=1000, n_pixels=1000, kind="look_angle", time_offset=0.05, ux_poly=[0.0],
                  uy_poly=[0.0, 2e-5])]
    cam = Camera("PAN", COLS, ROWS, LineTiming(-1.5, 1e-3), chips)
    return SceneModel("2020-01-01T00:00:00Z", Platform(Ephemeris(t, pos), att), [cam],
                      info={"height_range": [0.0, 500.0]})


def test_outline_is_closed_and_samples_both_sides_of_chip_boundaries():
    cam = _staggered_scene().cameras[0]
    col, row = image_outline(cam, samples_per_edge=8)
    assert (col[0], row[0]) == (col[-1], row[-1]) == (0.0, 0.0)
    top = col[row == 0.0]
    assert 1000.0 in top and np.any(np.abs(top - 1000.0 + 1e-6) < 1e-9)
    assert set(row[col == COLS]) >= {0.0, ROWS / 2, float(ROWS)}
    assert col.min() == 0.0 and col.max() == COLS and row.max() == ROWS


def test_footprint_ring_follows_the_exact_image_border():
    scene = _staggered_scene()
    (fp,) = footprints(scene, ConstantHeight(120.0), samples_per_edge=64)
    assert (fp.camera, fp.cols, fp.rows) == ("PAN", COLS, ROWS)
    assert fp.lon[0] == fp.lon[-1] and fp.lat[0] == fp.lat[-1]
    assert np.allclose(fp.height, 120.0, atol=1e-3)
    # counter-clockwise ring: positive signed geodesic area, equal to the reported one
    area, _ = Geod(ellps="WGS84").polygon_area_perimeter(fp.lon, fp.lat)
    assert area > 0 and abs(area / 1e6 - fp.area_km2) < 1e-9
    # image corners are on the ring
    corners = scene.image_to_ground(np.array([0.0, COLS, COLS, 0.0]), np.array([0.0, 0.0, ROWS, ROWS]), 120.0)
    clon, clat, _ = ecef_to_geodetic(corners)
    for lo, la in zip(clon, clat):
        assert np.min(np.hypot(fp.lon - lo, fp.lat - la)) < 1e-9
    # the staggered chip makes a ~350 m step at col 1000 on the top edge (0.05 s at 7 km/s)
    step = scene.image_to_ground(np.array([1000.0 - 1e-6, 1000.0]), np.zeros(2), 120.0)
    assert 300.0 < np.linalg.norm(step[1] - step[0]) < 400.0
    slon, slat, _ = ecef_to_geodetic(step)
    for lo, la in zip(slon, slat):
        assert np.min(np.hypot(fp.lon - lo, fp.lat - la)) < 1e-9
    # area close to the image size times the pixel footprint: ~12.4 m across, 7 m along track
    assert 0.9 < fp.area_km2 / (COLS * 12.45 * ROWS * 7.0 / 1e6) < 1.1


def test_footprint_outline_is_dense_enough_to_be_correct():
    """Between samples the true border departs from the straight chord by < 1 cm."""
    scene = _staggered_scene()
    (fp,) = footprints(scene, ConstantHeight(0.0), samples_per_edge=256)
    col = np.linspace(0.0, 999.0, 4001)  # fine sampling of the left chip's top edge
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground(col, np.zeros_like(col), 0.0))
    ring = np.stack([fp.lon, fp.lat], 1)
    seg = np.diff(ring, axis=0)
    pts = np.stack([lon, lat], 1)
    rel = pts[:, None, :] - ring[None, :-1, :]
    s = np.clip(np.einsum("psk,sk->ps", rel, seg) / np.einsum("sk,sk->s", seg, seg), 0, 1)
    gap_deg = np.min(np.linalg.norm(rel - s[..., None] * seg[None], axis=2), axis=1)
    assert gap_deg.max() * 111e3 < 0.01


def _write_dem(path, lon0, lat0, step, n, z=100.0):
    ds = gdal.GetDriverByName("GTiff").Create(str(path), n, n, 1, gdal.GDT_Float32)
    ds.SetGeoTransform((lon0, step, 0, lat0 + n * step, 0, -step))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds.SetProjection(srs.ExportToWkt())
    ds.GetRasterBand(1).Fill(z)
    ds = None


def test_footprint_on_a_dem_and_an_uncovering_dem(tmp_path):
    scene = _staggered_scene()
    _write_dem(tmp_path / "big.tif", -1.0, -1.0, 0.01, 200)
    (fp,) = footprints(scene, Dem(tmp_path / "big.tif", datum="ellipsoid"), samples_per_edge=16)
    assert np.allclose(fp.height, 100.0, atol=1e-3)
    _write_dem(tmp_path / "small.tif", -0.05, -0.05, 0.001, 20)
    with pytest.raises(InputError, match=r"camera 'PAN': DEM .*small.tif gives no height for 1027 of 1027 points of "
                                         r"the image outline \(1027 off its extent\)"):
        footprints(scene, Dem(tmp_path / "small.tif", datum="ellipsoid"))


def test_unknown_camera_is_named():
    with pytest.raises(InputError, match="camera 'NAD' is not in this scene"):
        footprints(_staggered_scene(), ConstantHeight(0.0), cameras=["NAD"])
