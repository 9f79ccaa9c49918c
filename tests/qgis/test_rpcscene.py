"""RPC-only scenes through every scene algorithm, in real QGIS (processing.run) and on the command
line (qgis_process): the Pleiades vendor RFM, scaled to a 2500 x 2390 image (16 times coarser
pixels), given as an image with RPC tags, as ``_RPC.TXT`` and as ``.RPB``."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal
from qgis.core import QgsProcessingException

import processing
from pushbroom_adjust.core.dem import ConstantHeight, Dem
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.core.products.ortho import default_grid
from pushbroom_adjust.core.products.footprint import footprints
from pushbroom_adjust.core.model.rpcscene import RpcScene
from pushbroom_adjust.core.formats import load_scene
from tests.support.ortho_compare import gdal_rpc_against_rigorous, gdalwarp_rpc, image_difference
from tests.support.processing import RecordingFeedback, field_values, image_table
from tests.support.qgis_process import read_layer, run_json
from tests.support.rpcdata import PLEIADES, padded_dem, pleiades_rpc, rpc_files, scaled


@pytest.fixture(scope="module")
def rpc(provider, shared_data, tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("rpc")
    files = rpc_files(folder, scaled(pleiades_rpc(shared_data), 16.0))
    files["dem"] = str(padded_dem(shared_data, folder / "dem.tif"))  # ellipsoidal heights
    return files


def _points(scene, n, seed=2):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, scene.camera.cols, n), rng.uniform(0, scene.camera.rows, n)


@pytest.mark.parametrize("source", ["tif", "txt", "rpb"])
def test_image_to_ground_and_back_on_the_dem(rpc, source):
    scene = load_scene(rpc[source])
    assert isinstance(scene, RpcScene)
    col, row = _points(scene, 100)
    dem = Dem(rpc["dem"], "ellipsoid")
    ground = processing.run("pushbroom:imagetoground", {"SCENE": str(rpc[source]), "INPUT": image_table(col, row),
                                                        "DEM": rpc["dem"], "DEM_DATUM": "ellipsoid",
                                                        "OUTPUT": "memory:"})["OUTPUT"]
    lon, lat, h = field_values(ground, "lon", "lat", "h_ellipsoid").T
    assert np.abs(h - dem.height(lon, lat)).max() < 0.01
    assert np.abs(geodetic_to_ecef(lon, lat, h) - scene.image_to_ground_dem(col, row, dem)).max() < 1e-3
    back = processing.run("pushbroom:groundtoimage", {"SCENE": str(rpc[source]), "INPUT": ground,
                                                      "OUTPUT": "memory:"})["OUTPUT"]
    c2, r2, inside = field_values(back, "col_2", "row_2", "in_image").T
    assert np.hypot(c2 - col, r2 - row).max() < 1e-3 and inside.min() == 1


def test_a_constant_height_outside_the_rpc_range_is_refused_and_one_partly_outside_warned(rpc):
    col, row = _points(load_scene(rpc["tif"]), 5)
    params = {"SCENE": str(rpc["tif"]), "INPUT": image_table(col, row), "OUTPUT": "memory:"}
    with pytest.raises(QgsProcessingException, match=r"HEIGHT 3000 m: heights 3000 to 3000 m lie outside the RPC's "
                                                     r"height range 490 to 660 m"):
        processing.run("pushbroom:imagetoground", {**params, "HEIGHT": 3000.0})
    feedback = RecordingFeedback()
    processing.run("pushbroom:imagetoground", {**params, "DEM": rpc["dem"], "DEM_DATUM": "ellipsoid"},
                   feedback=feedback)
    assert any("extend past the RPC's height range 490 to 660 m" in w for w in feedback.warnings)


def test_footprint_of_an_rpc_scene_is_the_rigorous_models(rpc, shared_data):
    out = processing.run("pushbroom:footprint", {"SCENE": str(rpc["txt"]), "HEIGHT": 575.0, "SAMPLES": 8,
                                                 "OUTPUT": "memory:"})["OUTPUT"]
    (f,) = list(out.getFeatures())
    assert (f["cols"], f["rows"]) == (2500, 2390)
    full = load_scene(shared_data / PLEIADES)  # cut to the 2390 * 16 rows the scaled image covers
    cut = replace(full, cameras=[replace(full.cameras[0], rows=2390 * 16)], _guess={})
    (rigorous,) = footprints(cut, ConstantHeight(575.0), samples_per_edge=8)
    assert f["area_km2"] == pytest.approx(rigorous.area_km2, rel=1e-4)


def test_orthorectify_matches_gdalwarp_with_the_same_rpc(rpc, tmp_path):
    scene = load_scene(rpc["tif"])
    dem = Dem(rpc["dem"], "ellipsoid")
    ours = tmp_path / "ours.tif"
    processing.run("pushbroom:orthorectify", {"INPUT": str(rpc["tif"]), "SCENE": str(rpc["tif"]), "DEM": rpc["dem"],
                                              "DEM_DATUM": "ellipsoid", "RESAMPLING": "bilinear", "NODATA": 0,
                                              "OUTPUT": str(ours)})
    ds = gdal.Open(str(ours))
    gt = ds.GetGeoTransform()
    grid = default_grid(scene, 0, dem)
    assert (ds.RasterXSize, ds.RasterYSize) == (grid.cols, grid.rows) and gt[1] == pytest.approx(grid.resolution)
    # geometry: our mapping against GDAL's RPC transformer with the DEM
    err = gdal_rpc_against_rigorous(scene, rpc["dem"], rpc["tif"], grid, n=20_000)
    assert err.size > 10_000 and np.percentile(err, 99) < 0.01
    theirs = tmp_path / "gdal.tif"
    gdalwarp_rpc(rpc["tif"], rpc["dem"], grid, theirs)
    diff = image_difference(str(ours), str(theirs), blocks=4)
    assert np.hypot(*diff["shift_px"]) < 0.05


def test_exportrpc_of_an_rpc_scene_reproduces_it(rpc, tmp_path):
    out = tmp_path / "again_RPC.TXT"
    res = processing.run("pushbroom:exportrpc", {"SCENE": str(rpc["txt"]), "DEM": rpc["dem"],
                                                 "DEM_DATUM": "ellipsoid", "OUTPUT": str(out)})
    assert res["RMS_PX"] < 1e-3
    again = load_scene(out)
    scene = load_scene(rpc["txt"])
    col, row = _points(scene, 200)
    xyz = scene.image_to_ground(col, row, 600.0)
    c, r = again.ground_to_image(xyz)
    assert np.hypot(c - col, r - row).max() < 2e-3


def test_footprint_of_an_rpc_image_from_the_command_line(qgis_process, rpc, tmp_path):
    out = tmp_path / "fp.gpkg"
    res = run_json(qgis_process, "pushbroom:footprint", SCENE=rpc["tif"], DEM=rpc["dem"], DEM_DATUM="ellipsoid",
                    OUTPUT=out)
    assert Path(res["OUTPUT"]).is_file()
    scene = load_scene(rpc["tif"])
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground_dem([0.0], [0.0], Dem(rpc["dem"], "ellipsoid")))
    _, (wkt,) = read_layer(out, "cols")
    corners = np.array([[float(v) for v in p.split()[:2]] for p in wkt.split("((")[1].rstrip(")").split(",")])
    assert np.hypot(*(corners - [lon[0], lat[0]]).T).min() < 1e-6
