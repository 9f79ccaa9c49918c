"""core.runs.preparedigitising: the display copy names its scene and camera, the empty line layer is
written beside it, both or neither; a raw image of another camera's size is refused."""
import pytest
from osgeo import gdal

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.runs import preparedigitising as use_case


def test_the_display_copy_and_the_empty_layer(th1, tmp_path):
    out, lines = str(tmp_path / "d.vrt"), str(tmp_path / "l.gpkg")
    result = use_case.run(use_case.PrepareRequest(th1["TRUE_SCENE"], th1["IMAGES"][1], out, lines, "FWD"))
    assert result.files == {"OUTPUT": out, "OUTPUT_LINES": lines} and result.figures == {"camera": "FWD"}
    copy, raw = gdal.Open(out), gdal.Open(th1["IMAGES"][1])
    assert (copy.RasterXSize, copy.RasterYSize) == (raw.RasterXSize, raw.RasterYSize) == (600, 493)
    assert copy.GetRasterBand(1).Checksum() == raw.GetRasterBand(1).Checksum()
    assert th1["TRUE_SCENE"] in open(out).read() and "FWD" in open(out).read()


def test_an_image_of_the_wrong_size_is_refused(th1, tmp_path):
    gdal.Translate(str(tmp_path / "small.tif"), th1["IMAGE"], srcWin=[0, 0, 100, 100])
    with pytest.raises(InputError) as refused:
        use_case.run(use_case.PrepareRequest(th1["TRUE_SCENE"], str(tmp_path / "small.tif"), str(tmp_path / "d.vrt"),
                                             str(tmp_path / "l.gpkg")))
    assert refused.value.parameter == use_case.IMAGE
    assert not (tmp_path / "d.vrt").exists() and not (tmp_path / "l.gpkg").exists()
