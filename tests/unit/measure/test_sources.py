"""What the measuring docks open (core.measure.sources, core.measure.display): a display copy that
carries its statistics (so that showing it writes nothing beside the raw image), kept in a cache
folder under a name of its own; the raw image proposed from a scene file's folder; a scene file, a
display copy or a raster opened with its raw image; which rasters can be DEMs; and adjusted
residuals read back into the GCP editor (core.measure.gcpmeasure)."""
import os

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.errors import InputError, MetadataError
from pushbroom_adjust.core.measure.display import cached_display_copy, write_display_vrt
from pushbroom_adjust.core.measure.gcpmeasure import Ground, PointEditor
from pushbroom_adjust.core.measure.sources import elevation_problem, open_image_source, raw_image_candidates
from pushbroom_adjust.core.observations.gcps import Residuals, read_gpkg, write_gpkg
from pushbroom_adjust.core.observations.tables import Heights
from tests.support.gcpblock import NAMES, gcp_block, true_ground  # noqa: F401 (the fixture)


def raster(path, cols=40, rows=30, bands=1, data_type=gdal.GDT_Byte, metadata=None, domain=""):
    """A raster of a ramp (values 10 .. 10 + cols * rows - 1, clipped by the type)."""
    ds = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, bands, data_type)
    for k in range(1, bands + 1):
        ds.GetRasterBand(k).WriteArray((10 + np.arange(rows * cols).reshape(rows, cols) % 200))
    if metadata:
        ds.SetMetadata(metadata, domain)
    ds = None
    return path


def test_a_display_copy_carries_its_statistics_and_writes_nothing_beside_the_raw_image(tmp_path):
    (tmp_path / "in").mkdir()
    raw = raster(tmp_path / "in" / "raw.tif")
    write_display_vrt(raw, tmp_path / "display.vrt", "", "NAD")
    ds = gdal.Open(str(tmp_path / "display.vrt"))
    band = ds.GetRasterBand(1)
    # stored in the copy (a 40 x 30 image is read whole): QGIS's exact request computes nothing
    assert band.GetMetadataItem("STATISTICS_MINIMUM") == "10" and band.GetMetadataItem("STATISTICS_MAXIMUM") == "209"
    assert band.GetStatistics(False, True)[:2] == [10.0, 209.0]
    band = ds = None
    assert sorted(os.listdir(tmp_path / "in")) == ["raw.tif"]


def test_display_copies_are_cached_by_image_scene_and_camera(tmp_path):
    (tmp_path / "in").mkdir()
    raw = raster(tmp_path / "in" / "raw.tif")
    cache = tmp_path / "cache"
    first = cached_display_copy(raw, "", "NAD", cache)
    made = first.stat().st_mtime_ns
    assert cached_display_copy(raw, "", "NAD", cache) == first and first.stat().st_mtime_ns == made  # reused
    other = cached_display_copy(raw, "", "FWD", cache)
    assert other != first and other.name.startswith("raw_FWD_") and first.parent == cache
    raster(raw, cols=41)                                                    # the image replaced: a new copy
    os.utime(raw, ns=(made + 10**9, made + 10**9))
    replaced = cached_display_copy(raw, "", "NAD", cache)
    assert replaced != first and gdal.Open(str(replaced)).RasterXSize == 41
    assert sorted(os.listdir(tmp_path / "in")) == ["raw.tif"]


def test_the_raw_image_is_proposed_from_the_scene_folder(tmp_path):
    scene = tmp_path / "scene.json"
    scene.write_text("{}")
    raster(tmp_path / "image_FWD.tif")
    raster(tmp_path / "image_NAD.tif")
    raster(tmp_path / "small.tif", cols=20)
    (tmp_path / "notes.tif").write_text("not a raster")
    write_display_vrt(tmp_path / "image_NAD.tif", tmp_path / "nad.vrt")
    found = raw_image_candidates(scene, 40, 30, "NAD")
    assert found == [tmp_path / "image_NAD.tif", tmp_path / "image_FWD.tif"]   # the camera's first; the copy is NAD
    assert raw_image_candidates(scene, 40, 31, "NAD") == []


def test_scenes_display_copies_and_rasters_open_with_their_raw_image(gcp_block, tmp_path):  # noqa: F811
    nad = gcp_block["result"].members["nad"]
    cache = tmp_path / "cache"
    opened = open_image_source(nad["onboard_scene"], cache)                 # the image found beside the scene
    assert (opened.image, opened.camera_name, opened.scene_path) == (nad["images"]["NAD"], "NAD",
                                                                     str(nad["onboard_scene"]))
    assert opened.display.parent == cache and opened.scene.cameras[0].cols == 500
    again = open_image_source(gcp_block["displays"]["nad"], cache)          # a display copy names all three
    assert (again.image, again.scene_path) == (nad["images"]["NAD"], str(nad["onboard_scene"]))
    with pytest.raises(InputError, match="names no scene file .* give the scene"):
        open_image_source(nad["images"]["NAD"], cache)
    alone = open_image_source(nad["images"]["NAD"], cache, require_scene=False)
    assert alone.scene is None and alone.image == nad["images"]["NAD"]
    with pytest.raises(MetadataError, match="gone.json: no such file"):
        open_image_source(tmp_path / "gone.json", cache)
    with pytest.raises(InputError, match="692 x 692 pixels but camera NAD of the scene delivers 500 x 500"):
        open_image_source(nad["onboard_scene"], cache, image=gcp_block["result"].reference)
    with pytest.raises(InputError, match="onboard_scene.json: camera 'FWD' is not in this scene"):
        open_image_source(nad["onboard_scene"], cache, camera="FWD")


@pytest.mark.parametrize("kind, expected", [
    ("float", ""), ("int16", ""),
    ("byte", "Byte values"), ("int32", "Int32 values"), ("two bands", "2 bands"),
    ("orthoimage", "PUSHBROOM_PRODUCT"), ("raw image", "PUSHBROOM_CAMERA"), ("rpc", "RPC metadata"),
    ("not a raster", "not a raster GDAL reads")])
def test_only_rasters_that_look_like_elevation_can_be_dems(tmp_path, kind, expected):
    path = tmp_path / "r.tif"
    rpc = {k: "1" for k in ("LINE_OFF", "SAMP_OFF", "LAT_OFF", "LONG_OFF", "HEIGHT_OFF", "LINE_SCALE", "SAMP_SCALE",
                            "LAT_SCALE", "LONG_SCALE", "HEIGHT_SCALE")}
    rpc.update({k: " ".join(["1"] + ["0"] * 19) for k in ("LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF",
                                                           "SAMP_DEN_COEFF")})
    made = {"float": lambda: raster(path, data_type=gdal.GDT_Float32),
            "int16": lambda: raster(path, data_type=gdal.GDT_Int16),
            "byte": lambda: raster(path),
            "int32": lambda: raster(path, data_type=gdal.GDT_Int32),
            "two bands": lambda: raster(path, bands=2, data_type=gdal.GDT_Float32),
            "orthoimage": lambda: raster(path, data_type=gdal.GDT_UInt16, metadata={"PUSHBROOM_PRODUCT": "orthoimage"}),
            "raw image": lambda: raster(path, data_type=gdal.GDT_UInt16, metadata={"PUSHBROOM_CAMERA": "NAD"}),
            "rpc": lambda: raster(path, data_type=gdal.GDT_UInt16, metadata=rpc, domain="RPC"),
            "not a raster": lambda: path.write_text("heights?")}
    made[kind]()
    problem = elevation_problem(path)
    assert (problem == "") if not expected else (expected in problem), problem


def test_adjusted_residuals_are_read_back_and_dropped_when_the_point_moves(gcp_block, tmp_path):  # noqa: F811
    editor = PointEditor()
    editor.new_point("G1")
    for k, name in enumerate(NAMES):
        editor.measure(name, "NAD", 100.0 + k, 200.0, (500, 500))
    lon, lat, h = true_ground(gcp_block, "G1")
    editor.set_ground_at(lon, lat, Heights("constant", "ellipsoid", None, h), height_from="the constant")
    assert editor.current().ground.height_from == "the constant" and editor.current().ground.h == h
    table = editor.table()
    table.residuals = Residuals(np.array([0.25, -0.5]), np.array([0.1, 0.2]), np.array([0.27, 0.54]),
                                np.array([1.0, 2.0]), np.array([True, True]))
    write_gpkg(table, tmp_path / "adjusted.gpkg")
    again = PointEditor()
    again.load(read_gpkg(tmp_path / "adjusted.gpkg"), list(NAMES), "adjusted.gpkg")
    point = again.points[0]
    assert [o.residual for o in point.observations] == [(0.25, 0.1), (-0.5, 0.2)]
    assert point.ground.height_from == "adjusted.gpkg"
    again.select(0)
    again.measure(NAMES[0], "NAD", 101.0, 201.0, (500, 500))                # moved: its residual no longer holds
    assert [o.residual for o in again.current().observations] == [None, (-0.5, 0.2)]
    assert again.undo() == "move" and again.current().observations[0].residual == (0.25, 0.1)
    assert isinstance(again.current().ground, Ground)


def test_a_real_rpc_product_opens_by_its_rpc_file_or_its_image(shared_data, tmp_path):
    """The Pleiades Giza pair (tests/data/pleiades_gizeh): img1_RPC.TXT names its image; the image
    with its RPC sidecar is its own scene. Nothing is written beside them."""
    folder = shared_data / "pleiades_gizeh"
    before = sorted(os.listdir(folder))
    by_text = open_image_source(folder / "img1_RPC.TXT", tmp_path)
    by_image = open_image_source(folder / "img1.tif", tmp_path)
    for opened in (by_text, by_image):
        assert opened.image.resolve() == (folder / "img1.tif").resolve() and opened.display.parent == tmp_path
        assert gdal.Open(str(opened.display)).RasterXSize == opened.scene.cameras[0].cols
    assert sorted(os.listdir(folder)) == before
