"""pushbroom:bundleadjust on RPC scenes (bias compensation, Grodecki & Dial 2003) in real QGIS and
through qgis_process: the WorldView-2 vendor RPB with a known shift and drift added to the GCPs;
the adjusted scene JSON and the refined RPC are read back by the plugin and by GDAL."""
import csv
import json
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal
from qgis.core import QgsProcessingException

import processing
from pushbroom_adjust.core.observations.gcps import write_gpkg
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.formats.rpcfiles import rpc_metadata, write_rpc
from pushbroom_adjust.core.model.rpcscene import RpcScene
from pushbroom_adjust.core.formats import load_scene
from tests.support.rpcdata import worldview2_rpc
from tests.support.processing import field_values, point_layer
from tests.support.qgis_process import run_json
from tests.support.rpc_bias import BIAS, NOISE, biased_gcps


@pytest.fixture(scope="module")
def wv2(provider, shared_data, tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("rpcadj")
    scene_path = write_rpc(worldview2_rpc(shared_data), folder / "wv2.RPB")
    scene = load_scene(scene_path)
    table, _, _ = biased_gcps(scene, BIAS)
    gcps = folder / "gcps.gpkg"
    write_gpkg(table, gcps)
    return {"scene": str(scene_path), "gcps": str(gcps), "folder": folder}


def test_adjusted_scene_and_refined_rpc(wv2, tmp_path):
    out = {k: str(tmp_path / v) for k, v in (("OUTPUT_SCENE", "s.json"), ("OUTPUT_REPORT", "r.html"),
                                              ("OUTPUT_GCPS", "g.gpkg"), ("OUTPUT_RESIDUALS", "v.gpkg"),
                                              ("OUTPUT_RPC", "refined_RPC.TXT"))}
    res = processing.run("pushbroom:bundleadjust", {"SCENE": wv2["scene"], "GCPS": wv2["gcps"],
                                                    "RPC_CORRECTION": "drift", **out})
    report = json.loads(Path(res["OUTPUT_REPORT_JSON"]).read_text())
    values = {p["name"].split(".")[-1]: p for p in report["parameters"]}
    for term, truth in (("a0", BIAS[0, 0]), ("a2", BIAS[0, 2]), ("b0", BIAS[1, 0]), ("b2", BIAS[1, 2])):
        assert abs(values[term]["value"] - truth) < 2 * values[term]["sigma"]
    assert report["check_points"]["image"]["rmse"] < 1.25 * np.sqrt(2) * NOISE
    assert report["trajectory"] is None and Path(out["OUTPUT_REPORT"]).stat().st_size > 1000
    adjusted = load_scene(out["OUTPUT_SCENE"])
    assert isinstance(adjusted, RpcScene) and adjusted.correction[0, 0] == pytest.approx(values["a0"]["value"])
    # the refined RPC, read by GDAL's RPC transformer, is the adjusted scene
    refined = load_scene(out["OUTPUT_RPC"])
    rng = np.random.default_rng(3)
    col, row = rng.uniform(0, adjusted.camera.cols, 500), rng.uniform(0, adjusted.camera.rows, 500)
    lon, lat, h = ecef_to_geodetic(adjusted.image_to_ground(col, row, 600.0))
    ds = gdal.GetDriverByName("MEM").Create("", adjusted.camera.cols, adjusted.camera.rows, 1)
    ds.SetMetadata(rpc_metadata(refined.rpc), "RPC")
    pts = np.array(gdal.Transformer(ds, None, ["METHOD=RPC"]).TransformPoints(1, np.c_[lon, lat, h].tolist())[0])
    assert np.max(np.hypot(pts[:, 0] - col, pts[:, 1] - row)) < 0.01


def test_rpc_options_that_do_not_apply_are_refused(wv2, tmp_path, simulated):
    with pytest.raises(QgsProcessingException, match="INTERIOR: an RPC scene has no interior parameters"):
        processing.run("pushbroom:bundleadjust", {"SCENE": wv2["scene"], "GCPS": wv2["gcps"], "INTERIOR": "x.f",
                                                  "OUTPUT_SCENE": str(tmp_path / "s.json")})
    with pytest.raises(QgsProcessingException, match="OUTPUT_RPC: only for a SCENE given by its RPC"):
        processing.run("pushbroom:bundleadjust", {"SCENE": simulated["ONBOARD_SCENE"], "GCPS": wv2["gcps"],
                                                  "OUTPUT_SCENE": str(tmp_path / "s.json"),
                                                  "OUTPUT_RPC": str(tmp_path / "x_RPC.TXT")})
    assert not list(tmp_path.iterdir())


def test_rpc_bundleadjust_from_the_command_line(qgis_process, wv2, tmp_path):
    res = run_json(qgis_process, "pushbroom:bundleadjust", SCENE=wv2["scene"], GCPS=wv2["gcps"],
                    RPC_CORRECTION="shift", OUTPUT_SCENE=tmp_path / "s.json", OUTPUT_RPC=tmp_path / "r_RPC.TXT")
    adjusted, refined = load_scene(res["OUTPUT_SCENE"]), load_scene(res["OUTPUT_RPC"])
    assert adjusted.correction[0, 0] == pytest.approx(3.2, abs=0.5) and adjusted.correction[0, 2] == 0.0
    xyz = adjusted.image_to_ground([100.0, 20000.0], [50.0, 15000.0], 600.0)
    c, r = adjusted.ground_to_image(xyz)
    c2, r2 = refined.ground_to_image(xyz)
    assert np.max(np.hypot(c2 - c, r2 - r)) < 1e-6  # a shift is folded into the numerators exactly


def test_import_adjust_and_use_the_adjusted_scene(wv2, tmp_path):
    """The user's path: GCPs from a CSV imported against the RPC scene, adjusted, and the adjusted
    scene JSON given to another algorithm (groundtoimage projects the check points to their
    measured image positions, to the noise)."""
    scene = load_scene(wv2["scene"])
    table, _, _ = biased_gcps(scene, BIAS)
    path = tmp_path / "gcps.csv"
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["id", "role", "col", "row", "lon", "lat", "h"])
        writer.writerows(zip(table.id, table.role, table.col, table.row, table.lon, table.lat, table.h))
    gpkg = processing.run("pushbroom:importgcps", {"SCENE": wv2["scene"], "INPUT_FILE": str(path), "Z_FIELD": "h",
                                                   "Z_DATUM": "ellipsoid", "ROLE_FIELD": "role", "SIGMA_PX": NOISE,
                                                   "OUTPUT": str(tmp_path / "gcps.gpkg")})["OUTPUT"]
    adjusted = processing.run("pushbroom:bundleadjust", {"SCENE": wv2["scene"], "GCPS": gpkg,
                                                         "OUTPUT_SCENE": str(tmp_path / "adj.json")})["OUTPUT_SCENE"]
    check = table.role == "check"
    points = point_layer(table.lon[check], table.lat[check], table.h[check], crs="EPSG:4979")
    out = processing.run("pushbroom:groundtoimage", {"SCENE": adjusted, "INPUT": points, "USE_Z": True,
                                                     "Z_DATUM": "ellipsoid", "OUTPUT": "memory:"})["OUTPUT"]
    c, r = field_values(out, "col", "row").T
    err = np.hypot(c - table.col[check], r - table.row[check])
    assert np.sqrt(np.mean(err ** 2)) < 1.25 * np.sqrt(2) * NOISE
