"""Interior parameters in image terms (px at the array end, arcsec) and their automatic
removal: on random TH-1 blocks with 4-9 GCPs, self-calibration with removal never ends worse
than the conventional adjustment, while the free 10-parameter set overfits."""
import json

import numpy as np
import pytest

from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.adjust.parameters import ParameterSet, parse_interior, sigma_in_si
from pushbroom_adjust.core.rotations import ARCSEC
from pushbroom_adjust.core.adjust.selection import _batch, information_shares
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation.presets import CAMERA_ERRORS
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate
from pushbroom_adjust.core.model.timebasis import TimeBasis

FREE_SET = "*.f, *.dxp, *.dyp, *.k1, *.k2, *.p1, *.p2, *.b1, *.b2, *.b3, FWD.roll, FWD.pitch, FWD.yaw, " \
           "BWD.roll, BWD.pitch, BWD.yaw"


def _table(result) -> G.GcpTable:
    return G.read_csv(result.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                      Heights("z", datum="ellipsoid"), sigma_px=0.5, sigma_xy=0.1, sigma_z=0.2)


def _params(scene, interior=None) -> ParameterSet:
    t0, t1 = scene.time_span()
    basis = TimeBasis.covering("polynomial", t0, t1, 0)
    return ParameterSet(scene, basis, basis, interior)


@pytest.fixture(scope="module")
def th1(tmp_path_factory):
    return load_scene(simulate("th1_tlc", tmp_path_factory.mktemp("th1"), seed=3, n_gcps=20).onboard_scene)


@pytest.fixture(scope="module")
def cbers(tmp_path_factory):
    return load_scene(simulate("cbers02b_hrc", tmp_path_factory.mktemp("cbers"), seed=3, n_gcps=20).onboard_scene)


# --- image terms -----------------------------------------------------------------------------------
def _end_displacement(scene, name: str, value: float) -> float:
    """Largest image displacement (px) at the array ends (each chip's first and last column,
    mid row) of a change ``value`` (SI) of parameter ``name``: the ground point seen there by
    the input scene, projected through the changed one."""
    params = _params(scene)
    p = params.params[params.index[name]]
    cam = scene.cameras[p.camera]
    chips = [cam.chips[p.chip]] if p.block == "chip" else cam.chips
    col = np.array([c for ch in chips for c in (ch.col_offset + 0.5, ch.col_offset + ch.n_pixels - 0.5)])
    row = np.full(col.shape, cam.rows / 2)
    ground = scene.image_to_ground(col, row, np.zeros(col.size), p.camera)
    p.value = value
    moved_col, moved_row = params.adjusted_scene().ground_to_image(ground, p.camera)
    return float(np.max(np.hypot(moved_col - col, moved_row - row)))


# px are detector pitches on the focal plane: along track, a line of the +-25 deg cameras is
# 2.8 % shorter on the ground than a pitch (the simulator keeps the nadir line period), so terms
# moving FWD's image along track (pitch, yaw at the array end) show 1.028 image rows.
@pytest.mark.parametrize("name, rows", [(n, 1.0) for n in ("NAD.f", "NAD.dxp", "NAD.dyp", "NAD.k1", "NAD.k2", "NAD.p1",
                                                             "NAD.p2", "NAD.b2", "NAD.b3", "FWD.roll")]
                         + [("FWD.pitch", 1.028), ("FWD.yaw", 1.028)])
def test_one_px_at_the_array_end_moves_the_end_point_by_one_px(th1, name, rows):
    params = _params(th1)
    sigma = sigma_in_si(th1, params.params[params.index[name]], 1.0, "px")
    assert _end_displacement(th1, name, sigma) == pytest.approx(rows, rel=0.005)
    assert _end_displacement(th1, name, 3 * sigma) == pytest.approx(3.0 * rows, rel=0.01)


@pytest.mark.parametrize("name", ["HRC-1.dx", "HRC-1.dy", "HRC-3.theta", "HRC.k1", "HRC.f"])
def test_one_px_on_a_multi_chip_focal_plane(cbers, name):
    params = _params(cbers)
    sigma = sigma_in_si(cbers, params.params[params.index[name]], 1.0, "px")
    assert _end_displacement(cbers, name, sigma) == pytest.approx(1.0, rel=0.01)


def test_known_conversions(th1):
    params = _params(th1)
    cam = th1.cameras[0]
    pitch, f, r = cam.chips[0].pitch, cam.focal_length, 0.5 * cam.chips[0].n_pixels * cam.chips[0].pitch
    by = {n: params.params[params.index[n]] for n in ("NAD.k1", "NAD.dxp", "NAD.f", "FWD.roll")}
    assert sigma_in_si(th1, by["NAD.dxp"], 2.0, "px") == pytest.approx(2 * pitch, rel=1e-9)
    assert sigma_in_si(th1, by["NAD.k1"], 1.0, "px") == pytest.approx(pitch / r ** 3, rel=1e-3)
    assert sigma_in_si(th1, by["NAD.f"], 1.0, "px") == pytest.approx(pitch * f / r, rel=1e-3)
    assert sigma_in_si(th1, by["FWD.roll"], 30.0, "arcsec") == pytest.approx(30 * np.pi / 648000, rel=1e-12)
    assert sigma_in_si(th1, by["NAD.k1"], 5e-3, "") == 5e-3  # SI as before


def test_parse_units_and_refusals(th1):
    assert parse_interior("NAD.k1=2px, FWD.*=30 arcsec, NAD.f=1e-5, BWD.*") == [
        ("NAD.k1", 2.0, "px"), ("FWD.*", 30.0, "arcsec"), ("NAD.f", 1e-5, ""), ("BWD.*", None, "")]
    for bad, text in (("NAD.k1=2mm", "followed by px or arcsec"), ("NAD.k1=-1px", "positive"),
                      ("NAD.k1=nanpx", "positive")):
        with pytest.raises(InputError, match=text):
            parse_interior(bad)
    with pytest.raises(InputError, match="arcsec applies to angles only"):
        _params(th1, "NAD.k1=3arcsec")


def test_default_preset(th1):
    params = _params(th1, "default")
    weighted = {p.name: p for p in params.params if p.mode == "weighted"}
    assert not any(n.startswith("NAD.") and n.split(".")[1] in ("roll", "pitch", "yaw") for n in weighted)
    assert weighted["FWD.yaw"].sigma == pytest.approx(30 * ARCSEC)
    assert {f"BWD.{t}" for t in ("f", "dxp", "dyp", "k1", "k2", "p1", "p2", "b2", "b3")} <= set(weighted)
    assert _end_displacement(th1, "NAD.k2", weighted["NAD.k2"].sigma) == pytest.approx(3.0, rel=0.02)
    # a later item overrides the preset
    override = _params(th1, "default, NAD.k2=0.5px")
    assert override.params[override.index["NAD.k2"]].sigma == pytest.approx(weighted["NAD.k2"].sigma / 6)


# --- automatic removal on random TH-1 blocks -----------------------------------------------------------
# Seeds and control counts of the blocks; 300 points each, the rest check points (measured in
# all three cameras, 0.3 px noise). Tolerance: 3 % of the conventional check RMSE, about 0.03 px
# (0.15 m) here, below the spread of the check RMSE between noise realisations of one block.
BLOCKS = [(0, 4), (1, 9), (2, 6), (3, 5), (4, 8), (5, 7)]
TOLERANCE = 1.03


@pytest.fixture(scope="module")
def blocks(tmp_path_factory):
    """Per block: check-point image RMSE (px) of the conventional adjustment, of INTERIOR=default
    with removal, of the free set with removal and of the free set kept as given (None where it
    has more unknowns than equations), and the selection report of the default run."""
    out = []
    for seed, n in BLOCKS:
        result = simulate("th1_tlc", tmp_path_factory.mktemp(f"th1_{seed}"), seed=seed,
                          gcp_settings=GcpSettings(n_gcps=300, check_fraction=(300 - n) / 300, image_noise=0.3))
        scene, table = load_scene(result.onboard_scene), _table(result)
        control = table.role == "control"
        assert np.unique(table.id[control]).size == n and control.sum() >= 2.5 * n  # most in all three cameras
        rmse = lambda r: r.report["check_points"]["image"]["rmse"]  # noqa: E731
        conventional = adjust(scene, table, AdjustmentSettings())
        default = adjust(scene, table, AdjustmentSettings(interior="default"))
        try:
            free = rmse(adjust(scene, table, AdjustmentSettings(interior=FREE_SET, interior_selection="keep")))
            selected = adjust(scene, table, AdjustmentSettings(interior=FREE_SET))
            free_selected, free_selection = rmse(selected), selected.report["interior_selection"]
        except InputError:  # too few GCPs for 36 free parameters
            free = free_selected = free_selection = None
        out.append({"seed": seed, "gcps": n, "conventional": rmse(conventional), "default": rmse(default),
                    "free_selected": free_selected, "free": free,
                    "selection": default.report["interior_selection"], "free_selection": free_selection})
    print(json.dumps([{k: v for k, v in b.items() if not k.endswith("selection")} | {
        "kept": [k["name"] for k in b["selection"]["kept"]], "outcome": b["selection"]["outcome"]} for b in out]))
    return out


def test_removal_never_ends_worse_than_conventional(blocks):
    for b in blocks:
        assert b["default"] <= TOLERANCE * b["conventional"], b
        if b["free_selected"] is not None:
            assert b["free_selected"] <= TOLERANCE * b["conventional"], b


# Blocks where removal ends worse than the conventional adjustment (issue 10, criterion 3;
# tests/bench/bench_interior_guard.py prints the sweep). TH-1 seed 17, 8 GCPs, the free set: the kept
# free terms fit the few control points far better (F = 87 against 2.1) and are wrong between and
# beyond them (3.37 against 2.69 px, measured; 2.75 when the null directions' basis, which rounding
# decided, made the determinability check fix another chip term). Strict: fixing it fails the test.
# ZY-3 seed 1, 5 GCPs, INTERIOR=default: 2.00 against 1.94 px before, now falls back to the
# conventional adjustment (see the test below).
@pytest.mark.parametrize("preset, seed, n, interior", [
    pytest.param("th1_tlc", 17, 8, FREE_SET, id="th1-seed17-free", marks=pytest.mark.xfail(
        strict=True, raises=AssertionError, reason="known: TH-1 seed 17, 8 GCPs, free set 3.37 px against 2.69 px")),
    pytest.param("zy3_tlc", 1, 5, "default", id="zy3-seed1-default")])
def test_known_blocks_where_removal_ends_worse(tmp_path, preset, seed, n, interior):
    result = simulate(preset, tmp_path, seed=seed,
                      gcp_settings=GcpSettings(n_gcps=300, check_fraction=(300 - n) / 300, image_noise=0.3))
    scene, table = load_scene(result.onboard_scene), _table(result)
    rmse = [adjust(scene, table, settings).report["check_points"]["image"]["rmse"]
            for settings in (AdjustmentSettings(), AdjustmentSettings(interior=interior))]
    assert rmse[1] <= TOLERANCE * rmse[0], rmse


def test_the_free_set_overfits_without_removal(tmp_path):
    """Where the onboard interior is right (the preset without its camera errors), 9 GCPs cannot
    carry the free set: kept as given it overfits (measured: 7.9 px at the check points against
    0.93 px conventional); removal brings it back (0.84 px), and so does INTERIOR=default (0.80
    px). With the preset's camera errors the free set is better than none (0.60 against 2.67 px
    on block (1, 9) above): the errors are large enough for 9 GCPs to see."""
    result = simulate("th1_tlc", tmp_path, seed=1, errors=dict.fromkeys(CAMERA_ERRORS, 0.0),
                      gcp_settings=GcpSettings(n_gcps=300, check_fraction=291 / 300, image_noise=0.3))
    scene, table = load_scene(result.onboard_scene), _table(result)
    rmse = {name: adjust(scene, table, AdjustmentSettings(**kw)).report["check_points"]["image"]["rmse"]
            for name, kw in (("conventional", {}), ("free", {"interior": FREE_SET, "interior_selection": "keep"}),
                             ("free_selected", {"interior": FREE_SET}), ("default", {"interior": "default"}))}
    assert rmse["free"] > 4.0 * rmse["conventional"], rmse
    assert rmse["free_selected"] <= TOLERANCE * rmse["conventional"], rmse
    assert rmse["default"] <= TOLERANCE * rmse["conventional"], rmse


def _guard_consistent(sel: dict) -> None:
    assert sel["outcome"] in ("self-calibration", "conventional")
    assert sel["guard"]["self_calibration_kept"] == (sel["outcome"] == "self-calibration")
    if sel["outcome"] == "conventional":
        assert sel["guard"]["reason"]
    else:
        assert sel["guard"]["F"] > sel["guard"]["F_critical"]
        assert 0 < sel["guard"]["effective_parameters"] <= sel["guard"]["kept_parameters"]


def test_the_report_names_removed_free_parameters(blocks):
    """Free parameters that fail a test are removed, each with its reasons; the kept ones pass."""
    for b in (b for b in blocks if b["free_selection"]):
        sel = b["free_selection"]
        _guard_consistent(sel)
        assert sel["removed"], b["seed"]
        for r in sel["removed"]:
            assert r["fails"] and all(isinstance(f, str) for f in r["fails"])
        if sel["outcome"] == "self-calibration":
            assert all(k["t"] >= 1.96 and not k.get("held_by_prior") for k in sel["kept"])


def test_weighted_parameters_are_held_by_their_priors_and_named(blocks):
    """INTERIOR=default (every term weighted): nothing is removed; the terms the control cannot
    support are kept, held by their priors, and named with the failed tests (on block (1, 9):
    measured 22 of 33, e.g. the principal point against the installation angles). 33: 9 terms of
    each camera and the 6 installation angles of FWD and BWD; b1 (x b1) of the arrays on the line
    x = 0 moves the image by rounding only and is left fixed (it was weighted with a sigma of
    ~1e12 until issue 22)."""
    for b in blocks:
        sel = b["selection"]
        _guard_consistent(sel)
        assert sel["removed"] == [] and len(sel["kept"]) == 33, b["seed"]
        held = [k for k in sel["kept"] if k.get("held_by_prior")]
        assert all(k["t"] < 1.96 or abs(k["correlation"]) > 0.98 or k["information"] < 1e-4 for k in held)
        assert all(k["t"] >= 1.96 for k in sel["kept"] if not k.get("held_by_prior"))
    nine = next(b for b in blocks if b["gcps"] == 9)["selection"]
    assert 10 <= sum(bool(k.get("held_by_prior")) for k in nine["kept"]) <= 30
    assert nine["guard"]["effective_parameters"] < 30


def test_self_calibration_is_kept_where_it_helps(blocks):
    """The guard compares the self-calibrated model re-solved under the conventional weights (its
    own solution is not their minimum): on blocks whose interior errors 6-9 GCPs can see it keeps
    self-calibration (measured, check points: 2.67 -> 0.58, 4.58 -> 1.61, 3.22 -> 0.95, 3.63 ->
    0.59 px; removing the weighted terms that failed their tests, as an earlier version did,
    gave 0.63, 2.19, 2.06, 0.65 px)."""
    for b in blocks:
        if b["seed"] in (1, 2, 4, 5):
            assert b["selection"]["outcome"] == "self-calibration", b
            assert b["default"] < 0.4 * b["conventional"], b


def test_information_shares_keep_one_of_an_inseparable_pair():
    """Two interior unknowns with the same effect (f and b3 of a line array) and one the trajectory
    absorbs: one of the pair keeps its information, the other none, the absorbed one none."""
    rng = np.random.default_rng(0)
    trajectory = rng.normal(size=(40, 2))
    a = rng.normal(size=40)
    design = np.column_stack([trajectory, a, 2.0 * a, trajectory @ [1.0, -0.5], rng.normal(size=40)])
    N = design.T @ design
    prior = np.array([1e-3, 0.0, 0.0, 0.0])
    N[[2, 3, 4, 5], [2, 3, 4, 5]] += prior
    shares = information_shares(N, np.array([2, 3, 4, 5]), prior)
    assert sorted(shares[:2]) == [pytest.approx(0.0, abs=1e-9), pytest.approx(1.0, rel=0.2)]
    assert shares[2] == pytest.approx(0.0, abs=1e-9)
    assert 0.5 < shares[3] <= 1.0


def test_a_round_never_removes_both_of_a_correlated_pair():
    fail = lambda name, partner, r, info=1.0: {"name": name, "correlated_with": partner,  # noqa: E731
                                               "correlation": r, "information": info, "t": 0.5}
    failing = [fail("NAD.k1", "NAD.k2", 0.99), fail("NAD.k2", "NAD.k1", 0.99), fail("FWD.b2", "NAD.k1", 0.3),
               fail("BWD.b2", "x", 0.1), fail("FWD.k1", "FWD.k2", -0.99), fail("FWD.k2", "FWD.k1", -0.99)]
    assert [x["name"] for x in _batch(failing)] == ["NAD.k1"]  # a third of six: two, NAD.k2 skipped
    assert [x["name"] for x in _batch([failing[0], failing[3], fail("NAD.b3", "NAD.f", 1.0, 0.0)])] == ["NAD.b3"]


def test_a_self_calibration_that_cannot_be_solved_is_never_reported_as_solved(tmp_path):
    """ZY-3 (three multi-chip cameras), 9 GCPs, INTERIOR=default: 58 lens, chip and installation
    terms held by their priors leave the normal matrix nearly singular; Gauss-Newton's damped
    steps were all refused and the solver returned the onboard model as "converged" (measured:
    29.6 px at the check points, sigma0 45.8, against 1.32 px conventional). Until issue 22 it then
    said "no step reduces the residuals": the px prior of NAD.b1, an array on the line x = 0 that
    b1 moves by rounding only (~1e-12 px per unit), was ~1e12, and the step it allowed wrecked
    the linearisation. b1 is left fixed there now, and the run kept as given converges (measured
    0.64 px at the check points, sigma0 0.61); with the automatic removal it falls back to the
    conventional adjustment and names why (53 effective parameters, 45 degrees of freedom)."""
    result = simulate("zy3_tlc", tmp_path, seed=5,
                      gcp_settings=GcpSettings(n_gcps=300, check_fraction=291 / 300, image_noise=0.3))
    scene, table = load_scene(result.onboard_scene), _table(result)
    rmse = lambda out: out.report["check_points"]["image"]["rmse"]  # noqa: E731
    conventional = rmse(adjust(scene, table, AdjustmentSettings()))
    kept = adjust(scene, table, AdjustmentSettings(interior="default", interior_selection="keep"))
    assert kept.report["sigma0"] < 1.0 and rmse(kept) < 0.6 * conventional
    assert {p["name"]: p["mode"] for p in kept.report["parameters"]}["NAD.b1"] == "fixed"
    selected = adjust(scene, table, AdjustmentSettings(interior="default"))
    assert rmse(selected) <= TOLERANCE * conventional
    sel = selected.report["interior_selection"]
    if sel["outcome"] == "conventional" and sel["guard"]["F"] is None:
        assert "did not converge" not in sel["guard"]["reason"] and sel["guard"]["reason"]
