"""A simulated CBERS-02B HRC strip with known truth (seed 000's long-strip experiment) and the
adjustment settings of its benchmarks: orientation images every 20 s (4-point Lagrange) for
position and attitude, onboard GPS as 100 m pseudo-observations. Used by
tests/bench/bench_adjust_cbers.py and tests/bench/bench_robust_sigmas.py."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from pushbroom_adjust.core.adjust import AdjustmentSettings
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import geodetic_to_ecef
from pushbroom_adjust.core.observations import gcps as G
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate

IMAGE_NOISE, GROUND_XY, GROUND_Z = 0.7, 3.0, 10.0
"""The simulated measurement noise (px; m horizontal, m height: seed 000's matched points), and their sigmas."""


def settings(**kw) -> AdjustmentSettings:
    """The strip's adjustment settings (Lagrange trajectory every 20 s, 100 m position sigma, no
    robust estimation), with ``kw`` replacing any of them."""
    base = dict(position_model="lagrange", position_interval=20.0, attitude_model="lagrange",
                attitude_interval=20.0, position_sigma=100.0, robust="none")
    return AdjustmentSettings(**{**base, **kw})


def strip(folder: Path, scenes: int, gcps: int, seed: int = 1, **measure) -> tuple:
    """(simulation result, onboard scene, GCP table) of a simulated strip."""
    m = dict(n_gcps=gcps, image_noise=IMAGE_NOISE, check_fraction=0.5, ground_noise_xy=GROUND_XY,
             ground_noise_z=GROUND_Z)
    m.update(measure)
    result = simulate("cbers02b_hrc", folder, seed=seed, n_scenes=scenes, gcp_settings=GcpSettings(**m))
    return result, load_scene(result.onboard_scene), read_table(result.gcps)


def read_table(path) -> G.GcpTable:
    """The simulated GCPs of ``path`` (gcps.csv) with the strip's sigmas."""
    return G.read_csv(path, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                      Heights("z", datum="ellipsoid"), sigma_px=IMAGE_NOISE, sigma_xy=GROUND_XY, sigma_z=GROUND_Z)


def model_error(scene, result, rows: np.ndarray) -> float:
    """RMSE (px) of a scene's ground -> image of the true check points against their true image
    positions: the model's own error, free of the measurement noise only a simulation can remove."""
    g = np.genfromtxt(result.gcps, delimiter=",", names=True, dtype=None, encoding=None)[rows]
    col, row = scene.ground_to_image(geodetic_to_ecef(g["lon_true"], g["lat_true"], g["h_true"]))
    return float(np.sqrt(np.mean((col - g["col_true"]) ** 2 + (row - g["row_true"]) ** 2)))
