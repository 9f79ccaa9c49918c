"""Robust estimation that does not trust the a-priori sigmas.

Variance components. The observations fall into groups: the image observations of each
camera ("image <camera>"), the planimetric and the height coordinates of the weighted
control points ("ground_xy", "ground_z") and the pseudo-observations (onboard position and
attitude, weighted interior parameters). Each group k gets a factor s_k on its a-priori
sigmas, estimated by Förstner's simplified Helmert estimator (Förstner 1979)

    s_k^2 <- s_k^2 * Omega_k / (kappa * r_k),   Omega_k = sum of p v^2,  r_k = sum of redundancy numbers

over the group's inliers (observations the robust step keeps), iterated with the solution
until every factor changes by less than COMPONENT_TOLERANCE. A factor is never below
MIN_FACTOR, nor is the first pass's robust scale: observations fitting far better than
their stated sigmas (exact, e.g. simulated, tie points among measured control points in one
camera's group) would otherwise drive it towards 0 pass after pass (the measured
observations flagged against the exact ones' scale, the exact ones then fitted alone), their
weights towards infinity, and the normal matrix towards singularity (the passes stopped
without converging). Measured groups stay well above it (matched GCPs of a rendered
simulation: 0.07). The report says when the floor holds a factor. kappa = E[w^2 | |w| <= c] of a
standard normal w truncated at the critical value c corrects for the tails the outlier
test cuts off (0.988 at alpha = 0.001). A group's factor is estimated only when its
redundancy is at least MIN_REDUNDANCY: below it the estimate scatters by more than 45 %
(the relative standard deviation of a variance from r degrees of freedom is sqrt(2 / r))
and the a-priori sigma stays. With points seen once, the image and ground groups cannot be
separated (their residuals are proportional): both get the same factor, which is what the
outlier test needs, since the normalised residual of such a point depends on the sum of its
image and ground variances only.

The outlier test then compares normalised residuals w = v / (s_k sigma sqrt(r)) with the
critical value: flags do not depend on the a-priori sigmas' scale. In the first pass, before
any component is known, the scale is the robust 1.4826 x median |w| (MAD), which gross
errors up to nearly half of the observations cannot inflate to their own size.

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

A group whose stated sigmas are wrong relative to each other (per-point sigmas off by
different factors) is not described by one factor; the iteration then drifts slowly towards
one group taking the misfit of another, and the loop stops at its pass limit, saying so.

References: Förstner, W. (1979): Ein Verfahren zur Schätzung von Varianz- und
Kovarianzkomponenten. Allgemeine Vermessungs-Nachrichten 86, 446-453. Zar, J. H. (1999):
Biostatistical Analysis, 4th ed., Prentice Hall, ch. 27.
"""
from __future__ import annotations

import logging
import math

import numpy as np
from scipy import stats

from .problem import Problem, image_group
from .statistics import Statistics, line_group_sums

log = logging.getLogger(__name__)

MIN_REDUNDANCY = 10.0
COMPONENT_TOLERANCE = 0.01
MIN_GROUP = 20
BREAKDOWN_SHARE = 0.4
SYSTEMATIC_RESULTANT = 0.5
SYSTEMATIC_SHARE = 0.1
MIN_SYSTEMATIC = 10
INFLATED_RATIO = 1.5
MAD_TO_SIGMA = 1.4826
WRONG_SHARE = 0.5       # a line with more than this share of its points failing the point test is wrong
MIN_FACTOR = 0.01  # lowest factor on stated sigmas: no measured group is 100 times more precise than stated


def critical(alpha: float) -> float:
    """Two-sided critical value of a standard normal normalised residual at ``alpha``."""
    return float(stats.norm.ppf(1.0 - alpha / 2.0))


def truncation(c: float) -> float:
    """E[w^2 | |w| <= c] of a standard normal w: the share of the variance an outlier test at
    c keeps."""
    return float(1.0 - 2.0 * c * stats.norm.pdf(c) / (2.0 * stats.norm.cdf(c) - 1.0))


def robust_scale(w: np.ndarray, redundancy: np.ndarray) -> float:
    """1.4826 x median |w| of the normalised residuals (n, 2) with a redundancy."""
    live = redundancy > 1e-6
    return max(MAD_TO_SIGMA * float(np.median(np.abs(w[live]))) if live.any() else 1.0, MIN_FACTOR)


def inliers(st: Statistics, scale: float, crit: float) -> np.ndarray:
    """(n,) image observations whose normalised residuals |w| / scale stay within ``crit``."""
    return (np.abs(st.w) <= crit * scale).all(axis=1)


def components(problem: Problem, st: Statistics, inlier: np.ndarray) -> dict[str, tuple[float, float, int]]:
    """(sum of p v^2 with the stated sigmas, redundancy, count) per observation group, over the
    inlier image observations, the control points all of whose observations are inliers, and
    all pseudo-observations."""
    out = _sums(problem, st, inlier)
    return {k: (pvv * problem.scale.get(k, 1.0) ** 2, r, n) for k, (pvv, r, n) in out.items()}


def _sums(problem: Problem, st: Statistics, inlier: np.ndarray) -> dict[str, tuple[float, float, int]]:
    """(sum of p v^2, redundancy, count) per group with the current weights (see :func:`components`)."""
    out = {}
    for c, cam in enumerate(problem.scene.cameras):
        m = inlier & (problem.obs.camera == c)
        if m.any():
            out[image_group(cam.name)] = (float(st.pvv[m].sum()), float(st.redundancy[m].sum()), 2 * int(m.sum()))
    if problem.weighted and problem.n_control:
        n_points = problem.ground.shape[0]
        good = (np.bincount(problem.obs.point, weights=~inlier, minlength=n_points) == 0)[:problem.n_control]
        for name, axes in (("ground_xy", slice(0, 2)), ("ground_z", slice(2, 3))):
            pvv, r = st.ground_pvv[good, axes], st.ground_redundancy[good, axes]
            out[name] = (float(pvv.sum()), float(r.sum()), int(pvv.size))
    out.update(st.pseudo)
    out.update(line_group_sums(problem, st, inlier))
    return out


def estimable(pvv: float, r: float) -> bool:
    return r >= MIN_REDUNDANCY and pvv > 0


def rescale(problem: Problem, comps: dict, kappa: float) -> float:
    """Set each estimable group's factor on its stated sigmas to sqrt(Omega / (kappa r)) (see
    :func:`components`); returns the largest relative change of a factor (0: none estimable)."""
    change = 0.0
    scale = dict(problem.scale)
    for group, (pvv, r, _) in comps.items():
        if estimable(pvv, r):
            factor = max(math.sqrt(pvv / (kappa * r)), MIN_FACTOR)
            if factor == MIN_FACTOR and problem.scale.get(group) != MIN_FACTOR:
                log.warning("%s: residuals %.2g times their stated sigmas; the factor on them is held at %g "
                            "(observations far more precise than stated, e.g. exact ones: state their sigmas)",
                            group, math.sqrt(pvv / (kappa * r)), MIN_FACTOR)
            change = max(change, abs(factor / problem.scale.get(group, 1.0) - 1.0))
            scale[group] = factor
    problem.set_scale(scale)
    return change


def robust_weights(problem: Problem, st: Statistics, scale: float) -> float:
    """One step of the robust method against the normalised residuals divided by ``scale``;
    returns the largest change of a weight factor."""
    crit = critical(problem.settings.alpha)
    old = problem.factor.copy()
    if problem.settings.robust == "selection":
        # Li Deren's selection weights: rows whose normalised residual exceeds the critical
        # value get the weight of their posterior variance.
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.abs(st.w) / scale
            sigma = problem.image_sigma()[:, None]
            ratio = np.where(t > crit, scale ** 2 * st.redundancy * sigma ** 2 / np.maximum(st.v * st.v, 1e-300), 1.0)
        problem.set_weight_factors(np.repeat(np.clip(ratio.min(axis=1), 1e-8, 1.0)[:, None], 2, axis=1))
    elif problem.settings.robust == "snooping":
        live = problem.factor[:, 0] > 0
        score = np.where(live, np.abs(st.w).max(axis=1) / scale, 0.0)
        worst = float(score.max(initial=0.0))
        if worst > crit:
            factor = problem.factor.copy()
            factor[score > max(crit, 0.5 * worst)] = 0.0
            problem.set_weight_factors(factor)
    return float(np.max(np.abs(problem.factor - old), initial=0.0))


def component_report(problem: Problem, comps: dict, kappa: float) -> dict:
    """Per group: observations, redundancy, sum of pvv (with the stated sigmas), the ratio
    sigma0 = estimated / stated sigma, the median stated and estimated sigma with their unit,
    whether the factor was estimated (and used), whether it is held at MIN_FACTOR, and whether
    the stated sigma passes the chi-square test at 95 %."""
    out = {}
    for group, (pvv, r, n) in comps.items():
        ratio = math.sqrt(pvv / (kappa * r)) if r > 0 else None
        stated, unit = problem.stated_sigma(group)
        lo, hi = stats.chi2.ppf([0.025, 0.975], r) / r if r > 0 else (None, None)
        out[group] = {"observations": n, "redundancy": r, "sum_pvv": pvv, "sigma0": ratio,
                      "apriori_sigma": stated, "estimated_sigma": None if ratio is None or stated is None
                      else stated * ratio, "unit": unit, "estimated": estimable(pvv, r),
                      "held_at_floor": estimable(pvv, r) and ratio < MIN_FACTOR,
                      "passed": None if ratio is None else bool(lo <= ratio ** 2 <= hi)}
    return out


def stated_sigma0(comps: dict, kappa: float) -> tuple[float, float]:
    """(sigma0 of the stated sigmas over all groups' inliers, its redundancy)."""
    pvv = sum(c[0] for c in comps.values())
    r = sum(c[1] for c in comps.values())
    return (math.sqrt(pvv / (kappa * r)) if r > 0 else float("nan")), r


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
    for c, cam in enumerate(problem.scene.cameras):
        chips = [(k, (obs.camera == c) & (obs.chip == k)) for k in range(len(cam.chips))]
        chips = [(k, m) for k, m in chips if m.sum() >= MIN_GROUP]
        for k, m in chips:
            name = f"{cam.name}/{cam.chips[k].name or k + 1}"
            n = int(m.sum())
            share = float(flagged[m].mean())
            if share > BREAKDOWN_SHARE:
                found.append({"group": name, "kind": "too_many_flagged", "share": share, "reliable": False,
                              "message": f"{name}: {100 * share:.0f} % of its {n} image observations are flagged as "
                                         f"gross errors (more than {100 * BREAKDOWN_SHARE:.0f} %): beyond that share a "
                                         "robust estimation can keep the wrong observations and still show small "
                                         "residuals; check the chip's points"})
            found += _systematic(name, st.v[m & flagged], n, alpha)
            others = np.zeros_like(m)
            for j, o in chips:
                if j != k:
                    others |= o
            found += _inflated(name, st, m & inlier, others & inlier, alpha)
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
    """A chip whose inlier residuals are larger than those of its camera's other chips."""
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


# --- control lines named wrong as a whole (see core.adjust.linepoints) -----------------------------------
def point_scores(problem: Problem, st: Statistics) -> np.ndarray:
    """(n,) per line point the larger of |w| across the line and of its image residual: the
    same test while both are weighted (the image residual of a line point lies across the
    line's image), and whichever is down-weighted keeps the misfit (a point whose image
    observation the robust step down-weighted sits on its line; a released line's point on
    its ray)."""
    return np.maximum(np.abs(st.lines.w), np.abs(st.w[problem.line_obs]).max(axis=1))


def line_tests(problem: Problem, score: np.ndarray, crit: float) -> tuple[np.ndarray, np.ndarray]:
    """Per line (K,): whether it fails (see :func:`flag_lines`) and the RMS of its points'
    scores (|w| / scale, (n,))."""
    key = problem.lines.obs.key
    k = problem.lines.obs.keys.size
    fail = score > crit
    n = np.bincount(key, minlength=k)
    share = np.bincount(key, weights=fail, minlength=k) / np.maximum(n, 1)
    passing = np.bincount(key, weights=~fail, minlength=k)
    chi2 = np.bincount(key, weights=np.where(fail, 0.0, score ** 2), minlength=k)
    limit = np.where(passing > 0, stats.chi2.ppf(1.0 - problem.settings.alpha, np.maximum(passing, 1)), np.inf)
    rms = np.sqrt(np.bincount(key, weights=score ** 2, minlength=k) / np.maximum(n, 1))
    return (share > WRONG_SHARE) | (chi2 > limit), rms


def flag_lines(problem: Problem, st: Statistics, scale: float, crit: float) -> float:
    """Name the lines that do not fit as a whole (see the module docstring) and release their
    across-line constraints; returns 1.0 when a line changed side, else 0.0. ``scale``: the
    robust scale of the normalised residuals of this pass."""
    if len(problem.lines) == 0:
        return 0.0
    fails, rms = line_tests(problem, point_scores(problem, st) / scale, crit)
    old = problem.line_flagged
    # As iterated data snooping: only the worst of the new failures (within a factor 2 of the
    # worst) are released per pass; a wrong line distorts the others' residuals until it is.
    candidate = fails & ~old
    worst = float(rms[candidate].max(initial=0.0))
    problem.set_line_flags((old & fails) | (candidate & (rms >= 0.5 * worst)))
    return float(not np.array_equal(old, problem.line_flagged))
