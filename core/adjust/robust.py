"""Robust estimation that does not trust the a-priori sigmas.

Variance components. The observations fall into groups: the image observations of each
camera's control and line points ("image <camera>"), the tie points of all cameras ("tie
points", apart: matched ties are often far more precise than control points measured by
hand), the planimetric and the height coordinates of the weighted control points
("ground_xy", "ground_z") and the pseudo-observations (onboard position and attitude,
weighted interior parameters). Each group k gets a factor s_k on its a-priori
sigmas, estimated by Förstner's simplified Helmert estimator (Förstner 1979)

    s_k^2 <- s_k^2 * Omega_k / (kappa * r_k),   Omega_k = sum of p v^2,  r_k = sum of redundancy numbers

over the group's inliers (observations the robust step keeps), iterated with the solution
until every factor changes by less than COMPONENT_TOLERANCE. A factor is never below its
floor (:func:`factor_floor`), nor is the first pass's robust scale: MIN_FACTOR, because
observations fitting far better than their stated sigmas (exact, e.g. simulated, ones) would
otherwise drive it towards 0 pass after pass, their weights towards infinity, and the normal
matrix towards singularity (the passes stopped without converging); measured groups stay well
above it (matched GCPs of a rendered simulation: 0.07). The tie-point group's floor is 1:
its stated sigma is the most the ties are trusted, because their residuals leave out the part of their
errors the self-calibration absorbs (matched tie points of a rendered TH-1 scene: 0.012 px
estimated, about 0.03 px against the truth; weighted by the estimate, their systematic part bent
the heights of the block by 0.9 m RMS). The report says when the floor holds a factor. kappa = E[w^2 | |w| <= c] of a
standard normal w truncated at the critical value c corrects for the tails the outlier
test cuts off (0.988 at alpha = 0.001). A group's factor is estimated only when its
redundancy is at least MIN_REDUNDANCY: below it the estimate scatters by more than 45 %
(the relative standard deviation of a variance from r degrees of freedom is sqrt(2 / r))
and the a-priori sigma stays.

Separability. Groups that share ground points can be told apart only as far as their residuals
are not proportional. A control point seen in one image has 2 image rows and 3 ground rows
against 3 unknowns: its misfit is split between the image residual and the ground shift in the
ratio of their stated variances, at every point alike, so the image and ground factors are not
separable, only the sum of the two variances is (the simplified estimator then drifts along the
inseparable direction pass after pass, and the image group's share, a redundancy of ~50 of
~5000 in the demo's matched GCPs, is no estimate of the matching's real error). The
estimation's matrix H_kl = tr(R_kl R_lk), E[Omega_k] = sum_l H_kl theta_l
(:func:`core.adjust.statistics.component_coupling`; the simplified estimator keeps its row
sums r_k only) says how well: a group's effective redundancy, 1 / (H^-1)_kk (r_k when H is
diagonal), is what the other groups leave of its redundancy. A group too weak to estimate alone
whose residuals are all but proportional to an estimable group's (coupling |H_kl| / sqrt(H_kk
H_ll) >= PROPORTIONAL) joins it; a group whose effective redundancy is below MIN_REDUNDANCY, or
below SEPARATE_SHARE of its redundancy r_k (most of its misfit is then decided by the others'
factors; the GCP heights of the demo's near-nadir image: r_k 215, effective 20, against 0.25 of
r_k for the groups of points seen in three cameras, which separate), is joined with the group
it is most coupled with, until every group or joint set is separable (:func:`joint_groups`). A
joint set gets one factor, estimated from its members' residuals together, and keeps the split
between them as stated, which is what the outlier test needs: the normalised residual of such a
point depends on the sum of its image and ground variances only. A join is kept for the rest of
the loop (so the loop converges); the report names each joint set. The separable groups and
sets of H are estimated together by Helmert's estimator, H theta = Omega
(:func:`helmert_factors`), so that coupled groups (each camera's image group and the ground of
points seen in three cameras) converge in a pass or two, where the simplified estimator creeps
or swings; the other groups (pseudo-observations) by the simplified one.

sigma0 of the stated sigmas (:func:`sigma0_test`): its 95 % acceptance interval is that of
the ratio of two variance estimates, F(r, STATED_DOF): the residuals' (r degrees of freedom)
and the stated sigmas' own, taken as known to about 10 % (STATED_DOF = 50; the relative
standard deviation of a variance from f degrees of freedom is sqrt(2 / f) = 0.2). A chi-square
test (the stated sigmas taken as exact) with thousands of matched points asks whether they
were stated to 2 %, which no sigma ever is, and fails whatever the fit; with tens of points
both intervals are alike.

The outlier test then compares normalised residuals w = v / (s_k sigma sqrt(r)) with the
critical value: flags do not depend on the a-priori sigmas' scale. In the first pass, before
any component is known, the scale is the robust 1.4826 x median |w| (MAD), which gross
errors up to nearly half of the observations cannot inflate to their own size; it is taken per
image group, so that precise tie points do not set the scale of the control points.

Breakdown signs per CCD chip are tested in :mod:`core.adjust.breakdown`.

A group whose stated sigmas are wrong relative to each other (per-point sigmas off by
different factors) is not described by one factor; the iteration then drifts slowly towards
one group taking the misfit of another, and the loop stops at its pass limit, saying so.

Convergence. The selection weight jumps at the critical value c: 1 just below it, 1/c^2 (0.09 at
alpha = 0.001) just above. An observation whose normalised residual sits near c can fall below it
once down-weighted (the solution moves towards it) and rise above it once weighted in full, and a
few such observations flip the others' residuals with them: the loop then swings between two sets of
flags for ever (issue 28, tests/data/pleiades_gizeh/ties_swinging.csv: 14 and 20 observations
down-weighted, weighted squared residuals 198 and 226 in turn, to the 12-pass limit). An observation
flagged anew REFLAGGED times (flagged, released, flagged again) is therefore held flagged for the
rest of the loop, weighted as a residual at c at least; the report counts them (``held_flagged``) and
counts them as flagged. Each observation can then change side at most three times, so the flags
settle. Chosen by measurement against its alternative, selection weights made continuous at c
(min(1, (c/t)^2), a redescending M-estimator): on the Giza pair matched at 16 heights with 12 grid
and window settings (141 tie sets that solve; tests/bench/bench_robust_giza.py), 4 sets swung to the
limit before; holding flags, none does (those 4 in 5 to 7 passes), and the other 137 sets keep their
passes and flags exactly, as does every existing result (an observation is held only where it was
flagged twice: the demo, the seeds' tests); the continuous weights also converge there but change every
result with a flagged observation (sigma0 1.007 against 0.945 on the swinging set: flagged ones keep
c^2 = 10.8 times more weight). On simulated RPC tri-stereos with 12 or 25 % gross errors of 0.5-10 px
(48 sets), neither rule changes the passes (6.4-6.5 on average) or the error at the clean points
(0.39 px): 3 sets of 25 % gross errors still creep, a few observations more flagged each pass as the
tie factor settles, to the pass limit, which the report says.

References: Förstner, W. (1979): Ein Verfahren zur Schätzung von Varianz- und
Kovarianzkomponenten. Allgemeine Vermessungs-Nachrichten 86, 446-453.
"""
from __future__ import annotations

import logging
import math

import numpy as np
from scipy import stats

from .problem import RPC_PRIOR_GROUP, TIE_GROUP, Problem
from .statistics import Statistics, line_group_sums
from .tieheights import TIE_HEIGHT_GROUP

log = logging.getLogger(__name__)

MIN_REDUNDANCY = 10.0
COMPONENT_TOLERANCE = 0.01
MAD_TO_SIGMA = 1.4826
WRONG_SHARE = 0.5       # a line with more than this share of its points failing the point test is wrong
MIN_FACTOR = 0.01  # lowest factor on stated sigmas: no measured group is 100 times more precise than stated
REFLAGGED = 2      # an observation flagged anew this often (flagged, released, flagged again) stays flagged


def factor_floor(group: str) -> float:
    """The lowest factor on a group's stated sigmas: MIN_FACTOR, and 1 for the tie-point group (matched
    tie points fit better than they are: their residuals leave out the part of their errors the
    interior parameters absorb, measured 0.012 px estimated against 0.03 px true on a rendered TH-1
    scene, and with their factor below 1 that part bent the block's heights: 3.67 against 2.99 m
    with exact ties)."""
    return 1.0 if group == TIE_GROUP else MIN_FACTOR
SEPARATE_SHARE = 0.2  # a separable group's effective redundancy is at least this share of its redundancy
PROPORTIONAL = 0.95  # coupling of two groups' residuals beyond which a weak group shares the other's factor
STATED_DOF = 50    # degrees of freedom of a stated sigma: known to about 10 % (see the module docstring)


def critical(alpha: float) -> float:
    """Two-sided critical value of a standard normal normalised residual at ``alpha``."""
    return float(stats.norm.ppf(1.0 - alpha / 2.0))


def truncation(c: float) -> float:
    """E[w^2 | |w| <= c] of a standard normal w: the share of the variance an outlier test at
    c keeps."""
    return float(1.0 - 2.0 * c * stats.norm.pdf(c) / (2.0 * stats.norm.cdf(c) - 1.0))


def robust_scale(problem: Problem, st: Statistics) -> np.ndarray:
    """(n,) per image observation 1.4826 x median |w| of the normalised residuals (n, 2) with a
    redundancy of its group (:attr:`Problem.image_groups`); 1 in a group without any."""
    labels, index = problem.image_groups
    live = st.redundancy > 1e-6
    scale = np.ones(len(labels))
    for k in range(len(labels)):
        mine = index == k
        w = np.abs(st.w[mine][live[mine]])
        scale[k] = max(MAD_TO_SIGMA * float(np.median(w)), factor_floor(labels[k])) if w.size else 1.0
    return scale[index]


def inliers(st: Statistics, scale: np.ndarray, crit: float) -> np.ndarray:
    """(n,) image observations whose normalised residuals |w| / scale ((n,) per observation) stay
    within ``crit``."""
    return (np.abs(st.w) <= crit * scale[:, None]).all(axis=1)


def components(problem: Problem, st: Statistics, inlier: np.ndarray) -> dict[str, tuple[float, float, int]]:
    """(sum of p v^2 with the stated sigmas, redundancy, count) per observation group, over the
    inlier image observations, the control points all of whose observations are inliers, and
    all pseudo-observations."""
    out = _sums(problem, st, inlier)
    return {k: (pvv * problem.scale.get(k, 1.0) ** 2, r, n) for k, (pvv, r, n) in out.items()}


def _sums(problem: Problem, st: Statistics, inlier: np.ndarray) -> dict[str, tuple[float, float, int]]:
    """(sum of p v^2, redundancy, count) per group with the current weights (see :func:`components`)."""
    out = {}
    labels, index = problem.image_groups
    for k, label in enumerate(labels):
        m = inlier & (index == k)
        if m.any():
            out[label] = (float(st.pvv[m].sum()), float(st.redundancy[m].sum()), 2 * int(m.sum()))
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


def effective_redundancy(H: np.ndarray) -> np.ndarray:
    """(g,) 1 / (H^-1)_kk of the estimation matrix H (g, g), by each group's Schur complement
    (0 where the others leave a group nothing, H singular included)."""
    out = np.empty(H.shape[0])
    for k in range(H.shape[0]):
        other = np.arange(H.shape[0]) != k
        if not other.any():
            out[k] = H[k, k]
            continue
        h = H[other, k]
        out[k] = H[k, k] - h @ np.linalg.lstsq(H[np.ix_(other, other)], h, rcond=None)[0]
    return np.maximum(out, 0.0)


def joint_groups(comps: dict, labels: list[str], H: np.ndarray, joined: list[tuple[str, ...]]) -> list[tuple[str, ...]]:
    """The sets of groups (of ``labels``, with the estimation matrix ``H``, see
    :func:`core.adjust.statistics.component_coupling`) whose factors cannot be estimated apart:
    the sets already ``joined`` (a join is kept); a group not estimable on its own (redundancy
    below MIN_REDUNDANCY) whose residuals are all but proportional to an estimable group's
    (coupling |H_kl| / sqrt(H_kk H_ll) >= PROPORTIONAL), joined with it (estimating that one
    alone would change the split between them, which nothing in the data decides); then, while
    a set's effective redundancy is below MIN_REDUNDANCY or SEPARATE_SHARE of its redundancy
    (the row sum of H), the set joined with the one it is most coupled with. Other groups not
    estimable on their own keep their stated sigmas and take no part. Only sets of two or more
    groups are returned."""
    index = {k: i for i, k in enumerate(labels)}
    before = {k for j in joined for k in j}
    present = [k for k in labels if k in comps and H[index[k], index[k]] > 0]
    live = [k for k in present if k in before or estimable(comps[k][0], comps[k][1])]
    sets = [[k] for k in live if k not in before]
    sets += [[k for k in j if k in live] for j in joined]
    sets = [m for m in sets if m]
    d = np.sqrt(np.diag(H))
    for k in present:
        if k in live or not sets:
            continue
        coupling = [max(abs(H[index[k], index[j]]) / (d[index[k]] * d[index[j]]) for j in m) for m in sets]
        best = int(np.argmax(coupling))
        if coupling[best] >= PROPORTIONAL:
            sets[best].append(k)
    while len(sets) > 1:
        M = np.zeros((len(labels), len(sets)))
        for n, members in enumerate(sets):
            M[[index[k] for k in members], n] = 1.0
        Hs = M.T @ H @ M
        eff = effective_redundancy(Hs)
        short = eff / np.maximum(MIN_REDUNDANCY, SEPARATE_SHARE * Hs.sum(axis=1))
        worst = int(np.argmin(short))
        if short[worst] >= 1.0:
            break
        ds = np.sqrt(np.diag(Hs))
        coupling = np.abs(Hs[worst]) / (ds[worst] * ds)
        coupling[worst] = -1.0
        partner = int(np.argmax(coupling))
        sets[worst] = sets[worst] + sets[partner]
        del sets[partner]
    return [tuple(sorted(m, key=labels.index)) for m in sets if len(m) > 1]


def factor_units(comps: dict, joint: list[tuple[str, ...]]) -> list[tuple[str, ...]]:
    """The groups that share a factor: each joint set, and every other group alone."""
    together = {k for j in joint for k in j}
    return list(joint) + [(k,) for k in comps if k not in together]


def helmert_factors(problem: Problem, comps: dict, kappa: float, units: list[tuple[str, ...]], labels: list[str],
                    H: np.ndarray) -> dict[tuple[str, ...], float]:
    """Squared factors on the stated sigmas of ``units`` (groups, or joint sets of them, all in
    ``labels``) by Helmert's estimator: E[Omega_k] = sum_l H_kl theta_l solved for the units'
    factors together (``H`` from :func:`core.adjust.statistics.component_coupling`, each row
    scaled to sum to the group's exact redundancy; groups of ``labels`` in no unit held at their
    current factor). Coupled groups then converge in a pass or two where the simplified
    estimator, which divides each Omega_k by r_k alone, creeps or swings. A unit whose solution
    is not positive is left out (the simplified value stays)."""
    if len(units) < 2:
        return {}
    index = {k: i for i, k in enumerate(labels)}
    current = np.array([problem.scale.get(k, 1.0) ** 2 for k in labels])
    r = np.array([comps[k][1] if k in comps else 0.0 for k in labels])
    rowsum = H.sum(axis=1)
    Ht = H * np.where(rowsum > 0, r / np.where(rowsum > 0, rowsum, 1.0), 0.0)[:, None]
    held = np.ones(len(labels), bool)
    G, omega = np.zeros((len(units), len(units))), np.zeros(len(units))
    for b, members in enumerate(units):
        held[[index[k] for k in members]] = False
    for a, members in enumerate(units):
        rows = [index[k] for k in members]
        omega[a] = sum(comps[k][0] / current[index[k]] for k in members) / kappa - Ht[np.ix_(rows, held)].sum()
        for b, others in enumerate(units):
            cols = [index[k] for k in others]
            G[a, b] = (Ht[np.ix_(rows, cols)] / current[cols][None, :]).sum()
    squared = np.linalg.lstsq(G, omega, rcond=None)[0]
    return {u: float(f) for u, f in zip(units, squared) if f > 0}


TRAJECTORY_PSEUDO_GROUPS = ("position pseudo-observations", "attitude pseudo-observations")


def datum_groups(problem: Problem) -> set[str]:
    """The onboard pseudo-observation groups (and the RPC images' prior) that alone hold the datum (no control point, no
    control line: tie points fix the block's shape, nothing else where it lies), and the tie points'
    heights above a reference DEM (:mod:`core.adjust.tieheights`), which hold the vertical datum at the
    DEM's stated accuracy. Their factors are not estimated: their residuals measure only how far the
    ties pull the block from the onboard data, so a factor from them would loosen the datum pass after
    pass (a block of 5 scenes with 2000 tie points: the position factor swung by 60-160 % per pass and
    the solution crept along the loosened datum without converging)."""
    if problem.n_control or len(problem.lines):
        return {TIE_HEIGHT_GROUP}
    return {*TRAJECTORY_PSEUDO_GROUPS, RPC_PRIOR_GROUP, TIE_HEIGHT_GROUP}


def rescale(problem: Problem, comps: dict, kappa: float, joint: list[tuple[str, ...]] = (),
            coupling: tuple[list[str], np.ndarray] | None = None) -> float:
    """Set each estimable group's factor on its stated sigmas to sqrt(Omega / (kappa r)) (see
    :func:`components`), one factor over each ``joint`` set's members together, and for the
    groups of ``coupling`` (labels, H: :func:`core.adjust.statistics.component_coupling`) by
    Helmert's estimator (:func:`helmert_factors`); returns the largest relative change of a
    factor (0: none estimable)."""
    change = 0.0
    scale = dict(problem.scale)
    held = datum_groups(problem)
    units = [u for u in factor_units(comps, list(joint))
             if not held & set(u) and estimable(sum(comps[k][0] for k in u), sum(comps[k][1] for k in u))]
    squared = {u: sum(comps[k][0] for k in u) / (kappa * sum(comps[k][1] for k in u)) for u in units}
    if coupling is not None:
        labels, H = coupling
        squared.update(helmert_factors(problem, comps, kappa, [u for u in units if set(u) <= set(labels)],
                                       labels, H))
    for members in units:
        floor = max(factor_floor(k) for k in members)
        factor = max(math.sqrt(squared[members]), floor)
        if factor == floor and any(problem.scale.get(k) != floor for k in members):
            _say_floor(members, math.sqrt(squared[members]), floor)
        for k in members:
            change = max(change, abs(factor / problem.scale.get(k, 1.0) - 1.0))
            scale[k] = factor
    problem.set_scale(scale)
    return change


def _say_floor(members: tuple[str, ...], ratio: float, floor: float) -> None:
    """Log that the factor of ``members`` is held at its floor (a warning below 1: observations far
    more precise than stated)."""
    names = " and ".join(members)
    if floor >= 1.0:
        log.info("%s: residuals %.2g times their stated sigmas; the stated sigmas are kept (tie points are never "
                 "weighted above them)", names, ratio)
        return
    log.warning("%s: residuals %.2g times their stated sigmas; the factor on them is held at %g (observations far "
                "more precise than stated, e.g. exact ones: state their sigmas)", names, ratio, floor)


def robust_weights(problem: Problem, st: Statistics, scale: np.ndarray, held: np.ndarray | None = None) -> float:
    """One step of the robust method against the normalised residuals divided by ``scale`` ((n,)
    per observation); returns the largest change of a weight factor. ``held`` (n,) bool: the
    observations held flagged (see the module docstring, Convergence): down-weighted as a residual at
    the critical value at least, whatever theirs is now."""
    crit = critical(problem.settings.alpha)
    old = problem.factor.copy()
    if problem.settings.robust == "selection":
        # Li Deren's selection weights: rows whose normalised residual exceeds the critical
        # value get the weight of their posterior variance, s^2 r sigma^2 / v^2 = 1 / t^2.
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.abs(st.w).max(axis=1) / scale
        if held is not None:
            t = np.where(held, np.maximum(t, crit), t)
        ratio = np.where((t > crit) | (held if held is not None else False), 1.0 / np.maximum(t, 1e-150) ** 2, 1.0)
        problem.set_weight_factors(np.repeat(np.clip(ratio, 1e-8, 1.0)[:, None], 2, axis=1))
    elif problem.settings.robust == "snooping":
        live = problem.factor[:, 0] > 0
        score = np.where(live, np.abs(st.w).max(axis=1) / scale, 0.0)
        worst = float(score.max(initial=0.0))
        if worst > crit:
            factor = problem.factor.copy()
            factor[score > max(crit, 0.5 * worst)] = 0.0
            problem.set_weight_factors(factor)
    return float(np.max(np.abs(problem.factor - old), initial=0.0))


def component_report(problem: Problem, comps: dict, kappa: float, joint: list[tuple[str, ...]] = ()) -> dict:
    """Per group: observations, redundancy, sum of pvv (with the stated sigmas), the ratio
    sigma0 = estimated / stated sigma its residuals imply (of its joint set, for a member of
    one), the median stated and estimated sigma with their unit, factor: the factor on the stated
    sigmas in use (None: none estimated; a group whose redundancy fell below MIN_REDUNDANCY once
    its factor made it stronger keeps that factor), whether one was estimated (and used), whether
    it is held at its floor (:func:`factor_floor`), whether it alone holds the datum (:func:`datum_groups`: not
    estimated), whether the stated sigma passes the 95 % test (:func:`sigma0_test`), and
    joint_with: the groups it shares its factor with (empty: estimated on its own)."""
    out = {}
    for members in factor_units(comps, list(joint)):
        pvv, r = sum(comps[k][0] for k in members), sum(comps[k][1] for k in members)
        ratio = math.sqrt(pvv / (kappa * r)) if r > 0 else None
        for group in members:
            stated, unit = problem.stated_sigma(group)
            used = problem.scale.get(group)
            out[group] = {"observations": comps[group][2], "redundancy": comps[group][1], "sum_pvv": comps[group][0],
                          "sigma0": ratio, "apriori_sigma": stated,
                          "estimated_sigma": None if ratio is None or stated is None else stated * ratio,
                          "unit": unit, "factor": used, "estimated": used is not None,
                          "held_at_floor": used == factor_floor(group), "holds_datum": group in datum_groups(problem),
                          "passed": None if ratio is None else sigma0_test(ratio, r)["passed"],
                          "joint_with": [k for k in members if k != group]}
    return out


def stated_sigma0(comps: dict, kappa: float) -> tuple[float, float]:
    """(sigma0 of the stated sigmas over all groups' inliers, its redundancy)."""
    pvv = sum(c[0] for c in comps.values())
    r = sum(c[1] for c in comps.values())
    return (math.sqrt(pvv / (kappa * r)) if r > 0 else float("nan")), r


def sigma0_test(sigma0: float, dof: float) -> dict:
    """The 95 % acceptance interval of sigma0 (ratio bounds) with ``dof`` degrees of freedom
    against stated sigmas known to STATED_DOF degrees of freedom (see the module docstring),
    and whether ``sigma0`` lies in it."""
    lo, hi = stats.f.ppf([0.025, 0.975], dof, STATED_DOF) if dof > 0 else (float("nan"), float("nan"))
    return {"ratio_bounds_95": [math.sqrt(lo), math.sqrt(hi)], "stated_dof": STATED_DOF,
            "passed": bool(lo <= sigma0 ** 2 <= hi)}


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


def flag_lines(problem: Problem, st: Statistics, scale: np.ndarray, crit: float) -> float:
    """Name the lines that do not fit as a whole (see the module docstring) and release their
    across-line constraints; returns 1.0 when a line changed side, else 0.0. ``scale``: the
    robust scale of the normalised residuals of this pass ((n,) per image observation)."""
    if len(problem.lines) == 0:
        return 0.0
    fails, rms = line_tests(problem, point_scores(problem, st) / scale[problem.line_obs], crit)
    old = problem.line_flagged
    # As iterated data snooping: only the worst of the new failures (within a factor 2 of the
    # worst) are released per pass; a wrong line distorts the others' residuals until it is.
    candidate = fails & ~old
    worst = float(rms[candidate].max(initial=0.0))
    problem.set_line_flags((old & fails) | (candidate & (rms >= 0.5 * worst)))
    return float(not np.array_equal(old, problem.line_flagged))
