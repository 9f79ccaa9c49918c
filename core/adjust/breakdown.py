"""Signs that the robust estimation of :mod:`core.adjust.robust` broke down, per CCD chip.

Breakdown. A robust estimator fails when the bad observations are too many or agree with
each other: it then keeps the wrong ones, or flags the good ones, and reports small
residuals. Three signs are tested per CCD chip (observations of one camera and chip, at
least MIN_GROUP of them), each named in the report:

- too many flagged: more than BREAKDOWN_SHARE of the chip's observations flagged. Random
  gross errors spread over the chips evenly; beyond 40 % the kept observations are barely a
  majority and the median-based scale itself is near its 50 % breakdown point, so no
  selection rule can be trusted to have kept the right ones;
- systematic: the flagged observations of a chip point the same way. Random blunders have
  uniformly distributed directions; the Rayleigh test (mean resultant length R of the unit
  residual vectors, p by Zar 1999 eq. 27.4) rejects uniformity at the adjustment's alpha and
  R >= SYSTEMATIC_RESULTANT (a half of them aligned). A shifted subset of measurements (a
  wrong datum, a mis-registered map sheet) looks like this; with SYSTEMATIC_SHARE or more of
  the chip the solution is pulled by it;
- inflated: the chip's inlier residuals are larger than those of the camera's other chips
  (F test at alpha on the Helmert ratios, and more than INFLATED_RATIO times): the chips of
  one camera share the measurement process, so a chip alone with large residuals carries a
  systematic error the model or the outlier test did not catch (e.g. a shift of half its
  observations by a few sigma, which makes its residual distribution bimodal).

Any of them makes the result "not reliable" (a warning in the log and the report, and in the
adjusted scene's adjustment info), except a systematic subset below SYSTEMATIC_SHARE, which
is named as a warning only: the outlier test removed it.

Reference: Zar, J. H. (1999): Biostatistical Analysis, 4th ed., Prentice Hall, ch. 27.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import stats

from ..model.block import chip_label
from ..model.sensor import rows_by
from .problem import Problem
from .robust import MIN_REDUNDANCY
from .statistics import Statistics

MIN_GROUP = 20
BREAKDOWN_SHARE = 0.4
SYSTEMATIC_RESULTANT = 0.5
SYSTEMATIC_SHARE = 0.1
MIN_SYSTEMATIC = 10
INFLATED_RATIO = 1.5


def rayleigh_p(n: int, resultant: float) -> float:
    """p-value of the Rayleigh test of uniform directions: n unit vectors with mean resultant
    length ``resultant`` (Zar 1999, eq. 27.4)."""
    rn = n * resultant
    return float(min(1.0, math.exp(math.sqrt(1.0 + 4.0 * n + 4.0 * (n * n - rn * rn)) - (1.0 + 2.0 * n))))


def breakdown(problem: Problem, st: Statistics, flagged: np.ndarray, inlier: np.ndarray) -> list[dict]:
    """Signs that the robust estimation broke down, per CCD chip (see the module docstring):
    each a dict with group, kind ('too_many_flagged', 'systematic', 'inflated'), share,
    reliable (False unless a small systematic subset the test removed) and message."""
    alpha = problem.settings.alpha
    found = []
    obs = problem.obs
    cameras = problem.scene.cameras
    for cam, rows in zip(cameras, rows_by(obs.camera, len(cameras))):  # rows, not masks: a region's 1,000 cameras
        chips = [(k, rows[obs.chip[rows] == k]) for k in range(len(cam.chips))]
        chips = [(k, m) for k, m in chips if m.size >= MIN_GROUP]
        for k, m in chips:
            name = chip_label(cam, k)
            n = int(m.size)
            share = float(flagged[m].mean())
            if share > BREAKDOWN_SHARE:
                found.append({"group": name, "kind": "too_many_flagged", "share": share, "reliable": False,
                              "message": f"{name}: {100 * share:.0f} % of its {n} image observations are flagged as "
                                         f"gross errors (more than {100 * BREAKDOWN_SHARE:.0f} %): beyond that share a "
                                         "robust estimation can keep the wrong observations and still show small "
                                         "residuals; check the chip's points"})
            found += _systematic(name, st.v[m[flagged[m]]], n, alpha)
            others = np.sort(np.concatenate([o for j, o in chips if j != k] + [np.zeros(0, np.int64)]))
            found += _inflated(name, st, m[inlier[m]], others[inlier[others]], alpha)
    return found


def _systematic(name: str, v: np.ndarray, n: int, alpha: float) -> list[dict]:
    """The flagged residuals v (k, 2) px of a chip of n observations pointing the same way."""
    if v.shape[0] < MIN_SYSTEMATIC:
        return []
    length = np.hypot(v[:, 0], v[:, 1])
    unit = v[length > 0] / length[length > 0, None]
    resultant = float(np.hypot(*unit.mean(axis=0)))
    p = rayleigh_p(unit.shape[0], resultant)
    if p >= alpha or resultant < SYSTEMATIC_RESULTANT:
        return []
    share = v.shape[0] / n
    mean = v.mean(axis=0)
    return [{"group": name, "kind": "systematic", "share": share, "reliable": share < SYSTEMATIC_SHARE,
             "message": f"{name}: {v.shape[0]} flagged image observations ({100 * share:.0f} % of the chip) have "
                        f"residuals pointing the same way (mean {mean[0]:+.2f} px col, {mean[1]:+.2f} px row; "
                        f"Rayleigh test p = {p:.1g}): a systematic error (e.g. a shifted set of measurements), "
                        "not random blunders"}]


def _inflated(name: str, st: Statistics, mine: np.ndarray, others: np.ndarray, alpha: float) -> list[dict]:
    """A chip whose inlier residuals are larger than those of its camera's other chips (``mine``,
    ``others``: their observations' indices)."""
    r_mine, r_other = float(st.redundancy[mine].sum()), float(st.redundancy[others].sum())
    if r_mine < MIN_REDUNDANCY or r_other < MIN_REDUNDANCY:
        return []
    f = (float(st.pvv[mine].sum()) / r_mine) / max(float(st.pvv[others].sum()) / r_other, 1e-300)
    if f <= stats.f.ppf(1.0 - alpha, r_mine, r_other) or math.sqrt(f) <= INFLATED_RATIO:
        return []
    return [{"group": name, "kind": "inflated", "share": None, "reliable": False,
             "message": f"{name}: its residuals are {math.sqrt(f):.1f} times those of the camera's other chips "
                        f"(F test, p < {alpha:g}): a systematic error in this chip's observations (e.g. part of "
                        "them shifted by a few sigma) or a model error"}]
