"""Geodesy, rotations, trajectory interpolation, line timing, corrections and DEM sampling."""
import numpy as np
import pytest
from pyproj import Transformer

from pushbroom_adjust.core.model import corrections as corr
from pushbroom_adjust.core.model.camera import LineTiming
from pushbroom_adjust.core.dem import ConstantHeight, Dem, geoid_undulation, to_ellipsoidal
from pushbroom_adjust.core.errors import InputError, MetadataError
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, enu_rotation, geodetic_to_ecef, ray_height_intersection
from pushbroom_adjust.core.rotations import matrix_to_quat, quat_to_matrix, rotation_from_angles
from pushbroom_adjust.core.model.trajectory import Ephemeris, QuaternionPolynomial, QuaternionSamples

RNG = np.random.default_rng(7)


def test_geodetic_conversions_match_proj_and_invert():
    lon = RNG.uniform(-180, 180, 2000)
    lat = RNG.uniform(-89.9, 89.9, 2000)
    h = RNG.uniform(-500, 800e3, 2000)
    xyz = geodetic_to_ecef(lon, lat, h)
    x, y, z = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True).transform(lon, lat, h)
    assert np.abs(xyz - np.stack([x, y, z], 1)).max() < 1e-6
    lon2, lat2, h2 = ecef_to_geodetic(xyz)
    assert np.abs(lon2 - lon).max() < 1e-10 and np.abs(lat2 - lat).max() < 1e-10
    assert np.abs(h2 - h).max() < 1e-6


def test_ray_height_intersection_lands_on_the_height():
    origin = geodetic_to_ecef(10.0, 45.0, 700e3)[None].repeat(500, 0)
    target = geodetic_to_ecef(RNG.uniform(9.5, 10.5, 500), RNG.uniform(44.5, 45.5, 500), 0.0)
    d = target - origin
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    h = RNG.uniform(-400, 8000, 500)
    s = ray_height_intersection(origin, d, h)
    assert np.abs(ecef_to_geodetic(origin + s[:, None] * d)[2] - h).max() < 1e-6


def test_enu_rotation_is_orthonormal_with_up_along_normal():
    r = enu_rotation(30.0, 60.0)
    assert np.allclose(r @ r.T, np.eye(3))
    up = geodetic_to_ecef(30.0, 60.0, 1.0) - geodetic_to_ecef(30.0, 60.0, 0.0)
    assert np.allclose(r @ up, [0, 0, 1], atol=1e-9)


def test_quaternion_matrix_round_trip_and_small_angles():
    q = RNG.normal(size=(1000, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1
    assert np.abs(matrix_to_quat(quat_to_matrix(q)) - q).max() < 1e-12
    r = rotation_from_angles(1e-6, -2e-6, 3e-6)
    assert np.allclose(r - np.eye(3), [[0, -3e-6, -2e-6], [3e-6, 0, -1e-6], [2e-6, 1e-6, 0]], atol=1e-11)


def test_lagrange_ephemeris_is_exact_for_polynomials_and_extrapolates():
    t = np.arange(0.0, 300.0, 30.0)
    coef = np.array([[7e6, 10.0, -0.5, 1e-3], [1e5, -7e3, 0.2, -2e-4], [3e6, 50.0, 0.01, 1e-5]])
    pos = np.stack([np.polynomial.polynomial.polyval(t, c) for c in coef], 1)
    eph = Ephemeris(t, pos, order=8)
    tq = np.array([0.0, 13.3, 151.7, 270.0, 285.0, 320.0])  # last two past the samples
    truth = np.stack([np.polynomial.polynomial.polyval(tq, c) for c in coef], 1)
    assert np.abs(eph.position(tq) - truth).max() < 1e-6
    vel = np.stack([np.polynomial.polynomial.polyval(tq, np.polynomial.polynomial.polyder(c)) for c in coef], 1)
    assert np.abs(eph.velocity(tq) - vel).max() < 1e-4


def test_ephemeris_rejects_bad_samples():
    with pytest.raises(MetadataError, match="strictly increasing"):
        Ephemeris(np.array([0.0, 1.0, 1.0]), np.zeros((3, 3)))
    with pytest.raises(MetadataError, match="non-finite"):
        Ephemeris(np.array([0.0, 1.0]), np.array([[0, 0, np.nan], [0, 0, 0]]))


def test_quaternion_samples_handle_sign_flips():
    t = np.linspace(0, 10, 11)
    q = matrix_to_quat(rotation_from_angles(0.01 * t, 0.02 * t, 0.3 * t))
    q[1::2] *= -1  # same rotations, alternate signs as some vendors deliver them
    att = QuaternionSamples(t, q, order=4)
    truth = rotation_from_angles(0.01 * 4.5, 0.02 * 4.5, 0.3 * 4.5)
    assert np.abs(att.rotation(np.array([4.5]))[0] - truth).max() < 1e-5


def test_quaternion_polynomial_rotation():
    att = QuaternionPolynomial(10.0, 5.0, np.array([[1.0, 0.0], [0.0, 0.1], [0.0, 0.0], [0.0, 0.0]]))
    r = att.rotation(np.array([15.0]))[0]  # u = 1: q = (1, 0.1, 0, 0) normalised
    ang = 2 * np.arctan(0.1)
    assert np.allclose(r, [[1, 0, 0], [0, np.cos(ang), -np.sin(ang)], [0, np.sin(ang), np.cos(ang)]])


def test_line_timing_table_extrapolates_instead_of_clamping():
    timing = LineTiming(lines=np.array([0.0, 1000.0, 2000.0]), times=np.array([0.0, 0.1, 0.2002]))
    t = timing.time(np.array([0.5, 2500.5, -99.5]))
    assert np.allclose(t, [0.0, 0.2002 + 500 * 0.1002 / 1000, -100 * 0.1 / 1000])
    assert np.allclose(timing.row(t), [0.5, 2500.5, -99.5])
    with pytest.raises(MetadataError, match="period"):
        LineTiming(0.0, -1.0)


def test_aberration_inverse_is_exact():
    u = RNG.normal(size=(100, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = RNG.normal(scale=7000.0, size=(100, 3))
    app = corr.apparent_from_geometric(u, v)
    assert np.degrees(np.abs(app - u).max()) * 3600 > 1.0  # v/c ~ 5 arcsec: a real shift
    assert np.abs(corr.geometric_from_apparent(app, v) - u).max() < 1e-15


def test_refraction_offset_magnitude():
    # ~2.3 m of refracting column at sea level: 0.2 m at 5 deg, 1.4 m at 26 deg off vertical.
    off = corr.refraction_offset(np.cos(np.radians([0.0, 5.0, 26.0])), np.zeros(3))
    assert off[0] == 0.0
    assert 0.18 < off[1] < 0.23 and 1.3 < off[2] < 1.5


def test_geoid_heights_use_egm96():
    n = geoid_undulation(np.array([0.0, 80.0]), np.array([0.0, 27.0]))
    # EGM96 undulation: +17.16 m at (0, 0); strongly negative over India (the Indian geoid low)
    assert abs(n[0] - 17.16) < 0.05 and -70 < n[1] < -50
    assert np.allclose(to_ellipsoidal(np.array([0.0]), np.array([0.0]), np.array([100.0]), "geoid"), 100 + n[0])
    with pytest.raises(InputError, match="datum"):
        to_ellipsoidal(0.0, 0.0, 0.0, "msl")


def _write_dem(path, crs_wkt, z, gt):
    from osgeo import gdal
    ds = gdal.GetDriverByName("GTiff").Create(str(path), z.shape[1], z.shape[0], 1, gdal.GDT_Float32)
    ds.SetGeoTransform(gt)
    if crs_wkt:
        ds.SetProjection(crs_wkt)
    ds.GetRasterBand(1).WriteArray(z)
    ds.GetRasterBand(1).SetNoDataValue(-9999)
    ds = None


def test_dem_bilinear_sampling_coverage_and_projected_crs(tmp_path):
    from pyproj import CRS
    yy, xx = np.mgrid[0:50, 0:60]
    z = (2.0 * xx + 3.0 * yy).astype(float)  # a plane: bilinear is exact inside
    z[0, 0] = -9999
    _write_dem(tmp_path / "geo.tif", CRS.from_epsg(4326).to_wkt(), z, (10.0, 0.01, 0, 46.0, 0, -0.01))
    dem = Dem(tmp_path / "geo.tif", datum="ellipsoid")
    lon = 10.0 + (np.array([10.5, 20.25]) + 0.5) * 0.01
    lat = 46.0 - (np.array([5.0, 30.75]) + 0.5) * 0.01
    assert np.allclose(dem.height(lon, lat), 2 * np.array([10.5, 20.25]) + 3 * np.array([5.0, 30.75]))
    out = dem.height(np.array([9.0, 10.005]), np.array([45.8, 45.995]))
    assert np.isnan(out).all()  # off the DEM, and on the nodata node
    utm = CRS.from_epsg(32632)
    _write_dem(tmp_path / "utm.tif", utm.to_wkt(), z, (500000.0, 30.0, 0, 5100000.0, 0, -30.0))
    dem_utm = Dem(tmp_path / "utm.tif", datum="ellipsoid")
    lon, lat = Transformer.from_crs(utm, "EPSG:4326", always_xy=True).transform(500000 + 30 * 10.5, 5100000 - 30 * 5.5)
    assert abs(dem_utm.height(np.array([lon]), np.array([lat]))[0] - (2 * 10 + 3 * 5)) < 1e-6


def test_dem_errors_name_the_file(tmp_path):
    _write_dem(tmp_path / "nocrs.tif", "", np.zeros((3, 3)), (0, 1, 0, 0, 0, -1))
    with pytest.raises(InputError, match="nocrs.tif.*no coordinate reference system"):
        Dem(tmp_path / "nocrs.tif")
    (tmp_path / "junk.tif").write_text("not a raster")
    with pytest.raises(InputError, match="junk.tif.*cannot be opened"):
        Dem(tmp_path / "junk.tif")
    assert ConstantHeight(12.0).height(np.zeros(3), np.zeros(3)).tolist() == [12.0] * 3
