"""The bundle adjustment engine on simulated scenes with known truth: analytic derivatives,
recovery of the simulated errors, determinability, gross errors, and bad input."""
import json
from dataclasses import replace

import numpy as np
import pytest

from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.adjust.checks import check_inputs
from pushbroom_adjust.core.adjust.problem import Problem
from pushbroom_adjust.core.errors import ConvergenceError, InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.scene_json import save_scene
from pushbroom_adjust.simulation.presets import CAMERA_ERRORS
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate

CBERS_CHIPS = "HRC-1.*, HRC-3.*"


def _table(result, sigma_px=0.5, sigma_xy=0.01, sigma_z=0.01) -> G.GcpTable:
    return G.read_csv(result.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                      Heights("z", datum="ellipsoid"), sigma_px=sigma_px, sigma_xy=sigma_xy, sigma_z=sigma_z)


@pytest.fixture(scope="module")
def cbers(tmp_path_factory):
    """A CBERS-02B scene: 3000 GCPs, 0.5 px noise, half of them check points."""
    result = simulate("cbers02b_hrc", tmp_path_factory.mktemp("cbers"), seed=4,
                      gcp_settings=GcpSettings(n_gcps=3000, image_noise=0.5, check_fraction=0.5))
    return result, load_scene(result.onboard_scene), _table(result), json.loads(result.manifest.read_text())


def _chip_truth(manifest, chip: str) -> dict:
    return next(c for c in manifest["truth"]["interior"][0]["chips"] if c["chip"] == chip)


# --- derivatives -----------------------------------------------------------------------------------
@pytest.mark.parametrize("preset, interior", [
    ("cbers02b_hrc", "HRC.*, HRC-*"),
    ("th1_tlc", "FWD.*, BWD.*, NAD.*"),
])
def test_analytic_jacobian_matches_central_differences(tmp_path, preset, interior):
    result = simulate(preset, tmp_path, seed=2, n_gcps=60)
    scene = load_scene(result.onboard_scene)
    settings = AdjustmentSettings(interior=interior, position_model="lagrange", position_interval=2.0,
                                  attitude_model="spline", attitude_interval=1.5, robust="none")
    table = check_inputs(scene, _table(result), settings)
    problem = Problem(scene, table, settings)
    params = problem.params
    rng = np.random.default_rng(0)
    # a point away from zero, so every term of the derivatives is exercised
    values = params.values()
    scales = {"m": 1e-5, "rad": 1e-4, "1/m2": 1.0, "1/m4": 1e2, "1/m": 1e-3, "": 1e-4}
    for i, p in enumerate(params.params):
        values[i] = rng.normal() * (5.0 if p.block == "position" else scales[p.unit])
    params.set_values(values)
    problem.structure()
    # the exact residuals (where the current model images each point) and their Jacobian there
    lin, _ = problem.linearize()
    analytic = lin.values  # (n, 2, q) in the columns of problem.columns
    for j in params.free:
        step = 1e-3 if params.params[j].block == "position" else max(abs(values[j]) * 1e-4, 1e-8)
        for sign in (1, -1):
            v = values.copy()
            v[j] += sign * step
            params.set_values(v)
            if sign == 1:
                plus = problem.residuals()
            else:
                minus = problem.residuals()
        params.set_values(values)
        numeric = (plus - minus) / (2 * step)
        col = problem.unknown[j]
        mine = np.where((problem.columns == col)[:, None, :], analytic, 0.0).sum(axis=2)
        scale = np.abs(numeric).max()
        # Refraction and the Earth's rotation in the aberration are held fixed in the analytic
        # derivatives (the velocity's own aberration is not: it follows a drift of the position).
        # plus a floor for rounding: the exact projection ends where r_u rounds to zero, ~1e-15 rad
        # (ECEF metres of 7e6 to 1e-9), i.e. ~5e-10 px, at any step (knots where this scene has
        # no observations have a true derivative of 0)
        assert np.abs(mine - numeric).max() < 3e-4 * scale + 2e-9 / step, params.params[j].name
    # ground derivatives
    for a in range(3):
        for sign in (1, -1):
            problem.ground = problem.ground.copy()
            problem.ground[:, a] += sign * 0.01
            if sign == 1:
                plus = problem.residuals()
            else:
                minus = problem.residuals()
            problem.ground[:, a] -= sign * 0.01
        numeric = (plus - minus) / 0.02
        assert np.abs(lin.jg[:, :, a] - numeric).max() < 3e-4 * np.abs(numeric).max()


# --- recovery ------------------------------------------------------------------------------------------
def test_chip_parameters_are_recovered_and_check_points_reach_the_noise(cbers, tmp_path):
    result, scene, table, manifest = cbers
    out = adjust(scene, table, AdjustmentSettings(interior=CBERS_CHIPS, robust="none"))
    rep = out.report
    assert rep["sigma0"] == pytest.approx(1.0, abs=0.06)
    assert rep["sigma0_test"]["passed"]
    assert rep["check_points_before"]["ground"]["rmse"] > 300.0  # the onboard model: hundreds of metres
    # check points: 0.5 px per axis of measurement noise, 2.36 m GSD
    assert rep["check_points"]["image"]["rmse_col"] == pytest.approx(0.5, rel=0.1)
    assert rep["check_points"]["image"]["rmse_row"] == pytest.approx(0.5, rel=0.1)
    assert rep["check_points"]["ground"]["rmse"] < 2.5
    params = {p["name"]: p for p in rep["parameters"]}
    for chip in ("HRC-1", "HRC-3"):
        truth = _chip_truth(manifest, chip)
        for term, key in (("dx", "dx_m"), ("dy", "dy_m"), ("theta", "dtheta_rad")):
            p = params[f"{chip}.{term}"]
            assert abs(p["value"] - truth[key]) < 3 * p["sigma"], p["name"]
            assert p["significant"]
    # the adjusted scene carries it all: parameters with sigmas and the settings, and its own
    # ground -> image meets the check points
    info = out.scene.info["adjustment"]
    assert info["settings"]["interior"] == CBERS_CHIPS and info["sigma0"] == rep["sigma0"]
    saved = {p["name"]: p for p in info["parameters"]}
    assert saved["HRC-1.dx"]["sigma"] == params["HRC-1.dx"]["sigma"] and "HRC-2.dx" not in saved
    checks = table.role == "check"
    col, row = out.scene.ground_to_image(table.select(checks).ecef())
    assert np.sqrt(np.mean((col - table.col[checks]) ** 2)) == pytest.approx(
        rep["check_points"]["image"]["rmse_col"], rel=1e-6)
    # ... also once written as scene JSON and read back, as every algorithm will read it
    save_scene(out.scene, tmp_path / "adjusted.json")
    col2, row2 = load_scene(tmp_path / "adjusted.json").ground_to_image(table.select(checks).ecef())
    assert np.max(np.hypot(col2 - col, row2 - row)) < 1e-6


def test_all_ten_parameters_are_reported_non_determinable_and_the_middle_chip_fixed(cbers):
    """Seed 000 Table II schemes 1-2: f and all three chips together cannot be determined;
    each chip term of the middle chip trades with an attitude angle."""
    _, scene, table, manifest = cbers
    out = adjust(scene, table, AdjustmentSettings(interior="HRC.f, HRC-1.*, HRC-2.*, HRC-3.*", robust="none",
                                                  interior_selection="keep"))  # f is not significant here
    found = out.report["determinability"]
    assert [d["fixed"] for d in found] == ["HRC-2.dx", "HRC-2.dy", "HRC-2.theta"]
    assert {"HRC-1.dx", "HRC-3.dx", "attitude.pitch.bias"} <= set(found[0]["parameters"])
    assert {"HRC-1.dy", "HRC-3.dy", "attitude.roll.bias"} <= set(found[1]["parameters"])
    assert "attitude.yaw.bias" in found[2]["parameters"]
    params = {p["name"]: p for p in out.report["parameters"]}
    assert params["HRC-2.dx"]["mode"] == "fixed" and params["HRC.f"]["mode"] == "free"
    truth = _chip_truth(manifest, "HRC-1")
    assert abs(params["HRC-1.dx"]["value"] - truth["dx_m"]) < 3 * params["HRC-1.dx"]["sigma"]
    with pytest.raises(InputError, match=r"cannot be determined together.*HRC-.\.dx"):
        adjust(scene, table, AdjustmentSettings(interior="HRC-1.*, HRC-2.*, HRC-3.*", robust="none",
                                                on_singular="stop"))


def test_without_interior_parameters_the_residuals_stay_large(cbers):
    """Seed 000 Table II scheme 11: no interior parameters leaves the CCD misalignment."""
    _, scene, table, _ = cbers
    rep = adjust(scene, table, AdjustmentSettings(robust="none")).report
    best = adjust(scene, table, AdjustmentSettings(interior=CBERS_CHIPS, robust="none")).report
    assert rep["sigma0"] > 1.8 and not rep["sigma0_test"]["passed"]  # measured 2.14
    assert rep["check_points"]["image"]["rmse"] > 1.8 * best["check_points"]["image"]["rmse"]  # 1.52 vs 0.71 px
    assert rep["check_points"]["ground"]["max"] > 2.0 * best["check_points"]["ground"]["max"]  # 12.7 vs 5.1 m


def test_three_line_installation_angles_with_weighted_ground(tmp_path):
    result = simulate("th1_tlc", tmp_path, seed=4, errors=dict.fromkeys(CAMERA_ERRORS, 0.0),
                      gcp_settings=GcpSettings(n_gcps=800, image_noise=0.5, check_fraction=0.5, ground_noise_xy=2.0,
                                               ground_noise_z=3.0))
    truth = json.loads(result.manifest.read_text())["truth"]["interior"]
    out = adjust(load_scene(result.onboard_scene), _table(result, 0.5, 2.0, 3.0),
                 AdjustmentSettings(interior="FWD.roll, FWD.pitch, FWD.yaw, BWD.roll, BWD.pitch, BWD.yaw",
                                    robust="none", interior_selection="keep"))  # every angle, significant or not
    rep = out.report
    assert rep["sigma0"] == pytest.approx(1.0, abs=0.08)
    for group in ("image FWD", "image NAD", "image BWD", "ground_xy", "ground_z"):
        assert rep["variance_components"][group]["sigma0"] == pytest.approx(1.0, abs=0.15), group
    params = {p["name"]: p for p in rep["parameters"]}
    for cam in truth[1:]:
        for angle, value in zip(("roll", "pitch", "yaw"), cam["installation_error_rad"]):
            p = params[f"{cam['camera']}.{angle}"]
            assert abs(p["value"] - value) < 3 * p["sigma"], p["name"]


# --- gross errors -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["selection", "snooping"])
def test_gross_errors_are_flagged_and_do_not_spoil_the_solution(tmp_path, cbers, method):
    result = simulate("cbers02b_hrc", tmp_path, seed=4,
                      gcp_settings=GcpSettings(n_gcps=3000, image_noise=0.5, check_fraction=0.5, gross_fraction=0.1))
    table = _table(result)
    gross = np.genfromtxt(result.gcps, delimiter=",", names=True, dtype=None, encoding=None)["gross"] == 1
    out = adjust(load_scene(result.onboard_scene), table, AdjustmentSettings(interior=CBERS_CHIPS, robust=method))
    control = table.role == "control"
    flagged = out.points["flagged"]
    assert flagged[control & gross].mean() >= 0.98
    assert flagged[control & ~gross].mean() <= 0.01
    _, scene, clean_table, _ = cbers
    clean = adjust(scene, clean_table, AdjustmentSettings(interior=CBERS_CHIPS, robust="none")).report
    # check points with gross errors are flagged and left out of the accuracy figures
    checks = table.role == "check"
    assert flagged[checks & gross].mean() >= 0.98 and flagged[checks & ~gross].mean() <= 0.01
    assert out.report["check_points"]["blunders"] == int(flagged[checks].sum())
    assert clean["check_points"]["blunders"] <= 0.005 * checks.sum()  # two axes at alpha 0.001: ~0.2%
    robust = out.report["check_points"]["without_blunders"]
    assert robust["image"]["rmse"] < 1.1 * clean["check_points"]["image"]["rmse"]
    assert robust["ground"]["rmse"] < 1.1 * clean["check_points"]["ground"]["rmse"]


# --- bad input ---------------------------------------------------------------------------------------------
def _subset(table, mask):
    return table.select(mask)


def test_degenerate_control_is_refused_with_a_reason(cbers):
    _, scene, table, _ = cbers
    settings = AdjustmentSettings(interior=CBERS_CHIPS, robust="none")
    control = table.role == "control"
    with pytest.raises(InputError, match="too few control points: 2"):
        adjust(scene, _subset(table, np.nonzero(control)[0][:2]), settings)
    with pytest.raises(InputError, match="too few GCPs for the chosen model: 5 image observations"):
        adjust(scene, _subset(table, np.nonzero(control)[0][:5]), settings)
    line = control & (np.abs(table.col - table.row) < 60)
    on_line = replace(table.select(line), col=table.select(line).row.copy())
    with pytest.raises(InputError, match="lie on a line"):
        adjust(scene, on_line, settings)
    corner = control & (table.col < 1000) & (table.row < 1000)
    with pytest.raises(InputError, match=r"cover only .* of the image \(one corner\)"):
        adjust(scene, _subset(table, corner), settings)


def test_nan_and_foreign_gcps_are_refused(cbers, tmp_path):
    _, scene, table, _ = cbers
    settings = AdjustmentSettings(robust="none")
    bad = replace(table, col=table.col.copy())
    bad.col[5] = np.nan
    with pytest.raises(InputError, match=f"GCPs {table.id[5]} have NaN"):
        adjust(scene, bad, settings)
    other = simulate("cbers02b_hrc", tmp_path, seed=8, n_gcps=50)
    elsewhere = load_scene(other.onboard_scene)
    elsewhere.platform.ephemeris.positions[:] += np.array([3e5, 0.0, 0.0])  # another orbit: ~300 km away
    with pytest.raises(InputError, match="another scene"):
        adjust(elsewhere, table, settings)


def test_unknown_interior_parameter_names_the_choices(cbers):
    _, scene, table, _ = cbers
    with pytest.raises(InputError, match=r"'HRC-9\.\*' matches none of this scene's parameters \(e\.g\. HRC\.roll"):
        adjust(scene, table, AdjustmentSettings(interior="HRC-9.*"))


@pytest.mark.parametrize("interior", ["HRC.f=1e-300", "HRC.k1=1e-12px", "HRC-1.dx=1e-200, HRC-3.*"])
def test_a_prior_that_holds_its_parameter_fixed_is_refused(cbers, interior):
    """A sigma too small to weigh (it overflowed the normal equations into a LinAlgError) is named."""
    _, scene, table, _ = cbers
    with pytest.raises(InputError, match=r"a sigma this small holds HRC") as info:
        adjust(scene, table, AdjustmentSettings(interior=interior))
    assert info.value.parameter == "settings.interior"


def test_a_run_that_does_not_converge_says_what_it_tried(cbers):
    _, scene, table, _ = cbers
    with pytest.raises(ConvergenceError, match=r"did not converge: still changing after 1 iteration\. .*#1: .*step 1\d\d\.?\d* px"):
        adjust(scene, table, AdjustmentSettings(interior=CBERS_CHIPS, robust="none", max_iterations=1))
