"""Pleiades DIMAP reader against the vendor's own models of the same scene (tests/data/pleiades):
the Global_RFM (direct and inverse rational functions) in the XML, and an independent 65x65
direct-localisation grid at 9 heights. Measured figures are in the assertions' comments."""
from __future__ import annotations

import re

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.dem import ConstantHeight, Dem
from pushbroom_adjust.core.errors import MetadataError
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.core.formats.dimaprfm import read_dimap_rfm
from pushbroom_adjust.core.formats import load_scene

XML = "pleiades/PHRDIMAP_P1BP--2018122638935449CP.XML"
GRID = "pleiades/GRID_P1BP--2018122638935449CP.tif"
MNT = "pleiades/MNT_P1BP--2018122638935449CP.tif"


@pytest.fixture(scope="module")
def scene(shared_data):
    return load_scene(shared_data / XML)


@pytest.fixture(scope="module")
def rfm(shared_data):
    return read_dimap_rfm(shared_data / XML)


@pytest.fixture(scope="module")
def grid(shared_data):
    """Vendor localisation grid: (GDAL col (n,), GDAL row (n,), heights (9,), lon (9, n), lat (9, n)).

    Node (i, j) is at GDAL (gt0 + j*gt1, gt3 + i*gt5), i.e. the geotransform origin 0.5 is the
    centre of the first pixel (vendor 1-based (1, 1)). Reading it as 1-based centres puts every
    node 0.5 px off (0.38 m), which the rigorous model and the RFM both show.
    """
    ds = gdal.Open(str(shared_data / GRID))
    gt = ds.GetGeoTransform()
    data = ds.ReadAsArray()
    meta = ds.GetMetadata()
    jj, ii = np.meshgrid(np.arange(ds.RasterXSize), np.arange(ds.RasterYSize))
    heights = np.array([float(meta[f"ALTITUDE_B{b}"]) for b in range(0, ds.RasterCount, 2)])
    return (gt[0] + jj.ravel() * gt[1], gt[3] + ii.ravel() * gt[5], heights,
            data[0::2].reshape(heights.size, -1), data[1::2].reshape(heights.size, -1))


def image_grid(scene, n: int = 10):
    """n x n GDAL image points from the first to the last pixel centre."""
    cam = scene.cameras[0]
    c, r = np.meshgrid(np.linspace(0.5, cam.cols - 0.5, n), np.linspace(0.5, cam.rows - 0.5, n))
    return c.ravel(), r.ravel()


# --- reader --------------------------------------------------------------------------------------
def test_reader_fields(scene):
    cam = scene.cameras[0]
    assert (cam.cols, cam.rows) == (40000, 38248)
    assert scene.epoch == "2018-12-26T10:48:55.449000Z"
    assert cam.timing.time(np.array([0.5]))[0] == 0.0  # row 1 (1-based) at START
    assert cam.timing.period == pytest.approx(0.0735e-3, rel=1e-12)
    assert scene.time_span()[1] == pytest.approx((38248 - 0.5) * 0.0735e-3, abs=1e-12)  # bottom edge
    ux, uy = cam.image_plane(np.array([0.5, 39999.5]))
    np.testing.assert_allclose(uy, [0.01422, 0.01422 - 39999 * 7.11e-07], rtol=1e-12)  # -PsiX
    np.testing.assert_allclose(ux, [8e-05, 8e-05], rtol=1e-12)  # PsiY
    assert not scene.aberration and not scene.refraction
    info = scene.info
    assert info["sensor"] == "Pleiades 1B"
    assert info["product_id"] == "DS_PHR1B_201812261048184_FR1_PX_E002N31_0301_01724"
    assert info["height_range"] == [490.0, 660.0]
    assert 0.50 < info["gsd_m"] < 0.56  # 0.530 m measured; 0.5 m theoretical resolution
    assert info["source"].endswith("PHRDIMAP_P1BP--2018122638935449CP.XML")


def test_rfm_origin_and_normalisation(rfm):
    inverse, direct = rfm
    assert inverse.origin == direct.origin == 1.0
    # RFM_Validity: Col A=19999.5, B=20000.5 (1-based centres of columns 1..40000).
    assert (inverse.samp_off, inverse.samp_scale) == (20000.5, 19999.5)
    lon, lat = direct.image_to_ground(20000.0, 19124.0, 575.0)  # GDAL centre of the normalisation
    col, row = inverse.ground_to_image(lon, lat, 575.0)
    assert abs(col - 20000.0) < 0.01 and abs(row - 19124.0) < 0.01


# --- against the vendor's models ----------------------------------------------------------------
def test_ground_to_image_of_direct_rfm_points(scene, rfm):
    """10 x 10 image points x 5 heights in the RFM validity range: vendor direct RFM ->
    ground -> our ground_to_image. Measured max 0.0008 px, 0.4 mm on the ground."""
    _, direct = rfm
    c, r = image_grid(scene)
    worst_px, worst_m = 0.0, 0.0
    for h in np.linspace(490.0, 660.0, 5):
        lon, lat = direct.image_to_ground(c, r, h)
        xyz = geodetic_to_ecef(lon, lat, h)
        col, row = scene.ground_to_image(xyz)
        worst_px = max(worst_px, np.max(np.abs(col - c)), np.max(np.abs(row - r)))
        worst_m = max(worst_m, np.max(np.linalg.norm(scene.image_to_ground(c, r, h) - xyz, axis=1)))
    assert worst_px < 0.002
    assert worst_m < 0.001


def test_inverse_rfm_matches_ground_to_image(scene, rfm):
    """Ground points of our image_to_ground, projected by the vendor inverse RFM and by our
    ground_to_image. Measured max 0.0016 px (RFM MODEL_PRECISION_COL is 0.001 px)."""
    inverse, _ = rfm
    c, r = image_grid(scene)
    for h in np.linspace(490.0, 660.0, 5):
        lon, lat, _ = ecef_to_geodetic(scene.image_to_ground(c, r, h))
        col, row = inverse.ground_to_image(lon, lat, h)
        assert np.max(np.abs(col - c)) < 0.003 and np.max(np.abs(row - r)) < 0.003
        col2, row2 = scene.ground_to_image(geodetic_to_ecef(lon, lat, h))
        assert np.max(np.abs(col - col2)) < 0.003 and np.max(np.abs(row - row2)) < 0.003


def test_localisation_grid(scene, grid):
    """65 x 65 nodes x 9 heights (-30 m .. 4900 m). Measured max 0.00039 px (row) and
    0.00020 m, RMS 0.00020 m; far outside the RFM's height range too."""
    c, r, heights, lon, lat = grid
    for k, h in enumerate(heights):
        xyz = geodetic_to_ecef(lon[k], lat[k], h)
        col, row = scene.ground_to_image(xyz)
        assert np.max(np.abs(col - c)) < 0.001 and np.max(np.abs(row - r)) < 0.001
        d = np.linalg.norm(scene.image_to_ground(c, r, h) - xyz, axis=1)
        assert d.max() < 0.0005


@pytest.mark.parametrize("aberration, refraction, low, high", [
    (True, False, 18.0, 18.6),   # measured 18.29 .. 18.44 m
    (False, True, 0.65, 0.85),   # measured 0.71 .. 0.79 m
])
def test_corrections_stay_off(shared_data, grid, aberration, refraction, low, high):
    """The vendor's look angles and attitudes already absorb aberration and refraction: turning
    either on moves the model off the vendor grid by metres (both off: 0.2 mm)."""
    s = load_scene(shared_data / XML)
    s.aberration, s.refraction = aberration, refraction
    c, r, heights, lon, lat = grid
    d = np.linalg.norm(s.image_to_ground(c, r, heights[1]) - geodetic_to_ecef(lon[1], lat[1], heights[1]), axis=1)
    assert low < d.min() and d.max() < high


# --- round trips ---------------------------------------------------------------------------------
def round_trip_points(scene):
    rng = np.random.default_rng(7)
    cam = scene.cameras[0]
    edges_c, edges_r = np.meshgrid(np.linspace(0.0, cam.cols, 41), np.linspace(0.0, cam.rows, 41))
    return (np.r_[edges_c.ravel(), rng.uniform(0, cam.cols, 20000)],
            np.r_[edges_r.ravel(), rng.uniform(0, cam.rows, 20000)])


def test_round_trip_dem(scene, shared_data):
    """image -> DEM -> image over the whole image. The MNT holds ellipsoidal heights (it sits in
    shareloc's 'ellipsoide' test folder and is used there without a geoid). Measured max 2e-6 px.
    Its last node column ends a few metres inside the image's east edge: rays there leave the
    DEM and come back NaN, by design, only in that strip."""
    dem = Dem(shared_data / MNT, datum="ellipsoid")
    c, r = round_trip_points(scene)
    g = scene.image_to_ground_dem(c, r, dem)
    ok = np.isfinite(g[:, 0])
    assert ok.mean() > 0.99
    assert np.all(c[~ok] > 39900.0)
    col, row = scene.ground_to_image(g[ok])
    assert np.max(np.hypot(col - c[ok], row - r[ok])) < 1e-4
    _, _, h = ecef_to_geodetic(g[ok])
    lon, lat, _ = ecef_to_geodetic(g[ok])
    assert np.max(np.abs(h - dem.height(lon, lat))) < 1e-3


def test_round_trip_constant_height(scene):
    c, r = round_trip_points(scene)
    g = scene.image_to_ground_dem(c, r, ConstantHeight(575.0))
    col, row = scene.ground_to_image(g)
    assert np.max(np.hypot(col - c, row - r)) < 1e-4  # measured 2e-6 px


def test_dem_ray_near_dem_edge(scene, shared_data):
    """This ray meets the DEM at ~655 m, 20 m inside its last node column (found by sampling the
    ray); the start at the DEM's mid height (560 m) lies outside the DEM."""
    dem = Dem(shared_data / MNT, datum="ellipsoid")
    g = scene.image_to_ground_dem(np.array([39974.235]), np.array([18076.936]), dem)
    assert np.all(np.isfinite(g))
    assert ecef_to_geodetic(g)[2][0] == pytest.approx(655.0, abs=1.0)


class ClippedDem:
    """A DEM with no data on one side of a line through (lon, lat) (direction (dlon, dlat) points
    into the cut-away side)."""
    def __init__(self, dem, lon, lat, dlon, dlat):
        self.dem, self.at, self.towards = dem, (lon, lat), (dlon, dlat)
        self.height_range = dem.height_range

    def height(self, lon, lat):
        side = (lon - self.at[0]) * self.towards[0] + (lat - self.at[1]) * self.towards[1]
        return np.where(side > 0, np.nan, self.dem.height(lon, lat))


def test_dem_ray_entering_dem_below_surface(scene, shared_data):
    """The edge ray with the DEM cut ~2 m past its crossing, on the side the ray comes from: it
    enters the DEM below the surface, so it meets the ground where the DEM is unknown (NaN), not
    on the DEM's edge (which bisection of a bracket starting off the DEM gave, 6 m underground)."""
    dem = Dem(shared_data / MNT, datum="ellipsoid")
    col, row = np.array([39974.235]), np.array([18076.936])
    g = scene.image_to_ground_dem(col, row, dem)
    _, _, _, u = scene.line_of_sight(col, row)
    lon, lat, _ = ecef_to_geodetic(g)
    lon_up, lat_up, _ = ecef_to_geodetic(g - 200.0 * u)  # 200 m back up the ray
    towards = np.array([lon_up - lon, lat_up - lat]).ravel()
    towards /= np.hypot(*towards)
    cut = -2e-5 * towards  # ~2 m (in degrees) past the crossing
    clipped = ClippedDem(dem, lon[0] + cut[0], lat[0] + cut[1], *towards)
    assert np.isnan(scene.image_to_ground_dem(col, row, clipped)).all()


# --- errors --------------------------------------------------------------------------------------
def mutated(shared_data, tmp_path, block: str):
    text = (shared_data / XML).read_text()
    out, n = re.subn(rf"<{block}>.*?</{block}>", "", text, flags=re.S)
    assert n >= 1
    path = tmp_path / "mutated.XML"
    path.write_text(out)
    return path


@pytest.mark.parametrize("block, named", [
    ("Sensor_Ephemeris", "Sensor_Ephemeris"),
    ("Sensor_Attitudes", "Sensor_Attitudes"),
    ("SENSOR_LINE_PERIOD", "SENSOR_LINE_PERIOD"),
    ("Q2", "Q2"),
    ("Viewing_Directions", "Viewing_Directions"),
    ("Global_RFM", "Global_RFM"),
])
def test_missing_block(shared_data, tmp_path, block, named):
    with pytest.raises(MetadataError, match=named):
        load_scene(mutated(shared_data, tmp_path, block))


def test_truncated_xml(shared_data, tmp_path):
    path = tmp_path / "truncated.XML"
    path.write_bytes((shared_data / XML).read_bytes()[:200_000])
    with pytest.raises(MetadataError, match="not well-formed XML, truncated"):
        load_scene(path)


def test_not_xml(tmp_path):
    path = tmp_path / "image.XML"
    path.write_bytes(bytes(range(256)) * 8)
    with pytest.raises(MetadataError, match="neither scene JSON nor XML"):
        load_scene(path)


def test_too_few_ephemeris_points(shared_data, tmp_path):
    text = (shared_data / XML).read_text()
    model = text.index("<Sensor_Ephemeris>")
    head, tail = text[:model], text[model:]
    tail = re.sub(r"<Point>.*?</Point>", "", tail, count=3, flags=re.S)
    path = tmp_path / "short.XML"
    path.write_text(head + tail)
    with pytest.raises(MetadataError, match="7 <Point> samples; 8 are needed"):
        load_scene(path)


# --- layouts the format allows: variants derived from the real product ---------------------------
PERIOD_S = 0.0735e-3  # SENSOR_LINE_PERIOD of the product


def variant(shared_data, tmp_path, cols=None, rows=None, retina=None, start_row=0, name="variant.XML"):
    """The product edited as DIMAP allows: Raster_Dimensions NCOLS/NROWS, Position_In_Retina
    FIRST_COL..LAST_COL and the sensor model's START/END moved by start_row lines (a product cut
    from the acquisition keeps the retina's look-angle polynomials), its Global_RFM's column and row
    offsets moved by the same cut (a cut product's RFM is its own: the reader checks the model
    against it)."""
    text = (shared_data / XML).read_text()
    first_col = retina[0] if retina is not None else 1
    if first_col != 1 or start_row:
        for tag, offset in (("Col", 20000.5 - (first_col - 1)), ("Row", 19124.5 - start_row)):
            text, n = re.subn(rf"(<{tag}>\s*<A>[^<]*</A>\s*<B>)[^<]*", rf"\g<1>{offset!r}", text, count=1)
            assert n == 1
    if cols is not None:
        text = text.replace("<NCOLS>40000</NCOLS>", f"<NCOLS>{cols}</NCOLS>", 1)
    if rows is not None:
        text = text.replace("<NROWS>38248</NROWS>", f"<NROWS>{rows}</NROWS>", 1)
    if retina is not None:
        text = re.sub(r"<Position_In_Retina>.*?</Position_In_Retina>",
                      f"<Position_In_Retina><FIRST_COL>{retina[0]}</FIRST_COL><LAST_COL>{retina[1]}</LAST_COL>"
                      "</Position_In_Retina>", text, flags=re.S)
    if start_row or rows is not None:
        start = np.datetime64("2018-12-26T10:48:55.449000000") + np.timedelta64(round(start_row * PERIOD_S * 1e9), "ns")
        end = start + np.timedelta64(round((rows or 38248) * PERIOD_S * 1e9), "ns")
        text = re.sub(r"<UTC_Sensor_Model_Range>.*?</UTC_Sensor_Model_Range>",
                      f"<UTC_Sensor_Model_Range><START>{start}Z</START><END>{end}Z</END></UTC_Sensor_Model_Range>",
                      text, flags=re.S)
    path = tmp_path / name
    path.write_text(text)
    return path


def test_retina_one_column_wider_than_the_image(shared_data, tmp_path, scene):
    """A real Pleiades product's model covers retina columns 1..NCOLS+1: the same model."""
    wider = load_scene(variant(shared_data, tmp_path, retina=(1, 40001)))
    col, row = image_grid(scene, 6)
    np.testing.assert_array_equal(wider.image_to_ground(col, row, 575.0), scene.image_to_ground(col, row, 575.0))
    wide = load_scene(variant(shared_data, tmp_path, retina=(1, 60000), name="wide.XML"))
    np.testing.assert_array_equal(wide.image_to_ground(col, row, 575.0), scene.image_to_ground(col, row, 575.0))


@pytest.mark.parametrize("first_col, first_row, cols, rows", [
    (12001, 0, 9000, 38248),       # cut across track: retina columns 12001..21000
    (1, 20000, 40000, 8000),       # cut along track: rows 20001..28000
    (30001, 5000, 10000, 10000),   # a window of the acquisition
])
def test_cut_product_meets_the_full_scenes_rfm(shared_data, tmp_path, rfm, first_col, first_row, cols, rows):
    """A product cut from the acquisition (its own NCOLS/NROWS, FIRST_COL in the retina, START
    moved by the rows cut) is the full scene's model shifted by the cut: the vendor RFM of the full
    scene at (col + FIRST_COL - 1, row + first_row) sees the same ground. Measured < 0.003 px."""
    cut = load_scene(variant(shared_data, tmp_path, cols=cols, rows=rows,
                             retina=(first_col, first_col + cols - 1), start_row=first_row))
    cam = cut.cameras[0]
    assert (cam.cols, cam.rows) == (cols, rows)
    col, row = image_grid(cut, 8)
    lon, lat, h = ecef_to_geodetic(cut.image_to_ground(col, row, 575.0))
    inverse, _ = rfm
    c_full, r_full = inverse.ground_to_image(lon, lat, h)
    assert np.max(np.abs(c_full - (col + first_col - 1))) < 0.01
    assert np.max(np.abs(r_full - (row + first_row))) < 0.01


@pytest.mark.parametrize("retina, cols, message", [
    ((1, 39999), None, r"retina columns 1\.\.39999 do not cover the image's 40000 columns"),
    ((0, 40000), None, r"retina columns 0\.\.40000 do not cover"),
    ((1.5, 40001), None, r"retina columns 1\.5\.\.40001"),
    ((40000, 1), None, r"retina columns 40000\.\.1 do not cover"),
    ((900001, 940000), None, r"PsiX_Model: look angles .* rad at the image's first and last columns"),
])
def test_implausible_retina_layouts_are_refused(shared_data, tmp_path, retina, cols, message):
    with pytest.raises(MetadataError, match=message):
        load_scene(variant(shared_data, tmp_path, cols=cols, retina=retina))


def test_look_angles_in_degrees_are_refused(shared_data, tmp_path):
    text = (shared_data / XML).read_text().replace("<COEFFICIENTS>-0.01422 7.11e-07</COEFFICIENTS>",
                                                    "<COEFFICIENTS>-0.8147 4.07e-05</COEFFICIENTS>")
    path = tmp_path / "degrees.XML"
    path.write_text(text)
    with pytest.raises(MetadataError, match=r"PsiX_Model: look angles -0\.8147 and .* \(radians expected\)"):
        load_scene(path)
