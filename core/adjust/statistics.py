"""Posterior statistics at a solution: cofactors, sigma0, redundancy numbers, normalised residuals,
the control points' and line points' ground statistics, and correlations worth a look."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import linalg, sparse

from ..errors import InputError
from .linepoints import ACROSS_GROUP, HEIGHT_GROUP
from .normal import Linearization, System, point_blocks
from .problem import Problem
from .sparsenormal import block_pattern, factorise, on_pattern, selected_inverse
from .tieheights import TIE_HEIGHT_GROUP

GROUND_GROUPS = ("ground_xy", "ground_z", ACROSS_GROUP, HEIGHT_GROUP)  # the groups of the ground points' priors
BLOCK_NUMBERS = 5_000_000  # numbers in one batch of per-point blocks (40 MB)

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
    """Posterior statistics at the solution: Q (cofactor matrix of the unknowns; sparse, on the
    products' blocks only, for a sparse system: :func:`cofactors`), sigma0, dof,
    per image row redundancy (n,2) and normalised residual w (n,2) (against the stated sigmas
    times their group's factor), the residuals v (n,2) px and p v^2 (n,2) with the current
    weights; per control point p e^2 (m,3) and redundancy (m,3) of its east, north, up ground
    coordinates (weighted ground; else (0,3)); per pseudo-observation group (sum of p v^2,
    redundancy, count); lines: the line points' constraint statistics (None without lines)."""
    Q: np.ndarray | sparse.spmatrix
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
    Q = cofactors(system)
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
        AQ = (A.reshape(-1, c.size) @ cofactor_block(Q, c, c)).reshape(A.shape)
        G[idx] = np.einsum("nkq,nlq->nkl", AQ, A)
    h = np.einsum("nkk->nk", G)
    qgg = system.K
    if weighted.any():
        h[weighted], qgg = _ground_leverage(lin, system, Q, G, weighted)
    redundancy = np.clip(1.0 - h * lin.p, 0.0, 1.0)
    v = lin.r
    # the line points are the last ground unknowns
    lines = line_statistics(problem, qgg[qgg.shape[0] - len(problem.lines):]) if len(problem.lines) else None
    heights = problem.tie_heights()
    ground_pvv, r_g = np.zeros((0, 3)), np.zeros((0, 3))
    if problem.weighted and problem.n_control:
        # the weighted control points are the first ground unknowns
        q_control = qgg[:problem.n_control]  # qgg stays whole: the tie heights below index it by tie point
        e = np.einsum("mij,mj->mi", problem.enu, (problem.ground - problem.ground0)[:problem.n_control])
        w_enu = np.einsum("mii->mi", np.einsum("mij,mjk,mlk->mil", problem.enu, problem.ground_weight, problem.enu))
        r_g = np.clip(1.0 - np.einsum("mij,mjk,mik->mi", problem.enu, q_control, problem.enu) * w_enu, 0.0, 1.0)
        ground_pvv = w_enu * e * e
    pseudo: dict[str, tuple[float, float, int]] = {}
    values = problem.params.values()
    for p in problem.pseudo():
        cols = problem.unknown[p.index]
        m = p.misfit(values)
        hp = np.einsum("kq,qr,kr->k", p.B, cofactor_block(Q, cols, cols), p.B) * p.weight
        old = pseudo.get(p.group, (0.0, 0.0, 0))
        pseudo[p.group] = (old[0] + float(np.sum(p.weight * m * m)), old[1] + float(np.sum(1 - hp)), old[2] + m.size)
    if heights is not None:  # the tie points' heights above the reference DEM (core.adjust.tieheights)
        pseudo[TIE_HEIGHT_GROUP] = heights.sums(qgg[problem.ground_point[problem.n_control:problem.line_first]])
    total_rows, total_unknowns = problem.counts()
    dof = float(total_rows - total_unknowns)
    if dof <= 0:
        raise InputError(f"too few observations: {total_rows} equations for {total_unknowns} unknowns")
    sigma0 = math.sqrt(system.cost / dof)
    w = normalised(problem, v, redundancy)
    return Statistics(Q, sigma0, dof, redundancy, w, v, lin.p * v * v, ground_pvv, r_g, pseudo, lines)


def cofactors(system: System) -> np.ndarray | sparse.csr_matrix:
    """Q = N^-1 of the reduced normal equations: dense, the full inverse; sparse
    (:attr:`System.is_sparse`), only on N's block pattern (:func:`core.adjust.sparsenormal.block_pattern`:
    within a column group, and between two groups that share points: every entry the statistics
    read; :func:`core.adjust.sparsenormal.selected_inverse` of N scaled to a unit diagonal as the
    solver factorises it)."""
    if not system.is_sparse:
        n_unknowns = system.N.shape[0]
        return linalg.cho_solve(linalg.cho_factor(system.N, check_finite=False), np.eye(n_unknowns),
                                check_finite=False)
    d = np.sqrt(system.N.diagonal())
    d[~(d > 0)] = 1.0
    scale = sparse.diags(1.0 / d)
    scaled = (scale @ system.N @ scale).tocsc()
    pattern = block_pattern(scaled, system.layouts or [])
    return (scale @ selected_inverse(factorise(on_pattern(scaled, pattern)), pattern) @ scale).tocsr()


def cofactor_block(Q: np.ndarray | sparse.spmatrix, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Q[rows][:, cols] as a dense array (Q dense, or sparse on N's pattern: see :func:`cofactors`)."""
    if sparse.issparse(Q):
        return Q[rows][:, cols].toarray()
    return Q[np.ix_(rows, cols)]


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
    pb = point_blocks(lin, weighted)
    s = np.zeros((n_points, 3, 3))                                                # M Q M'
    T = [np.zeros((g.point.size, g.columns.size, 3)) for g in pb.groups]         # (M Q)[:, layout]' per point
    for a, c, i, j in pb.crosses:  # in one cross each point appears once
        ga, gc = pb.groups[a], pb.groups[c]
        qbt = np.matmul(cofactor_block(Q, ga.columns, gc.columns), gc.B[j].transpose(0, 2, 1))  # (k,q_a,3)
        T[a][i] += qbt
        s[ga.point[i]] += np.matmul(ga.B[i], qbt)
    aqm = np.zeros((lin.r.shape[0], 2, 3))                                        # A Q M' per observation
    for g, t in zip(pb.groups, T):
        rows = np.where(g.slots[:, :, None] >= 0, t[g.pair[:, None], np.maximum(g.slots, 0)], 0.0)  # (o,q_obs,3)
        aqm[g.obs] = np.matmul(lin.values[g.obs], rows)
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



def component_coupling(problem: Problem, lin: Linearization, system: System, redundancy: np.ndarray,
                       inlier: np.ndarray) -> tuple[list[str], np.ndarray]:
    """The observation groups that share ground points (each camera's image group, ground_xy,
    ground_z, lines_across, lines_height) and the matrix H (g, g) of their variance component
    estimation, H_kl = sum over the rows i of group k and j of group l of R_ij R_ji, R = Q_vv P:
    E[Omega_k] = sum_l H_kl s_l^2 with the current factors s_l. Förstner's simplified estimator
    takes H as diagonal (row sums: the redundancy r_k); its off-diagonal terms say how well the
    groups can be told apart (see :func:`core.adjust.robust.joint_groups`).

    R is taken from each ground point's own block: its inlier image observations and its prior
    rows (east, north, up of a weighted control point; across and normal of a line point, lines
    named wrong left out; none for a tie point) with the point's eliminated cofactor K of the
    reduced system, R = I - A K A' P with A the rows' derivatives by the point. The parameters'
    share of R (a few tens of unknowns among thousands of redundancy numbers) is left out.
    Image observations of points without ground unknowns (fixed ground) add their redundancy
    numbers ``redundancy`` (n, 2) to the diagonal. ``inlier`` (n,): the image observations the
    robust step keeps; a control point's prior counts when all its observations are inliers."""
    images, group = problem.image_groups
    labels = images + list(GROUND_GROUPS)
    n_images, g = len(images), len(labels)
    flat = np.zeros(g * g)
    n_u = system.K.shape[0]
    seen = lin.point >= 0
    fixed = ~seen & inlier
    np.add.at(flat, group[fixed] * (g + 1), redundancy[fixed].sum(axis=1))
    if n_u == 0:
        return labels, flat.reshape(g, g)
    # the prior rows of each ground unknown: unit directions (u,3,3) ECEF, weights (u,3), group (u,3) (-1: none)
    direction, weight, label = np.zeros((n_u, 3, 3)), np.zeros((n_u, 3)), -np.ones((n_u, 3), np.int64)
    if problem.weighted and problem.n_control:
        u = problem.ground_point[:problem.n_control]
        direction[u] = problem.enu
        weight[u] = np.einsum("mij,mjk,mik->mi", problem.enu, problem.ground_weight, problem.enu)
        label[u] = n_images + np.array([0, 0, 1])
    if len(problem.lines):
        c = problem.lines.constraints(problem.line_ground(), problem.scale, problem.line_flagged)
        u = problem.ground_point[problem.line_first:]
        direction[u, 0], direction[u, 1] = c.across, c.normal
        weight[u, 0] = np.einsum("ni,nij,nj->n", c.across, c.weight, c.across)
        weight[u, 1] = np.einsum("ni,nij,nj->n", c.normal, c.weight, c.normal)
        wrong = problem.line_flagged[problem.lines.obs.key]
        label[u, 0], label[u, 1] = np.where(wrong, -1, n_images + 2), np.where(wrong, -1, n_images + 3)
    outlying = np.bincount(lin.point[seen], weights=~inlier[seen], minlength=n_u) > 0
    label[outlying] = -1
    counts = np.bincount(lin.point[seen], minlength=n_u)
    order = np.nonzero(seen)[0]
    order = order[np.argsort(lin.point[order], kind="stable")]
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    for k in np.unique(counts[counts > 0]):
        points = np.nonzero(counts == k)[0]
        n = 2 * k + 3
        for chunk in np.array_split(points, max(1, points.size * n * n // BLOCK_NUMBERS)):
            obs = order[starts[chunk][:, None] + np.arange(k)]                              # (m, k)
            m = chunk.size
            A = np.concatenate([lin.jg[obs].reshape(m, 2 * k, 3), direction[chunk]], axis=1)  # (m, n, 3)
            p = np.concatenate([lin.p[obs].reshape(m, 2 * k), weight[chunk]], axis=1)        # (m, n)
            rows = np.where(inlier[obs], group[obs], -1)
            lab = np.concatenate([np.repeat(rows, 2, axis=1), label[chunk]], axis=1)         # (m, n)
            R = np.eye(n) - (A @ system.K[chunk]) @ A.transpose(0, 2, 1) * p[:, None, :]
            both = (lab[:, :, None] >= 0) & (lab[:, None, :] >= 0)
            index = np.broadcast_to(lab[:, :, None] * g, both.shape) + np.broadcast_to(lab[:, None, :], both.shape)
            flat += np.bincount(index[both], weights=(R * R.transpose(0, 2, 1))[both], minlength=g * g)
    return labels, flat.reshape(g, g)


def correlation(Q: np.ndarray | sparse.spmatrix) -> np.ndarray | sparse.csr_matrix:
    """The correlation matrix of the cofactors Q (dense, or sparse on N's pattern)."""
    d = np.sqrt(Q.diagonal())
    if sparse.issparse(Q):
        scale = sparse.diags(1.0 / d)
        return (scale @ Q @ scale).tocsr()
    return Q / np.outer(d, d)


def correlated_pairs(corr: np.ndarray, params: list) -> list[dict]:
    """Pairs of unknowns worth a look: |r| > 0.9 where an interior parameter takes part, and
    |r| > 0.999 between trajectory terms (a split the control barely determines)."""
    trajectory = np.array([p.block in ("position", "attitude") for p in params])
    if sparse.issparse(corr):  # only the entries on N's pattern: those of unknowns that share points
        entries = sparse.triu(corr, 1).tocoo()
        a, b, r = entries.row, entries.col, entries.data
    else:
        a, b = np.triu_indices(len(params), 1)
        r = corr[a, b]
    both = trajectory[a] & trajectory[b]
    keep = np.nonzero(np.where(both, np.abs(r) > 0.999, np.abs(r) > 0.9))[0]
    keep = keep[np.argsort(-np.abs(r[keep]))][:50]
    return [{"a": params[a[k]].name, "b": params[b[k]].name, "r": float(r[k]), "trajectory": bool(both[k])}
            for k in keep]

