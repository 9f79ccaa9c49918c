"""Distances of image points to polylines (px), for checking predicted or digitised image lines
against a road's true image."""
import numpy as np


def distances_to_polylines(points: np.ndarray, runs: list) -> np.ndarray:
    """Distance (px) of each point (n, 2) to the nearest segment of the polylines ``runs``."""
    a = np.concatenate([r[:-1] for r in runs])
    b = np.concatenate([r[1:] for r in runs])
    d = b - a
    t = np.clip(np.einsum("nkj,kj->nk", points[:, None, :] - a, d) / np.einsum("kj,kj->k", d, d), 0.0, 1.0)
    return np.linalg.norm(points[:, None, :] - a - t[..., None] * d, axis=2).min(axis=1)
