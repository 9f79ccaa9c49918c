"""The datum directions a block's observations leave to the priors: named, with their size.

Tie points fix a block's shape, not where it lies. What they cannot see is any move of the whole
block that every product's correction can follow: the ground points move, each product's
correction moves its image the same way, and no residual changes. Which moves those are depends on
the corrections: with RPC_CORRECTION=shift (Grodecki & Dial 2003) the three common shifts, the height
shift among them (a stereo pair's parallax is absorbed by the images' own shifts); with drift also
the height tilt along the rows (the flight direction), which the row drift of each image follows; with
affine the tilt across as well, the rotation about the vertical and the scale. Only the priors hold
them: the onboard pseudo-observations (POSITION_SIGMA, ATTITUDE_SIGMA) and the RPC images' stated
accuracy (RPC_SIGMA), and the adjusted products move along them as far as the priors let the rest of
the solution pull them (measured on a ties-only Pleiades tri-stereo with drift: the heights rose by
a median 7.1 m and tilted 13.5 m across the 512 m crop; issue 28).

Each named move (:data:`MOVES`, in the local east-north-up frame at the tie points' centre, per metre
of its amplitude) is tested at the final linearisation:

1. the corrections that follow it: the parameter change dp whose image displacement J_p dp best fits
   J_g dG of the ground move dG at every observation with a ground unknown (weighted least squares,
   the observations' final weights); when that misses the move's displacement by more than FOLLOWED
   of its size (RMS), the corrections cannot follow it and the observations see it: not a datum
   direction of this correction model;
2. how well the observations and the priors determine dp: the observations' information
   dp' N_obs dp (the reduced normal matrix of the image observations, every ground point free to
   follow, control points held by their own priors) against the priors' dp' N_prior dp (every
   pseudo-observation: trajectory, RPC correction, weighted interior and the minimal prior). Below
   LEFT times the priors' information, the direction is left to the priors. With a reference DEM
   holding the tie points' heights (:mod:`core.adjust.tieheights`) its rows count among the
   observations; a direction the image observations alone leave to the priors and the DEM's rows
   hold is named as held by the reference DEM.

For the directions left to the priors: the priors' sigma along each (jointly, from
(D' N_prior D)^-1 of their dp, in metres of the move's amplitude and in px of the largest image
displacement it causes), and how far the adjustment moved the tie points along it (the amplitudes
of all MOVES fitted together to the tie points' displacement from their start, the forward
intersection through the input models, to their adjusted ground). A move beyond its prior sigma is
named as a warning: the priors, not the observations, decide it.

Blocks of RPC products only: their input models agree to a fraction of a pixel (the vendors' relative
bias), so the tie points' start is the vendors' geometry and their move from it is the adjustment's
(on the Giza pair it meets the change of the heights triangulated through the two sets of RPCs to
0.01 m). A block with rigorous scenes starts from onboard models tens of pixels apart: the move of its
tie points from their first intersection mixes the relative corrections in (a simulated tri-stereo's
tilt 'moved' 3.7 m where its onboard attitude holds it to 1.2 m), and its trajectories follow a
rotation about the vertical only to 10 %: such blocks keep their per-scene moves against the onboard
sigmas and the yaw sentence (:func:`core.adjust.ties.yaw_hold`), and are not analysed here.
"""
from __future__ import annotations

import logging

import numpy as np
from scipy import sparse

from ..geodesy import ecef_to_geodetic, enu_rotation
from .normal import GroundPrior, Linearization, System, assemble
from .problem import Problem

log = logging.getLogger(__name__)

# share (RMS) of a ground move's image displacement the corrections may miss and still follow it: the
# Giza pair's drift misses its tilt along the flight by 2.3 %, affine its moves by 0.4-1.7 %; a rigorous
# tri-stereo's trajectories miss the rotation about the vertical by 9.8 % (its tie points' move along
# it then mixes with the relative corrections and means little)
FOLLOWED = 0.05
LEFT = 1.0      # observations' information along a direction below this times the priors': left to the priors
MOVES = ("height shift", "height tilt along the flight direction", "height tilt across the flight direction",
         "shift east", "shift north", "rotation about the vertical", "horizontal scale")


def flight_direction(scene, height: float) -> np.ndarray:
    """(2,) unit east, north vector on the ground of the first camera's rows (its flight direction,
    along which an RPC image's drift terms act), at ``height`` (m)."""
    cam = scene.cameras[0]
    ends = scene.image_to_ground([cam.cols / 2] * 2, [0.0, float(cam.rows)], height, 0)
    lon, lat, _ = ecef_to_geodetic(ends.mean(axis=0))
    along = (enu_rotation(float(lon), float(lat)) @ (ends[1] - ends[0]))[:2]
    return along / np.linalg.norm(along)


def ground_moves(ground: np.ndarray, ties: np.ndarray, along: np.ndarray) -> tuple[np.ndarray, dict]:
    """The MOVES of ground points ``ground`` (m, 3) ECEF m per metre of amplitude, (K, m, 3) ECEF m, in
    the east-north-up frame at the centre of the tie points ``ties`` (m,) bool: the height shift and
    the horizontal shifts (1 m), the height tilts (1 m of height difference across the tie points'
    extent along the flight direction ``along`` (2,) east, north unit vector, and across it), the
    rotation about the vertical and the horizontal scale (1 m at the tie point farthest from the
    centre); and those extents (m: along, across, radius)."""
    centre = ground[ties].mean(axis=0)
    lon, lat, _ = ecef_to_geodetic(centre)
    rot = enu_rotation(float(lon), float(lat))
    enu = (ground - centre) @ rot.T
    east, north = enu[:, 0], enu[:, 1]
    x, y = east * along[0] + north * along[1], north * along[0] - east * along[1]  # along and across the flight
    extent = {"along_m": float(np.ptp(x[ties])), "across_m": float(np.ptp(y[ties])),
              "radius_m": float(np.hypot(east[ties], north[ties]).max())}
    one, zero = np.ones_like(east), np.zeros_like(east)
    width = {k: max(v, 1.0) for k, v in extent.items()}
    moves = np.stack([np.stack([zero, zero, one], axis=1),
                      np.stack([zero, zero, x / width["along_m"]], axis=1),
                      np.stack([zero, zero, y / width["across_m"]], axis=1),
                      np.stack([one, zero, zero], axis=1),
                      np.stack([zero, one, zero], axis=1),
                      np.stack([-north, east, zero], axis=1) / width["radius_m"],
                      np.stack([east, north, zero], axis=1) / width["radius_m"]])
    return moves @ rot, extent


def _image_steps(lin: Linearization, dp: np.ndarray) -> np.ndarray:
    """(K, n, 2) px: the image displacement J_p dp of each observation for parameter changes dp (K, u);
    one change at a time (an (n, q) temporary each, not K of them)."""
    cols, used = np.maximum(lin.columns, 0), lin.columns >= 0
    return np.stack([np.einsum("nkq,nq->nk", lin.values, np.where(used, d[cols], 0.0)) for d in dp])


def prior_matrix(problem: Problem, size: int, sparse_form: bool = False) -> np.ndarray | sparse.csr_matrix:
    """(u, u) the normal matrix of every pseudo-observation of ``problem`` (its priors) over its u free
    parameters (sparse_form: a CSR matrix)."""
    out = System(sparse.csr_matrix((size, size)) if sparse_form else np.zeros((size, size)),
                 np.zeros(size), np.zeros((0, 3, 3)), np.zeros((0, 3)), 0.0)
    blocks = []
    for p in problem.pseudo():
        w = np.broadcast_to(p.weight, (p.B.shape[0],))
        blocks.append((problem.unknown[p.index], p.B.T @ (w[:, None] * p.B)))
    out.add_blocks(blocks)
    return out.N


def _quadratic(d: np.ndarray, M: np.ndarray | sparse.spmatrix) -> np.ndarray:
    """(c,) d_c' M d_c of the rows of d (c, u); M (u, u) dense or sparse."""
    if sparse.issparse(M):
        return np.sum(d * (M @ d.T).T, axis=1)
    return np.einsum("cu,uv,cv->c", d, M, d)


def datum_directions(problem: Problem, lin: Linearization, system: System) -> list[dict]:
    """The MOVES of a block with tie points that its corrections can follow (see the module docstring),
    at the final linearisation ``lin`` and its normal equations ``system`` (for the ground prior): per
    direction its ``direction`` name, ``measure`` (what a metre of it is, '' for a shift),
    ``held_by``: 'priors' when the observations' information along it is below LEFT times the
    priors', else 'ties' (determined only through the ``unfollowed_share`` of its image displacement
    the corrections cannot follow), ``prior_sigma_m`` and ``prior_sigma_px`` (the priors' sigma along
    it, jointly with the other directions, and the largest image displacement one sigma makes),
    ``ties_sigma_m`` (the observations' alone; None when they give nothing), ``moved_m`` and
    ``moved_px`` (how far the tie points moved along it from their start, and the largest image
    displacement of that move). Empty without tie points or when the corrections follow none."""
    ties = np.zeros(problem.ground.shape[0], bool)
    ties[problem.obs.point[problem.is_tie]] = True
    n = int(problem.params.free.size)
    if ties.sum() < 3 or n == 0:
        return []
    height = float(np.mean(ecef_to_geodetic(problem.ground[ties])[2]))
    moves, extent = ground_moves(problem.ground, ties, flight_direction(problem.scene, height))
    follows = lin.point >= 0  # observations whose ground point is an unknown: it moves with the block
    target = np.einsum("nij,knj->kni", lin.jg, moves[:, problem.obs.point]) * follows[None, :, None]
    dp = _following(lin, target, n, problem.groups)
    miss = np.sqrt(np.einsum("nk,cnk->c", lin.p, (_image_steps(lin, dp) - target) ** 2)
                   / np.maximum(np.einsum("nk,cnk->c", lin.p, target ** 2), 1e-300))
    n_prior = prior_matrix(problem, n, system.is_sparse)
    info_prior = _quadratic(dp, n_prior)
    followed = np.nonzero((miss <= FOLLOWED) & (info_prior > 0))[0]
    if followed.size == 0:
        return []
    d = dp[followed]
    info_obs = _quadratic(d, assemble(lin, system.prior, n, problem.groups).N)
    info_images = info_obs if problem.ties.heights is None else \
        _quadratic(d, assemble(lin, _without_heights(problem, system.prior), n, problem.groups).N)
    cov = np.linalg.pinv(d @ n_prior @ d.T)  # (l, l) m^2: the priors' covariance of the directions followed
    sigma = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    # px: the largest image displacement of one sigma along each (the others moving with it as the
    # priors correlate them), and of each move the tie points made alone
    one_sigma = cov / np.where(sigma > 0, sigma, 1.0)[None, :]                      # (l, l): column j
    px_sigma = np.linalg.norm(np.einsum("lnk,lj->jnk", target[followed], one_sigma), axis=2).max(axis=1)
    px_metre = np.linalg.norm(target[followed], axis=2).max(axis=1)
    moved = _moved(problem, moves, ties)[followed]
    measures = {"height tilt along the flight direction": f"height difference across the tie points' "
                                                          f"{extent['along_m']:.0f} m along it",
                "height tilt across the flight direction": f"height difference across the tie points' "
                                                           f"{extent['across_m']:.0f} m across it",
                "rotation about the vertical": f"at {extent['radius_m']:.0f} m from the tie points' centre",
                "horizontal scale": f"at {extent['radius_m']:.0f} m from the tie points' centre"}
    return [{"direction": MOVES[k], "measure": measures.get(MOVES[k], ""),
             "held_by": "priors" if info_obs[j] < LEFT * info_prior[k] else
             "reference DEM" if info_images[j] < LEFT * info_prior[k] else "ties",
             "unfollowed_share": float(miss[k]), "prior_sigma_m": float(sigma[j]), "prior_sigma_px": float(px_sigma[j]),
             "ties_sigma_m": float(1.0 / np.sqrt(info_obs[j])) if info_obs[j] > 0 else None,
             "moved_m": float(moved[j]), "moved_px": float(moved[j] * px_metre[j])} for j, k in enumerate(followed)]


def _without_heights(problem: Problem, prior: GroundPrior) -> GroundPrior:
    """The ground prior ``prior`` without the tie points' height constraint (their rows zero)."""
    weight = prior.weight.copy()
    weight[problem.ground_point[problem.n_control:problem.line_first]] = 0.0
    return GroundPrior(weight, prior.misfit)


def _following(lin: Linearization, target: np.ndarray, n: int, obs_groups: list) -> np.ndarray:
    """(K, u) the parameter changes whose image displacements best fit ``target`` (K, n, 2) px at the
    observations (weighted least squares with their weights)."""
    plain = Linearization(lin.r, lin.p, lin.columns, lin.values, lin.jg, np.full(lin.point.size, -1))
    fit = assemble(plain, None, n, obs_groups)
    ok = lin.columns >= 0
    rhs = np.stack([np.bincount(lin.columns[ok], weights=np.einsum("nkq,nk->nq", lin.values, lin.p * t)[ok],
                                minlength=n) for t in target])
    if not fit.is_sparse:
        return np.linalg.lstsq(fit.N, rhs.T, rcond=None)[0].T
    # without ground unknowns the column groups do not couple: N is block diagonal, one fit per group
    out = np.zeros((target.shape[0], n))
    csr = fit.N.tocsr()
    for cols in fit.layouts:
        out[:, cols] = np.linalg.lstsq(csr[cols][:, cols].toarray(), rhs[:, cols].T, rcond=None)[0].T
    return out


def _moved(problem: Problem, moves: np.ndarray, ties: np.ndarray) -> np.ndarray:
    """(K,) m: the amplitudes of the MOVES ``moves`` (K, m, 3) fitted together (least squares) to the
    tie points' (``ties`` (m,) bool) displacement from their start (problem.ground0: the forward
    intersection through the input models) to their adjusted ground."""
    a = moves[:, ties].reshape(moves.shape[0], -1).T
    return np.linalg.lstsq(a, (problem.ground - problem.ground0)[ties].ravel(), rcond=None)[0]


def with_directions(held: dict, problem: Problem, result: dict) -> dict:
    """The datum entry ``held`` (:func:`core.adjust.ties.datum`) with the directions its corrections
    follow (:func:`datum_directions` at the solution ``result``'s linearisation and normal equations)
    under ``directions``, in words in its note; each moved beyond its prior sigma logged as a warning.
    None for a block with rigorous scenes (see the module docstring), with control lines or with 3
    control points or more (the control holds the datum); with 1 or 2 control points only those held
    by the priors (what the observations determine, the control may)."""
    rpc_only = problem.params.position_basis is None  # no trajectory: RPC corrections only
    if not rpc_only or held.get("control_lines") or held.get("control_points", 0) >= 3:
        return {**held, "directions": []}  # rigorous scenes in it, or the control holds the datum
    directions = datum_directions(problem, result["linearization"], result["system"])
    if held.get("control_points"):  # what the observations determine, the control may: only the priors' are named
        directions = [d for d in directions if d["held_by"] == "priors"]
    for warning in beyond_prior(directions):
        log.warning("%s", warning)
    return {**held, "directions": directions,
            "note": "; ".join(filter(None, (held.get("note"), directions_sentence(directions))))}


def _figures(d: dict) -> str:
    """A direction's figures in words: what a metre is, the priors' sigma, the ties' where they hold
    it, and the move."""
    measure = f"{d['measure']}: " if d["measure"] else ""
    ties = {"ties": f", the ties' {d['ties_sigma_m']:.1f} m",
            "reference DEM": f", the ties' and the reference DEM's {d['ties_sigma_m']:.1f} m"}.get(d["held_by"], "")
    return (f"{measure}the priors' sigma {d['prior_sigma_m']:.1f} m ({d['prior_sigma_px']:.1f} px){ties}; the tie "
            f"points moved {d['moved_m']:+.1f} m ({d['moved_px']:+.2f} px)")


def directions_sentence(directions: list[dict]) -> str:
    """The directions of :func:`datum_directions` in words ('' without any): those the ties leave to
    the priors, and those they determine only through the small part the corrections cannot follow."""
    left = [f"the {d['direction']} ({_figures(d)})" for d in directions if d["held_by"] == "priors"]
    weak = [f"the {d['direction']} (through {100 * d['unfollowed_share']:.1f} % of its image displacement; "
            f"{_figures(d)})" for d in directions if d["held_by"] == "ties"]
    dem = [f"the {d['direction']} ({_figures(d)})" for d in directions if d["held_by"] == "reference DEM"]
    parts = (["the ties leave to the priors " + ", ".join(left)] if left else []) + \
        (["the ties determine only through what the corrections cannot follow " + ", ".join(weak)] if weak else []) + \
        (["the reference DEM holds (the ties alone would leave them to the priors) " + ", ".join(dem)] if dem else [])
    return "; ".join(parts)


def beyond_prior(directions: list[dict]) -> list[str]:
    """Warnings for the directions of :func:`datum_directions` the tie points moved along by more than
    the priors' sigma: the priors allow less, and the observations hardly see that direction (a
    direction the reference DEM holds is no warning: the DEM moved them)."""
    return [f"the tie points moved {d['moved_m']:+.1f} m along the {d['direction']}"
            f"{' (' + d['measure'] + ')' if d['measure'] else ''}, more than the priors' sigma there "
            f"({d['prior_sigma_m']:.1f} m), which the tie points {'do not' if d['held_by'] == 'priors' else 'hardly'} "
            "determine: add control points (RPC products: or a correction the ties determine, RPC_CORRECTION=shift)"
            for d in directions if abs(d["moved_m"]) > d["prior_sigma_m"] and d["held_by"] != "reference DEM"]
