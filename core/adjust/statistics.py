"""Posterior statistics at a solution: cofactors, sigma0, redundancy numbers, normalised residuals,
the control points' and line points' ground statistics, and correlations worth a look."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import linalg

from ..errors import InputError
from .linepoints import ACROSS_GROUP, HEIGHT_GROUP
from .normal import Linearization, System, point_couplings
from .problem import Problem

@dataclass
class LineStatistics:
    """Per line point (n,): the prior's misfit across the line and in height (m, signed),
    their redundancy numbers and weights (1/m^2, with the current factors), and the across-line
    normalised residual w (against the stated sigma times the group's factor, released or not)."""
    d_across: np.ndarray
    d_height: np.ndarray
    r_across: np.ndarray
    r_height: np.ndarray
    w_across: np.ndarray
    w_height: np.ndarray
    w: np.ndarray



@dataclass
class Statistics:
    """Posterior statistics at the solution: Q (cofactor matrix of the unknowns), sigma0, dof,
    per image row redundancy (n,2) and normalised residual w (n,2) (against the stated sigmas
    times their group's factor), the residuals v (n,2) px and p v^2 (n,2) with the current
    weights; per control point p e^2 (m,3) and redundancy (m,3) of its east, north, up ground
    coordinates (weighted ground; else (0,3)); per pseudo-observation group (sum of p v^2,
    redundancy, count); lines: the line points' constraint statistics (None without lines)."""
    Q: np.ndarray
    sigma0: float
    dof: float
    redundancy: np.ndarray
    w: np.ndarray
    v: np.ndarray
    pvv: np.ndarray
    ground_pvv: np.ndarray
    ground_redundancy: np.ndarray
    pseudo: dict
    lines: LineStatistics | None = None


def statistics(problem: Problem, lin: Linearization, system: System) -> Statistics:
    """Redundancy numbers (diagonal of the hat matrix, ground points included through their
    Schur complement), normalised residuals and variance components."""
    n_unknowns = system.N.shape[0]
    Q = linalg.cho_solve(linalg.cho_factor(system.N, check_finite=False), np.eye(n_unknowns), check_finite=False)
    P = np.zeros((lin.r.shape[0], 2, 2))
    P[:, 0, 0], P[:, 1, 1] = lin.p[:, 0], lin.p[:, 1]
    weighted = lin.point >= 0
    G = np.zeros_like(P)
    for idx in problem.groups:
        keep = lin.columns[idx.start] >= 0
        if not keep.any():
            continue
        c = lin.columns[idx.start][keep]
        A = lin.values[idx][:, :, keep]
        AQ = (A.reshape(-1, c.size) @ Q[np.ix_(c, c)]).reshape(A.shape)
        G[idx] = np.einsum("nkq,nlq->nkl", AQ, A)
    h = np.einsum("nkk->nk", G)
    qgg = system.K
    if weighted.any():
        h[weighted], qgg = _ground_leverage(lin, system, Q, G, weighted)
    redundancy = np.clip(1.0 - h * lin.p, 0.0, 1.0)
    v = lin.r
    # the line points are the last ground unknowns
    lines = line_statistics(problem, qgg[qgg.shape[0] - len(problem.lines):]) if len(problem.lines) else None
    ground_pvv, r_g = np.zeros((0, 3)), np.zeros((0, 3))
    if problem.weighted and problem.n_control:
        # the weighted control points are the first ground unknowns
        qgg = qgg[:problem.n_control]
        e = np.einsum("mij,mj->mi", problem.enu, (problem.ground - problem.ground0)[:problem.n_control])
        w_enu = np.einsum("mii->mi", np.einsum("mij,mjk,mlk->mil", problem.enu, problem.ground_weight, problem.enu))
        r_g = np.clip(1.0 - np.einsum("mij,mjk,mik->mi", problem.enu, qgg, problem.enu) * w_enu, 0.0, 1.0)
        ground_pvv = w_enu * e * e
    pseudo: dict[str, tuple[float, float, int]] = {}
    for p in problem.pseudo():
        cols = problem.unknown[p.index]
        m = p.misfit(problem.params)
        hp = np.einsum("kq,qr,kr->k", p.B, Q[np.ix_(cols, cols)], p.B) * p.weight
        old = pseudo.get(p.group, (0.0, 0.0, 0))
        pseudo[p.group] = (old[0] + float(np.sum(p.weight * m * m)), old[1] + float(np.sum(1 - hp)), old[2] + m.size)
    total_rows, total_unknowns = problem.counts()
    dof = float(total_rows - total_unknowns)
    if dof <= 0:
        raise InputError(f"too few observations: {total_rows} equations for {total_unknowns} unknowns")
    sigma0 = math.sqrt(system.cost / dof)
    w = normalised(problem, v, redundancy)
    return Statistics(Q, sigma0, dof, redundancy, w, v, lin.p * v * v, ground_pvv, r_g, pseudo, lines)


def _ground_leverage(lin: Linearization, system: System, Q: np.ndarray, G: np.ndarray,
                     weighted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Diagonals (k,2) of the predicted observations' cofactors for the observations with a
    ground unknown, and the ground unknowns' cofactors (m,3,3).

    With M_p = sum over the point's observations of J_g' P A (3 x u) and K its eliminated
    block, the ground estimate is dg = -K (b_g + M_p dx): its cofactor is K + K M_p Q M_p' K,
    and an observation's prediction A dx + J_g dg has the cofactor
    J_g K J_g' + (A - J_g K M_p) Q (A - J_g K M_p)'. Every observation of a point enters M_p
    (a tie point's rays share its ground unknowns)."""
    n_points = system.K.shape[0]
    u = Q.shape[0]
    s = np.zeros((n_points, 3, 3))                                                # M Q M'
    aqm = np.zeros((lin.r.shape[0], 2, 3))                                        # A Q M' per observation
    for first, last, obs, M in point_couplings(lin, weighted, u, n_points):
        mq = (M.reshape(-1, u) @ Q).reshape(M.shape)
        s[first:last] = np.einsum("cau,cbu->cab", mq, M)
        cols = lin.columns[obs]
        mine = mq[(lin.point[obs] - first)[:, None, None], np.arange(3)[None, :, None], np.maximum(cols, 0)[:, None, :]]
        aqm[obs] = np.matmul(lin.values[obs], np.where(cols[:, None, :] >= 0, mine, 0.0).transpose(0, 2, 1))
    point = lin.point[weighted]
    aqm = aqm[weighted]
    jk = lin.jg[weighted] @ system.K[point]                                       # J_g K (k,2,3)
    h = np.einsum("nkg,nkg->nk", jk, lin.jg[weighted]) + np.einsum("nkk->nk", G[weighted]) \
        - 2.0 * np.einsum("nkg,nkg->nk", aqm, jk) + np.einsum("nkg,ngh,nkh->nk", jk, s[point], jk)
    return h, system.K + system.K @ s @ system.K


def normalised(problem: Problem, v: np.ndarray, redundancy: np.ndarray) -> np.ndarray:
    """Normalised residuals w (n,2) = v / (sigma sqrt(r)), sigma the stated image sigma times
    its camera's variance component factor."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(redundancy > 1e-6, v / (problem.image_sigma()[:, None] * np.sqrt(redundancy)), 0.0)



def line_statistics(problem: Problem, qgg: np.ndarray) -> LineStatistics:
    """Misfits and redundancy numbers of the line points' across and height constraints;
    qgg (n,3,3) the cofactors of their ground unknowns (ECEF)."""
    lines = problem.lines
    c = lines.constraints(problem.line_ground(), problem.scale, problem.line_flagged)
    wa = np.einsum("ni,nij,nj->n", c.across, c.weight, c.across)
    wh = np.einsum("ni,nij,nj->n", c.normal, c.weight, c.normal)
    r_a = np.clip(1.0 - np.einsum("ni,nij,nj->n", c.across, qgg, c.across) * wa, 0.0, 1.0)
    r_h = np.clip(1.0 - np.einsum("ni,nij,nj->n", c.normal, qgg, c.normal) * wh, 0.0, 1.0)
    sigma = lines.seg.sigma_across[c.segment] * problem.scale.get(ACROSS_GROUP, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(r_a > 1e-6, c.d_across / (sigma * np.sqrt(r_a)), 0.0)
    return LineStatistics(c.d_across, c.d_normal, r_a, r_h, wa, wh, w)


def line_group_sums(problem: Problem, st: Statistics, inlier: np.ndarray) -> dict:
    """(sum of p v^2, redundancy, count) of the groups lines_across and lines_height over the
    points whose image observation is an inlier, of lines not named wrong."""
    ls = st.lines
    if ls is None or ls.d_across.size == 0:
        return {}
    good = inlier[problem.line_obs] & ~problem.line_flagged[problem.lines.obs.key]
    return {ACROSS_GROUP: (float(np.sum(ls.w_across[good] * ls.d_across[good] ** 2)), float(ls.r_across[good].sum()),
                           int(good.sum())),
            HEIGHT_GROUP: (float(np.sum(ls.w_height[good] * ls.d_height[good] ** 2)), float(ls.r_height[good].sum()),
                           int(good.sum()))}



def correlated_pairs(corr: np.ndarray, params: list) -> list[dict]:
    """Pairs of unknowns worth a look: |r| > 0.9 where an interior parameter takes part, and
    |r| > 0.999 between trajectory terms (a split the control barely determines)."""
    trajectory = np.array([p.block in ("position", "attitude") for p in params])
    a, b = np.triu_indices(len(params), 1)
    r = corr[a, b]
    both = trajectory[a] & trajectory[b]
    keep = np.nonzero(np.where(both, np.abs(r) > 0.999, np.abs(r) > 0.9))[0]
    keep = keep[np.argsort(-np.abs(r[keep]))][:50]
    return [{"a": params[a[k]].name, "b": params[b[k]].name, "r": float(r[k]), "trajectory": bool(both[k])}
            for k in keep]

