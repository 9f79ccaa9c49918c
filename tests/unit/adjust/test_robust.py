"""Robust estimation that does not trust the stated sigmas (core.adjust.robust): variance
components recovered, flags and check figures independent of the sigmas' scale, the pass
limit reported, breakdowns named; per-point sigma columns on import."""
import copy
import logging
from dataclasses import replace

import numpy as np
import pytest

from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.adjust.breakdown import rayleigh_p
from pushbroom_adjust.core.adjust.robust import truncation
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation.presets import CAMERA_ERRORS
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate

IMAGE_NOISE, GROUND_XY, GROUND_Z = 0.7, 3.0, 10.0
CHIPS = "HRC-1.*, HRC-3.*"


def _settings(**kw) -> AdjustmentSettings:
    # the chip set as given: these tests are about the robust loop, not about interior selection
    return AdjustmentSettings(**{"interior": CHIPS, "robust": "selection", "interior_selection": "keep", **kw})


def _scene(folder, gross: float = 0.0):
    """(onboard scene, GCP table with the true sigmas, gross flags) of a CBERS-02B scene: 1500
    points, half of them check points, 0.7 px image and 3 m / 10 m ground noise."""
    result = simulate("cbers02b_hrc", folder, seed=7, gcp_settings=GcpSettings(
        n_gcps=1500, image_noise=IMAGE_NOISE, check_fraction=0.5, ground_noise_xy=GROUND_XY,
        ground_noise_z=GROUND_Z, gross_fraction=gross))
    table = G.read_csv(result.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                       Heights("z", datum="ellipsoid"), sigma_px=IMAGE_NOISE, sigma_xy=GROUND_XY, sigma_z=GROUND_Z)
    gross_flags = np.genfromtxt(result.gcps, delimiter=",", names=True, usecols=("gross",), dtype=int)["gross"] == 1
    return load_scene(result.onboard_scene), table, gross_flags


def _stated(table: G.GcpTable, image: float, ground: float) -> G.GcpTable:
    """The table with its sigmas multiplied: what a user who guessed wrong would state."""
    return replace(table, sigma_px=table.sigma_px * image, sigma_xy=table.sigma_xy * ground,
                   sigma_z=table.sigma_z * ground)


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    return _scene(tmp_path_factory.mktemp("clean"))


@pytest.fixture(scope="module")
def gross(tmp_path_factory):
    return _scene(tmp_path_factory.mktemp("gross"), gross=0.3)


@pytest.mark.parametrize("image, ground", [(0.5, 0.5), (2.0, 2.0)])
def test_variance_components_recover_the_simulated_noise(clean, image, ground):
    scene, table, _ = clean
    comps = adjust(scene, _stated(table, image, ground), _settings(robust="none")).report["variance_components"]
    # points seen once: image and ground share one factor (their residuals are proportional), so
    # each recovers the simulated sigma as far as the combined misfit tells it (measured 0.96-0.98)
    assert comps["image HRC"]["estimated_sigma"] == pytest.approx(IMAGE_NOISE, rel=0.08)
    assert comps["ground_xy"]["estimated_sigma"] == pytest.approx(GROUND_XY, rel=0.08)
    assert comps["image HRC"]["apriori_sigma"] == pytest.approx(IMAGE_NOISE * image)
    assert comps["image HRC"]["estimated"] and not comps["image HRC"]["passed"]
    # the height hardly moves a near-nadir image point: too little redundancy to estimate, said so
    assert not comps["ground_z"]["estimated"] and comps["ground_z"]["redundancy"] < 10


def test_three_line_components_are_separated_per_camera(tmp_path):
    """Seen in three cameras, image and ground components separate: the nadir camera's
    stated sigma is 3x too small, the others right; only its component moves."""
    result = simulate("th1_tlc", tmp_path, seed=4, errors=dict.fromkeys(CAMERA_ERRORS, 0.0),
                      gcp_settings=GcpSettings(n_gcps=600, image_noise=0.5, ground_noise_xy=2.0, ground_noise_z=3.0))
    table = G.read_csv(result.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                       Heights("z", datum="ellipsoid"), sigma_px=0.5, sigma_xy=2.0, sigma_z=3.0)
    table = replace(table, sigma_px=np.where(table.camera == "NAD", 0.5 / 3, 0.5))
    rep = adjust(load_scene(result.onboard_scene), table, AdjustmentSettings(
        interior="FWD.roll, FWD.pitch, FWD.yaw, BWD.roll, BWD.pitch, BWD.yaw", robust="none")).report
    comps = rep["variance_components"]
    for cam in ("FWD", "NAD", "BWD"):
        assert comps[f"image {cam}"]["estimated_sigma"] == pytest.approx(0.5, rel=0.1), cam
    assert comps["image NAD"]["sigma0"] == pytest.approx(3.0, rel=0.1)
    assert comps["ground_xy"]["estimated_sigma"] == pytest.approx(2.0, rel=0.15)


@pytest.mark.parametrize("image, ground", [(0.5, 0.5), (2.0, 2.0), (0.5, 2.0)])
def test_flags_and_check_figures_do_not_depend_on_the_stated_sigmas(gross, image, ground):
    """30 % gross errors: with sigmas stated half or twice the noise, the same flags and check
    figures as with the true ones (before: 15 % of good points flagged at x0.5, check RMSE
    23 % optimistic)."""
    scene, table, is_gross = gross
    right = adjust(scene, table, _settings()).report["check_points"]["without_blunders"]["ground"]["rmse"]
    out = adjust(scene, _stated(table, image, ground), _settings())
    flagged = out.points["flagged"]
    for role in ("control", "check"):
        m = table.role == role
        assert flagged[m & is_gross].mean() >= 0.98, role
        assert flagged[m & ~is_gross].mean() <= 0.01, role
    rep = out.report
    assert rep["check_points"]["without_blunders"]["ground"]["rmse"] == pytest.approx(right, rel=0.05)
    assert rep["reliability"]["reliable"] and not rep["robust"]["stopped_at_limit"]


def test_trusting_the_stated_sigmas_is_still_possible(gross):
    """variance_components=False is today's behaviour: sigmas stated half the noise flag good points."""
    scene, table, is_gross = gross
    out = adjust(scene, _stated(table, 0.5, 0.5), _settings(variance_components=False))
    assert out.points["flagged"][(table.role == "control") & ~is_gross].mean() > 0.05


def test_a_loop_at_its_pass_limit_says_so(gross, caplog):
    scene, table, _ = gross
    with caplog.at_level(logging.WARNING):
        rep = adjust(scene, table, _settings(max_robust_iterations=1)).report
    assert rep["robust"]["stopped_at_limit"] and len(rep["robust"]["passes"]) == 1
    assert "robust estimation stopped at its limit of 1 passes; the flags may be incomplete" in caplog.text
    assert adjust(scene, table, _settings()).report["robust"]["stopped_at_limit"] is False


def test_a_trial_solution_at_its_pass_limit_is_not_reported(gross, caplog, monkeypatch):
    """The interior selection's trial solutions (the guard's conventional one) may stop at the
    limit; only the reported solution's limit is the user's concern."""
    from pushbroom_adjust.core.adjust import engine

    def select_with_a_trial_at_the_limit(problem, est, estimate):
        trial = copy.deepcopy(problem)
        trial.settings = replace(trial.settings, max_robust_iterations=1)
        assert estimate(trial).at_limit
        return problem, est, {"outcome": "self-calibration"}

    monkeypatch.setattr(engine, "select_interior", select_with_a_trial_at_the_limit)
    scene, table, _ = gross
    with caplog.at_level(logging.WARNING):
        rep = adjust(scene, table, _settings(interior_selection="significant")).report
    assert not rep["robust"]["stopped_at_limit"]
    assert "stopped at its limit" not in caplog.text


def _shifted(table: G.GcpTable, scene, share: float, shift: float) -> tuple[G.GcpTable, np.ndarray]:
    """``share`` of the right CCD's (HRC-3) measurements moved by ``shift`` px in col and row."""
    on_chip = scene.cameras[0].chip_index(table.col) == 2
    moved = on_chip & (np.random.default_rng(5).random(len(table)) < share)
    return replace(table, col=table.col + shift * moved, row=table.row + shift * moved), moved


@pytest.mark.parametrize("shift, kind", [(20.0, "too_many_flagged"), (10.0, "inflated")])
def test_half_of_one_ccd_shifted_the_same_way_is_named(clean, shift, kind):
    """A breakdown: half of HRC-3's points shifted the same way. 20 px: the robust weights flag
    the whole chip; 10 px: they flag none and the chip's residuals are bimodal, 3.6 x the others'.
    Either way the result is not reliable and says which chip."""
    scene, table, _ = clean
    bad, _ = _shifted(table, scene, 0.5, shift)
    rep = adjust(scene, bad, _settings()).report
    assert not rep["reliability"]["reliable"]
    named = {(p["group"], p["kind"]) for p in rep["reliability"]["problems"]}
    assert ("HRC/HRC-3", kind) in named
    assert not any(g.endswith(("HRC-1", "HRC-2")) for g, _ in named)


def test_a_small_shifted_subset_is_flagged_and_named_systematic(clean):
    """5 % of HRC-3's points shifted 20 px the same way: flagged, their common direction named,
    the result itself still reliable."""
    scene, table, _ = clean
    bad, moved = _shifted(table, scene, 0.05, 20.0)
    out = adjust(scene, bad, _settings())
    control = table.role == "control"
    assert out.points["flagged"][moved & control].all()
    problems = out.report["reliability"]["problems"]
    assert [(p["group"], p["kind"]) for p in problems] == [("HRC/HRC-3", "systematic")]
    assert out.report["reliability"]["reliable"] and "mean -20." in problems[0]["message"]  # predicted - measured


def test_correct_data_and_random_gross_errors_raise_no_alarm(clean, gross):
    for scene, table, _ in (clean, gross):
        assert adjust(scene, table, _settings()).report["reliability"] == {"reliable": True, "problems": []}


def test_half_of_all_points_gross_is_not_reported_as_a_good_result(tmp_path):
    scene, table, _ = _scene(tmp_path, gross=0.5)
    rel = adjust(scene, table, _settings()).report["reliability"]
    assert not rel["reliable"]
    assert {p["kind"] for p in rel["problems"]} == {"too_many_flagged"}


def test_statistics_helpers():
    # truncation at 3.29: the tails beyond hold 1.2 % of the variance
    assert truncation(3.2905) == pytest.approx(0.9883, abs=1e-4)
    assert rayleigh_p(100, 0.0) == pytest.approx(1.0)
    assert rayleigh_p(20, 0.9) < 1e-6 and rayleigh_p(20, 0.2) > 0.4


def test_per_point_sigma_columns(tmp_path):
    path = tmp_path / "gcps.csv"
    path.write_text("id,col,row,lon,lat,h,spx,sxy,sz\n"
                    "surveyed,10,20,-50.0,-10.0,100,0.3,0.05,0.1\n"
                    "digitised,11,21,-50.001,-10.001,100,,8,\n")
    mapping = G.CsvMapping(z="h", sigma_px="spx", sigma_xy="sxy", sigma_z="sz")
    t = G.read_csv(path, mapping, "EPSG:4326", Heights("z"), sigma_px=0.7, sigma_z=15.0)
    assert t.sigma_px.tolist() == [0.3, 0.7] and t.sigma_xy.tolist() == [0.05, 8.0] and t.sigma_z.tolist() == [0.1, 15.0]
    for bad in ("0", "-1", "nan", "inf", "x", "1e308"):
        path.write_text(f"id,col,row,lon,lat,h,spx\nP1,10,20,-50.0,-10.0,100,{bad}\n")
        with pytest.raises(InputError, match=rf"gcps.csv: per-point sigma field 'spx'.*P1: '{bad}'"):
            G.read_csv(path, G.CsvMapping(z="h", sigma_px="spx"), "EPSG:4326", Heights("z"))
    with pytest.raises(InputError, match="no column 'spx2'"):
        G.read_csv(tmp_path / "gcps.csv", G.CsvMapping(z="h", sigma_xy="spx2"), "EPSG:4326", Heights("z"))
