"""RPC files read as scenes (core.formats.rpcfiles): the name of a scene whose RPC file has nothing before
its suffix, and the image size assumed when no image lies beside the RPC, said when it is assumed and
again when an image of another size is then given."""
from __future__ import annotations

import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.rpcfiles import image_name, image_stem, write_rpc
from pushbroom_adjust.core.products.rawimage import open_raw
from tests.support.rpcdata import pleiades_rpc, scaled, write_image


@pytest.mark.parametrize("name, stem, image", [
    ("img_RPC.TXT", "img", "img"), ("img_rpc.txt", "img", "img"), ("img.RPB", "img", "img"),
    ("_RPC.TXT", "", "scene7"), ("_rpc.txt", "", "scene7"),
])
def test_the_image_an_rpc_file_names(tmp_path, name, stem, image):
    path = tmp_path / "scene7" / name
    assert (image_stem(path), image_name(path)) == (stem, image)


def test_an_rpc_text_named_only_by_its_suffix_takes_its_folders_name(shared_data, tmp_path):
    folder = tmp_path / "date2"
    folder.mkdir()
    scene = load_scene(write_rpc(scaled(pleiades_rpc(shared_data), 16.0), folder / "_RPC.TXT"))
    assert scene.camera.name == "date2"


@pytest.fixture
def without_image(shared_data, tmp_path):
    """An RPC text with no image beside it (the image lies in another folder)."""
    folder = tmp_path / "rpc"
    folder.mkdir()
    return load_scene(write_rpc(scaled(pleiades_rpc(shared_data), 16.0), folder / "phr_RPC.TXT"))


def test_the_size_assumed_is_said_with_where_the_image_was_looked_for(without_image, tmp_path):
    camera = without_image.camera
    assert (camera.cols, camera.rows) == (2500, 2390)
    (warning,) = without_image.info["warnings"]
    assert warning == (f"its image's size 2500 x 2390 px is taken from the RPC's sample/line range, as no image was "
                       f"found beside phr_RPC.TXT (looked for phr.tif, .tiff, .ntf, .jp2, .img, .vrt in "
                       f"{tmp_path / 'rpc'}); an image of another size given with this scene is refused: put the "
                       "image beside its RPC file")
    assert camera.size_source in warning


def test_an_image_of_another_size_is_refused_saying_the_size_was_assumed(without_image, tmp_path):
    image = write_image(tmp_path / "elsewhere.tif", 1000, 800)
    with pytest.raises(InputError) as err:
        open_raw(image, without_image.camera)
    message = str(err.value)
    assert message.startswith(f"{image}: the raster is 1000 x 800 px but camera phr of the scene images 2500 x 2390 px "
                              "(the scene's size 2500 x 2390 px was assumed: taken from the RPC's sample/line range, "
                              "as no image was found beside phr_RPC.TXT (looked for phr.tif")
    assert message.endswith("is it the scene's image?")


def test_with_its_image_beside_it_the_size_is_the_images(shared_data, tmp_path):
    rpc = scaled(pleiades_rpc(shared_data), 16.0)
    write_image(tmp_path / "phr.tif", 2400, 2300)
    scene = load_scene(write_rpc(rpc, tmp_path / "phr_RPC.TXT"))
    assert (scene.camera.cols, scene.camera.rows) == (2400, 2300)
    assert scene.info["warnings"] == [] and scene.camera.size_source == ""
    with pytest.raises(InputError, match=r"camera phr of the scene images 2400 x 2300 px: is it"):
        open_raw(write_image(tmp_path / "other.tif", 100, 100), scene.camera)
