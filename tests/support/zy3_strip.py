"""The simulated ZY-3 three-line strip of Zhang et al. 2024 (seed 003) and its adjustment by Plans
A-D: the strip with GCPs in all cameras and tie points, the control layouts (4 corner GCPs, 16 on
a 2 x 8 grid, none), and the figures a run is judged by. Used by tests/bench/bench_seed003_zy3.py
(which prints them over several seeds) and tests/scenarios/test_seed003.py (which asserts the key ones);
the plans and the strip are described in the bench's docstring."""
from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.adjust.checkpoints import intersection_accuracy
from pushbroom_adjust.core.adjust.parameters import ANGLES, DEFAULT_INSTALLATION_ARCSEC
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.model.sensor import SceneModel
from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.observations.tiepoints import CsvMapping, TieTable, read_csv
from pushbroom_adjust.core.rotations import ARCSEC
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.presets import CAMERA_ERRORS
from pushbroom_adjust.simulation.simulator import simulate

NOISE_PX, GROUND_M = 0.3, 0.1
INSTALLATION = ", ".join(f"{cam}.{a}" for cam in ("FWD", "BWD") for a in ANGLES)
# the laboratory installation as a prior (INTERIOR=default's 30"): holds what no GCP does
WEIGHTED = ", ".join(f"{name}={DEFAULT_INSTALLATION_ARCSEC:g}arcsec" for name in INSTALLATION.split(", "))
# the preset's interior errors that no plan models (see tests/bench/bench_seed003_zy3.py's docstring)
NO_CAMERA_ERRORS = {"ccd_shift": 0.0, "ccd_rotation": 0.0, **dict.fromkeys(CAMERA_ERRORS, 0.0)}
BASE = AdjustmentSettings(position_sigma=10.0, attitude_sigma=1e-4, robust="none")
PLANS = {"A": {"camera_trajectory": "per_camera", "attitude_order": 1},
         "B": {"interior": INSTALLATION, "attitude_order": 0, "interior_selection": "keep"},
         "C": {"interior": INSTALLATION, "attitude_order": 1, "interior_selection": "keep"},
         "D": {"interior": INSTALLATION, "attitude_order": 2, "interior_selection": "keep"}}
GRID = [(x, y) for x in (0.25, 0.75) for y in np.linspace(1 / 16, 15 / 16, 8)]
CORNERS = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]


@dataclass
class Strip:
    """A simulated strip: onboard scene, GCPs (all 'control' as simulated), tie points, the
    onboard trajectory with the true cameras (its errors alone), the true installation
    angles (camera -> (roll, pitch, yaw) rad), the true scene (trajectory and cameras) and the
    GCPs with their noise-free image positions (``exact``, row for row as ``table``)."""
    scene: SceneModel
    table: G.GcpTable
    ties: TieTable
    onboard_trajectory: SceneModel
    installation: dict
    true: SceneModel
    exact: G.GcpTable


def simulate_strip(folder: Path, seed: int, scenes: int, gcps: int, ties: int, preset_errors: bool) -> Strip:
    """Simulate a ZY-3 strip of ``scenes`` scenes (``seed``) into ``folder``: ``gcps`` GCPs measured in
    all cameras and ``ties`` tie points, NOISE_PX image and GROUND_M ground noise; the preset's
    trajectory and installation errors, its camera and CCD errors too only with ``preset_errors``."""
    result = simulate("zy3_tlc", folder, seed=seed, n_scenes=scenes, errors=None if preset_errors else NO_CAMERA_ERRORS,
                      gcp_settings=GcpSettings(n_gcps=gcps, image_noise=NOISE_PX, ground_noise_xy=GROUND_M,
                                               ground_noise_z=GROUND_M, n_tie_points=ties))
    def read(**image) -> G.GcpTable:
        return G.read_csv(result.gcps, G.CsvMapping(z="h", role="role", camera="camera", **image), "EPSG:4326",
                          Heights("z", datum="ellipsoid"), sigma_px=NOISE_PX, sigma_xy=GROUND_M, sigma_z=GROUND_M)

    table = read()
    onboard, true = load_scene(result.onboard_scene), load_scene(result.true_scene)
    truth = json.loads(result.manifest.read_text())["truth"]
    return Strip(onboard, table, read_csv(result.tie_points, CsvMapping(), sigma_px=NOISE_PX),
                 replace(onboard, cameras=true.cameras, _guess={}),
                 {t["camera"]: t["installation_error_rad"] for t in truth["interior"]}, true,
                 read(col="col_true", row="row_true"))


def control_layouts(strip: Strip) -> dict[int, np.ndarray]:
    """GCP ids per layout: 0, 4 (nearest the strip's corners in the NAD image) and 16 (nearest
    a 2 x 8 grid); candidates are the points seen in all cameras."""
    table, nad = strip.table, strip.scene.cameras[0]
    ids, counts = np.unique(table.id, return_counts=True)
    m = (table.camera == nad.name) & np.isin(table.id, ids[counts == len(strip.scene.cameras)])
    xy = np.stack([table.col[m] / nad.cols, table.row[m] / nad.rows], axis=1)

    def nearest(targets) -> np.ndarray:
        return table.id[m][[int(np.argmin(np.linalg.norm(xy - np.array(t), axis=1))) for t in targets]]

    return {0: np.array([], str), 4: nearest(CORNERS), 16: nearest(GRID)}


def gcp_table(strip: Strip, layouts: dict, n: int) -> G.GcpTable:
    """The GCPs of layout ``n`` as control and every GCP of no layout as check point (the same
    check points for all layouts)."""
    used = np.concatenate(list(layouts.values()))
    control = np.isin(strip.table.id, layouts[n])
    sub = strip.table.select(control | ~np.isin(strip.table.id, used))
    sub.role = np.where(np.isin(sub.id, layouts[n]), "control", "check")
    return sub


def figures(strip: Strip, out, table: G.GcpTable) -> dict:
    """What a run is judged by: 3D check RMSE (east, north, plan, height m), tie residual RMSE
    per camera (col, row px), installation angles (name -> estimate, sigma, (estimate - truth)
    / sigma, in arcsec), the datum sentence, the interior selection, the per-point 3D errors."""
    rep = out.report
    inter = rep["check_points"]["intersection"]
    ties = {cam: (r["rmse_col"], r["rmse_row"]) for cam, r in rep["tie_points"]["residuals_per_camera"].items()}
    installation = {}
    for p in rep["parameters"]:
        if p["block"] == "installation" and p["sigma"]:
            cam, angle = p["name"].split(".")
            true = strip.installation[cam][ANGLES.index(angle)]
            installation[p["name"]] = (p["value"] / ARCSEC, p["sigma"] / ARCSEC, (p["value"] - true) / p["sigma"])
    datum = rep.get("datum") or {}
    checks = np.nonzero(table.role == "check")[0]
    return {"check": {k: inter[f"rmse_{k}"] for k in ("east", "north", "plan", "height")},
            "check_points": inter["intersected"], "ties": ties,
            "tie_points": rep["tie_points"]["points"], "installation": installation,
            "datum": f"datum held by {datum.get('held_by')}" + (f": {datum['note']}" if "note" in datum else ""),
            "determinability": rep["determinability"], "selection": rep.get("interior_selection"),
            "errors": intersection_accuracy(out.scene, table, checks)["errors"]}


def run(strip: Strip, table: G.GcpTable, plan: str, **extra) -> dict:
    """Adjust ``strip`` with ``table`` and the tie points by ``plan`` (A-D); its :func:`figures`."""
    out = adjust(strip.scene, table, replace(BASE, **{**PLANS[plan], **extra}), ties=strip.ties)
    return figures(strip, out, table)


def noise_free_control(strip: Strip, table: G.GcpTable) -> G.GcpTable:
    """``table`` with the control points' image positions without their noise (the check
    points keep theirs: the same noise floor)."""
    key = np.char.add(np.char.add(strip.exact.id.astype(str), "/"), strip.exact.camera.astype(str))
    order = np.argsort(key)
    control = np.nonzero(table.role == "control")[0]
    wanted = np.char.add(np.char.add(table.id[control].astype(str), "/"), table.camera[control].astype(str))
    rows = order[np.searchsorted(key[order], wanted)]
    out = table.select(np.arange(len(table.id)))
    out.col, out.row = out.col.copy(), out.row.copy()
    out.col[control], out.row[control] = strip.exact.col[rows], strip.exact.row[rows]
    return out
