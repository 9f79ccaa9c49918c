"""GCPs on an RPC scene with a known image bias, for the bias compensation (core.adjust.rpcbias,
Grodecki & Dial 2003): the ground of random image points by the vendor RPC, their image positions
moved by a shift and drift along the rows and measured with noise."""
from __future__ import annotations

import numpy as np

from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.observations.gcps import GcpTable

NOISE = 0.3  # px
"""The image noise of the simulated measurements (px), and their sigma_px."""
BIAS = np.array([[3.2, 0.0, 2e-5], [-1.7, 0.0, -1.5e-5]])  # shift and drift along the rows
"""The image bias added: rows (col, row) of (offset px, per col, per row), the RPC scene's correction layout."""


def biased_gcps(scene, bias, n=80, n_control=30, seed=5) -> tuple[GcpTable, np.ndarray, np.ndarray]:
    """GCPs at random image points and heights: ground by the vendor RPC, image positions with
    ``bias`` (the RPC scene's correction layout) and NOISE; the first ``n_control`` are control
    points, the others check points; (table, true col, true row)."""
    rng = np.random.default_rng(seed)
    cam = scene.cameras[0]
    col, row = rng.uniform(0, cam.cols, n), rng.uniform(0, cam.rows, n)
    lo, hi = scene.height_range
    lon, lat, h = ecef_to_geodetic(scene.image_to_ground(col, row, rng.uniform(lo, hi, n)))
    measured_col = col + bias[0, 0] + bias[0, 1] * col + bias[0, 2] * row + rng.normal(0, NOISE, n)
    measured_row = row + bias[1, 0] + bias[1, 1] * col + bias[1, 2] * row + rng.normal(0, NOISE, n)
    role = np.where(np.arange(n) < n_control, "control", "check")
    table = GcpTable(id=[f"p{i}" for i in range(n)], role=role, camera="", col=measured_col, row=measured_row,
                     lon=lon, lat=lat, h=h, sigma_px=NOISE, sigma_xy=0.05, sigma_z=0.1)
    return table, col, row
