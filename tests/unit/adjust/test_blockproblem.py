"""Blocks with RPC scenes (issue 23): rigorous scenes and RPC products adjusted in one run
(:func:`core.adjust.block.adjust_block`), each scene with its own correction, the ground points
shared. The block: tests/support/mixed_block.py (two TH-1 simulations, an RPC product of another
sensor with a known image bias, observations through the true models plus 0.3 px noise).

Noise floor of a scene's check figure: its check observations' residuals through the TRUE models
(the drawn noise itself, :func:`tests.support.mixed_block.floor_px`); a scene reaches it when its
adjusted model adds no more than its noise does (within 10 %: a model error below 0.46 of the noise,
added in quadrature).
"""
from dataclasses import replace

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.adjust import AdjustmentSettings
from pushbroom_adjust.core.adjust.block import adjust_block, block_inputs
from pushbroom_adjust.core.adjust.blockproblem import BlockProblem
from pushbroom_adjust.core.adjust.checks import check_inputs
from pushbroom_adjust.core.adjust.ties import set_up_ties
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.rpcfiles import rpc_metadata
from pushbroom_adjust.core.formats.scene_json import save_scene
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.model.rpcscene import RpcScene
from pushbroom_adjust.core.products.rpcfit import refined_rpcs
from tests.support.mixed_block import PRODUCTS, TRUE_CORRECTION, MixedBlock, floor_px

gdal.UseExceptions()

# onboard sigmas as the simulated errors: 10 m (GNSS), 2e-4 rad (41 arcsec, star trackers)
SETTINGS = AdjustmentSettings(position_order=1, attitude_order=1, position_sigma=10.0, attitude_sigma=2e-4)
TERMS = ("a0", "a1", "a2", "b0", "b1", "b2")


@pytest.fixture(scope="module")
def block(tmp_path_factory) -> MixedBlock:
    return MixedBlock(tmp_path_factory.mktemp("mixed"))


@pytest.fixture(scope="module")
def mixed(block):
    ties, gcps, truth = block.tables(block.true)
    return adjust_block(block.onboard, gcps, ties, SETTINGS), gcps, truth, ties


def correction_terms(report_entry: dict) -> dict:
    return {t: (v["value"], v["sigma"]) for t, v in report_entry["correction"].items()}


def assert_floor(out, gcps, truth, scenes) -> dict:
    """Every scene's check RMSE (px, the report's) within 10 % of its noise floor; returns both."""
    figures = {}
    for name in scenes:
        rmse, floor = out.report["scenes"][name]["check_points"]["rmse_px"], floor_px(gcps, truth, name)
        figures[name] = (rmse, floor)
        assert abs(rmse / floor - 1.0) <= 0.1, (name, rmse, floor)
    return figures


def test_mixed_block_reaches_every_scenes_noise_floor(block, mixed):
    """Two rigorous scenes + one RPC scene of another sensor, 8 GCPs (4 in S1's corners, 4 in R's),
    94 tie points (388 observations, 64 in R). Measured check RMSE against the floor (px): S1 0.446
    / 0.440, S2 0.450 / 0.444, R 0.466 / 0.436; onboard / vendor: 22-24 px and 4 px. R's bias
    recovered: a0 -3.31 (truth -3.20, sigma 0.15), b0 2.33 (2.49, 0.22), b2 -0.0038 (-0.0040,
    0.0007), a2 0.0006 (0, 0.0004). Tie RMS 21.6 px before, 0.32 after; sigma0 0.95; 7-8 s."""
    out, gcps, truth, _ = mixed
    assert_floor(out, gcps, truth, block.onboard)
    rep = out.report
    assert 0.7 < rep["block"]["sigma0"] < 1.3
    assert rep["block"]["tie_rmse_before_px"] > 10.0 and rep["block"]["tie_rmse_px"] < 0.5
    for name, entry in rep["scenes"].items():
        assert entry["ties"]["rmse_px"] < entry["ties"]["rmse_before_px"], name
        assert entry["model"] == ("rpc" if name == "R" else "rigorous")
    assert "control points" in rep["datum"]
    terms = correction_terms(rep["scenes"]["R"])
    assert set(terms) == {"a0", "a2", "b0", "b2"}  # drift mode
    for k, term in enumerate(TERMS):
        if term in terms:
            value, sigma = terms[term]
            assert abs(value - TRUE_CORRECTION.ravel()[k]) < 3.0 * sigma, (term, value, sigma)
    # vendor geolocation off by the bias (3-4 px at 2.1 m): moved by about that
    assert 5.0 < rep["scenes"]["R"]["moved_m"] < 15.0
    assert rep["scenes"]["R"]["check_points"]["rmse_px"] < 0.2 * _vendor_check_px(block, gcps, truth)


def test_mixed_ties_only_block_is_held_by_the_onboard_sigmas(block, mixed):
    """No GCPs: the rigorous scenes' onboard sigmas hold the datum and the RPC image follows them
    through the ties: its shift is estimated (not fixed as non-determinable: a datum-carrying term
    keeps little information of its own with the trajectories free, which is no defect) with a
    sigma of the onboard accuracy. Measured: tie RMS 21.5 px before, 0.32 after; R's a0 -5.1 +-
    22.3 px, b0 -5.9 +- 31.6 px (truth -3.2, 2.5); absolute check error (true ground through the
    adjusted scene against the truth) S1 2.7 px, R 8.5 px (13 and 18 m: the onboard datum); 9 s. RPC_CORRECTION
    is given (drift: R's bias drifts along its rows); auto would take shift, the block having no control point."""
    out = adjust_block(block.onboard, None, mixed[3], replace(SETTINGS, rpc_correction="drift"))
    rep = out.report
    assert "onboard pseudo-observations" in rep["datum"] and "RPC" not in rep["datum"]
    assert rep["block"]["tie_rmse_px"] < 0.5 < 10.0 < rep["block"]["tie_rmse_before_px"]
    assert not out.adjustment.report["determinability"]
    terms = correction_terms(rep["scenes"]["R"])
    assert set(terms) == {"a0", "a2", "b0", "b2"}
    for term in ("a0", "b0"):
        value, sigma = terms[term]
        assert 5.0 < sigma < 100.0 and abs(value - TRUE_CORRECTION.ravel()[TERMS.index(term)]) < 3.0 * sigma


def _vendor_check_px(block, gcps, truth) -> float:
    """RMS (px) of R's check observations through the vendor RPC."""
    m = (gcps.role == "check") & (gcps.scene == "R")
    col, row = block.onboard["R"].ground_to_image(gcps.select(m).ecef())
    return float(np.sqrt(np.mean((col - gcps.col[m]) ** 2 + (row - gcps.row[m]) ** 2)))


def test_adjusted_rpc_scene_is_written_as_a_single_rpc_adjustment(mixed, tmp_path):
    """The adjusted RPC scene: saved as scene JSON and loaded back under its own camera name with
    its correction, carrying the block's record; its refined RPC (refitted: the drift mixes rows
    and columns) read by gdal.Transformer reproduces it (measured 6e-8 px, limit 0.01); the written
    block images its fitted observations (measured 2e-10 px, limit 0.01)."""
    out = mixed[0]
    assert out.report["written_vs_fitted"]["max_px"] < 0.01
    scene = out.scenes["R"]
    assert isinstance(scene, RpcScene) and scene.camera.name == "PAN"
    assert scene.info["adjustment"]["block"] == {"scene": "R", "scenes": ["S1", "S2", "R"]}
    carried = [p["name"] for p in scene.info["adjustment"]["parameters"]]
    assert carried and all(n.startswith("R/") for n in carried)  # its own correction, not S1's or S2's
    save_scene(scene, tmp_path / "R.json")
    back = load_scene(tmp_path / "R.json")
    assert np.array_equal(back.correction, scene.correction)
    rpcs = refined_rpcs(out.scenes)
    assert set(rpcs) == {"R"} and rpcs["R"][1] == "refitted"
    rng = np.random.default_rng(9)
    col, row = rng.uniform(0, scene.camera.cols, 500), rng.uniform(0, scene.camera.rows, 500)
    lon, lat, h = ecef_to_geodetic(scene.image_to_ground(col, row, rng.uniform(300.0, 900.0, 500)))
    ds = gdal.GetDriverByName("MEM").Create("", scene.camera.cols, scene.camera.rows, 1)
    ds.SetMetadata(rpc_metadata(rpcs["R"][0]), "RPC")
    pts = np.array(gdal.Transformer(ds, None, ["METHOD=RPC"]).TransformPoints(1, np.c_[lon, lat, h].tolist())[0])
    assert np.max(np.hypot(pts[:, 0] - col, pts[:, 1] - row)) < 0.01


def test_rpc_only_block(block):
    """Three RPC products (S1's nadir, S2's forward, R), 182 tie observations among them and GCPs on
    a 3 x 3 lattice of each image (46 observations): each image's correction recovered and its check
    RMSE at its floor. Measured (px): R 0.456 / 0.423, S1 0.427 / 0.416, S2 0.437 / 0.442; S1's
    shift a0 4.20 (truth 4.0, sigma 0.15), b0 -1.64 (-1.5, 0.17), S2's -1.99 (-2.0, 0.08), -3.07
    (-3.0, 0.08), R's a0 -3.12, b0 2.63, b2 -0.0045 (sigmas 0.14, 0.17, 0.0006); tie RMS 3.4 px
    before, 0.26 after; 0.3-0.5 s. With 4 GCPs in the corners of S1's nadir and R's images only, R
    and S2 stay 10-13 % above their floors: the drift terms are then determined to 0.3-0.6 px at
    the images' ends."""
    ties, gcps, truth = block.tables(block.rpc_true, "lattices")
    out = adjust_block(block.rpc_vendor, gcps, ties, SETTINGS)
    assert_floor(out, gcps, truth, block.rpc_vendor)
    truths = {"R": TRUE_CORRECTION, **{name: -bias for name, (_, bias) in PRODUCTS.items()}}
    for name, entry in out.report["scenes"].items():
        assert entry["model"] == "rpc"
        assert entry["ties"]["rmse_px"] < entry["ties"]["rmse_before_px"], name
        for term, (value, sigma) in correction_terms(entry).items():
            truth_value = truths[name].ravel()[TERMS.index(term)]
            assert abs(value - truth_value) < 3.0 * sigma, (name, term, value, truth_value, sigma)
    assert out.adjustment.report["trajectory"] is None


def test_rpc_ties_only_block_is_held_by_the_vendor_accuracy(block):
    """No GCPs: the RPC images' stated accuracy (RPC_SIGMA 5 px; their biases are 2-4 px) holds
    where the block lies, and the report says so; without it the datum is a defect, refused naming
    RPC_SIGMA. Measured: tie RMS 3.4 px before, 0.29 after; moved from the vendor
    geolocation R 5.3 m, S1 24.2 m, S2 22.0 m against stated 11.1, 25.0, 27.8 m (5 px)."""
    ties, _, _ = block.tables(block.rpc_true)
    settings = replace(SETTINGS, rpc_sigma=5.0)
    out = adjust_block(block.rpc_vendor, None, ties, settings)
    rep = out.report
    assert "RPC correction priors" in rep["datum"] and "no control points" in rep["datum"]
    assert rep["block"]["tie_rmse_px"] < 0.5 < rep["block"]["tie_rmse_before_px"]
    for name, entry in rep["scenes"].items():
        assert entry["moved_m"] <= 3.0 * entry["vendor_sigma_m"], (name, entry["moved_m"], entry["vendor_sigma_m"])
    components = out.adjustment.report["variance_components"]["RPC correction pseudo-observations"]
    assert components["holds_datum"] and not components["estimated"]
    with pytest.raises(InputError, match=r"datum defect.*Give RPC_SIGMA \(the vendor's stated accuracy") as err:
        adjust_block(block.rpc_vendor, None, ties, SETTINGS)
    assert err.value.parameter == "settings.rpc_sigma" and "settings." not in str(err.value)


def test_bad_rpc_block_input_is_named(block):
    ties, gcps, _ = block.tables(block.rpc_true)
    with pytest.raises(InputError, match="INTERIOR") as err:
        adjust_block(block.rpc_vendor, gcps, ties, replace(SETTINGS, interior="*.k1"))
    assert err.value.parameter == "settings.interior"
    with pytest.raises(InputError, match="^RPC_SIGMA must be empty") as err:
        adjust_block(block.rpc_vendor, gcps, ties, replace(SETTINGS, rpc_sigma=-1.0))
    assert err.value.parameter == "settings.rpc_sigma"
    unobserved = RpcScene(block.rpc_vendor["R"].rpc, block.rpc_vendor["R"].camera)
    with pytest.raises(InputError, match="'P'.*no control point or tie point"):
        adjust_block({**block.rpc_vendor, "P": unobserved}, gcps, ties, SETTINGS)


# --- the block's problem: what each camera's parameters are, how the unknowns are numbered ------------
STEPS = {"m": 1e-5, "rad": 1e-5, "px": 0.5, "px/px": 1e-3}
"""A change in each parameter's unit that moves an imaged point by a tenth of a pixel or more (a
position by 1 m; other lengths are in the focal plane: 10 um)."""


def block_problem(scenes: dict, tables: tuple, settings: AdjustmentSettings) -> BlockProblem:
    """The problem the engine solves for the block ``scenes`` and its (ties, gcps, _) ``tables``."""
    ties, gcps, _ = tables
    composite, gcps, ties, _ = block_inputs(scenes, gcps, ties, None)
    return BlockProblem(composite, check_inputs(composite, gcps, settings, ties), settings,
                        set_up_ties(composite, ties))


def moved_cameras(problem: BlockProblem, j: int) -> set:
    """The cameras (indices) whose observations move (> 1e-6 px) when free parameter j changes."""
    values = problem.params.values()
    before = problem.residuals()
    changed = values.copy()
    p = problem.params.params[j]
    changed[j] += 1.0 if p.block == "position" else STEPS[p.unit]
    problem.params.set_values(changed)
    try:
        after = problem.residuals()
    finally:
        problem.params.set_values(values)
    assert np.isfinite(after).all(), p.name
    return set(np.unique(problem.obs.camera[np.abs(after - before).max(axis=1) > 1e-6]).tolist())


def assert_imaged_by_is_what_moves(problem: BlockProblem) -> None:
    """Every free parameter is marked imaged by exactly the cameras whose observations it moves."""
    cameras = range(len(problem.scene.cameras))
    marked = np.array([problem.params.imaged_by(c) for c in cameras])  # (cameras, parameters)
    for j in problem.params.free:
        name = problem.params.params[j].name
        assert set(np.nonzero(marked[:, j])[0].tolist()) == moved_cameras(problem, j), name


def test_block_parameters_imaged_by_marks_what_each_camera_sees(block):
    """Two rigorous TH-1 scenes (their trajectories, S1's nadir chip and S2's forward focal length
    free) and R's RPC image (a0, a2, b0, b2 free): each of the 32 free parameters is marked for
    exactly the cameras whose observations it moves (changed one at a time)."""
    problem = block_problem(block.onboard, block.tables(block.true),
                            replace(SETTINGS, interior="S1/NAD-1.*, S2/FWD.f"))
    names = [c.name for c in problem.scene.cameras]
    assert names == ["S1/NAD", "S1/FWD", "S1/BWD", "S2/NAD", "S2/FWD", "S2/BWD", "R/PAN"]
    assert problem.params.free.size == 24 + 4 + 4
    assert_imaged_by_is_what_moves(problem)
    params = problem.params.params
    rpc = problem.params.imaged_by(names.index("R/PAN"))
    assert [params[j].name for j in np.nonzero(rpc)[0]] == [f"R/PAN.{t}" for t in TERMS]  # fixed ones too
    nadir = problem.params.imaged_by(names.index("S1/NAD"))
    assert {params[j].name for j in np.nonzero(nadir)[0] if params[j].block in ("chip", "camera")} >= \
        {"S1/NAD-1.dx", "S1/NAD-1.dy", "S1/NAD-1.theta"}
    assert not any(params[j].name.startswith(("S2", "R/", "S1/FWD", "S1/BWD")) for j in np.nonzero(nadir)[0])


def test_block_unknowns_are_the_rigorous_ones_then_each_images_free_terms(block):
    """The mixed block (24 rigorous unknowns, then R's 4) and three RPC images alone (4 each, in the
    block's order): the free parameters numbered in order, the rigorous composite's first, then
    each RPC image's free terms together; an RPC observation's columns are exactly its image's."""
    for scenes, tables, rigorous in ((block.onboard, block.tables(block.true), 24),
                                     (block.rpc_vendor, block.tables(block.rpc_true, "lattices"), 0)):
        problem = block_problem(scenes, tables, SETTINGS)
        params, unknown, free = problem.params.params, problem.unknown, problem.params.free
        np.testing.assert_array_equal(unknown[free], np.arange(free.size))
        assert (np.delete(unknown, free) == -1).all()
        assert all(params[j].block in ("position", "attitude") for j in free[:rigorous])
        cameras = problem.scene.cameras[problem.scene.n_rigorous:]
        assert len(cameras) == len(scenes) - (2 if rigorous else 0)
        assert free.size == rigorous + 4 * len(cameras)
        for k, cam in enumerate(cameras):
            mine = rigorous + 4 * k + np.arange(4)  # drift mode: a0, a2, b0, b2
            assert [params[j].name for j in free[mine]] == [f"{cam.name}.{t}" for t in ("a0", "a2", "b0", "b2")]
            rows = problem.columns[problem.obs.camera == problem.scene.n_rigorous + k]
            assert rows.shape[0] > 0
            assert all(sorted(r[r >= 0].tolist()) == mine.tolist() for r in rows), cam.name
    assert_imaged_by_is_what_moves(problem)  # the RPC images alone: each image's terms move it alone
