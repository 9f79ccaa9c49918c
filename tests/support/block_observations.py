"""Image observations of known ground points in every camera of a block's scenes, with noise: the
measurements of the simulated blocks of tests/unit/adjust/test_block.py and
tests/support/mixed_block.py."""
from __future__ import annotations

import numpy as np

MARGIN = 5.0  # px: observations this far inside the image


def measure_block(scenes: dict, ground: np.ndarray, rng: np.random.Generator, noise: float) -> dict:
    """Observations of ECEF points ``ground`` (p, 3) in every camera of ``scenes`` (name -> rigorous
    or RPC scene) that sees them MARGIN px inside its image, with normal noise of ``noise`` px per
    axis drawn from ``rng`` (col, then row, camera by camera): point (index), scene, camera, col, row
    (n,) arrays, and true_col, true_row (without the noise)."""
    out = {k: [] for k in ("point", "scene", "camera", "col", "row", "true_col", "true_row")}
    for name, scene in scenes.items():
        for c, cam in enumerate(scene.cameras):
            col, row = scene.ground_to_image(ground, c)
            ok = np.isfinite(col) & (col > MARGIN) & (col < cam.cols - MARGIN) & (row > MARGIN) & \
                (row < cam.rows - MARGIN)
            n = int(ok.sum())
            out["point"].append(np.nonzero(ok)[0])
            out["scene"] += [name] * n
            out["camera"] += [cam.name] * n
            out["true_col"].append(col[ok])
            out["true_row"].append(row[ok])
            out["col"].append(col[ok] + rng.normal(0.0, noise, n))
            out["row"].append(row[ok] + rng.normal(0.0, noise, n))
    return {k: np.array(v) if k in ("scene", "camera") else np.concatenate(v) for k, v in out.items()}
