"""What both docks share (core.runs.docks): the heights form's choices as heights and words (never a
guessed DEM: 'dem' without one is the constant, said), the files a raw image opened reads, the square a
zoom frames, and what the scene dialog proposes (on the rendered block of tests/support/gcpblock.py)."""
import shutil
from pathlib import Path

from pushbroom_adjust.core.measure.sources import ImageSource
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.runs.docks import (LINE_MARGIN_PX, files_read, form_heights, frame, proposed_image,
                                              scene_cameras)
from tests.support.gcpblock import gcp_block  # noqa: F401 (the fixture)


def test_the_form_heights_and_their_words():
    assert form_heights("dem", "geoid", 12.0, None, "", "the lines' Z") == (
        Heights("constant", "geoid", None, 12.0), "the constant 12.0 m (geoid), no DEM chosen")
    assert form_heights("dem", "ellipsoid", 0.0, "/d/dem.tif", "srtm", "z") == (
        Heights("dem", "ellipsoid", "/d/dem.tif", 0.0), "the DEM srtm")
    assert form_heights("z", "geoid", 3.0, None, "", "the reference point's Z")[1] == "the reference point's Z"
    assert form_heights("constant", "ellipsoid", -20.25, "/d/dem.tif", "srtm", "z") == (
        Heights("constant", "ellipsoid", "/d/dem.tif", -20.25), "the constant -20.2 m (ellipsoid)")


def test_the_files_a_raw_image_reads():
    source = ImageSource("/s/scene.json", None, 0, "NAD", Path("/s/raw.tif"), Path("/cache/abc.vrt"))
    assert files_read("nad/NAD", "/s/scene.json", source) == {
        "nad/NAD (scene file)": ["/s/scene.json"], "nad/NAD (display copy)": ["/cache/abc.vrt"],
        "nad/NAD (raw image)": ["/s/raw.tif"]}
    opened_copy = files_read("nad/NAD", "/mine/display.vrt", source)
    assert opened_copy["nad/NAD (display copy)"] == ["/cache/abc.vrt", "/mine/display.vrt"]


def test_the_square_a_zoom_frames():
    """A line from (100, 50) to (160, 70) px: centred at (130, 60), half its longer side (30) plus the margin."""
    assert frame([(100.0, 50.0), (160.0, 70.0), (120.0, 55.0)], 20.0) == (130.0, 60.0, 50.0)
    assert frame([(100.0, 50.0), (100.0, 90.0)]) == (100.0, 70.0, 20.0 + LINE_MARGIN_PX)


def test_the_scene_dialog_proposes_the_raw_image_of_the_camera(gcp_block, tmp_path):  # noqa: F811
    """The block's nad scene file names its raw image beside it (500 x 500 px): proposed; a copy of the
    scene file alone in a folder: none, and the note says what to choose; a file that is no scene: said."""
    member = gcp_block["result"].members["nad"]
    scene, cameras, note = scene_cameras(str(member["onboard_scene"]))
    assert cameras == ["NAD"] and note.endswith(": 1 camera(s)")
    assert proposed_image(scene, str(member["onboard_scene"]), "NAD") == (str(member["images"]["NAD"]), "")
    alone = tmp_path / "scene.json"
    shutil.copy(member["onboard_scene"], alone)
    assert proposed_image(scene, str(alone), "NAD") == (
        "", "No raster of 500 x 500 px (camera NAD) beside the scene: choose its raw image")
    (tmp_path / "notes.json").write_text("not a scene")
    assert scene_cameras(str(tmp_path / "notes.json"))[:2] == (None, [])
