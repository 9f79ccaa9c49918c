"""Hostile RPC scenes (harness: hostile.py): broken RPC files, an image that is not the one its RPC
describes, a DEM or height outside the RPC's height range. Each is refused with a message naming
the file (and key) or parameter and what is wrong, inputs and output folder unchanged; a legitimate
crop of an RPC image (offsets moved, as gdal_translate -srcwin writes them) is accepted; so is a crop whose RPC
keeps the full product's offsets (tests/unit/model/test_rpc_domain.py)."""
from __future__ import annotations

import json
import numpy as np
import pytest
from osgeo import gdal

import processing
from pushbroom_adjust.core.model.rpcscene import RpcScene
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.scene_json import rpc_scene_to_dict
from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.rpcdata import padded_dem, pleiades_rpc, rpc_files, scaled, write_image

gdal.UseExceptions()


@pytest.fixture(scope="module")
def good(provider, shared_data, tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("rpc_good")
    rpc = scaled(pleiades_rpc(shared_data), 16.0)
    files = rpc_files(folder, rpc)
    files.update(rpc=rpc, folder=folder, text=files["txt"].read_text(),
                 dem=str(padded_dem(shared_data, folder / "dem.tif")))
    return files


def _edited(good, tmp_path, edit) -> str:
    path = tmp_path / "in" / "bad_RPC.TXT"
    path.parent.mkdir()
    path.write_text(edit(good["text"]))
    return str(path)


def _without(prefix):
    return lambda t: "\n".join(line for line in t.splitlines() if not line.startswith(prefix))


def _set(key, value):
    return lambda t: "\n".join(f"{key}: {value}" if line.startswith(key + ":") else line for line in t.splitlines())


@pytest.mark.parametrize("edit, expected", [
    (_without("LINE_NUM_COEFF_5:"), ("bad_RPC.TXT", "LINE_NUM_COEFF holds 19 numbers; RPC00B has 20")),
    (_without("HEIGHT_OFF:"), ("bad_RPC.TXT", "HEIGHT_OFF is missing")),
    (_set("SAMP_DEN_COEFF_3", "abc"), ("bad_RPC.TXT", "SAMP_DEN_COEFF is 'abc', not a number")),
    (_set("LAT_OFF", "31,02 degrees"), ("bad_RPC.TXT", "LAT_OFF is", "not a number")),
    (_set("LINE_NUM_COEFF_2", "nan"), ("bad_RPC.TXT", "LINE_NUM_COEFF", "not a finite number")),
    (_set("LONG_SCALE", "0.0 degrees"), ("bad_RPC.TXT", "LONG_SCALE", "a scale must be a non-zero number")),
    (_set("LINE_DEN_COEFF_1", "0"), ("bad_RPC.TXT", "LINE_DEN_COEFF is 0", "denominator vanishes")),
    (_set("LAT_OFF", "1e300 degrees"), ("bad_RPC.TXT", "LAT_OFF", "between -90 and 90")),
    (_set("HEIGHT_SCALE", "-1e9 meters"), ("bad_RPC.TXT", "HEIGHT_SCALE", "between 0 and 100000")),
    (_set("LINE_OFF", "1e12 pixels"), ("bad_RPC.TXT", "LINE_OFF", "between -1e+08 and 1e+08")),
], ids=["missing coefficient", "missing offset", "non-numeric coefficient", "comma decimal", "NaN coefficient",
        "zero scale", "zero denominator", "latitude beyond the poles", "absurd height scale", "absurd line offset"])
def test_broken_rpc_text_is_refused_naming_file_and_key(good, tmp_path, edit, expected):
    scene = _edited(good, tmp_path, edit)
    out = tmp_path / "out"
    out.mkdir()
    assert_refused("pushbroom:footprint", {"SCENE": scene, "HEIGHT": 575.0, "OUTPUT": str(out / "fp.gpkg")},
                   "SCENE", *expected, watch=[tmp_path])


def test_rpc_scene_json_with_a_zero_scale(good, tmp_path):
    d = rpc_scene_to_dict(RpcScene(good["rpc"], load_scene(good["txt"]).camera))
    d["rpc"]["LINE_SCALE"] = 0
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(d))
    assert_refused("pushbroom:footprint", {"SCENE": str(scene), "HEIGHT": 575.0, "OUTPUT": str(tmp_path / "f.gpkg")},
                   "s.json", "rpc.LINE_SCALE: a scale must not be 0", watch=[tmp_path])


def test_an_image_larger_than_its_rpc_range_is_refused(good, tmp_path):
    image = write_image(tmp_path / "big.tif", 2 * good["cols"], good["rows"], good["rpc"])
    assert_refused("pushbroom:footprint", {"SCENE": str(image), "HEIGHT": 575.0, "OUTPUT": str(tmp_path / "f.gpkg")},
                   "big.tif", f"the image ({2 * good['cols']} x {good['rows']} px) cannot be the one its RPC describes",
                   f"its upper-right corner ({2 * good['cols']}, 0) at 490 m lands at latitude 31.09642, longitude "
                   "2.56768, 3.02 times", "valid over latitude 30.92313 to 31.11423, longitude 2.11840 to 2.34201",
                   "Is it the image this RPC belongs to?", watch=[tmp_path])


def test_an_image_of_another_size_given_to_orthorectify(good, tmp_path):
    small = write_image(tmp_path / "small.tif", 100, 100)
    assert_refused("pushbroom:orthorectify", {"INPUT": str(small), "SCENE": str(good["txt"]), "HEIGHT": 575.0,
                                              "RESOLUTION": 50.0, "OUTPUT": str(tmp_path / "o.tif")},
                   "small.tif", "100 x 100", "2500 x 2390", watch=[tmp_path, good["folder"]])


def test_a_dem_outside_the_rpc_height_range_is_refused(good, tmp_path):
    src = gdal.Open(good["dem"])
    high = gdal.Translate(str(tmp_path / "high.tif"), src, scaleParams=[[0, 1, 3000, 3001]],
                          outputType=gdal.GDT_Float32)  # heights 3000 m higher
    del high  # closes the file
    assert_refused("pushbroom:footprint", {"SCENE": str(good["tif"]), "DEM": str(tmp_path / "high.tif"),
                                           "DEM_DATUM": "ellipsoid", "OUTPUT": str(tmp_path / "f.gpkg")},
                   "DEM", "high.tif", "lie outside the RPC's height range 490 to 660 m", watch=[tmp_path])


def test_a_broken_rpc_from_the_command_line(qgis_process, good, tmp_path):
    scene = _edited(good, tmp_path, _set("SAMP_SCALE", "0"))
    assert_refused_cli(qgis_process, "pushbroom:footprint", {"SCENE": scene, "HEIGHT": 575.0,
                                                             "OUTPUT": str(tmp_path / "f.gpkg")},
                       "SAMP_SCALE", "non-zero", watch=[tmp_path])


def test_a_crop_with_its_offsets_moved_is_accepted(good, tmp_path):
    """gdal_translate -srcwin keeps the RPC and moves LINE_OFF/SAMP_OFF: the crop's footprint is
    the part of the full image's it shows."""
    crop = tmp_path / "crop.tif"
    gdal.Translate(str(crop), str(good["tif"]), srcWin=[500, 400, 1000, 800])
    scene = load_scene(crop)
    assert (scene.camera.cols, scene.camera.rows) == (1000, 800)
    full = load_scene(good["tif"])
    xyz = scene.image_to_ground([0.0, 1000.0], [0.0, 800.0], 575.0)
    c, r = full.ground_to_image(xyz)
    assert np.allclose(c, [500.0, 1500.0], atol=1e-6) and np.allclose(r, [400.0, 1200.0], atol=1e-6)
    res = processing.run("pushbroom:footprint", {"SCENE": str(crop), "HEIGHT": 575.0, "OUTPUT": "memory:"})
    assert res["OUTPUT"].featureCount() == 1



@pytest.fixture(scope="module")
def other_products(provider, shared_data, tmp_path_factory) -> dict:
    """An RPC scene (the Ventoux left crop's _RPC.TXT, 500 x 500 px) and, of the same size, another product's
    image: a crop of the Giza img1 carrying its own RPC (gdal_translate writes it into the GeoTIFF's tags), one
    without an RPC, and a DEM of the Giza plateau with heights inside the Ventoux RPC's range (500 m,
    ellipsoidal)."""
    folder = tmp_path_factory.mktemp("other_products")
    ventoux = folder / "ventoux"
    ventoux.mkdir()
    for name in ("left_image.tif", "left_image_RPC.TXT"):
        (ventoux / name).write_bytes((shared_data / "pleiades_ventoux" / name).read_bytes())
    giza = gdal.Translate(str(folder / "giza_crop.tif"), str(shared_data / "pleiades_gizeh" / "img1.tif"),
                          srcWin=[100, 100, 500, 500])
    assert giza.GetMetadata("RPC")
    giza = None
    plain = write_image(folder / "plain.tif", 500, 500)
    dem = gdal.GetDriverByName("GTiff").Create(str(folder / "giza_dem.tif"), 40, 40, 1, gdal.GDT_Float32)
    dem.SetGeoTransform((31.10, 0.001, 0.0, 30.00, 0.0, -0.001))
    dem.SetProjection("EPSG:4326")
    dem.GetRasterBand(1).Fill(500.0)
    dem = None
    return {"scene": str(ventoux / "left_image_RPC.TXT"), "giza": str(folder / "giza_crop.tif"),
            "plain": str(plain), "dem": str(folder / "giza_dem.tif"), "folder": folder}


def test_an_rpc_scene_given_another_products_image_is_refused_naming_both(other_products, tmp_path):
    """Issue 28's hostile case ('DEM does not cover the scene' for an RPC scene given another product's image):
    the image carries its own RPC, which puts it on the Giza plateau, where the Ventoux RPC sees nothing: refused
    before the DEM is read, naming INPUT, the image and the scene, and where the image's RPC puts it."""
    o = other_products
    assert_refused("pushbroom:orthorectify", {"INPUT": o["giza"], "SCENE": o["scene"], "DEM": o["dem"],
                                              "DEM_DATUM": "ellipsoid", "RESOLUTION": 1.0,
                                              "OUTPUT": str(tmp_path / "o.tif")},
                   "INPUT: ", f"{o['giza']}: the image and the scene {o['scene']} do not belong together",
                   "the image's own RPC puts its centre at latitude 29.9", "which the scene ",
                   "Is it the scene's image, and the scene the image's model?", watch=[tmp_path, o["folder"]])


def test_an_rpc_scene_given_an_image_without_rpc_and_another_area_s_dem(other_products, tmp_path):
    """Without an RPC of its own the image cannot be judged; the DEM of another area then does not cover the
    scene, and the refusal names the DEM, the scene and where the scene puts the image (north-west of Mont
    Ventoux), so that the mismatch shows."""
    o = other_products
    assert_refused("pushbroom:orthorectify", {"INPUT": o["plain"], "SCENE": o["scene"], "DEM": o["dem"],
                                              "DEM_DATUM": "ellipsoid", "RESOLUTION": 1.0,
                                              "OUTPUT": str(tmp_path / "o.tif")},
                   f"DEM {o['dem']} does not cover the scene {o['scene']}: the image's ",
                   "the scene puts the image's centre at latitude 44.20", "longitude 5.19",
                   "check that the scene is the image's model", watch=[tmp_path, o["folder"]])
