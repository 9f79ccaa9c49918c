"""A small rendered scene with a reference orthoimage, for the matching tests: the CBERS-02B HRC
geometry (778 km, 2.36 m GSD, staggered CCDs) cut down to two CCDs of 1024 px and 1200 rows, so
it renders in seconds. Its onboard model is about 150-250 m off (attitude and position biases)."""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.geodesy import geodetic_to_ecef
from pushbroom_adjust.core.measure.matching import MatchSettings
from pushbroom_adjust.core.measure.tiematching import match_tiepoints
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation.presets import PRESETS, CameraSpec, ErrorSettings, Preset, cut_preset
from pushbroom_adjust.simulation.simulator import SimulationResult, simulate
from pushbroom_adjust.core.observations.tiepoints import TieTable

MINI = Preset("mini_hrc", "CBERS-02B HRC geometry, 2 CCDs of 1024 px, 1200 rows", 778e3,
              (CameraSpec("HRC", 3.3, 10e-6, 2, 1024, overlap=21, stagger=0.8e-3),), 1200,
              ErrorSettings(position_bias=40.0, attitude_bias=3e-4, ccd_shift=1.0))
SEARCH = 500.0  # m: the search range the mini scene's size allows (the coarse chips must fit in it)


def mini_scene(folder: Path, seed: int = 5) -> SimulationResult:
    """Simulate and render the mini scene (with its reference.tif) into ``folder``."""
    return simulate(MINI, folder, seed=seed, n_gcps=20, render=True)


def true_errors(folder: Path, table) -> np.ndarray:
    """Distances (px) between matched image positions and the true scene's projection of their ground."""
    scene = load_scene(Path(folder) / "true_scene.json")
    col, row = scene.ground_to_image(geodetic_to_ecef(table.lon, table.lat, table.h), 0)
    return np.hypot(col - table.col, row - table.row)


def manifest(folder: Path) -> dict:
    return json.loads((Path(folder) / "simulation.json").read_text())


MINI_TLC = Preset("mini_tlc", "TH-1 three-line geometry cut down to 1500 px x 1200 rows", 500e3,
                  (CameraSpec("NAD", 1.0, 10e-6, 1, 1500),
                   CameraSpec("FWD", 1.0, 10e-6, 1, 1500, tilt=0.436332),
                   CameraSpec("BWD", 1.0, 10e-6, 1, 1500, tilt=-0.436332)), 1200,
                  ErrorSettings(position_bias=10.0, attitude_bias=1e-4, focal=1.0, installation=1e-4),
                  inclination=1.698, centre=(113.5, 35.0))


def mini_tlc_scene(folder: Path, seed: int = 7) -> SimulationResult:
    """Simulate and render the three-line mini scene (a 12 km strip of 5 m pixels) into ``folder``."""
    return simulate(MINI_TLC, folder, seed=seed, n_gcps=20, render=True)


def th1_cut(cols: int, rows: int) -> Preset:
    """The TH-1 preset (its trajectory, installation and interior errors; seed 001) with its three
    cameras cut down to ``cols`` detectors and ``rows`` lines, so it renders in seconds
    (:func:`simulation.presets.cut_preset`: the interior errors scaled by cols / 12000)."""
    return cut_preset(PRESETS["th1_tlc"], cols, rows)


def exact_ties(true, dem, matched: TieTable) -> TieTable:
    """Perfect tie points at the matched ones' positions: each base (first camera) observation kept,
    the other cameras' observations the true scene's projections of the true ground it sees; the
    same ids and sigmas."""
    base = matched.camera == true.cameras[0].name
    where = {i: k for k, i in enumerate(matched.id[base])}
    at = np.array([where[i] for i in matched.id])
    ground = true.image_to_ground_dem(matched.col[base][at], matched.row[base][at], dem, 0)
    col, row = matched.col.copy(), matched.row.copy()
    for k, cam in enumerate(true.cameras[1:], start=1):
        sel = matched.camera == cam.name
        col[sel], row[sel] = true.ground_to_image(ground[sel], k)
    return replace(matched, col=col, row=row, apriori=None)


def tie_errors(exact: TieTable, matched: TieTable) -> np.ndarray:
    """Distances (px) between matched and exact observations (the base ones are 0)."""
    return np.hypot(exact.col - matched.col, exact.row - matched.row)


@dataclass
class TieComparison:
    """Matched against exact tie points on a rendered three-line scene: the matching (table,
    rejected counts, seconds), per-camera errors against the truth (px), and the 3D check-point
    figures (report['check_points']['intersection']) of the same adjustment with the matched
    and with the exact ties; the adjustment's reports and its GCP table."""
    matched: TieTable
    rejected: dict
    seconds: float
    errors: dict
    with_matched: dict
    with_exact: dict
    reports: dict
    gcps: G.GcpTable


def compare_ties(sim: SimulationResult, n_control: int, settings: MatchSettings,
                 adjustment: AdjustmentSettings) -> TieComparison:
    """Match tie points on ``sim`` (a rendered three-line simulation with check points), then
    adjust with the ``n_control`` control points nearest the nadir image's corners and edges and
    (a) the matched, (b) exact tie points at the same positions."""
    onboard, true, dem = load_scene(sim.onboard_scene), load_scene(sim.true_scene), Dem(sim.dem, "geoid")
    images = {k: sim.images[c.name] for k, c in enumerate(onboard.cameras)}
    start = time.perf_counter()
    matched, rejected = match_tiepoints(onboard, images, dem, settings)
    seconds = time.perf_counter() - start
    exact = exact_ties(true, dem, matched)
    e = tie_errors(exact, matched)
    errors = {c.name: e[matched.camera == c.name] for c in onboard.cameras[1:]}
    table = few_control(G.read_csv(sim.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                                   Heights("z", datum="ellipsoid"), sigma_px=0.3, sigma_xy=0.01, sigma_z=0.01),
                        onboard.cameras[0], n_control)
    runs = {name: adjust(onboard, table, adjustment, ties=ties).report
            for name, ties in (("matched", matched), ("exact", exact))}
    inter = {k: r["check_points"]["intersection"] for k, r in runs.items()}
    return TieComparison(matched, rejected, seconds, errors, inter["matched"], inter["exact"], runs, table)


def few_control(table, cam, n: int):
    """The check points and the control points (all their observations) nearest n spots spread over
    camera ``cam``'s image (corners first, then edge middles and the centre)."""
    spots = np.array([[0, 0], [1, 1], [0, 1], [1, 0], [0.5, 0], [0.5, 1], [0, 0.5], [1, 0.5], [0.5, 0.5]])[:n]
    control = (table.role == "control") & (table.camera == cam.name)
    xy = np.stack([table.col[control] / cam.cols, table.row[control] / cam.rows], axis=1)
    chosen = table.id[control][[int(np.argmin(np.linalg.norm(xy - s, axis=1))) for s in spots]]
    return table.select((table.role == "check") | np.isin(table.id, chosen))
