"""The seed-001-sized TH-1 three-line block (Zhang et al. 2015 analogue): simulated with 9 GCPs
measured in all three cameras, 25 tie points and many check points, and adjusted conventionally,
self-calibrated, at the floor (the true interior) and with 1 GCP; the check figures of each run.
Used by tests/bench/bench_seed001_th1.py (which prints them) and tests/scenarios/test_seed001.py
(which asserts them)."""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.model.camera import CAMERA_TERMS
from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations import tiepoints as T
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate

IMAGE_NOISE, GROUND_XY, GROUND_Z = 0.7, 0.1, 0.2  # seed 001: manual measurement 0.5-1 px; GCPs 0.1 m / 0.2 m
CONTROL, TIES, CHECKS = 9, 25, 80
FREE_SET = ", ".join(f"*.{term}" for term in CAMERA_TERMS)  # eq. 7's 10 terms of every camera, free
# Seed 001 adjusts the attitude (bias and rates) of a GPS-positioned platform; the defaults of
# bundleadjust otherwise (robust selection, variance components).
SETTINGS = AdjustmentSettings(position_order=0, position_sigma=10.0, attitude_order=2)
# 1 GCP: the onboard positions hold the datum's shifts, pitch and roll firmly, its yaw only weakly (a block
# rotation about the vertical through the GCP moves the orbit by metres); the star trackers (about the
# preset's attitude bias) hold it: ATTITUDE_SIGMA.
ATTITUDE_SIGMA = 1e-4  # rad, 20 arcsec
RUNS = ("conventional", "default + removal", "default kept", "free 10 + removal", "free 10 kept",
        "floor (true interior)", "1 GCP + ties, default", "1 GCP + ties + attitude")
"""The adjustments :func:`block` can make, by name."""
SPREAD_CANDIDATES = 6  # points simulated per control point of a spread layout (the nearest to each node is taken)


@dataclass
class Run:
    """One adjustment's check figures (m): monoplotted plan RMSE, 3D plan and height RMSE,
    intersected / check points, the interior selection outcome and the datum sentence."""
    mono: float
    plan: float
    height: float
    intersected: int
    points: int
    outcome: str
    kept: int
    datum: str


def adjusted_run(scene, table, ties, interior: str, selection: str, settings: AdjustmentSettings) -> Run:
    """Adjust ``scene`` with ``table`` and ``ties`` by ``settings`` with INTERIOR ``interior`` and
    interior selection ``selection``; its :class:`Run` figures."""
    out = adjust(scene, table, replace(settings, interior=interior, interior_selection=selection), ties=ties)
    rep = out.report
    inter = rep["check_points"]["intersection"]
    sel = rep.get("interior_selection") or {}
    held = rep.get("datum") or {}
    sentence = f"datum held by {held.get('held_by', '?')}" + (f": {held['note']}" if held.get("note") else "")
    return Run(rep["check_points"]["ground"]["rmse"], inter["rmse_plan"], inter["rmse_height"], inter["intersected"],
               inter["points"], sel.get("outcome", "-" if not interior else "kept as given"), len(sel.get("kept", [])),
               sentence)


def spread_control(table: G.GcpTable, cols: int, rows: int, control: int, checks: int) -> G.GcpTable:
    """``table`` with the point nearest each node of a k x k grid over the nadir image (k =
    ceil(sqrt(control)), the first ``control`` nodes, 8 % margins; positions in px of the nadir
    camera's cols x rows image) as control and ``checks`` of the others as check points."""
    k = math.ceil(math.sqrt(control))
    axis = np.linspace(0.08, 0.92, k)
    nodes = np.array([(x * cols, y * rows) for x in axis for y in axis])[:control]
    nad = table.camera == "NAD"
    ids, at = table.id[nad], np.column_stack([table.col[nad], table.row[nad]])
    distance = np.linalg.norm(at[None, :, :] - nodes[:, None, :], axis=2)  # (nodes, points)
    chosen: list[str] = []
    for row in distance:
        chosen.append(next(ids[j] for j in np.argsort(row) if ids[j] not in chosen))
    others = [i for i in dict.fromkeys(table.id) if i not in chosen][:checks]
    keep = np.isin(table.id, chosen + others)
    role = np.where(np.isin(table.id, chosen), "control", "check")
    return replace(table, role=role).select(keep)


def exact_control(table: G.GcpTable, gcps_csv: Path) -> G.GcpTable:
    """``table`` with its control points' col, row, lon, lat, h replaced by the simulation's
    true values (columns col_true ... h_true of ``gcps_csv``, matched by id and camera)."""
    truth = {(r["id"], r["camera"]): r for r in csv.DictReader(gcps_csv.open())}
    out = replace(table, **{f: getattr(table, f).copy() for f in ("col", "row", "lon", "lat", "h")})
    for k in np.flatnonzero(table.role == "control"):
        r = truth[(table.id[k], table.camera[k])]
        for f in ("col", "row", "lon", "lat", "h"):
            getattr(out, f)[k] = float(r[f"{f}_true"])
    return out


def block(seed: int, folder: Path, checks: int = CHECKS, runs=RUNS, control: int = CONTROL,
          layout: str = "random", exact: bool = False) -> dict[str, Run]:
    """Simulate the seed-001-sized TH-1 block ``seed`` in ``folder`` (``control`` GCPs laid out
    as ``layout``, ``checks`` check points) and adjust it as ``runs``."""
    points = control + checks if layout == "random" else SPREAD_CANDIDATES * control + checks
    result = simulate("th1_tlc", folder, seed=seed, gcp_settings=GcpSettings(
        n_gcps=points, check_fraction=checks / points, image_noise=IMAGE_NOISE, ground_noise_xy=GROUND_XY,
        ground_noise_z=GROUND_Z, n_tie_points=TIES))
    table = G.read_csv(result.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                       Heights("z", datum="ellipsoid"), sigma_px=IMAGE_NOISE, sigma_xy=GROUND_XY,
                       sigma_z=GROUND_Z)
    ties = T.read_csv(result.tie_points, sigma_px=IMAGE_NOISE)
    onboard, true = load_scene(result.onboard_scene), load_scene(result.true_scene)
    if layout == "spread":
        table = spread_control(table, onboard.cameras[0].cols, onboard.cameras[0].rows, control, checks)
    if exact:
        table = exact_control(table, Path(result.gcps))
    floor = replace(onboard, cameras=true.cameras, _guess={})  # true interior, onboard trajectory
    one = table.id[table.role == "control"][0]
    one_gcp = table.select((table.role == "check") | (table.id == one))
    star_trackers = replace(SETTINGS, attitude_sigma=ATTITUDE_SIGMA)
    plans = {"conventional": (onboard, table, "", "significant", SETTINGS),
             "default + removal": (onboard, table, "default", "significant", SETTINGS),
             "default kept": (onboard, table, "default", "keep", SETTINGS),
             "free 10 + removal": (onboard, table, FREE_SET, "significant", SETTINGS),
             "free 10 kept": (onboard, table, FREE_SET, "keep", SETTINGS),
             "floor (true interior)": (floor, table, "", "significant", SETTINGS),
             "1 GCP + ties, default": (onboard, one_gcp, "default", "significant", SETTINGS),
             "1 GCP + ties + attitude": (onboard, one_gcp, "default", "significant", star_trackers)}
    return {name: adjusted_run(*plans[name][:2], ties, *plans[name][2:]) for name in runs}
