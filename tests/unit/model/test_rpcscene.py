"""RPC-only scenes (core.model.rpcscene) from the real vendor RPCs: every source reads to the same model,
ground <-> image against GDAL's RPC transformer and the rigorous Pleiades model, the DEM
intersection, the image-space correction, scene JSON, and bad RPC files.

Measured: Pleiades vendor RFM vs gdal.Transformer(METHOD=RPC) 1e-8 px; vs the rigorous DIMAP model
< 0.001 px; image -> ground -> image 1e-8 px (with an affine correction too); on the DEM 2e-4 px.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import MetadataError
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.formats.rpcfiles import rpc_metadata, write_rpc
from pushbroom_adjust.core.model.rpcscene import RpcScene
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.scene_json import save_scene
from tests.support.rpcdata import PLEIADES, PLEIADES_DEM, pleiades_rpc, rpc_files, scaled, worldview2_rpc

gdal.UseExceptions()


@pytest.fixture(scope="module")
def pleiades(shared_data, tmp_path_factory):
    folder = tmp_path_factory.mktemp("rpc")
    return rpc_files(folder, scaled(pleiades_rpc(shared_data), 16.0))


def _points(scene, n=500, seed=1):
    rng = np.random.default_rng(seed)
    cam = scene.cameras[0]
    lo, hi = scene.height_range
    return rng.uniform(0, cam.cols, n), rng.uniform(0, cam.rows, n), rng.uniform(lo, hi, n)


def _gdal_image_positions(rpc, cols, rows, xyz):
    ds = gdal.GetDriverByName("MEM").Create("", cols, rows, 1)
    ds.SetMetadata(rpc_metadata(rpc), "RPC")
    lon, lat, h = ecef_to_geodetic(xyz)
    pts, _ = gdal.Transformer(ds, None, ["METHOD=RPC"]).TransformPoints(1, np.c_[lon, lat, h].tolist())
    return np.array(pts)[:, :2].T


def test_every_source_reads_the_same_model(pleiades):
    scenes = [load_scene(pleiades[k]) for k in ("txt", "rpb", "tif")]
    assert all(isinstance(s, RpcScene) for s in scenes)
    assert {(s.camera.cols, s.camera.rows) for s in scenes} == {(pleiades["cols"], pleiades["rows"])}
    col, row, h = _points(scenes[0])
    xyz = scenes[0].image_to_ground(col, row, h)
    for s in scenes:
        c, r = s.ground_to_image(xyz)
        assert np.max(np.hypot(c - col, r - row)) < 1e-6


def test_ground_to_image_is_gdals_rpc_transformer(pleiades):
    scene = load_scene(pleiades["tif"])
    col, row, h = _points(scene)
    xyz = scene.image_to_ground(col, row, h)
    c, r = _gdal_image_positions(scene.rpc, scene.camera.cols, scene.camera.rows, xyz)
    assert np.max(np.hypot(c - col, r - row)) < 1e-6


def test_the_vendor_rfm_meets_the_rigorous_pleiades_model(shared_data, tmp_path):
    scene = load_scene(write_rpc(pleiades_rpc(shared_data), tmp_path / "phr_RPC.TXT"))
    assert (scene.camera.cols, scene.camera.rows) == (40000, 38248)
    assert "taken from the RPC" in scene.info["warnings"][0]
    rigorous = load_scene(shared_data / PLEIADES)
    col, row, h = _points(scene)
    xyz = scene.image_to_ground(col, row, h)
    c, r = rigorous.ground_to_image(xyz)
    assert np.max(np.hypot(c - col, r - row)) < 0.005


def test_intersection_with_the_dem_lies_on_it(shared_data, pleiades):
    scene = load_scene(pleiades["txt"])
    dem = Dem(shared_data / PLEIADES_DEM, "ellipsoid")
    col, row, _ = _points(scene)
    xyz = scene.image_to_ground_dem(col, row, dem)
    lon, lat, h = ecef_to_geodetic(xyz)
    assert np.max(np.abs(dem.height(lon, lat) - h)) < 1e-2
    c, r = scene.ground_to_image(xyz)
    assert np.max(np.hypot(c - col, r - row)) < 1e-3


def test_affine_correction_round_trip_and_scene_json(pleiades, tmp_path):
    scene = load_scene(pleiades["txt"])
    col, row, h = _points(scene)
    xyz = scene.image_to_ground(col, row, h)
    scene.correction = np.array([[1.5, 2e-4, -3e-4], [-0.7, 1e-4, 5e-4]])
    c, r = scene.ground_to_image(xyz)
    assert np.allclose(c, col + 1.5 + 2e-4 * col - 3e-4 * row, atol=1e-6)
    assert np.allclose(r, row - 0.7 + 1e-4 * col + 5e-4 * row, atol=1e-6)
    assert np.max(np.abs(scene.image_to_ground(c, r, h) - xyz)) < 1e-4
    save_scene(scene, tmp_path / "s.json")
    again = load_scene(tmp_path / "s.json")
    c2, r2 = again.ground_to_image(xyz)
    assert np.max(np.hypot(c2 - c, r2 - r)) < 1e-9
    assert json.loads((tmp_path / "s.json").read_text())["model"] == "rpc"


def test_worldview2_rpb_with_its_image_size(shared_data, tmp_path):
    files = rpc_files(tmp_path, scaled(worldview2_rpc(shared_data), 32.0), "wv2")
    scene = load_scene(files["rpb"])
    assert (scene.camera.cols, scene.camera.rows) == (1026, 874)  # 32837 / 32, 27968 / 32
    assert scene.height_range == (93.0, 1095.0)


@pytest.mark.parametrize("edit, expected", [
    (lambda t: t.replace("LINE_SCALE:", "LINE_SCALE: 0 pixels\nX:"), "LINE_SCALE"),
    (lambda t: "\n".join(x for x in t.splitlines() if not x.startswith("SAMP_OFF")), "SAMP_OFF is missing"),
    (lambda t: t.replace("LINE_NUM_COEFF_7: ", "LINE_NUM_COEFF_7: x"), "LINE_NUM_COEFF"),
    (lambda t: "\n".join(x for x in t.splitlines() if not x.startswith("SAMP_DEN_COEFF_20")), "holds 19"),
])
def test_bad_rpc_text_is_named(pleiades, tmp_path, edit, expected):
    bad = tmp_path / "bad_RPC.TXT"
    bad.write_text(edit(pleiades["txt"].read_text()))
    with pytest.raises(MetadataError, match=expected):
        load_scene(bad)


def test_a_dimap_rpc_file(shared_data, tmp_path):
    """A Pleiades RPC_*.XML (<Dimap_Document><Rational_Function_Model><Global_RFM>): the vendor RFM
    and, with no DIM_*.XML or image tile beside it, the image size of its validity domain, with a
    warning saying so and where the product was looked for."""
    text = (shared_data / PLEIADES).read_text()
    rfm = text[text.index("<Global_RFM>"):text.index("</Global_RFM>") + len("</Global_RFM>")]
    path = tmp_path / "RPC_PHR1B_P_TEST.XML"
    path.write_text(f"<?xml version='1.0'?><Dimap_Document><Rational_Function_Model>{rfm}</Rational_Function_Model>"
                    "</Dimap_Document>")
    scene = load_scene(path)
    assert isinstance(scene, RpcScene) and (scene.camera.cols, scene.camera.rows) == (40000, 38248)
    (warning,) = scene.info["warnings"]
    assert "40000 x 38248 px is taken from the RFM's direct-model validity domain" in warning
    assert "neither DIM_PHR1B_P_TEST.XML nor a single image tile IMG_PHR1B_P_TEST_R1C1.* was found" in warning
    assert scene.camera.size_source in warning
    text_scene = load_scene(write_rpc(pleiades_rpc(shared_data), tmp_path / "phr_RPC.TXT"))
    col, row, h = _points(scene)
    xyz = scene.image_to_ground(col, row, h)
    c, r = text_scene.ground_to_image(xyz)
    assert np.max(np.hypot(c - col, r - row)) < 1e-6
