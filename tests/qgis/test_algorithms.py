"""The sensor-model algorithms through processing.run on a small simulated scene, checked
against the core and against each other; every kind of bad input gives a clear error."""
import csv
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal, osr
from pyproj import Transformer
from qgis.core import QgsGeometry, QgsPointXY, QgsProject, QgsProcessingException

import processing
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.core.products.footprint import footprints
from pushbroom_adjust.core.formats import load_scene
from tests.support.processing import RecordingFeedback, field_values, image_table, point_layer
from tests.support.seams import round_trip_errors

RNG = np.random.default_rng(11)


@pytest.fixture(scope="session")
def scene(simulated):
    return load_scene(simulated["TRUE_SCENE"])


@pytest.fixture(scope="session")
def dem(simulated):
    return Dem(simulated["DEM"], datum="geoid")


def _random_image_points(scene, n):
    cam = scene.cameras[0]
    return RNG.uniform(0.0, cam.cols, n), RNG.uniform(0.0, cam.rows, n)


# --- simulatescene ---------------------------------------------------------------------------------
def test_simulatescene_writes_loadable_models_gcps_and_dem(simulated, scene, dem):
    for key in ("ONBOARD_SCENE", "TRUE_SCENE", "GCPS", "DEM"):
        assert Path(simulated[key]).is_file(), key
    onboard = load_scene(simulated["ONBOARD_SCENE"])
    assert [c.name for c in onboard.cameras] == [c.name for c in scene.cameras]
    with open(simulated["GCPS"], newline="") as f:
        assert len(list(csv.DictReader(f))) == 12
    # the onboard model is off the truth by the simulated errors: a ground point moves in the image
    col, row = _random_image_points(scene, 20)
    ground = scene.image_to_ground_dem(col, row, dem)
    c2, r2 = onboard.ground_to_image(ground)
    assert 0.5 < np.nanmax(np.hypot(c2 - col, r2 - row)) < 5000.0


# --- footprint --------------------------------------------------------------------------------------
def test_footprint_polygons_follow_the_core_outline_on_the_dem(simulated, scene, dem):
    out = processing.run("pushbroom:footprint", {"SCENE": simulated["TRUE_SCENE"], "DEM": simulated["DEM"],
                                                 "DEM_DATUM": "geoid", "SAMPLES": 32, "OUTPUT": "memory:"})["OUTPUT"]
    assert out.crs().authid() == "EPSG:4326" and out.featureCount() == len(scene.cameras)
    truth = footprints(scene, dem, samples_per_edge=32)
    for f, fp in zip(out.getFeatures(), truth):
        assert (f["camera"], f["cols"], f["rows"]) == (fp.camera, fp.cols, fp.rows)
        ring = np.array([(p.x(), p.y()) for p in f.geometry().asPolygon()[0]])
        assert ring.shape == (fp.lon.size, 2)
        assert np.abs(ring - np.stack([fp.lon, fp.lat], 1)).max() < 1e-12
        assert abs(f["area_km2"] - fp.area_km2) < 1e-9 and fp.area_km2 > 1.0
    # the image centre's ground point lies inside the outline
    cam = scene.cameras[0]
    centre = scene.image_to_ground_dem([cam.cols / 2], [cam.rows / 2], dem)
    lon, lat, _ = ecef_to_geodetic(centre)
    first = next(out.getFeatures()).geometry()
    assert first.contains(QgsGeometry.fromPointXY(QgsPointXY(float(lon[0]), float(lat[0]))))


def test_footprint_on_a_dem_not_covering_the_scene_is_refused(simulated, tmp_path, scene, dem):
    small = _tiny_dem(tmp_path / "small.tif", scene, dem)
    with pytest.raises(QgsProcessingException, match="DEM .*small.tif gives no height for .* points of the image outline"):
        processing.run("pushbroom:footprint", {"SCENE": simulated["TRUE_SCENE"], "DEM": str(small),
                                               "OUTPUT": "memory:"})


def _tiny_dem(path, scene, dem, size_deg=0.001):
    """A 10 x 10 DEM around the image centre, far smaller than the scene."""
    cam = scene.cameras[0]
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground_dem([cam.cols / 2], [cam.rows / 2], dem))
    ds = gdal.GetDriverByName("GTiff").Create(str(path), 10, 10, 1, gdal.GDT_Float32)
    ds.SetGeoTransform((lon[0] - size_deg / 2, size_deg / 10, 0, lat[0] + size_deg / 2, 0, -size_deg / 10))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds.SetProjection(srs.ExportToWkt())
    ds.GetRasterBand(1).Fill(100.0)
    ds = None
    return path


# --- image <-> ground ---------------------------------------------------------------------------------
def test_image_to_ground_then_back_returns_the_pixels(simulated, scene, dem):
    col, row = _random_image_points(scene, 200)
    ground = processing.run("pushbroom:imagetoground", {"SCENE": simulated["TRUE_SCENE"], "INPUT": image_table(col, row),
                                                        "DEM": simulated["DEM"], "DEM_DATUM": "geoid",
                                                        "OUTPUT": "memory:"})["OUTPUT"]
    assert ground.crs().authid() == "EPSG:4979" and ground.featureCount() == 200
    lon, lat, h = field_values(ground, "lon", "lat", "h_ellipsoid").T
    # the points lie on the DEM (ellipsoidal heights), where the core puts them
    assert np.abs(h - dem.height(lon, lat)).max() < 1e-3
    truth = scene.image_to_ground_dem(col, row, dem)
    assert np.abs(geodetic_to_ecef(lon, lat, h) - truth).max() < 1e-3
    back = processing.run("pushbroom:groundtoimage", {"SCENE": simulated["TRUE_SCENE"], "INPUT": ground,
                                                      "OUTPUT": "memory:"})["OUTPUT"]
    # input fields kept; the new image coordinates get a suffix since the input has col/row already
    c2, r2, inside = field_values(back, "col_2", "row_2", "in_image").T
    assert np.abs(field_values(back, "id")[:, 0] - np.arange(200)).max() == 0
    err, _ = round_trip_errors(scene, dem, col, row, c2, r2)
    assert err.max() < 1e-4
    assert inside.min() == 1


def test_ground_to_image_in_a_projected_crs_with_heights_from_the_dem(simulated, scene, dem):
    col, row = _random_image_points(scene, 50)
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground_dem(col, row, dem))
    zone = int((lon.mean() + 180) // 6) + 1
    epsg = (32600 if lat.mean() >= 0 else 32700) + zone
    x, y = Transformer.from_crs(4326, epsg, always_xy=True).transform(lon, lat)
    layer = point_layer(x, y, crs=f"EPSG:{epsg}")
    out = processing.run("pushbroom:groundtoimage", {"SCENE": simulated["TRUE_SCENE"], "INPUT": layer,
                                                     "DEM": simulated["DEM"], "DEM_DATUM": "geoid",
                                                     "OUTPUT": "memory:"})["OUTPUT"]
    assert out.crs().authid() == f"EPSG:{epsg}" and [f["name"] for f in out.getFeatures()][:2] == ["p0", "p1"]
    c2, r2 = field_values(out, "col", "row").T
    err, _ = round_trip_errors(scene, dem, col, row, c2, r2)
    assert err.max() < 1e-3


def test_points_outside_the_image_are_kept_flagged_and_counted(simulated, scene, dem):
    cam = scene.cameras[0]
    col = np.array([cam.cols * 0.5, cam.cols * 1.3, -0.2 * cam.cols])
    row = np.array([cam.rows * 0.5, cam.rows * 0.5, cam.rows * 0.2])
    lon, lat, h = ecef_to_geodetic(scene.image_to_ground(col, row, 100.0))
    feedback = RecordingFeedback()
    out = processing.run("pushbroom:groundtoimage", {"SCENE": simulated["TRUE_SCENE"], "INPUT": point_layer(lon, lat, h),
                                                     "Z_DATUM": "ellipsoid", "OUTPUT": "memory:"}, feedback=feedback)["OUTPUT"]
    c2, r2, inside = field_values(out, "col", "row", "in_image").T
    assert list(inside) == [1, 0, 0]
    assert np.abs(c2 - col).max() < 1e-3 and np.abs(r2 - row).max() < 1e-3
    assert any("2 of 3 points fall outside the image" in w for w in feedback.warnings)


def test_camera_by_name_and_index(simulated, scene):
    cam = scene.cameras[-1]
    col, row = np.array([cam.cols / 3]), np.array([cam.rows / 4])
    results = []
    for camera in (cam.name, str(len(scene.cameras) - 1)):
        out = processing.run("pushbroom:imagetoground", {"SCENE": simulated["TRUE_SCENE"], "CAMERA": camera,
                                                         "INPUT": image_table(col, row), "HEIGHT": 250.0,
                                                         "OUTPUT": "memory:"})["OUTPUT"]
        results.append(field_values(out, "lon", "lat", "h_ellipsoid")[0])
    truth = scene.image_to_ground(col, row, 250.0, camera=len(scene.cameras) - 1)
    assert np.allclose(results[0], results[1])
    assert np.abs(geodetic_to_ecef(*results[0]) - truth[0]).max() < 1e-3


# --- bad input -------------------------------------------------------------------------------------------
def test_unreadable_metadata_names_the_parameter(tmp_path, provider):
    bad = tmp_path / "scene.xml"
    bad.write_text("<?xml version='1.0'?><kml></kml>")
    with pytest.raises(QgsProcessingException, match=r"SCENE: .*scene.xml.*unrecognised XML metadata"):
        processing.run("pushbroom:footprint", {"SCENE": str(bad), "OUTPUT": "memory:"})


def test_unknown_camera_lists_the_cameras(simulated, scene):
    with pytest.raises(QgsProcessingException, match=f"CAMERA: camera 'XYZ' is not in this scene.*{scene.cameras[0].name}"):
        processing.run("pushbroom:imagetoground", {"SCENE": simulated["TRUE_SCENE"], "CAMERA": "XYZ",
                                                   "INPUT": image_table([1.0], [1.0]), "OUTPUT": "memory:"})


def test_nan_image_coordinates_are_refused(simulated):
    with pytest.raises(QgsProcessingException, match=r"INPUT: 1 features have missing or non-finite col/row"):
        processing.run("pushbroom:imagetoground", {"SCENE": simulated["TRUE_SCENE"],
                                                   "INPUT": image_table([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], extra_null=True),
                                                   "OUTPUT": "memory:"})


def test_nan_ground_coordinates_are_refused(simulated):
    with pytest.raises(QgsProcessingException, match=r"INPUT: 1 features have missing or non-finite point coord"):
        processing.run("pushbroom:groundtoimage", {"SCENE": simulated["TRUE_SCENE"],
                                                   "INPUT": point_layer([0.1, np.nan], [0.2, 0.3]), "OUTPUT": "memory:"})


def test_a_layer_without_a_crs_is_refused(simulated):
    with pytest.raises(QgsProcessingException, match="INPUT: the layer has no valid CRS"):
        processing.run("pushbroom:groundtoimage", {"SCENE": simulated["TRUE_SCENE"],
                                                   "INPUT": point_layer([0.1], [0.2], crs=None), "OUTPUT": "memory:"})


def test_points_off_the_dem_are_refused(simulated, tmp_path, scene, dem):
    small = _tiny_dem(tmp_path / "small.tif", scene, dem)
    col, row = _random_image_points(scene, 5)
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground(col, row, 0.0))
    with pytest.raises(QgsProcessingException, match=r"INPUT: DEM .*small.tif gives no height for 5 of 5 points \(5 off its extent\)"):
        processing.run("pushbroom:groundtoimage", {"SCENE": simulated["TRUE_SCENE"], "INPUT": point_layer(lon, lat),
                                                   "DEM": str(small), "OUTPUT": "memory:"})
    with pytest.raises(QgsProcessingException, match=r"DEM: DEM .*small.tif gives no height for 5 of 5 points \(5 off its extent\): their lines of sight "
                                                            "leave it"):
        processing.run("pushbroom:imagetoground", {"SCENE": simulated["TRUE_SCENE"], "INPUT": image_table(col, row),
                                                   "DEM": str(small), "OUTPUT": "memory:"})


def test_a_dem_without_crs_is_refused(simulated, tmp_path):
    path = tmp_path / "nocrs.tif"
    ds = gdal.GetDriverByName("GTiff").Create(str(path), 4, 4, 1, gdal.GDT_Float32)
    ds.SetGeoTransform((0, 1, 0, 4, 0, -1))
    ds = None
    with pytest.raises(QgsProcessingException, match="DEM: .*nocrs.tif: has no coordinate reference system"):
        processing.run("pushbroom:footprint", {"SCENE": simulated["TRUE_SCENE"], "DEM": str(path),
                                               "OUTPUT": "memory:"})


# --- styling -----------------------------------------------------------------------------------------------
def test_output_layers_are_styled_when_loaded_into_the_project(simulated, scene):
    project = QgsProject.instance()
    fp = processing.runAndLoadResults("pushbroom:footprint", {"SCENE": simulated["TRUE_SCENE"], "SAMPLES": 8,
                                                              "OUTPUT": "memory:"})["OUTPUT"]
    layer = project.mapLayer(fp)
    assert layer.labelsEnabled() and layer.labeling().settings().fieldName == "camera"
    pts = processing.runAndLoadResults("pushbroom:groundtoimage", {"SCENE": simulated["TRUE_SCENE"],
                                                                   "INPUT": point_layer([0.0], [0.0], [0.0]),
                                                                   "Z_DATUM": "ellipsoid", "OUTPUT": "memory:"}
                                       )["OUTPUT"]
    renderer = project.mapLayer(pts).renderer()
    assert renderer.type() == "categorizedSymbol" and renderer.classAttribute() == "in_image"
    project.removeAllMapLayers()
