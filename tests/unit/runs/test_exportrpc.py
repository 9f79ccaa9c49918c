"""core.runs.exportrpc: the use case behind pushbroom:exportrpc, on a rendered cut of a simulated
CBERS-02B scene (tests.support.ortho_compare): the RPC file written reproduces the rigorous model within
the check figures it returns, the VRT carries it, refusals name their input and leave nothing behind."""
import json
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import Cancelled, InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.rpcfiles import read_rpc_text
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.products.rpcfit import dem_height_range
from pushbroom_adjust.core.runs import exportrpc as use_case
from pushbroom_adjust.core.runs.base import FilesInUse, Terrain
from tests.support.ortho_compare import saved_cut


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    """(scene JSON, raw image, geoid DEM) of a 400-row cut of the true camera."""
    return saved_cut(tmp_path_factory.mktemp("runs_exportrpc"), seed=3, rows=400)


def test_the_rpc_written_reproduces_the_rigorous_model(cut, tmp_path):
    scene_path, image, _ = cut
    out = tmp_path / "raw_RPC.TXT"
    result = use_case.run(use_case.RpcRequest(scene_path, str(out), Terrain(height=600.0), height_span=300.0,
                                              image=image))
    vrt = tmp_path / "raw.vrt"
    assert result.files == {use_case.OUTPUT: str(out), use_case.REPORT: f"{out}.json",
                            use_case.IMAGE_WITH_RPC: str(vrt)}
    report = json.loads(Path(f"{out}.json").read_text())
    assert report["height_range"] == [300.0, 900.0] and report["scene"] == scene_path and report["image"] == image
    assert result.figures["rms_px"] == report["check"]["rms_px"] < result.figures["max_px"]
    # the RPC as read back from its file against the rigorous model, at the ends and the middle of the heights
    scene, rpc = load_scene(scene_path), read_rpc_text(out).rpc
    cam = scene.cameras[0]
    col, row = (a.ravel() for a in np.meshgrid(np.linspace(0, cam.cols, 9), np.linspace(0, cam.rows, 9)))
    errors = []
    for h in (300.0, 600.0, 900.0):
        lon, lat, _ = ecef_to_geodetic(scene.image_to_ground(col, row, h, 0))
        c, r = rpc.ground_to_image(lon, lat, np.full(lon.shape, h))
        errors.append(np.hypot(c - col, r - row))
    assert np.max(errors) < 2 * result.figures["max_px"] + 1e-3
    assert gdal.Open(str(vrt)).GetMetadata("RPC")["LINE_OFF"].split()[0] == repr(float(rpc.line_off))
    texts = [line.text for line in result.lines]
    assert texts[0].startswith("camera ") and "heights 300 to 900 m (ellipsoidal)" in texts[0]
    assert texts[1] == (f"check on {report['check']['points']} independent points: RMS "
                        f"{report['check']['rms_px']:.4f} px, max {report['check']['max_px']:.4f} px")
    assert texts[-1] == f"RPC written to {out} (report {out}.json); image with RPC: {vrt}"


def test_with_a_dem_the_heights_are_the_dem_s_over_the_image(cut, tmp_path):
    scene_path, _, dem = cut
    out = tmp_path / "cut.RPB"
    result = use_case.run(use_case.RpcRequest(scene_path, str(out), Terrain(dem), grid=11, levels=5))
    expected = dem_height_range(load_scene(scene_path), Dem(dem, "geoid"), 0)
    assert result.figures["report"]["height_range"] == pytest.approx(list(expected))
    assert result.files[use_case.IMAGE_WITH_RPC] is None and 'SpecId = "RPC00B";' in out.read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.RPB", "cut.RPB.json"]


def test_refusals_name_their_input_and_leave_nothing(cut, tmp_path):
    scene_path, image, _ = cut
    with pytest.raises(InputError, match=r"must end in _RPC.TXT") as refused:
        use_case.run(use_case.RpcRequest(scene_path, str(tmp_path / "x.json")))
    assert refused.value.parameter == use_case.OUTPUT
    with pytest.raises(InputError, match=r"camera 'PAN' is not in this scene") as refused:
        use_case.run(use_case.RpcRequest(scene_path, str(tmp_path / "x_RPC.TXT"), camera="PAN"))
    assert refused.value.parameter == "camera"
    small = tmp_path / "small.tif"
    gdal.GetDriverByName("GTiff").Create(str(small), 10, 10, 1, gdal.GDT_Byte)
    with pytest.raises(InputError, match=r"not this camera's image") as refused:
        use_case.run(use_case.RpcRequest(scene_path, str(tmp_path / "x_RPC.TXT"), image=str(small), grid=5, levels=4))
    assert refused.value.parameter == use_case.IMAGE
    with pytest.raises(InputError, match=r"it would be replaced") as refused:
        use_case.run(use_case.RpcRequest(scene_path, str(tmp_path / "x_RPC.TXT"),
                                         files=FilesInUse({"SCENE": [str(tmp_path / "x_RPC.TXT.json")]})))
    with pytest.raises(Cancelled):
        use_case.run(use_case.RpcRequest(scene_path, str(tmp_path / "x_RPC.TXT")), is_cancelled=lambda: True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["small.tif"]
    # a name GDAL will not find by itself is written, with a warning
    result = use_case.run(use_case.RpcRequest(scene_path, str(tmp_path / "x.txt"), grid=5, levels=4))
    assert result.lines[0] == ("x.txt does not end in _RPC.TXT: GDAL will not find it beside an image by itself",
                               True, None)


def test_the_sensor_corrected_hint_only_for_a_poor_fit_at_the_seams():
    """The hint needs several chips and a seam maximum over 0.1 px; a good fit or one chip gets none."""
    def report(chips, seam_max):
        seams = {"rms_px": seam_max / 2, "max_px": seam_max} if seam_max is not None else None
        return {"camera": "HRC", "check": {"chips": [{}] * chips, **({"seams": seams} if seams else {})}}
    assert "up to 1.70 px at the CCD seams (RMS 0.85 px)" in use_case.sensor_corrected_hint(report(3, 1.7))
    assert "pushbroom:sensorcorrect" in use_case.sensor_corrected_hint(report(3, 0.11))
    assert use_case.sensor_corrected_hint(report(3, 0.09)) is None
    assert use_case.sensor_corrected_hint(report(1, None)) is None
