"""Adjustment reports on a real small adjustment: JSON that parses back, one self-contained HTML
page with the headline figures, the decisions and three inline PNG plots, written atomically."""
import base64
import json
import re

import matplotlib
import numpy as np
import pytest

from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.adjust.checkpoints import without_label
from pushbroom_adjust.core.adjust.report import onboard_advice, report_to_json, write_report_json
from pushbroom_adjust.core.adjust.report_html import write_report_html
from pushbroom_adjust.core.adjust.report_plots import MAX_ARROWS
from pushbroom_adjust.core.files import OutputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation.presets import CAMERA_ERRORS
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
IMAGES = re.compile(r"data:image/png;base64,([A-Za-z0-9+/=]+)")


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """A CBERS-02B scene with 400 GCPs (half check points, 5 % gross errors) and its GCP table."""
    sim = simulate("cbers02b_hrc", tmp_path_factory.mktemp("sim"), seed=6,
                   gcp_settings=GcpSettings(n_gcps=400, image_noise=0.5, check_fraction=0.5, gross_fraction=0.05))
    table = G.read_csv(sim.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                       Heights("z", datum="ellipsoid"), sigma_px=0.5, sigma_xy=0.01, sigma_z=0.01)
    return sim, table


@pytest.fixture(scope="module")
def result(simulated):
    """All three chips' interior terms: the middle chip's are not determinable and get fixed."""
    sim, table = simulated
    out = adjust(load_scene(sim.onboard_scene), table, AdjustmentSettings(interior="HRC-1.*, HRC-2.*, HRC-3.*"))
    assert out.report["determinability"], "the fixture must exercise the determinability messages"
    return out


@pytest.fixture(scope="module")
def page(result, tmp_path_factory):
    path = tmp_path_factory.mktemp("html") / "report.html"
    write_report_html(result.report, result.points, path, title="CBERS <script>alert(1)</script>")
    return path.read_text(encoding="utf-8")


def test_json_parses_back_with_numpy_converted_and_nan_as_null(result, tmp_path):
    path = tmp_path / "report.json"
    extra = {"nan": np.nan, "inf": np.float64(np.inf), "f32": np.float32(1.5), "i64": np.int64(3),
             "flag": np.bool_(True), "array": np.array([[1.0, np.nan], [2.0, 3.0]])}
    write_report_json({**result.report, "extra": extra}, path)
    back = json.loads(path.read_text())
    assert back["sigma0"] == result.report["sigma0"]
    assert back["extra"] == {"nan": None, "inf": None, "f32": 1.5, "i64": 3, "flag": True,
                             "array": [[1.0, None], [2.0, 3.0]]}
    assert [p["name"] for p in back["parameters"]] == [p["name"] for p in result.report["parameters"]]
    assert len(back["trajectory"]["position"]) == len(result.report["trajectory"]["time"])
    assert not (tmp_path / "report.json.part").exists()
    assert "NaN" not in report_to_json(result.report)


def test_html_has_three_inline_png_plots(page):
    images = IMAGES.findall(page)
    assert len(images) == 3
    for data in images:
        assert base64.b64decode(data)[:8] == PNG_MAGIC
    assert "<img" in page and "src='http" not in page and "src=\"http" not in page  # self-contained


def test_html_leads_with_sigma0_control_and_check_point_accuracy(result, page):
    rep = result.report
    assert f"sigma0 = {rep['sigma0']:.3f}" in page
    assert page.index("sigma0 =") < page.index("Settings") < page.index("data:image/png")
    ctl = rep["control_residuals"]
    assert f"RMSE col {ctl['rmse_col']:.3f} px, row {ctl['rmse_row']:.3f} px" in page
    checks = rep["check_points"]
    row = re.search(r"<tr><td class='l'>after adjustment</td>(.*?)</tr>", page).group(1)
    assert f"<td>{checks['image']['rmse_col']:.3f}</td><td>{checks['image']['rmse_row']:.3f}</td>" in row
    assert f"<td>{checks['ground']['ce90']:.2f}</td>" in row
    before = rep["check_points_before"]
    assert f"<td>{before['image']['rmse_col']:.3f}</td>" in page
    assert checks["blunders"] and not checks["model_error"]  # 5 % gross errors: blunders, not a model error
    assert without_label(checks["blunder_points"]) in page and checks["blunder_points"] > 1
    assert "Monoplotted, per observation" in page and "Model error" not in page
    assert "3D intersection" in page and "no check point is intersected" in page  # one camera: no 3D figures


def test_html_names_the_fixed_parameters_and_the_flagged_count(result, page):
    for decision in result.report["determinability"]:
        assert f"<b>{decision['fixed']}</b> was fixed" in page
        # and the interior table marks it
        assert re.search(rf"<td class='l'>{re.escape(decision['fixed'])}</td><td class='l'>fixed \(not determinable\)",
                         page)
    assert f"{result.report['robust']['flagged']} image observations flagged" in page


def test_html_shows_interior_parameters_in_readable_units(result, page):
    p = next(p for p in result.report["parameters"] if p["name"] == "HRC-1.theta")
    assert p["unit"] == "rad" and p["mode"] == "free"
    arcsec = np.degrees(p["value"]) * 3600
    assert re.search(rf"<td class='l'>HRC-1.theta</td><td class='l'>free</td><td>{arcsec:.4g}</td>"
                     r"<td>[^<]+</td><td>arcsec</td>", page)


def test_title_and_text_are_escaped(page):
    assert "<script>" not in page
    assert "<title>CBERS &lt;script&gt;alert(1)&lt;/script&gt;</title>" in page


def test_many_trajectory_coefficients_are_summarised_per_axis(simulated, tmp_path):
    sim, table = simulated
    out = adjust(load_scene(sim.onboard_scene), table,
                 AdjustmentSettings(attitude_model="spline", attitude_interval=0.3, attitude_sigma=1e-4))
    n_trajectory = sum(p["block"] in ("position", "attitude") for p in out.report["parameters"])
    assert n_trajectory > 24
    path = tmp_path / "spline.html"
    write_report_html(out.report, out.points, path)
    text = path.read_text(encoding="utf-8")
    assert f"{n_trajectory} coefficients, summarised per axis" in text
    assert "<td class='l'>attitude.roll</td>" in text and "attitude.roll.S2" not in text
    assert len(IMAGES.findall(text)) == 3


def test_half_a_million_points_are_subsampled(result, tmp_path):
    # What is drawn, not how long it takes (timings belong to tests/bench).
    n = 500_000
    take = np.resize(np.arange(len(result.points["col"])), n)
    points = {k: np.asarray(v)[take] for k, v in result.points.items()}
    usable = int((np.isfinite(points["res_col"]) & np.isfinite(points["res_row"])).sum())
    write_report_html(result.report, points, tmp_path / "big.html")
    text = (tmp_path / "big.html").read_text(encoding="utf-8")
    assert f"{MAX_ARROWS} of the {usable} points are drawn" in text


def test_no_matplotlib_figure_is_left_open(result, tmp_path):
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    before = plt.get_fignums()
    write_report_html(result.report, result.points, tmp_path / "report.html")
    assert plt.get_fignums() == before


def test_an_unwritable_report_raises_and_leaves_nothing(result, tmp_path):
    missing = tmp_path / "no such folder" / "report.html"
    with pytest.raises(OutputError, match="no such folder"):
        write_report_html(result.report, result.points, missing)
    with pytest.raises(OutputError, match="no such folder"):
        write_report_json(result.report, missing.with_suffix(".json"))
    assert not (tmp_path / "no such folder").exists()
    assert list(tmp_path.iterdir()) == []


def test_a_failing_report_leaves_the_previous_file_untouched(result, tmp_path):
    path = tmp_path / "report.html"
    path.write_text("previous report")
    broken = {k: v for k, v in result.report.items() if k != "trajectory"}
    with pytest.raises(KeyError):
        write_report_html(broken, result.points, path)
    assert path.read_text() == "previous report"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.html"]


def test_html_has_the_3d_intersection_table(tmp_path):
    """TH-1 three-line block: check points in all three cameras get a 3D row block with the
    figures of the JSON report, before and after. The preset's camera errors are switched off: the
    default adjustment does not self-calibrate, and with them its LE90 (28.2 m) is no better than
    the onboard model's (21.6 m); measured without them: 103.6 m -> 4.38 m."""
    sim = simulate("th1_tlc", tmp_path / "th1", seed=2, errors=dict.fromkeys(CAMERA_ERRORS, 0.0),
                   gcp_settings=GcpSettings(n_gcps=60, check_fraction=0.5))
    table = G.read_csv(sim.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                       Heights("z", datum="ellipsoid"), sigma_px=0.3, sigma_xy=0.01, sigma_z=0.01)
    out = adjust(load_scene(sim.onboard_scene), table, AdjustmentSettings())
    path = tmp_path / "report.html"
    write_report_html(out.report, out.points, path)
    page = path.read_text(encoding="utf-8")
    inter = out.report["check_points"]["intersection"]
    assert inter["intersected"] == inter["points"] == 30
    assert "<h3>3D intersection (30 points in &gt;= 2 cameras)</h3>" in page
    row = re.search(r"<h3>3D intersection.*?<tr><td class='l'>after adjustment</td>(.*?)</tr>", page, re.S).group(1)
    assert row.startswith("<td>30</td>")
    for key in ("rmse_east", "rmse_north", "rmse_plan", "rmse_height", "max_plan", "max_height", "ce90", "le90"):
        assert f"<td>{inter[key]:.2f}</td>" in row
    before = out.report["check_points_before"]["intersection"]
    assert f"<td>{before['le90']:.2f}</td>" in page and before["le90"] > 5 * inter["le90"]
    assert "(30 points, 90 observations)" in page


def test_a_trajectory_correlation_names_the_onboard_sigma_that_is_missing():
    """Correlated position and attitude corrections: the log says which onboard sigma holds their
    split and asks only for the one that was not given."""
    from_position = onboard_advice({"position_sigma": 100.0, "attitude_sigma": None})
    assert from_position.startswith("their split rests on POSITION_SIGMA; give ATTITUDE_SIGMA")
    assert "POSITION_SIGMA and" not in from_position
    assert onboard_advice({"position_sigma": 100.0, "attitude_sigma": 1e-5}) == \
        "their split rests on POSITION_SIGMA and ATTITUDE_SIGMA"
    assert onboard_advice({}).startswith("nothing but the GCPs holds their split; give POSITION_SIGMA and ATTITUDE_SIGMA")
