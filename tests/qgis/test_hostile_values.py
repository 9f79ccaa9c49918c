"""Hostile-input suite: extreme and implausible values — heights above the satellite, inf/NaN/huge
numbers in every numeric field of a GCP file, nodata values the output type cannot hold, output
sizes no disk holds, extents off the scene, lines where points are meant. Each run must stop with
a message naming the parameter (or file and field) and leave the watched files as they were; the
legitimate variants must give a correct result (with a warning where one is due)."""
import csv
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal
from pyproj import CRS, Transformer
from qgis.core import (QgsCoordinateTransformContext, QgsFeature, QgsGeometry, QgsPoint, QgsPointXY, QgsVectorFileWriter,
                       QgsVectorLayer)

import processing
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.products.mapping import utm_crs
from pushbroom_adjust.core.formats import load_scene
from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.processing import RecordingFeedback

gdal.UseExceptions()


@pytest.fixture(scope="module")
def files(simulated, tmp_path_factory) -> dict:
    """Inputs shared by the cases: raw images of the camera's size (Byte and Float32), a DEM
    whose voids are -32768 without a declared nodata, and the image and ground points of the GCPs."""
    folder = tmp_path_factory.mktemp("hostile_values")
    scene = load_scene(simulated["ONBOARD_SCENE"])
    cam = scene.cameras[0]
    out = {}
    for name, kind in (("byte", gdal.GDT_Byte), ("float", gdal.GDT_Float32)):
        path = folder / f"raw_{name}.tif"
        ds = gdal.GetDriverByName("GTiff").Create(str(path), cam.cols, cam.rows, 1, kind,
                                                  ["COMPRESS=DEFLATE", "TILED=YES"])
        ds.GetRasterBand(1).Fill(100)
        ds = None
        out[name] = str(path)
    dem = gdal.Translate(str(folder / "dem_voids.tif"), simulated["DEM"], noData="none")
    band = dem.GetRasterBand(1)
    z = band.ReadAsArray()
    z[:5, :5] = -32768
    band.DeleteNoDataValue()
    band.WriteArray(z)
    dem = None
    out["dem_voids"] = str(folder / "dem_voids.tif")
    with open(simulated["GCPS"]) as f:
        out["gcp_rows"] = list(csv.reader(f))
    centre = scene.image_to_ground(np.array([cam.cols / 2]), np.array([cam.rows / 2]), 800.0)[0]
    lon, lat, _ = ecef_to_geodetic(centre[None])
    out["centre_lonlat"] = (float(lon[0]), float(lat[0]))
    out["scene"] = scene
    return out


def _gcp_csv(files, folder: Path, field: str, value: str, row: int = 3) -> Path:
    """The simulated GCP CSV with one cell replaced."""
    rows = [list(r) for r in files["gcp_rows"]]
    rows[row][rows[0].index(field)] = value
    path = folder / "gcps.csv"
    with open(path, "w", newline="") as f:
        csv.writer(f).writerows(rows)
    return path


def _import_params(simulated, path, tmp_path, **extra) -> dict:
    return {"SCENE": simulated["ONBOARD_SCENE"], "INPUT_FILE": str(path), "Z_FIELD": "h", "ROLE_FIELD": "role",
            "CAMERA_FIELD": "camera", "HEIGHT_SOURCE": "z", "Z_DATUM": "ellipsoid", "OUTPUT": str(tmp_path / "out.gpkg"),
            **extra}


# --- GCP files: one cell of the CSV replaced --------------------------------------------------------------
GCP_CELLS = [
    ("h", "1e308", ["h of point(s) G3", "not a terrain height"]),  # the IndexError
    ("col", "1e308", ["col/row of point(s) G3", "beyond any image"]),  # the "points on a line"
    ("row", "-1e308", ["col/row of point(s) G3", "beyond any image"]),
    ("col", "-2e9", ["col/row of point(s) G3"]),
    ("col", "inf", ["col is missing or not a number", "G3"]),
    ("row", "nan", ["row is missing or not a number", "G3"]),
    ("row", "-Infinity", ["row is missing or not a number", "G3"]),
    ("h", "-inf", ["z is missing or not a number", "G3"]),
    ("h", "nan", ["z is missing or not a number", "G3"]),
    ("h", "1000000", ["h of point(s) G3", "not a terrain height"]),
    ("h", "-11000", ["h of point(s) G3", "not a terrain height"]),
    ("h", "1e-400", None),  # underflows to 0: a legitimate height of 0 m
    ("lon", "1e308", ["ground coordinates of point(s) G3"]),
    ("lon", "inf", ["x is missing or not a number", "G3"]),
    ("lat", "95", ["ground coordinates of point(s) G3"]),
    ("lat", "-1e308", ["ground coordinates of point(s) G3"]),
    ("col", "1,5e3", ["col", "not a number", "G3"]),
    ("col", "0x1F", ["col", "not a number", "G3"]),
]


@pytest.mark.parametrize("field, value, texts", GCP_CELLS, ids=[f"{f}={v}" for f, v, _ in GCP_CELLS])
def test_extreme_value_in_a_gcp_csv(provider, simulated, files, tmp_path, field, value, texts):
    path = _gcp_csv(files, tmp_path, field, value)
    params = _import_params(simulated, path, tmp_path)
    if texts is None:
        out = processing.run("pushbroom:importgcps", params)["OUTPUT"]
        layer = QgsVectorLayer(out, "gcps", "ogr")
        h = {f["id"]: f["h"] for f in layer.getFeatures()}
        assert h["G3"] == 0.0 and layer.featureCount() == len(files["gcp_rows"]) - 1
        return
    assert_refused("pushbroom:importgcps", params, "gcps.csv", *texts, watch=[tmp_path])


@pytest.mark.parametrize("sigma, value, texts", [
    ("SIGMA_PX", 1e308, ["sigma_px", "below"]),
    ("SIGMA_PX", 0.0, ["sigma_px", "> 0"]),
    ("SIGMA_XY", 1e300, ["sigma_xy", "below"]),
    ("SIGMA_Z", 1e300, ["sigma_z", "below"]),
])
def test_absurd_sigma_option(provider, simulated, files, tmp_path, sigma, value, texts):
    path = _gcp_csv(files, tmp_path, "h", files["gcp_rows"][3][files["gcp_rows"][0].index("h")])
    assert_refused("pushbroom:importgcps", _import_params(simulated, path, tmp_path, **{sigma: value}), *texts,
                   watch=[tmp_path])


POINTS_CELLS = [(0, "1e308", "ground coordinates"), (2, "1e308", "beyond any image"),
                (3, "-1e308", "beyond any image"), (1, "inf", "y is missing or not a number")]


@pytest.mark.parametrize("column, value, text", POINTS_CELLS, ids=[f"column{c}={v}" for c, v, _ in POINTS_CELLS])
def test_extreme_value_in_a_points_file(provider, simulated, files, tmp_path, column, value, text):
    rows = files["gcp_rows"]
    header = rows[0]
    lines = ["#CRS: EPSG:4326", "mapX,mapY,sourceX,sourceY,enable,dX,dY,residual"]
    for r in rows[1:6]:
        cells = [r[header.index("lon")], r[header.index("lat")], r[header.index("col")],
                 str(-float(r[header.index("row")])), "1", "0", "0", "0"]
        lines.append(",".join(cells))
    cells = lines[4].split(",")
    cells[column] = value
    lines[4] = ",".join(cells)
    path = tmp_path / "gcps.points"
    path.write_text("\n".join(lines) + "\n")
    assert_refused("pushbroom:importgcps", {"SCENE": simulated["ONBOARD_SCENE"], "INPUT_FILE": str(path),
                                            "HEIGHT_SOURCE": "constant", "HEIGHT": 800.0,
                                            "OUTPUT": str(tmp_path / "out.gpkg")},
                   "gcps.points", text, watch=[tmp_path])


# --- heights: constant, DEM, Z values ---------------------------------------------------------------------
def _table_layer(tmp_path) -> str:
    path = tmp_path / "image_points.csv"
    path.write_text("id,col,row\n1,6000.5,6000.5\n2,100.5,200.5\n")
    return str(path)


def _ground_layer(tmp_path, files, z: float | None) -> str:
    """A GeoPackage with one point at the image centre (PointZ with ``z``, else 2-D)."""
    lon, lat = files["centre_lonlat"]
    point = QgsPoint(lon, lat) if z is None else QgsPoint(lon, lat, z)
    return _layer_file(tmp_path / "ground.gpkg", "Point" if z is None else "PointZ", QgsGeometry(point))


HEIGHTS = [
    ("imagetoground", 1e6), ("imagetoground", -1e4), ("imagetoground", 1e308),
    ("exportrpc", 1e6), ("footprint", 1e6), ("groundtoimage", 1e6), ("orthorectify", 1e6), ("importgcps", 1e6),
]


def _height_params(alg, value, simulated, files, tmp_path) -> dict:
    scene = {"SCENE": simulated["ONBOARD_SCENE"], "HEIGHT": value}
    return {"imagetoground": {**scene, "INPUT": _table_layer(tmp_path), "OUTPUT": str(tmp_path / "g.gpkg")},
            "exportrpc": {**scene, "OUTPUT": str(tmp_path / "scene_RPC.TXT")},
            "footprint": {**scene, "OUTPUT": str(tmp_path / "fp.gpkg")},
            "groundtoimage": {**scene, "INPUT": _ground_layer(tmp_path, files, None), "OUTPUT": str(tmp_path / "i.gpkg")},
            "orthorectify": {**scene, "INPUT": files["byte"], "OUTPUT": str(tmp_path / "ortho.tif")},
            "importgcps": _import_params(simulated, _gcp_csv(files, tmp_path, "h", "800"), tmp_path,
                                         HEIGHT_SOURCE="constant", HEIGHT=value)}[alg]


@pytest.mark.parametrize("alg, value", HEIGHTS, ids=[f"{a} HEIGHT={v:g}" for a, v in HEIGHTS])
def test_height_no_terrain_has_is_refused(provider, simulated, files, tmp_path, alg, value):
    """HEIGHT above the satellite gave a point behind the camera (imagetoground) and a 35 px RPC
    with exit 0 (exportrpc)."""
    assert_refused(f"pushbroom:{alg}", _height_params(alg, value, simulated, files, tmp_path), "HEIGHT",
                   "not a terrain height", watch=[tmp_path])


def test_height_above_the_satellite_on_the_command_line(qgis_process, simulated, tmp_path):
    assert_refused_cli(qgis_process, "pushbroom:exportrpc", {"SCENE": simulated["ONBOARD_SCENE"], "HEIGHT": "1e6",
                                                             "OUTPUT": tmp_path / "scene_RPC.TXT"},
                       "HEIGHT", "not a terrain height", watch=[tmp_path])


@pytest.mark.parametrize("z", [1e6, -5e4])
def test_ground_point_z_no_terrain_has(provider, simulated, files, tmp_path, z):
    assert_refused("pushbroom:groundtoimage", {"SCENE": simulated["ONBOARD_SCENE"],
                                               "INPUT": _ground_layer(tmp_path, files, z),
                                               "Z_DATUM": "ellipsoid", "OUTPUT": str(tmp_path / "i.gpkg")},
                   "INPUT", "Z values", "USE_Z", watch=[tmp_path])


@pytest.mark.parametrize("alg", ["footprint", "exportrpc", "imagetoground"])
def test_dem_with_undeclared_voids(provider, simulated, files, tmp_path, alg):
    params = {**_height_params(alg, 0.0, simulated, files, tmp_path), "DEM": files["dem_voids"], "DEM_DATUM": "ellipsoid"}
    assert_refused(f"pushbroom:{alg}", params, "DEM", "-32768", "nodata value not declared", watch=[tmp_path])


# --- nodata, output sizes, extents -----------------------------------------------------------------------
NODATA = [("byte", -5, "0 to 255"), ("byte", float("nan"), "0 to 255"), ("byte", 256, "0 to 255"),
          ("byte", 1.5, "whole numbers"), ("float", 1e300, "float32"), ("float", float("inf"), "")]


@pytest.mark.parametrize("image, nodata, text", NODATA, ids=[f"{i} NODATA={v}" for i, v, _ in NODATA])
def test_nodata_the_output_type_cannot_hold(provider, simulated, files, tmp_path, image, nodata, text):
    """NODATA=-5 on an 8-bit image wrote 251 into the fill while the tag said -5; NaN gave a traceback."""
    assert_refused("pushbroom:orthorectify", {"INPUT": files[image], "SCENE": simulated["ONBOARD_SCENE"],
                                              "HEIGHT": 800.0, "NODATA": nodata, "OUTPUT": str(tmp_path / "o.tif")},
                   "NODATA", text, watch=[tmp_path])


def test_nodata_nan_on_the_command_line(qgis_process, simulated, files, tmp_path):
    assert_refused_cli(qgis_process, "pushbroom:orthorectify", {"INPUT": files["byte"], "SCENE": simulated["ONBOARD_SCENE"],
                                                                "HEIGHT": 800, "NODATA": "nan", "OUTPUT": tmp_path / "o.tif"},
                       "NODATA", "0 to 255", watch=[tmp_path])


@pytest.mark.parametrize("resolution", [1e-6, 1e-300])
def test_output_no_disk_holds(provider, simulated, files, tmp_path, resolution):
    message = assert_refused("pushbroom:orthorectify", {"INPUT": files["byte"], "SCENE": simulated["ONBOARD_SCENE"],
                                                        "HEIGHT": 800.0, "RESOLUTION": resolution,
                                                        "OUTPUT": str(tmp_path / "o.tif")},
                             "resolution", "would have", watch=[tmp_path])
    assert "e+" in message  # the size it would have, e.g. 2.9e+10 x 2.9e+10 pixels


@pytest.mark.parametrize("resolution", [1e7, 1e5])
def test_a_pixel_larger_than_the_scene(provider, simulated, files, tmp_path, resolution):
    """Not 'ground coordinates contain NaN or infinite values' (the grid's pixel centres far off the
    UTM zone): RESOLUTION, the size the grid would have and the range."""
    assert_refused("pushbroom:orthorectify", {"INPUT": files["byte"], "SCENE": simulated["ONBOARD_SCENE"],
                                              "HEIGHT": 800.0, "RESOLUTION": resolution,
                                              "OUTPUT": str(tmp_path / "o.tif")},
                   f"RESOLUTION: {resolution:g} m: the orthoimage would have", "give a pixel size from",
                   "(2 pixels across)", watch=[tmp_path])


def _utm_box(files, dx: float, dy: float, half: float) -> str:
    lon, lat = files["centre_lonlat"]
    crs = utm_crs(lon, lat)
    x, y = Transformer.from_crs(CRS.from_epsg(4326), crs, always_xy=True).transform(lon, lat)
    return f"{x + dx - half},{x + dx + half},{y + dy - half},{y + dy + half} [{crs.to_string()}]"


def test_extent_off_the_scene_is_refused(provider, simulated, files, tmp_path):
    assert_refused("pushbroom:orthorectify", {"INPUT": files["byte"], "SCENE": simulated["ONBOARD_SCENE"],
                                              "HEIGHT": 800.0, "EXTENT": _utm_box(files, 200e3, 0.0, 500.0),
                                              "OUTPUT": str(tmp_path / "o.tif")},
                   "EXTENT", "does not overlap", watch=[tmp_path])


def test_extent_half_off_the_scene_warns_and_nan_nodata_is_kept_on_float(provider, simulated, files, tmp_path):
    """Legitimate: NaN nodata on a float image, and an extent straddling the footprint's east
    edge (the footprint is ~29 km wide): the part outside is nodata, with a warning saying how much."""
    feedback = RecordingFeedback()
    out = processing.run("pushbroom:orthorectify", {"INPUT": files["float"], "SCENE": simulated["ONBOARD_SCENE"],
                                                    "HEIGHT": 800.0, "NODATA": float("nan"), "RESOLUTION": 20.0,
                                                    "EXTENT": _utm_box(files, 14.5e3, 0.0, 1000.0),
                                                    "OUTPUT": str(tmp_path / "o.tif")}, feedback=feedback)["OUTPUT"]
    warning = next(w for w in feedback.warnings if "EXTENT" in w)
    share = float(warning.split("EXTENT: ")[1].split(" %")[0])
    ds = gdal.Open(out)
    values = ds.GetRasterBand(1).ReadAsArray()
    assert np.isnan(ds.GetRasterBand(1).GetNoDataValue())
    assert 100 * np.isnan(values).mean() == pytest.approx(share, abs=5.0)
    assert 10.0 < share < 90.0 and np.all(values[np.isfinite(values)] == 100.0)


# --- geometry types and options ---------------------------------------------------------------------------
def _layer_file(path: Path, kind: str, geometry: QgsGeometry) -> str:
    """A GeoPackage layer of one feature with the fields of a GCP: id, role, col, row."""
    layer = QgsVectorLayer(f"{kind}?crs=EPSG:4326&field=id:string&field=role:string&field=col:double"
                           f"&field=row:double", "l", "memory")
    f = QgsFeature(layer.fields())
    f.setGeometry(geometry)
    f.setAttributes(["1", "control", 6000.5, 6000.5])
    layer.dataProvider().addFeatures([f])
    options = QgsVectorFileWriter.SaveVectorOptions()
    error = QgsVectorFileWriter.writeAsVectorFormatV3(layer, str(path), QgsCoordinateTransformContext(), options)
    assert error[0] == QgsVectorFileWriter.NoError, error
    return str(path)


def _line_layer(tmp_path, files) -> str:
    lon, lat = files["centre_lonlat"]
    return _layer_file(tmp_path / "lines.gpkg", "LineString",
                       QgsGeometry.fromPolylineXY([QgsPointXY(lon, lat), QgsPointXY(lon + 0.01, lat)]))


@pytest.mark.parametrize("alg", ["importgcps", "groundtoimage"])
def test_line_layer_where_points_are_meant(provider, simulated, files, tmp_path, alg):
    lines = _line_layer(tmp_path, files)
    params = {"SCENE": simulated["ONBOARD_SCENE"], "INPUT": lines, "OUTPUT": str(tmp_path / "out.gpkg")}
    if alg == "importgcps":
        params.update(ID_FIELD="id", HEIGHT_SOURCE="constant", HEIGHT=800.0)
    assert_refused(f"pushbroom:{alg}", params, "INPUT", "LineString", "point layer", watch=[tmp_path])


def _adjust_outputs(folder: Path) -> dict:
    return {name: str(folder / f"{name.lower()}{ext}") for name, ext in
            (("OUTPUT_SCENE", ".json"), ("OUTPUT_REPORT", ".html"), ("OUTPUT_GCPS", ".gpkg"),
             ("OUTPUT_RESIDUALS", "_vectors.gpkg"))}


def test_line_layer_as_gcps_of_the_adjustment(provider, simulated, files, tmp_path):
    lines = _line_layer(tmp_path, files)
    assert_refused("pushbroom:bundleadjust", {"SCENE": simulated["ONBOARD_SCENE"], "GCPS": lines,
                                              **_adjust_outputs(tmp_path)},
                   "linestring", "not a point", watch=[tmp_path])


OPTIONS = [
    ("bundleadjust", "RESIDUAL_SCALE", 1e308), ("footprint", "SAMPLES", 10 ** 9), ("exportrpc", "HEIGHT_SPAN", 1e9),
    ("exportrpc", "GRID", 10 ** 6), ("simulatescene", "N_GCPS", 10 ** 9), ("simulatescene", "N_SCENES", 10 ** 6),
    ("simulatescene", "IMAGE_NOISE", 1e308), ("simulatescene", "POSITION_BIAS", 1e308),
    ("simulatescene", "ATTITUDE_DRIFT", 1e9), ("simulatescene", "FOCAL_ERROR", 1e6),
]


@pytest.mark.parametrize("alg, name, value", OPTIONS, ids=[f"{a} {n}={v:g}" for a, n, v in OPTIONS])
def test_absurd_option_is_refused(provider, simulated, files, tmp_path, alg, name, value):
    params = {"bundleadjust": {"SCENE": simulated["ONBOARD_SCENE"], "GCPS": _line_layer(tmp_path, files),
                               **_adjust_outputs(tmp_path)},
              "footprint": {"SCENE": simulated["ONBOARD_SCENE"], "OUTPUT": str(tmp_path / "fp.gpkg")},
              "exportrpc": {"SCENE": simulated["ONBOARD_SCENE"], "OUTPUT": str(tmp_path / "s_RPC.TXT")},
              "simulatescene": {"OUTPUT_FOLDER": str(tmp_path / "sim")}}[alg]
    assert_refused(f"pushbroom:{alg}", {**params, name: value}, name, watch=[tmp_path])
