"""Vendor products through the algorithms as a user runs them: GeoEye-1 products (detector rotation in
radians, reverse scan) and a Pleiades DIMAP 2.15 sensor product give the footprint of the product they
derive from, and say how well they meet their own RPC; a product with a wrong angle is refused with
the figure; RPC files named by their suffix alone, and RPC scenes whose image is not beside them, are
named and explained. The products are derived in the tests from tests/data (tests/support/vendor_variants.py).
"""
from __future__ import annotations

import pytest

import processing
from pushbroom_adjust.ui.inputs import block_scene_names
from pushbroom_adjust.core.formats.rpcfiles import write_rpc
from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.processing import RecordingFeedback
from tests.support.rpcdata import pleiades_rpc, scaled, write_image
from tests.support.vendor_variants import DETROTANGLE, edited, geoeye_like, reverse_scan, set_text, write_dimap215

WV1 = "worldview1/WV01_20210201005130_10200100A1865800_21FEB01005130-P1BS-016263048010_01_P001.xml"
PLEIADES = "pleiades/PHRDIMAP_P1BP--2018122638935449CP.XML"


def _geoeye(shared_data, folder, name, *more):
    def edit(root):
        geoeye_like(root)
        for e in more:
            e(root)
    path = folder / name
    path.write_text(edited(shared_data / WV1, edit))
    return path


def _footprint(scene, height, feedback=None):
    out = processing.run("pushbroom:footprint", {"SCENE": str(scene), "HEIGHT": height, "OUTPUT": "memory:"},
                         feedback=feedback)["OUTPUT"]
    (feature,) = out.getFeatures()
    return feature


def test_geoeye_reverse_scan_footprint_is_the_worldview1_products(provider, shared_data, tmp_path):
    reverse = _geoeye(shared_data, tmp_path, "ge01_reverse.xml", reverse_scan)
    feedback = RecordingFeedback()
    fp = _footprint(reverse, 3443.0, feedback)
    ref = _footprint(shared_data / WV1, 3443.0)
    assert fp["area_km2"] == pytest.approx(ref["area_km2"], rel=1e-6) and (fp["cols"], fp["rows"]) == (35180, 24344)
    assert fp.geometry().symDifference(ref.geometry()).area() < 1e-9 * ref.geometry().area()
    (check,) = [i for i in feedback.infos if "against ge01_reverse.xml (its RPB section)" in i]
    assert check.startswith(f"SCENE: {reverse}: the rigorous model") and "0.078 px RMS" in check


def test_dimap215_footprint_is_the_dimap20_products(provider, shared_data, tmp_path):
    dim, rpc = write_dimap215(shared_data / PLEIADES, tmp_path)
    feedback = RecordingFeedback()
    fp = _footprint(dim, 575.0, feedback)
    ref = _footprint(shared_data / PLEIADES, 575.0)
    assert fp["area_km2"] == pytest.approx(ref["area_km2"], rel=1e-9)
    assert any(f"against {rpc}: 0.001 px RMS" in i for i in feedback.infos)


def test_a_wrong_detector_rotation_is_refused(provider, shared_data, tmp_path):
    path = _geoeye(shared_data, tmp_path, "ge01_off.xml", lambda root: set_text(root, DETROTANGLE, "3.1590459"))
    assert_refused("pushbroom:footprint", {"SCENE": str(path), "HEIGHT": 3443.0, "OUTPUT": str(tmp_path / "f.gpkg")},
                   "SCENE:", "ge01_off.xml: the rigorous model against ge01_off.xml (its RPB section)", "px RMS",
                   "beyond the 1 px RMS", "DETROTANGLE 3.1590459 read as radians (181 deg)", watch=[tmp_path])


def test_geoeye_radians_product_on_the_command_line(qgis_process, shared_data, tmp_path):
    good = _geoeye(shared_data, tmp_path, "ge01.xml")
    done = qgis_process("run", "pushbroom:footprint", "--", f"SCENE={good}", "HEIGHT=3443",
                        f"OUTPUT={tmp_path / 'ge01.gpkg'}")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "against ge01.xml (its RPB section): 0.078 px RMS" in done.stdout + done.stderr
    bad = tmp_path / "wv1_off.xml"
    bad.write_text(edited(shared_data / WV1, lambda root: set_text(root, DETROTANGLE, "1.0")))
    assert_refused_cli(qgis_process, "pushbroom:footprint", {"SCENE": bad, "HEIGHT": 3443, "OUTPUT": tmp_path / "w.gpkg"},
                       "wv1_off.xml: the rigorous model against wv1_off.xml (its RPB section)",
                       "DETROTANGLE 1.0 read as degrees", watch=[bad])


def test_rpc_files_named_by_their_suffix_take_their_folders_names(provider, shared_data, tmp_path):
    rpc = scaled(pleiades_rpc(shared_data), 16.0)
    paths = []
    for name in ("date1", "date2"):
        (tmp_path / name).mkdir()
        paths.append(write_rpc(rpc, tmp_path / name / "_RPC.TXT"))
    assert block_scene_names(paths) == ["date1", "date2"]


def test_an_rpc_scene_without_its_image_says_the_size_it_assumed(provider, shared_data, tmp_path):
    """The RPC text alone, its image given from another folder: the refusal says which size was assumed
    and where the image was looked for."""
    (tmp_path / "rpc").mkdir()
    txt = write_rpc(scaled(pleiades_rpc(shared_data), 16.0), tmp_path / "rpc" / "phr_RPC.TXT")
    image = write_image(tmp_path / "phr_image.tif", 1250, 1195)
    assert_refused("pushbroom:orthorectify", {"INPUT": str(image), "SCENE": str(txt), "HEIGHT": 575.0,
                                              "RESOLUTION": 50.0, "OUTPUT": str(tmp_path / "o.tif")},
                   "phr_image.tif", "1250 x 1195", "the scene's size 2500 x 2390 px was assumed",
                   "taken from the RPC's sample/line range", f"looked for phr.tif, .tiff, .ntf, .jp2, .img, .vrt in "
                   f"{tmp_path / 'rpc'}", watch=[tmp_path])
