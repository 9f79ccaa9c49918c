"""Pleiades DIMAP 2.15 sensor products (core.formats.dimap, the ``Refined_Model`` layout) and the
products' RPC_*.XML as GDAL reads them (core.formats.dimaprfm).

The 2.15 product is the real DIMAP 2.0 product of tests/data/pleiades written under the 2.15 names
(tests/support/vendor_variants.py: element texts copied unchanged), with its Global_RFM as its
RPC_<id>.XML. Measured: the 2.15 reading meets the product's RPC file to 0.0005 px RMS, 0.0013 px max
(the 2.0 reading against its Global_RFM: the same), and is the 2.0 model to 1e-9 m. The real RPC files
of tests/data/pleiades_rpc (CNES shareloc: a DIMAP 2.0 and a DIMAP 2.15 RPC_*.XML) and the derived one
are read as GDAL reads them to 1.5e-11 px.
"""
from __future__ import annotations

import re
import shutil

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.errors import MetadataError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.dimaprfm import read_dimap_rfm
from pushbroom_adjust.core.formats.rpcfiles import rpc_from_metadata
from tests.support.vendor_variants import write_dimap215

gdal.UseExceptions()

XML = "pleiades/PHRDIMAP_P1BP--2018122638935449CP.XML"
PRODUCT_ID = "PHR1B_P_201812261048554_SEN_TEST-001"
REAL_RPC = ("RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML", "RPC_PHR1A_P_202503191043438_SEN_7342362101-1.XML")
MODEL = "Geometric_Data/Refined_Model"


@pytest.fixture(scope="module")
def product(shared_data, tmp_path_factory):
    """(DIM_<id>.XML, RPC_<id>.XML) of the 2.15 product."""
    return write_dimap215(shared_data / XML, tmp_path_factory.mktemp("dimap215"))


@pytest.fixture(scope="module")
def scene(product):
    return load_scene(product[0])


def _grid(scene, n=8):
    cam = scene.cameras[0]
    c, r = np.meshgrid(np.linspace(0.5, cam.cols - 0.5, n), np.linspace(0.5, cam.rows - 0.5, n))
    return c.ravel(), r.ravel()


def test_the_215_product_meets_its_rpc_file(scene, product):
    info = scene.info
    assert info["format"] == "Pleiades DIMAP 2.15 (sensor geometry)" and info["sensor"] == "Pleiades 1B"
    assert info["height_range"] == [490.0, 660.0] and (scene.cameras[0].cols, scene.cameras[0].rows) == (40000, 38248)
    check = info["rpc_check"]
    assert check["rpc"] == str(product[1]) and check["rms_px"] < 0.001 and check["max_px"] < 0.002


def test_the_215_product_is_the_20_model(scene, shared_data):
    original = load_scene(shared_data / XML)
    c, r = _grid(scene)
    for h in (490.0, 660.0):
        assert np.abs(scene.image_to_ground(c, r, h) - original.image_to_ground(c, r, h)).max() < 1e-6
    assert original.info["rpc_check"]["rms_px"] == pytest.approx(scene.info["rpc_check"]["rms_px"], abs=1e-6)


def test_a_line_period_in_microseconds(shared_data, tmp_path, scene):
    dim, _ = write_dimap215(shared_data / XML, tmp_path, line_period=("microsecond", 1000.0))
    c, r = _grid(scene, 4)
    assert np.abs(load_scene(dim).image_to_ground(c, r, 575.0) - scene.image_to_ground(c, r, 575.0)).max() < 1e-6


def test_a_line_period_in_another_unit_is_refused(shared_data, tmp_path):
    dim, _ = write_dimap215(shared_data / XML, tmp_path, line_period=("s", 1e-3))
    with pytest.raises(MetadataError, match=rf"<{MODEL}/Time/Time_Stamp/LINE_PERIOD> is in 's'; expected "
                                            r"milliseconds \(ms\) or microseconds"):
        load_scene(dim)


def _copy(product, tmp_path, edit=lambda t: t, rpc_name=None):
    dim = tmp_path / product[0].name
    dim.write_text(edit(product[0].read_text()))
    if rpc_name:
        shutil.copy(product[1], tmp_path / rpc_name)
    return dim


def test_without_its_rpc_file_the_product_is_refused(product, tmp_path):
    dim = _copy(product, tmp_path)
    with pytest.raises(MetadataError) as err:
        load_scene(dim)
    message = str(err.value)
    assert message.startswith(f"{dim}: no vendor RFM") and f"RPC_{PRODUCT_ID}.XML in {tmp_path}" in message


def test_the_rpc_component_the_document_names_is_used(product, tmp_path):
    dim = _copy(product, tmp_path, lambda t: t.replace(f'href="RPC_{PRODUCT_ID}.XML"', 'href="RPC_other.XML"'),
                rpc_name="RPC_other.XML")
    assert load_scene(dim).info["rpc_check"]["rpc"] == str(tmp_path / "RPC_other.XML")


@pytest.mark.parametrize("edit, message", [
    (lambda t: re.sub(r"<Refined_Model>.*</Refined_Model>", "", t, flags=re.S),
     r"<Geometric_Data/Sensor_Model_Characteristics> \(DIMAP 2.0\) and <Geometric_Data/Refined_Model> "
     r"\(DIMAP 2.15\) are both missing"),
    (lambda t: re.sub(r"<XLOS_0>[^<]*</XLOS_0>", "", t),
     rf"<{MODEL}/Geometric_Calibration/Instrument_Calibration/Polynomial_Look_Angles/XLOS_0> is missing"),
    (lambda t: re.sub(r"<Swath_Range>.*</Swath_Range>", "", t, flags=re.S),
     rf"<{MODEL}/Geometric_Calibration/Instrument_Calibration/Swath_Range> is missing"),
    (lambda t: re.sub(r"<Polynomial_Quaternions>.*</Polynomial_Quaternions>", "", t, flags=re.S),
     rf"<{MODEL}/Attitudes/Polynomial_Quaternions> is missing"),
    (lambda t: re.sub(r"<Point>.*?</Point>", "", t, count=3, flags=re.S), r"holds 7 <Point> samples"),
    (lambda t: re.sub(r"<XLOS_0>[^<]*", "<XLOS_0>-0.8147", t),  # in degrees
     r"Polynomial_Look_Angles/XLOS_\*: look angles -0\.8147 and .* \(radians expected\)"),
])
def test_broken_215_products_are_refused_naming_the_element(product, tmp_path, edit, message):
    dim = _copy(product, tmp_path, edit, rpc_name=product[1].name)
    with pytest.raises(MetadataError, match=message):
        load_scene(dim)


def test_without_last_col_the_swath_ends_with_the_image(product, tmp_path, scene):
    dim = _copy(product, tmp_path, lambda t: re.sub(r"<LAST_COL>[^<]*</LAST_COL>", "", t), rpc_name=product[1].name)
    c, r = _grid(scene, 4)
    assert np.abs(load_scene(dim).image_to_ground(c, r, 575.0) - scene.image_to_ground(c, r, 575.0)).max() < 1e-9


# --- the products' RPC_*.XML as GDAL reads them --------------------------------------------------
def _gdal_rpc(rpc_file, folder):
    """The RPC GDAL reads for a tiny image IMG_<id>_R1C1.tif beside a copy of ``rpc_file`` (its
    Pleiades metadata reader pairs them by name)."""
    copy = folder / rpc_file.name
    if copy != rpc_file:
        shutil.copy(rpc_file, copy)
    tif = folder / f"IMG_{rpc_file.stem[4:]}_R1C1.tif"
    gdal.GetDriverByName("GTiff").Create(str(tif), 4, 4)
    md = gdal.Open(str(tif)).GetMetadata("RPC")
    assert md, "GDAL read no RPC"
    return rpc_from_metadata(md, "GDAL")


def _largest_difference(ours, theirs) -> float:
    """Largest image distance (px) between two RPCs over 2000 points of the first's ground domain."""
    rng = np.random.default_rng(3)
    lon, lat, h = (off + scale * rng.uniform(-1.0, 1.0, 2000) for off, scale in
                   ((ours.lon_off, ours.lon_scale), (ours.lat_off, ours.lat_scale), (ours.height_off, ours.height_scale)))
    (c1, r1), (c2, r2) = ours.ground_to_image(lon, lat, h), theirs.ground_to_image(lon, lat, h)
    return float(np.hypot(c1 - c2, r1 - r2).max())


@pytest.mark.parametrize("name", REAL_RPC + ("derived",))
def test_rpc_files_are_read_as_gdal_reads_them(shared_data, product, tmp_path, name):
    rpc_file = product[1] if name == "derived" else shared_data / "pleiades_rpc" / name
    ours, _ = read_dimap_rfm(rpc_file)
    assert ours.origin == 1.0
    assert _largest_difference(ours, _gdal_rpc(rpc_file, tmp_path)) < 1e-6


def test_dimap3_names_are_read_as_gdal_reads_them(shared_data, tmp_path):
    """DIMAP 3 (Pleiades Neo) names the inverse model GroundtoImage_Values and gives the image origin
    in ImagetoGround_Validity_Domain/FIRST_COL (here 0: the first pixel's centre is 0)."""
    text = (shared_data / "pleiades_rpc" / REAL_RPC[0]).read_text()
    text = text.replace("Inverse_Model>", "GroundtoImage_Values>").replace(
        "<RFM_Validity>", "<RFM_Validity><ImagetoGround_Validity_Domain><FIRST_COL>0</FIRST_COL><FIRST_ROW>0"
                          "</FIRST_ROW></ImagetoGround_Validity_Domain>")
    rpc_file = tmp_path / "RPC_PNEO3_TEST.XML"
    rpc_file.write_text(text)
    ours, _ = read_dimap_rfm(rpc_file)
    assert ours.origin == 0.0
    assert _largest_difference(ours, _gdal_rpc(rpc_file, tmp_path)) < 1e-6


def test_the_direct_model_of_an_rpc_file_meets_its_inverse(shared_data):
    """The direct model's SAMP_* coefficients are the longitude's, LINE_* the latitude's: image points
    through the direct model and back through the inverse, measured 0.0017 px."""
    inverse, direct = read_dimap_rfm(shared_data / "pleiades_rpc" / REAL_RPC[0])
    c, r = np.meshgrid(np.linspace(0.5, 39207.5, 9), np.linspace(0.5, 42247.5, 9))
    for h in (190.0, 1960.0):
        col, row = inverse.ground_to_image(*direct.image_to_ground(c.ravel(), r.ravel(), h), h)
        assert np.hypot(col - c.ravel(), row - r.ravel()).max() < 0.003


def test_an_rpc_file_takes_its_size_from_the_dim_beside_it(product):
    scene = load_scene(product[1])
    assert (scene.camera.cols, scene.camera.rows) == (40000, 38248)
    assert scene.info["warnings"] == [] and scene.camera.size_source == ""


def test_an_rpc_file_takes_its_size_from_its_single_image_tile(shared_data, tmp_path):
    rpc_file = tmp_path / REAL_RPC[0]
    shutil.copy(shared_data / "pleiades_rpc" / REAL_RPC[0], rpc_file)
    gdal.GetDriverByName("GTiff").Create(str(tmp_path / f"IMG_{rpc_file.stem[4:]}_R1C1.tif"), 400, 300)
    scene = load_scene(rpc_file)
    assert (scene.camera.cols, scene.camera.rows) == (400, 300) and scene.info["warnings"] == []


def test_an_rpc_file_alone_says_the_size_it_assumed(shared_data):
    """The real DIMAP 2.15 RPC file of shareloc, alone: its size from the RFM's validity domain."""
    scene = load_scene(shared_data / "pleiades_rpc" / REAL_RPC[1])
    (warning,) = scene.info["warnings"]
    assert (scene.camera.cols, scene.camera.rows) == (33253, 135312)
    assert "33253 x 135312 px is taken from the RFM's direct-model validity domain (LAST_COL, LAST_ROW)" in warning
    assert f"neither DIM_{REAL_RPC[1][4:]} nor a single image tile" in warning
