"""The graphical model with control lines (resources/models/adjust_with_lines.model3): it loads,
is valid, and runs import GCPs -> import control lines -> adjust with LINES on simulated
CBERS-02B HRC roads, naming the wrong ones."""
import json
from pathlib import Path

from osgeo import ogr

import processing

from tests.support.modelcheck import assert_shipped_model
from tests.support.control_lines import roads  # noqa: F401 (the fixture)

MODEL_FILE = Path(__file__).resolve().parents[2] / "resources" / "models" / "adjust_with_lines.model3"
MODEL_ID = "pushbroom:Adjust with GCPs and control lines"


def test_the_lines_model_is_valid_and_in_the_toolbox(provider):
    assert_shipped_model(MODEL_FILE, MODEL_ID, ["pushbroom:importgcps", "pushbroom:importlines",
                                                "pushbroom:bundleadjust"], "Tommaselli")


def test_the_lines_model_adjusts_and_names_the_wrong_lines(provider, roads, tmp_path):  # noqa: F811
    result, _ = roads
    out = processing.run(MODEL_ID, {
        "SCENE": str(result.onboard_scene), "GCP_FILE": str(result.gcps),
        "GROUND_LINES": f"{result.lines}|layername=ground_lines", "IMAGE_LINES": f"{result.lines}|layername=image_lines",
        "lines:Control lines": str(tmp_path / "control_lines.gpkg"), "adjust:Adjusted scene": str(tmp_path / "a.json"),
        "adjust:Adjustment report": str(tmp_path / "report.html"),
        "adjust:Line residuals": str(tmp_path / "line_residuals.gpkg")})
    rep = json.loads((tmp_path / "report.json").read_text())
    truth = ogr.Open(str(result.lines))
    wrong = {f.GetField("line_id") for f in truth.GetLayer("ground_lines") if (f.GetField("kind") or "correct")
             != "correct"}
    assert set(rep["lines"]["flagged_line_ids"]) == wrong and rep["check_points"]["ground"]["rmse"] < 5.0
    assert Path(out["adjust:Line residuals"]).is_file()
