"""GeoEye-1 products (Maxar isd XML, core.formats.maxar) as they write what WorldView products do not:
the detector rotation in radians, and a reverse scan (line times decreasing with the line).

The products are the WorldView-1 product of tests/data written as GeoEye-1 writes its focal plane,
and with its image rows flipped (tests/support/vendor_variants.py; the derivation is in
tests/data/README.md). Both keep the model exactly, so each must meet its own (rewritten) RPB as the
original does: measured 0.078 px RMS, 0.103 px max for both (the issue's real GeoEye-1 products:
0.028 px forward, 0.134 px reverse). Read in degrees, the radians product's model is 41,605 px RMS off
its RPB and refused (the issue's real product: 10,577 px, accepted before the check).
"""
from __future__ import annotations

import numpy as np
import pytest

from pushbroom_adjust.core.errors import MetadataError
from pushbroom_adjust.core.formats import load_scene, maxar
from pushbroom_adjust.core.formats.scene_json import save_scene
from pushbroom_adjust.core.products.sensorcorrect import virtual_camera
from tests.support.vendor_variants import DETROTANGLE, edited, geoeye_like, reverse_scan, set_text

WV1 = "worldview1/WV01_20210201005130_10200100A1865800_21FEB01005130-P1BS-016263048010_01_P001.xml"
ROWS = 24344


def _write(shared_data, folder, name, *edits) -> object:
    def edit(root):
        for e in edits:
            e(root)
    path = folder / name
    path.write_text(edited(shared_data / WV1, edit))
    return path


@pytest.fixture(scope="module")
def products(shared_data, tmp_path_factory):
    """{name: path} of the WorldView-1 product and its GeoEye-like variants."""
    folder = tmp_path_factory.mktemp("geoeye")
    return {"wv1": shared_data / WV1, "forward": _write(shared_data, folder, "ge01.xml", geoeye_like),
            "reverse": _write(shared_data, folder, "ge01_reverse.xml", geoeye_like, reverse_scan)}


def _grid(n=9):
    c, r = np.meshgrid(np.linspace(0.5, 35179.5, n), np.linspace(0.5, ROWS - 0.5, n))
    return c.ravel(), r.ravel()


def test_radians_product_meets_its_rpb(products, caplog):
    with caplog.at_level("INFO", logger="pushbroom_adjust.core.formats.maxar"):
        scene = load_scene(products["forward"])
    rotation = scene.info["detector_rotation"]
    assert (rotation["value"], rotation["unit"], rotation["radians"]) == (np.pi, "radians", np.pi)
    assert f"{DETROTANGLE} 3.141592653589793 read as radians (180 deg)" in caplog.text
    assert scene.info["sensor"] == "GE01" and "warnings" not in scene.info
    check = scene.info["rpc_check"]
    assert check["rms_px"] < 0.09 and check["max_px"] < 0.12  # measured 0.078 / 0.103


def test_radians_product_is_the_worldview1_model(products):
    c, r = _grid()
    ge, wv = load_scene(products["forward"]), load_scene(products["wv1"])
    assert np.abs(ge.image_to_ground(c, r, 3443.0) - wv.image_to_ground(c, r, 3443.0)).max() < 1e-6


def test_read_in_degrees_the_radians_product_is_refused(products, monkeypatch):
    """What the reader did before: the check refuses it, naming the figure and the reading."""
    def in_degrees(value, where):
        return {"value": value, "unit": "degrees", "radians": float(np.radians(value)),
                "read_as": f"{where} {value!r} read as degrees"}
    monkeypatch.setattr(maxar, "detector_rotation", in_degrees)
    with pytest.raises(MetadataError, match=r"ge01\.xml: the rigorous model against ge01\.xml \(its RPB section\): "
                                            r"4\d{4}\.\d{3} px RMS") as err:
        load_scene(products["forward"])
    assert "3.141592653589793 read as degrees" in str(err.value)


@pytest.mark.parametrize("value, unit", [("180", "degrees"), ("-180.0", "degrees"), ("3.14159", "radians"),
                                         ("-3.141592653589793", "radians")])
def test_either_unit_of_the_same_rotation_gives_the_same_model(shared_data, tmp_path, value, unit):
    """Measured 0.078 px RMS; 0.093 px with 3.14159 (2.7 urad from pi)."""
    path = _write(shared_data, tmp_path, "x.xml", geoeye_like, lambda root: set_text(root, DETROTANGLE, value))
    scene = load_scene(path)
    assert scene.info["detector_rotation"]["unit"] == unit and scene.info["rpc_check"]["rms_px"] < 0.1


def test_reverse_scan_meets_its_rewritten_rpb(products):
    scene = load_scene(products["reverse"])
    assert scene.info["scan_direction"] == "Reverse" and "warnings" not in scene.info
    timing = scene.cameras[0].timing
    assert timing.reverse and timing.mean_period() == pytest.approx(-1 / 24000.0, rel=1e-6)
    check = scene.info["rpc_check"]
    assert check["rms_px"] < 0.09 and check["max_px"] < 0.12  # measured 0.078 / 0.103


def test_reverse_scan_sees_the_flipped_rows(products):
    """Row r of the reversed product is row N - r of the original, on the same ground."""
    c, r = _grid()
    reverse, forward = load_scene(products["reverse"]), load_scene(products["forward"])
    assert np.abs(reverse.image_to_ground(c, ROWS - r, 3443.0) - forward.image_to_ground(c, r, 3443.0)).max() < 1e-4
    col, row = reverse.ground_to_image(forward.image_to_ground(c, r, 3000.0))
    assert np.abs(col - c).max() < 1e-4 and np.abs(row - (ROWS - r)).max() < 1e-4


def test_reverse_scan_round_trips_through_scene_json(products, tmp_path):
    scene = load_scene(products["reverse"])
    save_scene(scene, tmp_path / "reverse.json")
    back = load_scene(tmp_path / "reverse.json")
    c, r = _grid(5)
    assert back.cameras[0].timing.reverse
    assert np.abs(back.image_to_ground(c, r, 3443.0) - scene.image_to_ground(c, r, 3443.0)).max() < 1e-6


def test_one_timing_entry_follows_the_scan_direction(products, tmp_path):
    """With one TLCLIST entry the timing is completed with AVGLINERATE (24000 lines/s) in the direction
    SCANDIRECTION gives: the same model as the two-entry table (whose rate is 24000.008 lines/s: 3.5 mm
    apart at the far end)."""
    text = products["reverse"].read_text()
    first, rest = text.split("<TLCLIST>", 1)
    single = first + "<TLCLIST>" + rest.split("</TLCLIST>", 1)[1].split("<TLCLIST>", 1)[1]
    single = single.replace("<NUMTLC>2</NUMTLC>", "<NUMTLC>1</NUMTLC>")
    path = tmp_path / "single.xml"
    path.write_text(single)
    one, two = load_scene(path), load_scene(products["reverse"])
    assert one.cameras[0].timing.lines.size == 2 and one.cameras[0].timing.reverse
    c, r = _grid(5)
    assert np.abs(one.image_to_ground(c, r, 3443.0) - two.image_to_ground(c, r, 3443.0)).max() < 0.005


def test_a_scan_direction_the_table_contradicts_is_warned(products, tmp_path):
    path = tmp_path / "contradiction.xml"
    path.write_text(products["reverse"].read_text().replace("<SCANDIRECTION>Reverse<", "<SCANDIRECTION>Forward<"))
    scene = load_scene(path)
    (warning,) = scene.info["warnings"]
    assert "IMD/IMAGE/SCANDIRECTION is 'Forward' but the line times of IMD/IMAGE/TLCLISTList decrease" in warning
    assert scene.info["scan_direction"] == "Reverse" and scene.info["rpc_check"]["rms_px"] < 0.09


def test_a_timing_table_not_monotonic_is_refused(products, tmp_path):
    text = products["forward"].read_text()
    path = tmp_path / "zigzag.xml"
    path.write_text(text.replace("<NUMTLC>2</NUMTLC>", "<NUMTLC>3</NUMTLC>").replace(
        "</TLCLISTList>", "<TLCLIST>30000.0 0.5</TLCLIST></TLCLISTList>"))
    with pytest.raises(MetadataError, match=r"zigzag\.xml: IMD/IMAGE/TLCLISTList: line timing table needs .* "
                                            r"strictly decreasing: a reverse scan"):
        load_scene(path)


def test_the_virtual_camera_of_a_reverse_scan_keeps_its_times(products):
    """pushbroom:sensorcorrect's straight virtual array of a reverse-scan camera: the same first and last
    row times, decreasing."""
    camera = load_scene(products["reverse"]).cameras[0]
    virtual = virtual_camera(camera)
    rows = np.array([0.5, ROWS / 2.0, ROWS - 0.5])
    assert virtual.timing.reverse
    np.testing.assert_allclose(virtual.timing.time(rows), camera.timing.time(rows), atol=1e-9)
