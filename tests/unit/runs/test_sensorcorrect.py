"""core.runs.sensorcorrect: the use case behind pushbroom:sensorcorrect, on a rendered 120-row cut of a
simulated CBERS-02B scene (three staggered CCDs): one straight virtual line, an RPC that reproduces the
virtual scene written to hundredths of a pixel, the log it returns; refusals name their input."""
import json
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.rpcfiles import read_rpc_text
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.runs import sensorcorrect as use_case
from pushbroom_adjust.core.runs.base import FilesInUse, Terrain
from tests.support.ortho_compare import saved_cut


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    """(scene JSON, raw image, geoid DEM) of a 120-row cut of the true camera."""
    return saved_cut(tmp_path_factory.mktemp("runs_sensorcorrect"), seed=6, rows=120)


def test_one_virtual_line_with_an_rpc_to_hundredths_of_a_pixel(cut, tmp_path):
    scene_path, image, dem = cut
    out, scene_out = tmp_path / "sc.tif", tmp_path / "sc.json"
    result = use_case.run(use_case.SensorCorrectRequest(scene_path, image, str(out), str(scene_out), Terrain(dem)))
    assert result.files == {use_case.OUTPUT: str(out), use_case.OUTPUT_SCENE: str(scene_out),
                            use_case.RPC: str(tmp_path / "sc_RPC.TXT"), use_case.REPORT: str(tmp_path / "sc_RPC.TXT.json"),
                            use_case.IMAGE_WITH_RPC: str(tmp_path / "sc.vrt")}
    assert len(load_scene(scene_path).cameras[0].chips) == 3
    virtual = load_scene(scene_out)
    cam = virtual.cameras[0]
    assert len(cam.chips) == 1 and virtual.info["sensor_corrected"]["source_image"] == image
    ds = gdal.Open(str(out))
    f = result.figures
    assert (ds.RasterXSize, ds.RasterYSize) == (cam.cols, cam.rows) == (f["cols"], f["rows"])
    assert f["rpc_check_max_px"] < 0.01
    assert json.loads(Path(f["report"]).read_text())["check"]["max_px"] == f["rpc_check_max_px"]
    # the RPC read back from its file against the virtual scene, at the middle of its height range
    rpc = read_rpc_text(Path(f["rpc"])).rpc
    h = float(np.mean(f["height_range"]))
    col, row = (a.ravel() for a in np.meshgrid(np.linspace(0, cam.cols, 7), np.linspace(0, cam.rows, 5)))
    lon, lat, _ = ecef_to_geodetic(virtual.image_to_ground(col, row, h, 0))
    c, r = rpc.ground_to_image(lon, lat, np.full(lon.shape, h))
    assert np.max(np.hypot(c - col, r - row)) < 0.01
    texts = [line.text for line in result.lines]
    assert texts[-2].startswith(f"sensor-corrected image {cam.cols} x {cam.rows} px written in ")
    assert texts[-1] == (f"RPC fitted to the virtual camera over heights {f['height_range'][0]:.0f} to "
                         f"{f['height_range'][1]:.0f} m: independent check RMS {f['rpc_check_rms_px']:.4f} px, "
                         f"max {f['rpc_check_max_px']:.4f} px")


def test_refusals_name_their_input_and_leave_nothing(cut, tmp_path):
    scene_path, image, _ = cut

    def run(**changed):
        fields = {"scene": scene_path, "image": image, "output": str(tmp_path / "sc.tif"),
                  "scene_output": str(tmp_path / "sc.json"), "terrain": Terrain(height=800.0), **changed}
        with pytest.raises(InputError) as refused:
            use_case.run(use_case.SensorCorrectRequest(**fields))
        return refused.value.parameter, str(refused.value)
    parameter, message = run(output=str(tmp_path / "sc.png"))
    assert parameter == use_case.OUTPUT and "written as GeoTIFF" in message
    assert run(image="") == (use_case.IMAGE, "no raw image given")
    parameter, message = run(camera="PAN")
    assert parameter == "camera" and "'PAN' is not in this scene" in message
    parameter, message = run(files=FilesInUse({"INPUT": [image]}), output=image)
    assert message.startswith("OUTPUT: ") and "INPUT" in message
    assert list(tmp_path.iterdir()) == []
