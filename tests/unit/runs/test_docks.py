"""What both docks share (core.runs.docks): the heights form's choices as heights and words (never a
guessed DEM: 'dem' without one is the constant, said), and the files a raw image opened reads."""
from pathlib import Path

from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.runs.docks import files_read, form_heights
from pushbroom_adjust.core.measure.sources import ImageSource


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
