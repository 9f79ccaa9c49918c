"""pushbroom:matchgcps through processing.run and qgis_process on a small rendered scene with
known truth (tests/matchscene.py), and the chain matchgcps -> bundleadjust without a manual point."""
import re
from pathlib import Path

import numpy as np
import pytest

import processing
from pushbroom_adjust.core.observations import gcps
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.formats import load_scene
from tests.support.matchscene import SEARCH, mini_scene, true_errors
from tests.support.processing import RecordingFeedback


@pytest.fixture(scope="module")
def mini(provider, tmp_path_factory):
    return mini_scene(tmp_path_factory.mktemp("mini_match"))


def params(mini, output, **kw) -> dict:
    return {"INPUT": str(mini.images["HRC"]), "SCENE": str(mini.onboard_scene), "REFERENCE": str(mini.reference),
            "DEM": str(mini.dem), "DEM_DATUM": "geoid", "SPACING": 60, "SEARCH_RANGE": SEARCH, "OUTPUT": str(output),
            **kw}


def grid_error(mini, adjusted_scene) -> np.ndarray:
    """Adjusted model's error (px) at a 15 x 15 grid of true image points (true ground on the DEM)."""
    true, adjusted = load_scene(mini.true_scene), load_scene(adjusted_scene)
    cam = true.cameras[0]
    cc, rr = np.meshgrid(np.linspace(20, cam.cols - 20, 15), np.linspace(20, cam.rows - 20, 15))
    ground = true.image_to_ground_dem(cc.ravel(), rr.ravel(), Dem(mini.dem, "geoid"), 0)
    col, row = adjusted.ground_to_image(ground, 0)
    return np.hypot(col - cc.ravel(), row - rr.ravel())


def test_matchgcps_then_bundleadjust_without_a_manual_point(mini, tmp_path):
    out = processing.run("pushbroom:matchgcps", params(mini, tmp_path / "matched.gpkg", CHECK_FRACTION=0.2))
    table = gcps.read_gpkg(out["OUTPUT"])
    e = true_errors(mini.folder, table)
    assert len(table) >= 400 and np.median(e) <= 0.1 and np.mean(e > 1) <= 0.03
    assert 0.15 <= np.mean(table.role == "check") <= 0.25
    # the a-priori residuals against the onboard model show its ~200 m error
    assert np.median(table.residuals.m) > 100
    adjusted = processing.run("pushbroom:bundleadjust", {"SCENE": str(mini.onboard_scene), "GCPS": out["OUTPUT"],
                                                          "INTERIOR": "HRC-1.*",
                                                          "OUTPUT_SCENE": str(tmp_path / "adjusted.json")})
    error = grid_error(mini, adjusted["OUTPUT_SCENE"])
    assert np.sqrt(np.mean(error ** 2)) <= 0.3, error.max()


def test_matchgcps_layer_has_quality_fields(mini, tmp_path):
    from osgeo import ogr
    out = processing.run("pushbroom:matchgcps", params(mini, tmp_path / "m.gpkg", N_POINTS=150, WINDOW=41))
    ds = ogr.Open(out["OUTPUT"])
    layer = ds.GetLayer(0)
    names = [layer.GetLayerDefn().GetFieldDefn(i).GetName() for i in range(layer.GetLayerDefn().GetFieldCount())]
    assert {"quality", "peak_ratio", "sigma_px", "res_px"} <= set(names)
    q = np.array([f.GetField("quality") for f in layer])
    assert 80 <= q.size <= 150 and q.min() >= 0.6 and q.max() <= 1.0


def test_matchgcps_through_qgis_process(mini, tmp_path, qgis_process):
    output = tmp_path / "cli.gpkg"
    done = qgis_process("run", "pushbroom:matchgcps", "--",
                        *(f"{k}={v}" for k, v in params(mini, output).items()))
    assert done.returncode == 0, done.stderr + done.stdout
    assert "rejected:" in done.stdout + done.stderr
    assert len(gcps.read_gpkg(output)) >= 400
    assert Path(output).stat().st_size > 0


def test_window_and_fine_radius_reach_the_matcher(mini, tmp_path):
    """WINDOW and FINE_RADIUS given to the algorithm are the matcher's: a larger window or search radius
    keeps the grid further from the image's edges and the CCD seams (measured: 627 grid points, 38 near a
    seam by default (31 px, 8 px); 576 and 54 with FINE_RADIUS 40 or WINDOW 101)."""
    grids, seams = {}, {}
    for name, kw in {"default": {}, "FINE_RADIUS": {"FINE_RADIUS": 40}, "WINDOW": {"WINDOW": 101}}.items():
        log = RecordingFeedback()
        processing.run("pushbroom:matchgcps", params(mini, tmp_path / f"{name}.gpkg", **kw), feedback=log)
        text = "\n".join(log.lines)
        grids[name] = int(re.search(r"matched \d+ of (\d+) grid points", text).group(1))
        seams[name] = int(re.search(r"rejected: (\d+) near a CCD seam", text).group(1))
    for name in ("FINE_RADIUS", "WINDOW"):
        assert grids[name] < grids["default"] and seams[name] > seams["default"], (grids, seams)
