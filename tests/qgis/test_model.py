"""The shipped graphical models (resources/models/*.model3): they load, are valid, appear in the
toolbox and from qgis_process, and run the whole chain — simulate (with the raw image) ->
import GCPs -> adjust -> orthorectify -> export RPC — to an orthoimage that lies on the known
ground texture, and an RPC GDAL reads; the variant without a manual point matches its GCPs
against the simulated reference orthoimage instead of importing them."""
import json
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal
from qgis.core import QgsApplication, QgsProcessingModelAlgorithm

import processing
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.products.rpcfit import fit_rpc
from pushbroom_adjust.core.formats import load_scene
from tests.support.ortho_compare import shift_against_texture


MODEL_FILE = Path(__file__).resolve().parents[2] / "resources" / "models" / "simulate_adjust_orthorectify.model3"
MODEL_ID = "pushbroom:Simulate, adjust, orthorectify and export RPC"
MATCH_MODEL_FILE = MODEL_FILE.with_name("simulate_match_adjust_orthorectify.model3")
MATCH_MODEL_ID = "pushbroom:Simulate, match GCPs, adjust, orthorectify and export RPC"


@pytest.mark.parametrize("path, model_id, gcps", [(MODEL_FILE, MODEL_ID, "pushbroom:importgcps"),
                                                   (MATCH_MODEL_FILE, MATCH_MODEL_ID, "pushbroom:matchgcps")])
def test_the_model_file_is_valid_and_in_the_toolbox(provider, path, model_id, gcps):
    model = QgsProcessingModelAlgorithm()
    assert model.fromFile(str(path))
    ok, problems = model.validate()
    assert ok, problems
    assert [c.algorithmId() for c in sorted(model.childAlgorithms().values(), key=lambda c: c.position().y())] == [
        "pushbroom:simulatescene", gcps, "pushbroom:bundleadjust", "pushbroom:orthorectify",
        "pushbroom:exportrpc"]
    alg = QgsApplication.processingRegistry().algorithmById(model_id)
    assert alg is not None and alg.group() == "Workflows" and "orthorectify" in alg.shortHelpString()


@pytest.fixture(scope="module")
def chain(provider, tmp_path_factory):
    """The model run by processing.run, as the toolbox and Python console run it."""
    out = tmp_path_factory.mktemp("model")
    results = processing.run(MODEL_ID, {
        "SEED": 1, "N_GCPS": 1000, "simulate:Simulation folder": str(out / "sim"),
        "adjust:Adjusted scene": "TEMPORARY_OUTPUT", "adjust:Adjustment report": str(out / "report.html"),
        "ortho:Orthoimage": str(out / "ortho.tif"), "rpc:RPC file": str(out / "image_HRC_RPC.TXT")})
    return results, out


def test_the_model_chain_gives_an_orthoimage_on_the_texture(chain):
    results, out = chain
    assert Path(results["adjust:Adjusted scene"]).is_file() and Path(results["adjust:Adjustment report"]).is_file()
    frame = json.loads((out / "sim" / "simulation.json").read_text())["texture"]
    shift, used = shift_against_texture(results["ortho:Orthoimage"], frame)
    # the onboard model is off by ~150 px; the adjusted one by what 500 noisy GCPs leave
    assert used == 400_000 and np.hypot(*shift) < 0.1, shift


def test_the_model_chain_exports_an_rpc_gdal_uses(chain):
    results, out = chain
    rpc = Path(results["rpc:RPC file"])
    report = json.loads(Path(f"{rpc}.json").read_text())
    # the adjusted CCDs are misaligned, as the true ones: one RPC follows them to ~1 px (per CCD in the report)
    assert report["check"]["rms_px"] < 1.5 and len(report["check"]["chips"]) == 3
    vrt = gdal.Open(str(rpc.with_name("image_HRC.vrt")))  # the raw image with the RPC, beside the RPC file
    assert (vrt.RasterXSize, vrt.RasterYSize) == (12246, 12246)
    # GDAL's RPC transformer on the VRT maps ground points of the adjusted model back into the
    # image as the fitted RPC does, and within the fit's own check error of the rigorous model
    scene = load_scene(results["adjust:Adjusted scene"])
    fitted, _ = fit_rpc(scene, 0, report["height_range"])
    h = float(np.mean(report["height_range"]))
    col, row = (a.ravel() for a in np.meshgrid(np.linspace(500, 11700, 6), np.linspace(500, 11700, 6)))
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground(col, row, np.full(col.size, h)))
    tr = gdal.Transformer(vrt, None, ["METHOD=RPC", f"RPC_HEIGHT={h}"])
    pts = np.array(tr.TransformPoints(1, np.stack([lon, lat, np.zeros_like(lon)], axis=1).tolist())[0])
    fc, fr = fitted.ground_to_image(lon, lat, np.full(lon.size, h))
    assert np.hypot(pts[:, 0] - fc, pts[:, 1] - fr).max() < 1e-3
    err = np.hypot(pts[:, 0] - col, pts[:, 1] - row)
    assert err.max() <= report["check"]["max_px"] + 0.01, err


def test_the_model_runs_from_qgis_process(qgis_process, tmp_path):
    """Outputs not given on the command line reach the steps empty: they are written to temporary
    files (the adjusted scene the later steps need among them)."""
    listing = qgis_process("list")
    assert MODEL_ID in listing.stdout
    done = qgis_process("--json", "run", MODEL_ID, "--", "SEED=2", "N_GCPS=300",
                        f"simulate:Simulation folder={tmp_path / 'sim'}", f"ortho:Orthoimage={tmp_path / 'o.tif'}",
                        f"rpc:RPC file={tmp_path / 'image_HRC_RPC.TXT'}")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    results = json.loads(done.stdout)["results"]
    # a temporary file (removed when qgis_process ends), which orthorectify and exportrpc read
    assert results["adjust:Adjusted scene"].endswith("output_scene.json")
    assert results["ortho:Orthoimage"] == str(tmp_path / "o.tif")
    ds = gdal.Open(str(tmp_path / "o.tif"))
    assert ds.RasterCount == 1 and ds.GetRasterBand(1).GetOverviewCount() > 0
    assert (tmp_path / "image_HRC.vrt").is_file()


def test_the_matching_model_adjusts_without_a_manual_point(provider, tmp_path):
    """Simulate -> matchgcps -> bundleadjust -> orthorectify -> exportrpc: the orthoimage lies on the
    ground texture and the adjusted model on the true one, from matched GCPs alone."""
    from pushbroom_adjust.core.dem import Dem
    results = processing.run(MATCH_MODEL_ID, {
        "SEED": 1, "N_GCPS": 20, "simulate:Simulation folder": str(tmp_path / "sim"),
        "adjust:Adjusted scene": str(tmp_path / "adjusted.json"), "adjust:Adjustment report": "TEMPORARY_OUTPUT",
        "ortho:Orthoimage": str(tmp_path / "ortho.tif"), "rpc:RPC file": str(tmp_path / "image_HRC_RPC.TXT")})
    frame = json.loads((tmp_path / "sim" / "simulation.json").read_text())["texture"]
    shift, used = shift_against_texture(results["ortho:Orthoimage"], frame)
    assert used == 400_000 and np.hypot(*shift) < 0.1, shift
    true, adjusted = load_scene(tmp_path / "sim" / "true_scene.json"), load_scene(tmp_path / "adjusted.json")
    cc, rr = (a.ravel() for a in np.meshgrid(np.linspace(100, 12100, 15), np.linspace(100, 12100, 15)))
    ground = true.image_to_ground_dem(cc, rr, Dem(tmp_path / "sim" / "dem.tif", "geoid"), 0)
    col, row = adjusted.ground_to_image(ground, 0)
    error = np.hypot(col - cc, row - rr)
    assert np.sqrt(np.mean(error ** 2)) <= 0.3, (np.sqrt(np.mean(error ** 2)), error.max())
    assert Path(results["rpc:RPC file"]).is_file() and (tmp_path / "image_HRC.vrt").is_file()
