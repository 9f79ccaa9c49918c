"""The shipped three-line graphical model (resources/models/simulate_match_ties_adjust.model3): it
loads, is valid, and runs simulate (TH-1, rendered, cut to 2000 x 2000 px) -> import the GCPs ->
match tie points between the three cameras -> adjust with TIE_POINTS; the check points intersected
in 3D with the adjusted model lie near the truth, as near as the same observations intersected
with the true model allow."""
import json
from pathlib import Path

import numpy as np
from osgeo import ogr

import processing
from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.adjust.checkpoints import intersection_accuracy
from pushbroom_adjust.core.formats import load_scene

from tests.support.modelcheck import assert_shipped_model

MODEL_FILE = Path(__file__).resolve().parents[2] / "resources" / "models" / "simulate_match_ties_adjust.model3"
MODEL_ID = "pushbroom:Three-line block: simulate, match tie points, adjust"


def test_the_three_line_model_is_valid_and_in_the_toolbox(provider):
    assert_shipped_model(MODEL_FILE, MODEL_ID, ["pushbroom:simulatescene", "pushbroom:importgcps",
                                                "pushbroom:matchtiepoints", "pushbroom:bundleadjust"],
                         "Zhang et al. 2015")


def test_the_three_line_model_adjusts_the_block_to_matched_tie_points(provider, tmp_path):
    out = processing.run(MODEL_ID, {
        "SEED": 3, "N_GCPS": 40, "simulate:Simulation folder": str(tmp_path / "sim"),
        "adjust:Adjusted scene": str(tmp_path / "adjusted.json"), "adjust:Adjustment report": str(tmp_path / "r.html"),
        "adjust:Adjusted tie points": str(tmp_path / "ties.gpkg")})
    rep = json.loads((tmp_path / "r.json").read_text())
    sim = tmp_path / "sim"
    table = G.read_csv(sim / "gcps.csv", G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                       Heights("z", datum="ellipsoid"))
    checks = np.nonzero(table.role == "check")[0]
    n_checks = np.unique(table.id[checks]).size
    # the floor: the same check observations intersected with the true model (their 0.3 px noise only)
    floor = intersection_accuracy(load_scene(sim / "true_scene.json"), table, checks)
    onboard = intersection_accuracy(load_scene(sim / "onboard_scene.json"), table, checks)
    inter = rep["check_points"]["intersection"]
    assert inter["intersected"] == floor["intersected"] == n_checks >= 20
    # measured: plan / height 1.83 / 4.48 m against 1.25 / 3.95 m with the true model, 49.2 / 64.6 m onboard
    assert inter["rmse_plan"] <= 1.5 * floor["rmse_plan"] + 0.5, (inter, floor)
    assert inter["rmse_height"] <= 1.5 * floor["rmse_height"] + 0.5, (inter, floor)
    assert onboard["rmse_plan"] > 20 * inter["rmse_plan"]
    ties = rep["tie_points"]
    assert ties["points"] >= 60 and ties["observations"] >= 2 * ties["points"]
    assert all(r["rmse_col"] < 0.5 for r in ties["residuals_per_camera"].values())
    # the yaw moves the corners by less than one control point's ground sigma (1 m) times sigma0: measured 0.92 m
    assert 0 < rep["datum"]["yaw"]["edge_m"] < rep["sigma0"] * 1.0
    layer = (ds := ogr.Open(out["adjust:Adjusted tie points"])).GetLayer(0)
    assert ds is not None and layer.GetFeatureCount() == ties["observations"] + sum(v["points"] for v in ties.get("left_out", {}).values())
