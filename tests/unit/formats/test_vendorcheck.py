"""Every rigorous vendor product is checked on load against the RPC its vendor ships with it
(core.formats.vendorcheck): the figure is kept and logged below the bound, and a product whose
model misses its own RPC is refused, naming both models and the figure.

Measured on the real products of tests/data (11 x 11 image points x 3 heights, the RPC's height
range), RMS / max px: WorldView-1 0.078 / 0.103, WorldView-2 wv_mvp_1 0.126 / 0.187, wv_mvp_2
0.256 / 0.407, WorldView-3 (RPB refitted by ASP, compared without the corrections) 1.019 / 1.641,
Pleiades 0.0005 / 0.0013. A detector rotation off by one degree: 366 px RMS; the camera turned by
0.05 degree about its axis (a yaw error): 9.8 px RMS.
"""
from __future__ import annotations

import re

import pytest

from pushbroom_adjust.core.errors import MetadataError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.maxar import read_maxar_rpc
from pushbroom_adjust.core.formats.rpcfiles import rpc_rpb
from pushbroom_adjust.core.formats.vendorcheck import GRID, MAX_RMS_PX, REFIT_MAX_RMS_PX
from tests.support.vendor_variants import DETROTANGLE, edited, rotated_camera, set_text

WV1 = "worldview1/WV01_20210201005130_10200100A1865800_21FEB01005130-P1BS-016263048010_01_P001.xml"
# product -> (RMS, max) bounds (px) of its check, a little above the measured figures (module docstring)
PRODUCTS = {WV1: (0.09, 0.12), "worldview2/wv_mvp_1.xml": (0.14, 0.21), "worldview2/wv_mvp_2.xml": (0.28, 0.45),
            "worldview3/1040010074793300.xml": (1.1, 1.8), "pleiades/PHRDIMAP_P1BP--2018122638935449CP.XML": (0.001, 0.002)}


@pytest.mark.parametrize("product", sorted(PRODUCTS))
def test_each_real_product_meets_its_own_rpc(shared_data, caplog, product):
    with caplog.at_level("INFO", logger="pushbroom_adjust.core.formats.vendorcheck"):
        scene = load_scene(shared_data / product)
    check = scene.info["rpc_check"]
    rms, worst = PRODUCTS[product]
    assert check["rms_px"] <= rms and check["max_px"] <= worst
    assert check["points"] == f"{GRID} x {GRID} image points x 3 heights"
    assert check["heights_m"] == scene.info["height_range"]
    refit = product.startswith("worldview3")
    assert check["bound_rms_px"] == (REFIT_MAX_RMS_PX if refit else MAX_RMS_PX)
    assert check["corrections"] == ("off (the model the RPC was fitted to)" if refit else "as read")
    assert check["rpc"] == f"{product.split('/')[1]} ({'its Global_RFM' if 'pleiades' in product else 'its RPB section'})"
    assert [r.getMessage() for r in caplog.records if r.name.endswith(".vendorcheck")] == [check["summary"]]
    assert f"{check['rms_px']:.3f} px RMS, {check['max_px']:.3f} px max" in check["summary"]


def _refused(shared_data, tmp_path, edit) -> str:
    path = tmp_path / "edited.xml"
    path.write_text(edited(shared_data / WV1, edit))
    with pytest.raises(MetadataError) as err:
        load_scene(path)
    return str(err.value)


def _figure(message: str) -> float:
    return float(re.search(r"([0-9.]+) px RMS", message).group(1))


def test_a_detector_rotation_one_degree_off_is_refused(shared_data, tmp_path):
    message = _refused(shared_data, tmp_path, lambda root: set_text(root, DETROTANGLE, "1.0"))
    assert message.startswith(f"{tmp_path / 'edited.xml'}: the rigorous model against edited.xml (its RPB section): ")
    assert 330.0 < _figure(message) < 400.0
    assert "beyond the 1 px RMS the vendor's own RPC meets" in message
    assert message.endswith(f"(assumed: {DETROTANGLE} 1.0 read as degrees (1 deg); IMD/IMAGE/TLCLISTList read as a "
                            "forward scan)")


def test_a_yaw_error_of_the_camera_is_refused(shared_data, tmp_path):
    message = _refused(shared_data, tmp_path, rotated_camera(0.05))
    assert 8.0 < _figure(message) < 12.0 and "edited.xml (its RPB section)" in message


def test_an_rpb_beside_the_xml_is_used(shared_data, tmp_path):
    """Maxar delivers <name>.XML with <name>.RPB: without an RPB section the model is checked against
    the file beside it; another product's RPB there is refused."""
    path = tmp_path / "scene.XML"
    path.write_text(re.sub(r"<RPB>.*</RPB>", "", (shared_data / WV1).read_text(), flags=re.S))
    (tmp_path / "scene.RPB").write_text(rpc_rpb(read_maxar_rpc(shared_data / WV1)))
    scene = load_scene(path)
    assert scene.info["rpc_check"]["rpc"] == str(tmp_path / "scene.RPB") and scene.info["rpc_check"]["rms_px"] < 0.09
    assert scene.info["rpb_origin"] == "Maxar" and "warnings" not in scene.info
    (tmp_path / "scene.RPB").write_text(rpc_rpb(read_maxar_rpc(shared_data / "worldview2/wv_mvp_1.xml")))
    with pytest.raises(MetadataError, match=r"scene\.XML: the rigorous model against .*scene\.RPB: [0-9.]+ px RMS"):
        load_scene(path)


def test_without_an_rpb_the_product_loads_with_a_warning(shared_data, tmp_path):
    path = tmp_path / "scene.xml"
    path.write_text(re.sub(r"<RPB>.*</RPB>", "", (shared_data / WV1).read_text(), flags=re.S))
    scene = load_scene(path)
    (warning,) = scene.info["warnings"]
    assert "no RPB (neither an RPB section nor scene.RPB beside it)" in warning and "could not be checked" in warning
    assert "rpc_check" not in scene.info


def test_a_dimap_product_missing_its_own_rfm_is_refused(shared_data, tmp_path):
    """A cut of the Pleiades product (60 rows less at the top) whose Global_RFM was not moved with it."""
    text = (shared_data / "pleiades/PHRDIMAP_P1BP--2018122638935449CP.XML").read_text()
    text = text.replace("<START>2018-12-26T10:48:55.4490000Z</START>", "<START>2018-12-26T10:48:55.4534100Z</START>")
    path = tmp_path / "cut.XML"
    path.write_text(text)
    with pytest.raises(MetadataError, match=r"cut\.XML: the rigorous model against cut\.XML \(its Global_RFM\): "
                                            r"60\.0\d\d px RMS"):
        load_scene(path)
