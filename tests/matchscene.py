"""A small rendered scene with a reference orthoimage, for the matching tests: the CBERS-02B HRC
geometry (778 km, 2.36 m GSD, staggered CCDs) cut down to two CCDs of 1024 px and 1200 rows, so
it renders in seconds. Its onboard model is about 150-250 m off (attitude and position biases)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from core.geodesy import geodetic_to_ecef
from core.scene_io import load_scene
from core.simulator import CameraSpec, ErrorSettings, Preset, SimulationResult, simulate

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
