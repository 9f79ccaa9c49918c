"""core.runs.orthorectify: the use case behind pushbroom:orthorectify, on a rendered cut of a simulated
CBERS-02B scene (tests.support.ortho_compare): the file written and the figures and log it returns agree
with the file; refusals name their input and leave nothing behind."""

import numpy as np
import pytest
from osgeo import gdal
from pyproj import CRS

from pushbroom_adjust.core.log import LogLine
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.runs import orthorectify as use_case
from pushbroom_adjust.core.runs.base import FilesInUse, Terrain
from tests.support.ortho_compare import saved_cut


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    """(scene JSON, raw image, geoid DEM) of a 400-row cut of the true camera."""
    return saved_cut(tmp_path_factory.mktemp("runs_ortho"), seed=3, rows=400)


def request(cut, output, **fields) -> use_case.OrthoRequest:
    scene, image, dem = cut
    return use_case.OrthoRequest(scene, str(output), **{"terrain": Terrain(dem, "geoid"), "image": image, **fields})


def test_one_camera_writes_the_orthoimage_the_figures_describe(cut, tmp_path):
    out = tmp_path / "ortho.tif"
    result = use_case.run(request(cut, out, resolution=10.0))
    assert result.files == {use_case.OUTPUT: str(out)}
    ds = gdal.Open(str(out))
    f = result.figures
    assert (ds.RasterXSize, ds.RasterYSize) == (f["cols"], f["rows"]) and f["resolution_m"] == 10.0
    assert ds.GetGeoTransform()[1] == 10.0 and CRS.from_wkt(ds.GetProjection()).to_string() == f["crs"] == "EPSG:32650"
    assert f["densification_error_px"] < 0.01 and f["dem_gap_pixels"] == 0
    assert all(isinstance(line, LogLine) for line in result.lines)  # what the ui adapter pushes
    texts = [line.text for line in result.lines]
    assert texts[0] == f"orthoimage {f['cols']} x {f['rows']} px at 10.000 m in EPSG:32650"
    assert texts[1].startswith("written in ") and not any(line.warning for line in result.lines)
    band = ds.GetRasterBand(1).ReadAsArray()
    assert abs(np.count_nonzero(band) / f["footprint_pixels"] - 1) < 0.01  # the footprint's pixels, nodata around


def test_an_extent_half_off_the_footprint_is_a_warning_and_one_off_it_a_refusal(cut, tmp_path):
    whole = use_case.run(request(cut, tmp_path / "whole.tif", resolution=10.0)).figures
    ds = gdal.Open(str(tmp_path / "whole.tif"))
    x0, _, _, y0, _, _ = ds.GetGeoTransform()
    x1, y1 = x0 + 10.0 * whole["cols"], y0 - 10.0 * whole["rows"]
    width = x1 - x0
    result = use_case.run(request(cut, tmp_path / "part.tif", resolution=10.0,
                                  extent=lambda crs: (x0 - width, y1, x1, y0)))
    warnings = [line for line in result.lines if line.warning]
    assert len(warnings) == 1 and warnings[0].parameter == use_case.EXTENT
    share = float(warnings[0].text.split(" %")[0])
    assert 50.0 < share < 100.0, warnings[0].text  # at least the added half is outside
    assert result.figures["cols"] == 2 * whole["cols"]
    with pytest.raises(InputError, match="does not overlap the image's footprint") as refused:
        use_case.run(request(cut, tmp_path / "off.tif", extent=lambda crs: (x0 - 3 * width, y1, x0 - 2 * width, y0)))
    assert refused.value.parameter == use_case.EXTENT and not (tmp_path / "off.tif").exists()


def test_refusals_name_their_input_and_write_nothing(cut, tmp_path):
    scene, image, _ = cut
    cases = [(request(cut, tmp_path / "o.png"), use_case.OUTPUT, "written as GeoTIFF"),
             (request(cut, tmp_path / "o.tif", image=""), use_case.IMAGE, "no raw image given"),
             (request(cut, tmp_path / "o.tif", camera="PAN9"), "camera", "PAN9"),
             (request(cut, tmp_path / "o.tif", terrain=Terrain(str(tmp_path / "none.tif"))), "dem", "^DEM: "),
             (request(cut, tmp_path / "o.tif", terrain=Terrain(height=1e6)), None, "HEIGHT: 1e\\+06 m is not a terrain"),
             (request(cut, tmp_path / "o.tif", images=(image, image)), use_case.IMAGES, "2 raw image\\(s\\) given")]
    for req, parameter, message in cases:
        with pytest.raises(InputError, match=message) as refused:
            use_case.run(req)
        assert refused.value.parameter == parameter
    with pytest.raises(InputError, match="o.tif is the file of SCENE"):
        use_case.run(request(cut, scene.replace("cut.json", "o.tif"), files=FilesInUse({"SCENE": [
            scene.replace("cut.json", "o.tif")]})))
    assert list(tmp_path.iterdir()) == []


def test_every_camera_into_a_new_folder(cut, tmp_path):
    _, image, _ = cut
    folder = tmp_path / "orthos"
    result = use_case.run(request(cut, folder, image="", images=(image,), resolution=20.0))
    assert result.files == {use_case.ORTHO_FOLDER: str(folder), use_case.ORTHOIMAGES: [str(folder / "ortho_HRC.tif")]}
    ds = gdal.Open(str(folder / "ortho_HRC.tif"))
    (f,) = result.figures
    assert (ds.RasterXSize, ds.RasterYSize) == (f["cols"], f["rows"])
    assert [line.text.split(":")[0] for line in result.lines[:2]] == ["camera HRC", "ortho_HRC.tif"]
    with pytest.raises(InputError, match="not files") as refused:
        use_case.run(request(cut, tmp_path / "none", images=("",)))
    assert refused.value.parameter == use_case.IMAGES and not (tmp_path / "none").exists()
