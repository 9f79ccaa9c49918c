"""Adjustment reports: JSON that parses back, one HTML page with the figures and plots."""
import base64
import json
import re

import numpy as np
import pytest

from core import gcps as G
from core.adjust import AdjustmentSettings, adjust
from core.adjust.report import report_to_json, write_report_html, write_report_json
from core.scene_io import load_scene
from core.simulator import GcpSettings, simulate


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    sim = simulate("cbers02b_hrc", tmp_path_factory.mktemp("sim"), seed=6,
                   gcp_settings=GcpSettings(n_gcps=600, image_noise=0.5, check_fraction=0.5, gross_fraction=0.05))
    table = G.read_csv(sim.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                       G.Heights("z", datum="ellipsoid"), sigma_px=0.5, sigma_xy=0.01, sigma_z=0.01)
    # all three chips: the middle one's terms are not determinable and get fixed
    return adjust(load_scene(sim.onboard_scene), table, AdjustmentSettings(interior="HRC-1.*, HRC-2.*, HRC-3.*"))


def test_json_parses_back_with_nan_as_null(result, tmp_path):
    path = tmp_path / "report.json"
    write_report_json({**result.report, "extra": [np.nan, np.float32(1.5), np.int64(3)]}, path)
    back = json.loads(path.read_text())
    assert back["sigma0"] == result.report["sigma0"] and back["extra"] == [None, 1.5, 3]
    assert back["parameters"][0]["name"] == result.report["parameters"][0]["name"]
    assert "NaN" not in report_to_json(result.report)


def test_html_holds_the_figures_decisions_and_three_plots(result, tmp_path):
    path = tmp_path / "report.html"
    write_report_html(result.report, result.points, path, title="CBERS <script>alert(1)</script>")
    text = path.read_text()
    assert "<script>" not in text and "&lt;script&gt;" in text
    images = re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", text)
    assert len(images) == 3
    assert base64.b64decode(images[0])[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"sigma0 = {result.report['sigma0']:.3f}" in text
    assert format(result.report["check_points"]["image"]["rmse_col"], ".3f") in text
    assert "HRC-2.dx</b> was fixed" in text
    assert f"{result.report['robust']['flagged']} image observations flagged" in text


def test_an_unwritable_report_leaves_nothing(result, tmp_path):
    missing = tmp_path / "no such folder" / "report.html"
    with pytest.raises(OSError):
        write_report_html(result.report, result.points, missing)
    with pytest.raises(OSError):
        write_report_json(result.report, missing.with_suffix(".json"))
    assert not (tmp_path / "no such folder").exists()
