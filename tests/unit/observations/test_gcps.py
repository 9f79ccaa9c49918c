"""GCP import: CSV mapping, QGIS .points files, CRS and height conversion, a-priori residuals
against a scene with a known attitude error, outside-image marking, errors, GeoPackage."""
from dataclasses import replace

import numpy as np
import pytest
from osgeo import ogr
from pyproj import CRS

from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations.tables import Heights, resolve_cameras
from pushbroom_adjust.core.model.camera import Camera, Chip, LineTiming
from pushbroom_adjust.core.dem import geoid_undulation
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.model.sensor import SceneModel
from pushbroom_adjust.core.model.trajectory import Ephemeris, Platform, QuaternionPolynomial

IFOV = 2e-5  # rad per pixel of the test camera (look angle uy = -0.01 + IFOV * (col - 0.5))
ROLL = 1e-4  # rad: attitude error of the "onboard" scene


def _scene(roll: float = 0.0, name: str = "PAN") -> SceneModel:
    """Circular-ish orbit at 622 km over (0, 0) flying north; camera x north, z down, y east.
    ``roll`` rotates the camera about its x axis (installation error)."""
    t = np.arange(-20.0, 21.0, 5.0)
    pos = np.stack([7.0e6 + 0 * t, 1000.0 + 0 * t, 7000.0 * t], 1)
    att = QuaternionPolynomial(0.0, 1.0, np.array([[0.5 ** 0.5, 0.0], [0.0, 0.0], [-(0.5 ** 0.5), 0.0], [0.0, 0.0]]))
    c, s = np.cos(roll), np.sin(roll)
    chip = Chip(col_offset=0, n_pixels=1000, kind="look_angle", ux_poly=[0.0], uy_poly=[-0.01, IFOV])
    cam = Camera(name, 1000, 2000, LineTiming(-1.0, 1e-3), [chip], installation=[[1, 0, 0], [0, c, -s], [0, s, c]])
    return SceneModel("2020-01-01T00:00:00Z", Platform(Ephemeris(t, pos), att), [cam], aberration=True,
                      info={"height_range": [0.0, 300.0]})


def _ground_truth(col, row, h):
    """(lon, lat) of image points in the true scene at ellipsoidal heights h."""
    lon, lat, _ = ecef_to_geodetic(_scene().image_to_ground(col, row, h))
    return lon, lat


def _ellipsoid(value=0.0):
    return Heights("constant", "ellipsoid", value=value)


# --- CSV ------------------------------------------------------------------------------------
def test_csv_mapping_semicolons_decimal_commas_roles_and_z(tmp_path):
    path = tmp_path / "pts.csv"
    path.write_text("Name;Pixel;Line;E;N;Alt;Kind;Cam\n"
                    "A1;10,5;20,25;2,5;45,1;100,0;GCP;PAN\n"
                    "B2; 500.5 ;1000.5;2.6;45.2;200;Check;PAN\n"
                    "C3;800;1500;2.7;45.3;300;;PAN\n")
    mapping = G.CsvMapping(id="Name", col="Pixel", row="Line", x="E", y="N", z="Alt", role="Kind", camera="Cam")
    t = G.read_csv(path, mapping, "EPSG:4326", Heights("z", "ellipsoid"), sigma_px=0.3)
    assert t.id.tolist() == ["A1", "B2", "C3"]
    assert t.col.tolist() == [10.5, 500.5, 800.0] and t.row.tolist() == [20.25, 1000.5, 1500.0]
    assert t.lon.tolist() == pytest.approx([2.5, 2.6, 2.7], abs=1e-12)
    assert t.lat.tolist() == pytest.approx([45.1, 45.2, 45.3], abs=1e-12)
    assert t.h.tolist() == [100.0, 200.0, 300.0]
    assert t.role.tolist() == ["control", "check", "control"]
    assert t.camera.tolist() == ["PAN"] * 3 and t.sigma_px.tolist() == [0.3] * 3


def test_csv_errors_name_columns_rows_and_crs(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("id,col,row,lon,lat\np1,1,2,3,4\np2,,5,6,7\np3,1,2,nan,4\n")
    with pytest.raises(InputError, match=r"bad.csv: col is missing or not a number for point\(s\) p2$"):
        G.read_csv(path, G.CsvMapping(), "EPSG:4326", _ellipsoid())
    path.write_text("id,col,row,lon,lat\np1,1,2,3,4\np3,1,2,nan,4\np4,1,2,north,4\n")
    with pytest.raises(InputError, match=r"column 'lon' is not a number for point\(s\) p4"):
        G.read_csv(path, G.CsvMapping(), "EPSG:4326", _ellipsoid())
    path.write_text("id,col,row,lon,lat\np1,1,2,3,4\np3,1,2,nan,4\n")
    with pytest.raises(InputError, match=r"x is missing or not a number for point\(s\) p3"):
        G.read_csv(path, G.CsvMapping(), "EPSG:4326", _ellipsoid())
    path.write_text("id,col,row,lon,lat\np1,1,2,3,4\n")
    with pytest.raises(InputError, match="unknown ground CRS 'EPSG:999999'"):
        G.read_csv(path, G.CsvMapping(), "EPSG:999999", _ellipsoid())
    with pytest.raises(InputError, match="unknown ground CRS '\\+proj=nonsense'"):
        G.read_csv(path, G.CsvMapping(), "+proj=nonsense", _ellipsoid())
    with pytest.raises(InputError, match="no column 'height' \\(columns: id, col, row, lon, lat\\)"):
        G.read_csv(path, G.CsvMapping(z="height"), "EPSG:4326", Heights("z"))
    with pytest.raises(InputError, match="no Z values"):
        G.read_csv(path, G.CsvMapping(), "EPSG:4326", Heights("z"))
    path.write_text("id,col,row,lon,lat,kind\np1,1,2,3,4,tie\n")
    with pytest.raises(InputError, match=r"unknown role\(s\) \['tie'\] for point\(s\) p1"):
        G.read_csv(path, G.CsvMapping(role="kind"), "EPSG:4326", _ellipsoid())
    path.write_text("id,col,row,lon,lat\np1,1,2,3,4\n ,5,6,3,4\n")
    with pytest.raises(InputError, match=r"empty point id in data line\(s\) 2"):
        G.read_csv(path, G.CsvMapping(), "EPSG:4326", _ellipsoid())
    path.write_text("id,col,row,lon,lat\np1,1,2,3,4\np1,5,6,3,4\n")
    with pytest.raises(InputError, match=r"id\(s\) p1 occur more than once"):
        G.read_csv(path, G.CsvMapping(), "EPSG:4326", _ellipsoid())


def test_utm_csv_is_converted_to_wgs84(tmp_path):
    # Known UTM zone 31N values: the central meridian is 3 deg E; the WGS84 meridian arc to
    # 45 deg N is 4 984 944.378 m, times the scale factor 0.9996 -> northing 4 982 950.400 m.
    path = tmp_path / "utm.csv"
    path.write_text("id,col,row,x,y,z\nm,1,1,500000,4982950.400,0\ne,2,2,500000,0,0\n")
    t = G.read_csv(path, G.CsvMapping(x="x", y="y", z="z"), "EPSG:32631", Heights("z"))
    assert t.lon == pytest.approx([3.0, 3.0], abs=1e-9)
    assert t.lat == pytest.approx([45.0, 0.0], abs=1e-8)  # 1e-8 deg ~ 1 mm
    wkt = CRS.from_epsg(32631).to_wkt()
    assert G.read_csv(path, G.CsvMapping(x="x", y="y", z="z"), wkt, Heights("z")).lat[0] == pytest.approx(45.0)


def test_geoid_heights_differ_from_ellipsoidal_by_egm96_undulation(tmp_path):
    path = tmp_path / "h.csv"
    path.write_text("id,col,row,lon,lat,h\na,1,1,0,0,100\nb,2,2,80,27,250\n")
    mapping = G.CsvMapping(z="h")
    geo = G.read_csv(path, mapping, "EPSG:4326", Heights("z", "geoid"))
    ell = G.read_csv(path, mapping, "EPSG:4326", Heights("z", "ellipsoid"))
    diff = geo.h - ell.h
    assert diff == pytest.approx(geoid_undulation(geo.lon, geo.lat), abs=1e-9)
    # EGM96: +17.16 m at (0, 0); the Indian geoid low at (80 E, 27 N)
    assert abs(diff[0] - 17.16) < 0.05 and -70 < diff[1] < -50
    const = G.read_csv(path, mapping, "EPSG:4326", Heights("constant", "geoid", value=10.0))
    assert const.h - 10.0 == pytest.approx(diff, abs=1e-9)


def test_heights_from_a_dem_and_uncovered_points(tmp_path):
    from osgeo import gdal
    dem_path = tmp_path / "dem.tif"
    ds = gdal.GetDriverByName("GTiff").Create(str(dem_path), 20, 20, 1, gdal.GDT_Float32)
    ds.SetGeoTransform((-0.1, 0.01, 0, 0.1, 0, -0.01))
    ds.SetProjection(CRS.from_epsg(4326).to_wkt())
    ds.GetRasterBand(1).WriteArray(np.full((20, 20), 123.0))
    ds = None
    path = tmp_path / "p.csv"
    path.write_text("id,col,row,lon,lat\na,1,1,0,0\nb,2,2,0.5,0\n")
    with pytest.raises(InputError, match=r"dem.tif gives no height for 1 of 2 points \(1 off its extent\): point\(s\) b"):
        G.read_csv(path, G.CsvMapping(), "EPSG:4326", Heights("dem", "ellipsoid", dem=dem_path))
    path.write_text("id,col,row,lon,lat\na,1,1,0,0\n")
    t = G.read_csv(path, G.CsvMapping(), "EPSG:4326", Heights("dem", "geoid", dem=dem_path))
    assert t.h[0] == pytest.approx(123.0 + 17.16, abs=0.05)


# --- QGIS georeferencer .points -------------------------------------------------------------
def test_points_file_negative_y_crs_line_and_disabled_points(tmp_path, caplog):
    wkt = CRS.from_epsg(32631).to_wkt()
    path = tmp_path / "img.tif.points"
    path.write_text(f"#CRS: {wkt}\n"
                    "mapX,mapY,sourceX,sourceY,enable,dX,dY,residual\n"
                    "500000,4982950.4,10.5,-20.5,1,0,0,0\n"
                    "500000,0,300.25,-1999.75,0,0.1,0.2,0.22\n"
                    "500000,0,0.0,0.5,1,0,0,0\n")
    t = G.read_points_file(path, _ellipsoid(50.0), crs="EPSG:4326")  # the file's #CRS wins
    assert t.id.tolist() == ["0", "1", "2"]  # the QGIS GCP table's ids
    assert t.col.tolist() == [10.5, 300.25, 0.0]
    assert t.row.tolist() == [20.5, 1999.75, -0.5]  # y negative down; a point above the image stays above
    assert t.role.tolist() == ["control", "check", "control"]
    assert "disabled point(s) imported as check points: 1" in caplog.text
    assert t.lat[0] == pytest.approx(45.0, abs=1e-8) and t.lon[0] == pytest.approx(3.0, abs=1e-9)
    assert t.h.tolist() == [50.0, 50.0, 50.0]


def test_points_file_pixel_header_without_crs_and_line_numbers(tmp_path):
    path = tmp_path / "old.points"
    path.write_text("mapX,mapY,pixelX,pixelY,enable,dX,dY,residual\n"
                    "2.5,45.5,100,200,1,0,0,0\n2.6,45.6,300,400,1,0,0,0\n")
    with pytest.raises(InputError, match="no ground CRS given"):
        G.read_points_file(path, _ellipsoid())
    t = G.read_points_file(path, _ellipsoid(), crs="EPSG:4326")
    assert t.row.tolist() == [200.0, 400.0]  # all y >= 0: column/line numbers already
    assert t.lon.tolist() == pytest.approx([2.5, 2.6]) and t.role.tolist() == ["control", "control"]
    tabbed = tmp_path / "tab.points"
    tabbed.write_text("2.5\t45.5\t100\t-200\n")
    assert G.read_points_file(tabbed, _ellipsoid(), crs="EPSG:4326").row.tolist() == [200.0]
    with pytest.raises(InputError, match="carry no heights"):
        G.read_points_file(path, Heights("z"), crs="EPSG:4326")
    path.write_text("#CRS: LOCAL_CS[\"nowhere\"]\nmapX,mapY,sourceX,sourceY\n1,2,3,-4\n")
    with pytest.raises(InputError, match="ground CRS 'nowhere' is not a horizontal"):
        G.read_points_file(path, _ellipsoid())
    path.write_text("#CRS: EPSG:12345678\nmapX,mapY,sourceX,sourceY\n1,2,3,-4\n")
    with pytest.raises(InputError, match="old.points: unknown ground CRS 'EPSG:12345678'"):
        G.read_points_file(path, _ellipsoid(), crs="EPSG:4326")


# --- roles and cameras ----------------------------------------------------------------------
def test_check_fraction_is_deterministic_and_spread_along_track():
    n = 40
    rng = np.random.default_rng(3)
    table = G.GcpTable(np.arange(n).astype(str), "control", "PAN", rng.uniform(0, 1000, n), rng.uniform(0, 2000, n),
                       0.0, 0.0, 0.0, 0.5, 1.0, 1.0)
    a = G.assign_check_points(table, 0.25)
    b = G.assign_check_points(G.GcpTable(*[getattr(table, k) for k in table.ARRAYS]), 0.25)
    assert (a.role == b.role).all() and np.sum(a.role == "check") == 10
    rows = np.sort(a.row[a.role == "check"])
    assert rows.min() < 400 and rows.max() > 1600  # spread over the strip, not bunched
    assert np.sum(G.assign_check_points(a, 0.25).role == "check") == 10  # existing checks count
    with pytest.raises(InputError, match="between 0 and 1"):
        G.assign_check_points(table, 1.5)


def test_cameras_are_resolved_by_name_index_or_single_camera(caplog):
    scene = _scene()
    table = G.GcpTable(np.array(["a", "b"]), "control", np.array(["", "0"]), 1.0, 1.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.0)
    assert resolve_cameras(table, scene).camera.tolist() == ["PAN", "PAN"]
    assert resolve_cameras(table, scene, "0").camera.tolist() == ["PAN", "PAN"]
    # one other camera named for every point of a single-camera scene (the simulator's HRC against an RPC
    # product): every point is the scene's, and the log says so
    other = G.GcpTable(np.array(["a", "b"]), "control", np.array(["NAD", ""]), 1.0, 1.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.0)
    assert resolve_cameras(other, scene).camera.tolist() == ["PAN", "PAN"]
    assert "the camera column names camera 'NAD' for the points, but the scene has one camera, 'PAN': all 2 " \
           "point(s) are taken as measured in it" in caplog.messages
    # several other cameras: which rows are the scene's cannot be told
    bad = G.GcpTable(np.array(["a", "b"]), "control", np.array(["NAD", "FWD"]), 1.0, 1.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.0)
    with pytest.raises(InputError, match=r"camera '(NAD|FWD)' of point\(s\) (a|b) is not in the scene \(cameras: PAN\)"):
        resolve_cameras(bad, scene)


# --- a-priori residuals ---------------------------------------------------------------------
def test_apriori_residuals_equal_the_known_roll_offset_and_outside_points_are_marked():
    """GCPs placed with the true scene, checked against an 'onboard' scene whose camera is
    rolled by ROLL: a ray at look angle uy = tan(a) in the true camera has tan(a + ROLL) in the
    onboard one, so the predicted column moves by (tan(atan(uy) + ROLL) - uy) / IFOV and the
    row not at all (rolling about x keeps ux = 0), whatever the aberration."""
    col = np.array([10.5, 250.0, 500.5, 750.25, 990.0, 998.0, -30.0, 400.0])
    row = np.array([0.5, 1999.0, 1000.0, 400.0, 1500.0, 10.0, 100.0, 2100.0])
    h = np.array([0.0, 100.0, 200.0, 50.0, 300.0, 10.0, 0.0, 0.0])
    lon, lat = _ground_truth(col, row, h)
    ids = np.array([f"g{i}" for i in range(col.size)])
    table = G.build_table(ids, col, row, lon, lat, crs="EPSG:4326", heights=Heights("z"), z=h)
    out = G.check_against_scene(table, _scene(ROLL), "onboard.json", check_fraction=0.25)
    uy = -0.01 + IFOV * (col - 0.5)
    expected = (np.tan(np.arctan(uy) + ROLL) - uy) / IFOV  # ~5 px
    res = out.residuals
    assert np.abs(res.col - expected).max() < 1e-4
    assert np.abs(res.row).max() < 1e-4
    assert res.px == pytest.approx(np.abs(expected), abs=1e-4)
    # ground size: 5 px of 2e-5 rad at ~622 km range = 62 m
    assert res.m == pytest.approx(np.abs(expected) * IFOV * 622e3, rel=0.01)
    # predicted beyond the right edge (998 + 5 > 1000), measured left of the image, below the last row
    assert out.id[~res.inside].tolist() == ["g5", "g6", "g7"]
    assert out.scene_path == "onboard.json" and np.sum(out.role == "check") == 2
    checks = out.select(out.role == "check")
    assert len(checks) == 2 and checks.scene_path == "onboard.json"
    assert checks.residuals.col.tolist() == res.col[out.role == "check"].tolist()
    s = G.summary(out)
    assert (s["points"], s["control"], s["check"], s["outside"]) == (8, 6, 2, 3)
    assert s["median_px"] == pytest.approx(np.median(expected[res.inside]), abs=1e-4)
    assert s["max_px"] == pytest.approx(expected[res.inside].max(), abs=1e-4)


def test_same_scene_gives_zero_residuals():
    col, row = np.array([100.5, 900.0]), np.array([50.0, 1900.0])
    lon, lat = _ground_truth(col, row, 20.0)
    table = G.build_table(["a", "b"], col, row, lon, lat, crs="EPSG:4326", heights=_ellipsoid(20.0))
    res = G.check_against_scene(table, _scene()).residuals
    assert res.px.max() < 1e-4 and res.m.max() < 1e-3 and res.inside.all()


# --- GeoPackage -----------------------------------------------------------------------------
def test_gpkg_round_trip_fields_crs_and_scene(tmp_path):
    col, row = np.array([100.5, 900.0, 1200.0]), np.array([50.0, 1900.0, 10.0])
    lon, lat = _ground_truth(col, row, 20.0)
    table = G.build_table(["a", "b", "c"], col, row, lon, lat, crs="EPSG:4326", heights=_ellipsoid(20.0),
                          role=["control", "check", "gcp"], sigma_xy=2.0)
    table = G.check_against_scene(table, _scene(ROLL), "/data/onboard.json")
    path = tmp_path / "gcps.gpkg"
    G.write_gpkg(table, path)
    ds = ogr.Open(str(path))
    lyr = ds.GetLayer(0)
    names = [lyr.GetLayerDefn().GetFieldDefn(i).GetName() for i in range(lyr.GetLayerDefn().GetFieldCount())]
    assert names == ["id", "role", "camera", "col", "row", "h", "sigma_px", "sigma_xy", "sigma_z", "res_col",
                     "res_row", "res_px", "res_m", "inside"]
    assert lyr.GetSpatialRef().GetAuthorityCode(None) == "4979" and lyr.GetGeomType() == ogr.wkbPoint25D
    assert lyr.GetFeatureCount() == 3
    back = G.read_gpkg(path)
    for name in table.ARRAYS:
        a, b = getattr(table, name), getattr(back, name)
        assert (a == b).all() if a.dtype.kind == "U" else np.allclose(a, b, rtol=0, atol=1e-12), name
    assert back.scene_path == "/data/onboard.json" and back.role.tolist() == ["control", "check", "control"]
    assert back.residuals.inside.tolist() == [True, True, False]
    assert np.allclose(back.residuals.col, table.residuals.col, atol=1e-12)
    plain = tmp_path / "plain.gpkg"
    G.write_gpkg(G.build_table(["x"], [1.0], [2.0], [3.0], [4.0], crs="EPSG:4326", heights=_ellipsoid()), plain)
    assert G.read_gpkg(plain).residuals is None
    with pytest.raises(InputError, match="use a .gpkg file name"):
        G.write_gpkg(table, tmp_path / "gcps.shp")


def test_gpkg_carries_the_block_scene_of_every_row(tmp_path):
    """A GCP measured in the products of a block names its product in the field 'scene' (written
    only when a row names one); rows without a name read back as ''."""
    table = G.build_table(["a", "a", "b"], [1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [3.0] * 3, [4.0] * 3,
                          crs="EPSG:4326", heights=_ellipsoid(), camera=["P", "MS", "P"])
    assert (G.read_gpkg(_written(table, tmp_path / "none.gpkg")).scene == "").all()
    named = replace(table, scene=np.array(["PHR_A", "PHR_B", ""]))
    ds = ogr.Open(str(_written(named, tmp_path / "named.gpkg")))
    assert ds.GetLayer(0).GetLayerDefn().GetFieldIndex("scene") >= 0
    ds = None
    assert G.read_gpkg(tmp_path / "named.gpkg").scene.tolist() == ["PHR_A", "PHR_B", ""]


def test_one_point_in_camera_p_of_two_products_is_two_rows(tmp_path):
    """A block's GCP CSV with a column 'scene' (read under its name, as pushbroom:simulateblock writes
    it): ids are unique per (id, scene, camera), so point A measured by camera P of two Pleiades
    products is two rows; twice in one product's P it is refused."""
    path = tmp_path / "block.csv"
    path.write_text("id,camera,scene,col,row,lon,lat\nA,P,PHR_1,1,2,3,4\nA,P,PHR_2,5,6,3,4\nB,P,PHR_1,7,8,3.1,4\n")
    table = G.read_csv(path, G.CsvMapping(), "EPSG:4326", _ellipsoid())
    assert table.scene.tolist() == ["PHR_1", "PHR_2", "PHR_1"] and table.id.tolist() == ["A", "A", "B"]
    with pytest.raises(InputError, match=r"point id\(s\) A occur more than once for the same camera$"):
        G.read_csv(path, G.CsvMapping(scene=""), "EPSG:4326", _ellipsoid())  # '': no scene column
    path.write_text(path.read_text() + "A,P,PHR_1,9,9,3,4\n")
    with pytest.raises(InputError, match=r"point id\(s\) A occur more than once for the same camera of the same scene"):
        G.read_csv(path, G.CsvMapping(), "EPSG:4326", _ellipsoid())


def _written(table, path):
    G.write_gpkg(table, path)
    return path
