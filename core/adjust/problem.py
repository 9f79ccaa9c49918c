"""The unknowns, observations and weights of one adjustment, and one linearisation of it.

:class:`Problem` holds the scene, the parameters (:mod:`core.adjust.parameters`), the image
observations of control points, tie points and line points in one sorted array, the ground points
(control, tie, line) with their priors, and the weights: stated sigmas times the variance component
factor of their group (``scale``) times the robust weight factors (``factor``). The stages that change
them (variance components, robust weights, wrong lines, interior selection) do so through its methods.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import ConvergenceError
from ..geodesy import enu_rotations, geodetic_to_ecef
from ..model.timebasis import TimeBasis
from ..observations.gcps import GcpTable
from . import linepoints
from .linepoints import LineSetUp
from .model import ImageObservations, Imaging, Jacobian, Model, build_observations, project
from .normal import GroundPrior, Linearization, System, assemble, back_substitute, groups
from .parameters import ANGLES, CAMERA_TERMS, ParameterSet, trajectory_groups
from .scenesigmas import camera_scene
from .settings import AdjustmentSettings
from .startvalues import start_from_existing_correction
from .tieheights import TIE_HEIGHT_GROUP, HeightConstraint
from .ties import TieSetUp, camera_indices


# The pseudo-observation group of the minimal trajectory prior (core.adjust.minimalprior). Like the
# constraints of a minimal datum it decides what the observations leave open: no redundancy, so
# its rows do not count among the equations (they would lower sigma0 by adding degrees of freedom
# their near-zero residuals do not fill).
HELD_GROUP = "minimal trajectory prior"
# The pseudo-observation group of the RPC images' corrections: the vendor's stated accuracy
# (settings.rpc_sigma, core.adjust.rpcbias).
RPC_PRIOR_GROUP = "RPC correction pseudo-observations"


def image_group(camera: str) -> str:
    """The variance component group of a camera's image observations of control and line points."""
    return f"image {camera}"


# The variance component group of all tie-point observations: apart from the cameras' control
# observations, because matched tie points are often ten times more precise than control points
# measured by hand (with one factor for both, the control points were flagged against the ties' scale
# and left out: 4 GCPs of a matched tri-stereo block all flagged, 0.3 px against 0.01 px). One group for
# every camera: the matching's precision is the same process in each, and a tie point's rays in two or
# three cameras share its misfit, so per-camera factors are barely separable (an unmodelled lens error
# went all to the base camera's ties: factor 5.3 there, 1 in the others).
TIE_GROUP = "tie points"


class Problem:
    """The data and unknowns of one adjustment, and one linearisation of it (see the module docstring).
    ``rpc_choice``: what RPC_CORRECTION=auto chose for RPC images and why
    (:func:`core.adjust.rpcbias.chosen_correction`; None: given, or no RPC image).

    Built in one way for every kind of scene: the settings the scene takes
    (:meth:`chosen_settings`), the ground points, then the unknowns and observations its kind
    defines (:meth:`set_up`, which the RPC scene's and the block's problems override), then the
    weights as stated."""

    rpc_choice: dict | None = None

    def __init__(self, scene, table: GcpTable, settings: AdjustmentSettings,
                 ties: TieSetUp | None = None, lines: LineSetUp | None = None):
        ties = ties or TieSetUp.empty()
        lines = lines or LineSetUp.empty()
        control = np.nonzero(table.role == "control")[0]
        ids, first, point = np.unique(table.id[control], return_index=True, return_inverse=True)
        self.scene = scene
        self.settings, self.rpc_choice = self.chosen_settings(settings, int(ids.size))
        self._set_up_ground(table, control[first], ties.ground, lines)
        self.ties = ties
        self.params, self.obs, self.is_tie, self.is_line, self.rows = \
            self.set_up(table, control, point, ids, ties, lines)
        # where the current model images the observations (the last projection: the next one's
        # start) and the pixel map there; see :meth:`project`
        self.imaged, self.map = self.obs, None
        self.line_obs = np.empty(len(lines), np.int64)  # each line point's observation
        self.line_obs[self.rows[self.is_line]] = np.nonzero(self.is_line)[0]
        self.factor = np.ones((len(self.obs), 2))  # robust weight factors per residual row
        self.scale: dict[str, float] = {}  # variance component factor on the stated sigmas, per group
        self.held: list[Pseudo] = []  # the minimal trajectory prior, if any (core.adjust.minimalprior)
        self.rescaled()
        self.structure()

    def chosen_settings(self, settings: AdjustmentSettings, n_control: int) -> tuple[AdjustmentSettings, dict | None]:
        """The settings this problem adjusts with, for ``n_control`` control points, and what was
        chosen for the user (None: the settings as given): a rigorous scene takes them as given."""
        return settings, None

    def set_up(self, table: GcpTable, control: np.ndarray, point: np.ndarray, ids: np.ndarray, ties: TieSetUp,
               lines: LineSetUp):
        """(parameters, observations, is_tie (n,) bool, is_line (n,) bool, rows (n,)) of the rigorous
        scene: its trajectory and interior unknowns, and the image observations of the control rows
        ``control`` of ``table`` (of control points ``point`` (c,): indices into ``ids``, the control
        points' sorted ids), of the tie observations and of the line points, sorted by their parameter
        columns. ``rows``: each observation's row in the GCP table, the tie table or the line points."""
        scene, settings = self.scene, self.settings
        # trajectory bases over each measured trajectory's time span (the scene's; a block scene's)
        spans = [scene.time_span(cams) for cams in trajectory_groups(scene)]
        params = ParameterSet(
            scene,
            [TimeBasis.covering(settings.position_model, *span, settings.position_order, settings.position_interval)
             for span in spans],
            [TimeBasis.covering(settings.attitude_model, *span, settings.attitude_order, settings.attitude_interval)
             for span in spans],
            settings.interior, per_camera=settings.camera_trajectory == "per_camera")
        start_from_existing_correction(scene, params)
        # GCP observations, then tie observations (their points after the GCPs'), then line points
        kind = np.repeat([0, 1, 2], [control.size, len(ties), len(lines)])
        self.imaging = Imaging(scene, params)
        obs = build_observations(self.imaging,
                                 np.r_[camera_indices(scene, table.camera[control]), ties.camera, lines.camera],
                                 np.r_[table.col[control], ties.table.col[ties.rows], lines.obs.col],
                                 np.r_[table.row[control], ties.table.row[ties.rows], lines.obs.row],
                                 np.r_[point, ids.size + ties.point, self.line_first + np.arange(len(lines))],
                                 np.r_[table.sigma_px[control], ties.table.sigma_px[ties.rows], lines.obs.sigma_px])
        # Observations sorted by what decides their parameter columns, so that observations
        # sharing columns are contiguous whatever the free parameters: groups are slices.
        order = np.lexsort((obs.att_first, obs.pos_first, obs.chip, obs.camera))
        rows = np.r_[control, ties.rows, np.arange(len(lines))][order]
        return params, obs.select(order), kind[order] == 1, kind[order] == 2, rows

    # --- sigmas: stated, times the variance component factor of their group ----------------
    def rescaled(self) -> None:
        """Ground weights (m,3,3) ECEF from the stated sigmas and the current factors."""
        s = np.array([self.scale.get("ground_xy", 1.0)] * 2 + [self.scale.get("ground_z", 1.0)])
        self.ground_weight = np.einsum("mki,mk,mkj->mij", self.enu, 1.0 / (self.ground_sigma * s) ** 2, self.enu)

    def set_scale(self, scale: dict[str, float]) -> None:
        """Variance component factors on the stated sigmas, per group (a group not named: 1)."""
        self.scale = dict(scale)
        self.rescaled()

    def set_weight_factors(self, factor: np.ndarray) -> None:
        """Robust weight factors (n, 2) of the image observations' residual rows, in [0, 1]."""
        self.factor = np.array(factor, dtype=float)

    def set_weights_of(self, other: "Problem") -> None:
        """The variance component factors and robust weight factors of ``other`` (same observations)."""
        self.set_weight_factors(other.factor)
        self.set_scale(other.scale)

    def reset_weights(self) -> None:
        """Weights as stated: no variance component factors, no robust down-weighting."""
        self.set_weight_factors(np.ones_like(self.factor))
        self.set_scale({})

    def set_line_flags(self, flagged: np.ndarray) -> None:
        """(K,) the control lines named wrong as a whole (their across-line constraints released)."""
        self.line_flagged = np.asarray(flagged, dtype=bool)

    def fix(self, names: list[str]) -> None:
        """Fix the parameters ``names`` at their current values and renumber the unknowns."""
        self.params.fix(names)
        self.structure()

    def fix_at_zero(self, indices) -> None:
        """Fix the parameters of ``indices`` (into params.params) at 0 and renumber the unknowns."""
        for i in indices:
            p = self.params.params[i]
            p.mode, p.value = "fixed", 0.0
        self.structure()

    @cached_property
    def image_groups(self) -> tuple[list[str], np.ndarray]:
        """(labels, (n,) index into labels): the variance component group of each image observation,
        per camera its control and line observations (:func:`image_group`), and TIE_GROUP for the tie
        observations of every camera; groups without observations left out."""
        keys, index = np.unique(np.where(self.is_tie, -1, self.obs.camera), return_inverse=True)
        names = [c.name for c in self.scene.cameras]
        return [TIE_GROUP if k < 0 else image_group(names[k]) for k in keys.tolist()], index

    def image_sigma(self) -> np.ndarray:
        """(n,) px: each image observation's stated sigma times its group's factor."""
        labels, index = self.image_groups
        return self.obs.sigma * np.array([self.scale.get(k, 1.0) for k in labels])[index]

    def stated_sigma(self, group: str) -> tuple[float | None, str]:
        """The median stated sigma of a group and its unit (None for interior pseudo-observations,
        whose sigmas have several units); of the trajectory pseudo-observations, the median over the
        corrections of their scenes' sigmas (settings.scene_sigmas or the global one)."""
        labels, index = self.image_groups
        if group in labels:
            return float(np.median(self.obs.sigma[index == labels.index(group)])), "px"
        if group.startswith("ground"):
            return float(np.median(self.ground_sigma[:, 2 if group == "ground_z" else 0])), "m"
        if group in (linepoints.ACROSS_GROUP, linepoints.HEIGHT_GROUP):
            seg = self.lines.seg
            return float(np.median(seg.sigma_across if group == linepoints.ACROSS_GROUP else seg.sigma_h)), "m"
        s = self.settings
        for block, unit in (("position", "m"), ("attitude", "rad")):
            if group == f"{block} pseudo-observations":
                if getattr(s, f"{block}_sigma") is None:
                    return None, unit
                return float(np.median([self.correction_sigma(block, o)
                                        for o in range(len(self.params.bases[block]))])), unit
        stated = {RPC_PRIOR_GROUP: (s.rpc_sigma, "px"), TIE_HEIGHT_GROUP: (s.tie_height_sigma, "m")}
        return stated.get(group, (None, ""))

    # --- unknowns and their columns -------------------------------------------------------
    def _set_up_ground(self, table: GcpTable, sel: np.ndarray, tie_ground: np.ndarray | None = None,
                       lines: LineSetUp | None = None) -> None:
        """Ground points: the control points ``sel`` (rows of ``table``, one per point), then the
        tie points (start values ``tie_ground`` (t, 3) ECEF m), then the line points of ``lines``
        (from ``line_first``; their prior is the lines', :meth:`ground_prior`). ground0 / ground (m, 3) ECEF m:
        measured (start) and current positions; for weighted ground the control points' ENU
        rotations and stated east, north, up sigmas (m, (n, 3)). The ground unknowns are the
        weighted control points and all tie points (which have no prior): ``estimated`` (k,)
        their indices in ground, ``ground_point`` (m,) each point's unknown index or -1."""
        tie_ground = np.zeros((0, 3)) if tie_ground is None else tie_ground
        self.lines = lines or LineSetUp.empty()
        # lines named wrong as a whole (released); grossly wrong ones from the start
        self.line_flagged = linepoints.screen(self.scene, self.lines) if len(self.lines) else \
            np.zeros(0, bool)
        self.n_control = int(sel.size)
        self.line_first = int(sel.size + tie_ground.shape[0])
        self.ground0 = np.concatenate([geodetic_to_ecef(table.lon[sel], table.lat[sel], table.h[sel]).reshape(-1, 3),
                                       tie_ground, self.lines.ground])
        self.ground = self.ground0.copy()
        self.weighted = self.settings.ground == "weighted"
        self.enu = enu_rotations(table.lon[sel], table.lat[sel]) if self.weighted else np.zeros((0, 3, 3))
        self.ground_sigma = np.stack([table.sigma_xy[sel], table.sigma_xy[sel], table.sigma_z[sel]], 1) \
            if self.weighted else np.zeros((0, 3))
        self.estimated = np.arange(self.n_control * (not self.weighted), self.ground0.shape[0])
        self.ground_point = -np.ones(self.ground0.shape[0], np.int64)
        self.ground_point[self.estimated] = np.arange(self.estimated.size)

    def counts(self) -> tuple[int, int]:
        """(equations, unknowns): image rows, ground priors, the tie points' heights held to a reference
        DEM (one row each) and pseudo-observations against the free parameters and the ground unknowns."""
        heights = self.tie_heights()
        n_eq = 2 * len(self.obs) + 3 * self.enu.shape[0] + 2 * len(self.lines) + \
            sum(p.B.shape[0] for p in self.pseudo() if p.group != HELD_GROUP) + \
            (int(heights.on.sum()) if heights is not None else 0)
        return n_eq, int(self.params.free.size) + 3 * int(self.estimated.size)

    def structure(self) -> None:
        """Unknown numbering and each observation's columns (after a change of the free set)."""
        params = self.params
        free = params.free
        self.unknown = -np.ones(len(params.params), dtype=np.int64)
        self.unknown[free] = np.arange(free.size)
        obs = self.obs
        pos = params.block_indices("position")
        att = params.block_indices("attitude")
        wp, wa = obs.pos_weights.shape[1], obs.att_weights.shape[1]
        cols = [pos[obs.pos_first[:, None] + np.arange(wp)].reshape(-1, 3 * wp),
                att[obs.att_first[:, None] + np.arange(wa)].reshape(-1, 3 * wa)]
        inst = np.stack([params.camera_indices(c, "installation", ANGLES) for c in range(len(params.scene.cameras))])
        cams = np.stack([params.camera_indices(c, "camera", CAMERA_TERMS) for c in range(len(params.scene.cameras))])
        chip = -np.ones((len(obs), 4), dtype=np.int64)
        for c, cam in enumerate(params.scene.cameras):
            for k in range(len(cam.chips)):
                _, idx = params.chip_indices(c, k)
                chip[(obs.camera == c) & (obs.chip == k), :idx.size] = idx
        cols += [inst[obs.camera], chip, cams[obs.camera]]
        param_cols = np.concatenate(cols, axis=1)
        columns = np.where(param_cols >= 0, self.unknown[np.maximum(param_cols, 0)], -1)
        # Only the column slots some observation uses (fixed terms cost nothing then).
        self.slots = np.nonzero((columns >= 0).any(axis=0))[0]
        self.columns = columns[:, self.slots]
        self.groups = groups(self.columns)

    def values(self, jac: Jacobian, imaged: ImageObservations) -> np.ndarray:
        """Jacobian values (n, 2, q) in the column layout of :meth:`structure`, of the
        observations imaged at ``imaged`` (whose trajectory windows the layout has)."""
        obs = self.obs
        wp, wa = obs.pos_weights.shape[1], obs.att_weights.shape[1]
        pos_weights, pos_rates, att_weights = imaged.pos_weights, imaged.pos_rates, imaged.att_weights
        out = np.empty((len(obs), 2, self.slots.size))
        for j, slot in enumerate(self.slots):
            if slot < 3 * wp:
                out[:, :, j] = jac.S[:, :, slot % 3] * pos_weights[:, slot // 3, None] + \
                    jac.V[:, :, slot % 3] * pos_rates[:, slot // 3, None]
            elif slot < 3 * (wp + wa):
                k = slot - 3 * wp
                out[:, :, j] = jac.angles[:, :, k % 3] * att_weights[:, k // 3, None]
            else:
                k = slot - 3 * (wp + wa)
                block, k = ((jac.installation, k) if k < 3 else (jac.chip, k - 3) if k < 7 else (jac.camera, k - 7))
                out[:, :, j] = block[:, :, k]
        return out

    # --- one linearisation --------------------------------------------------------------------
    def weights(self) -> np.ndarray:
        return self.factor / self.image_sigma()[:, None] ** 2

    def project(self, new_map: bool = False) -> tuple[Model, np.ndarray]:
        """Where the current model images the observations' ground points: (the model, the
        imaged (col, row) (n,2) px, NaN where it does not). Newton from the last projection
        (:func:`core.adjust.model.project`) with its pixel map, or (``new_map``) a new one."""
        model = Model(self.scene, self.params)
        self.imaged, self.map, predicted = project(model, self.imaging, self.obs, self.ground[self.obs.point],
                                                   self.imaged, None if new_map else self.map)
        return model, predicted

    def fitted(self) -> np.ndarray:
        """(n,2) px: where the current model images the observations' ground points."""
        return self.project()[1]

    def linearize(self) -> tuple[Linearization, GroundPrior | None]:
        model, predicted = self.project(new_map=True)
        r = predicted - np.stack([self.obs.col, self.obs.row], axis=1)
        if not np.all(np.isfinite(r)):
            bad = ~np.all(np.isfinite(r), axis=1)
            kinds = np.where(self.is_tie, "tie point", np.where(self.is_line, "line point", "GCP"))[bad]
            raise ConvergenceError(f"the current model images {int(bad.sum())} observation(s) nowhere on their chips "
                                   f"({', '.join(f'{k} row {i}' for k, i in zip(kinds[:5], self.rows[bad][:5]))}): "
                                   "the solution diverged, or the points lie behind the camera")
        imaged = self.imaged
        if not (np.array_equal(imaged.pos_first, self.obs.pos_first) and
                np.array_equal(imaged.att_first, self.obs.att_first)):
            # imaged across a knot of a piecewise trajectory model: the columns follow the
            # coefficients that act where the point is imaged (those of its measured time may not)
            self.obs.pos_first, self.obs.att_first = imaged.pos_first, imaged.att_first
            self.structure()
        jac = model.linearize(imaged, self.ground[self.obs.point], self.map)
        return Linearization(r, self.weights(), self.columns, self.values(jac, self.imaged), jac.ground,
                             self.ground_point[self.obs.point]), self.ground_prior()

    def ground_prior(self) -> GroundPrior | None:
        """The ground unknowns' prior: the weighted control points' stated weights, zero for tie
        points or (a reference DEM) their rank-1 height constraint at the current ground
        (:meth:`tie_heights`), the rank-2 line constraints at the current ground for line points (the
        nearest segment refreshed) (None without ground unknowns)."""
        if self.estimated.size == 0:
            return None
        weight = np.concatenate([self.ground_weight, np.zeros((self.estimated.size - self.enu.shape[0], 3, 3))])
        misfit = (self.ground - self.ground0)[self.estimated]
        heights = self.tie_heights()
        if heights is not None:
            ties = self.ground_point[self.n_control:self.line_first]
            weight[ties], misfit[ties] = heights.weight, heights.misfit
        if len(self.lines):
            c = self.lines.constraints(self.line_ground(), self.scale, self.line_flagged)
            weight[-len(self.lines):], misfit[-len(self.lines):] = c.weight, c.misfit
            self.line_association = (self.line_ground().copy(), c.weight, c.misfit, dict(self.scale),
                                     self.line_flagged.copy())
        return GroundPrior(weight, misfit)

    def tie_heights(self) -> HeightConstraint | None:
        """The tie points' height constraint at their current ground (None: no reference DEM)."""
        reference = self.ties.heights
        return None if reference is None else reference.at(self.ground[self.n_control:self.line_first])

    def line_cost(self) -> float:
        """The line constraints' weighted squared misfits at the current ground. Within one
        linearisation the association of each point with its segment is kept (the constraint of
        that segment, a plane pair, at the new ground): refreshed at every step, a point far off its
        line (a line paired with the wrong road) that changes segment makes the cost jump by
        hundreds for a millimetre's move, and no step would be taken."""
        x = self.line_ground()
        kept = getattr(self, "line_association", None)
        if kept is not None and kept[3] == self.scale and np.array_equal(kept[4], self.line_flagged):
            e = kept[2] + (x - kept[0])
            return float(np.einsum("mi,mij,mj->", e, kept[1], e))
        line = self.lines.constraints(x, self.scale, self.line_flagged)
        return float(np.einsum("mi,mij,mj->", line.misfit, line.weight, line.misfit))

    def line_ground(self) -> np.ndarray:
        """(n, 3) ECEF m: the line points' current ground positions."""
        return self.ground[self.line_first:]

    def residuals(self) -> np.ndarray:
        """(n,2) px: imaged minus measured (col, row), NaN where the model does not image a point."""
        return self.fitted() - np.stack([self.obs.col, self.obs.row], axis=1)

    def cost(self) -> float:
        """Weighted squared residuals of the current state (inf where a point is not imaged)."""
        r = self.residuals()
        if not np.all(np.isfinite(r)):
            return float("inf")
        c = float(np.sum(self.weights() * r * r))
        if self.weighted:
            e = (self.ground - self.ground0)[:self.n_control]
            c += float(np.einsum("mi,mij,mj->", e, self.ground_weight, e))
        if len(self.lines):
            c += self.line_cost()
        if self.ties.heights is not None:
            c += self.tie_heights().cost
        values = self.params.values()
        return c + sum(float(np.sum(p.weight * p.misfit(values) ** 2)) for p in self.pseudo())

    def correction_sigma(self, block: str, owner: int) -> float:
        """The stated sigma (m for 'position', rad for 'attitude') of trajectory correction
        ``owner``'s pseudo-observations: its block scene's own (settings.scene_sigmas, the scene
        from its cameras' composite names ``<scene>/<camera>``) or the global one."""
        scene = camera_scene(self.scene.cameras[int(self.params.owners[owner][0])].name)
        return self.settings.sigma(f"{block}_sigma", scene)

    def pseudo(self) -> list["Pseudo"]:
        """Pseudo-observations: trajectory corrections at the knots (each correction's with the sigma
        of its block scene, settings.scene_sigmas, or the global one), weighted parameters, the
        minimal trajectory prior (:attr:`held`; its weights are not variance components')."""
        out = []
        s = self.settings
        for block in ("position", "attitude"):
            if getattr(s, f"{block}_sigma") is None:  # none in any scene: the global value decides the datum
                continue
            group = f"{block} pseudo-observations"
            indices = self.params.block_indices(block)
            for o, basis in enumerate(self.params.bases[block]):  # per trajectory correction
                sigma = self.correction_sigma(block, o)
                times = basis.knot_times() if basis.kind != "polynomial" else \
                    basis.t0 + basis.scale * np.linspace(-1.0, 1.0, basis.size)
                B = basis.matrix(times)  # (k, m)
                rows = indices[self.params.owner_rows(block, o)]
                for a in range(3):
                    out.append(Pseudo(group, rows[:, a], B, 1.0 / (sigma * self.scale.get(group, 1.0)) ** 2))
        weighted = [i for i, p in enumerate(self.params.params) if p.mode == "weighted"]
        if weighted:
            group = "interior pseudo-observations"
            sigmas = np.array([self.params.params[i].sigma for i in weighted]) * self.scale.get(group, 1.0)
            out.append(Pseudo(group, np.array(weighted), np.eye(len(weighted)), 1.0 / sigmas ** 2))
        return out + self.held

    def system(self, linearized: tuple[Linearization, GroundPrior | None] | None = None,
               ground_damping: float = 0.0) -> tuple[Linearization, System]:
        """The linearisation (made now, or ``linearized``: (lin, ground prior)) and its reduced
        normal equations with the pseudo-observations (ground_damping: see :func:`assemble`)."""
        lin, prior = linearized or self.linearize()
        system = assemble(lin, prior, int(self.params.free.size), self.groups, ground_damping)
        blocks, values = [], self.params.values()
        for p in self.pseudo():
            cols = self.unknown[p.index]
            m = p.misfit(values)
            w = np.broadcast_to(p.weight, m.shape)
            blocks.append((cols, p.B.T @ (w[:, None] * p.B)))
            system.b += np.bincount(cols, weights=p.B.T @ (w * m), minlength=system.b.size)
            system.cost += float(np.sum(w * m * m))
        system.add_blocks(blocks)
        return lin, system

    def model_cost(self, lin: Linearization, prior: GroundPrior | None, dx: np.ndarray, dg: np.ndarray) -> float:
        """The weighted squared residuals the linearisation ``lin`` (with its ground prior) predicts
        after the parameter step dx and the ground step dg (k,3) of the ground unknowns."""
        step = np.einsum("nkq,nq->nk", lin.values, np.where(lin.columns >= 0, dx[np.maximum(lin.columns, 0)], 0.0))
        seen = lin.point >= 0
        step[seen] += np.einsum("nki,ni->nk", lin.jg[seen], dg[lin.point[seen]])
        r = lin.r + step
        cost = float(np.sum(lin.p * r * r))
        if prior is not None and dg.size:
            e = prior.misfit + dg
            cost += float(np.einsum("mi,mij,mj->", e, prior.weight, e))
        values = self.params.values()
        for p in self.pseudo():
            m = p.misfit(values) + p.B @ dx[self.unknown[p.index]]
            cost += float(np.sum(p.weight * m * m))
        return cost

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """The current parameter values and ground positions, for :meth:`restore`."""
        return self.params.values(), self.ground.copy()

    def restore(self, state: tuple[np.ndarray, np.ndarray]) -> None:
        """Back to a :meth:`state` (a refused step)."""
        self.params.set_values(state[0])
        self.ground = state[1]

    def step(self, lin: Linearization, system: System, dx: np.ndarray) -> None:
        values = self.params.values()
        values[self.params.free] += dx
        self.params.set_values(values)
        if self.estimated.size:
            self.ground = self.ground.copy()
            self.ground[self.estimated] += back_substitute(lin, system, dx)


@dataclass
class Pseudo:
    """A group of pseudo-observations B @ x[index] = 0 with weights (1/sigma^2)."""
    group: str
    index: np.ndarray
    B: np.ndarray
    weight: np.ndarray | float

    def misfit(self, values: np.ndarray) -> np.ndarray:
        """B @ x[index] of the parameters' values ``values`` (all of them, :meth:`ParameterSet.values`:
        taken once by the caller for every pseudo-observation, not once per pseudo-observation)."""
        return self.B @ values[self.index]

