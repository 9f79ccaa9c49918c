"""The engine's problem of a block with RPC images (:class:`core.model.mixedblock.MixedBlock`): the
rigorous scenes' composite and every RPC image adjusted together, sharing the ground points.

Each scene keeps its own correction: the rigorous scenes their trajectory and interior blocks (one
:class:`core.adjust.problem.Problem` over their composite, as a block of rigorous scenes alone),
each RPC image its image-space correction (Grodecki & Dial 2003, :class:`core.adjust.rpcbias.RpcImage`).
The ground points (control points, tie points) are one set, eliminated from the normal equations as
in one scene: an observation in a rigorous camera and one in an RPC image of the same point touch
the same ground unknowns. :class:`BlockProblem` offers what the engine uses of a Problem, so its
stages (determinability, Levenberg-Marquardt, robust estimation and variance components, check
points, the written-vs-fitted check, the report) run unchanged.

Unknowns: the rigorous parameters first (numbered as in the composite's own problem), then each RPC
image's six terms (those of RPC_CORRECTION free). Observations: the rigorous ones in their
problem's order (sorted by parameter columns), then each RPC image's. With settings.rpc_sigma the
RPC corrections carry the vendor's stated accuracy as pseudo-observations
(:meth:`core.adjust.rpcbias.RpcImage.prior`), as the onboard sigmas do for the trajectories.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..model.mixedblock import MixedBlock
from ..observations.gcps import GcpTable
from .normal import GroundPrior, Linearization, groups
from .parameters import ParameterSet
from .problem import RPC_PRIOR_GROUP, Problem, Pseudo
from .rpcbias import RpcImage, RpcObservations, chosen_correction
from .settings import AdjustmentSettings
from .ties import TieSetUp, camera_indices


class BlockParameters(ParameterSet):
    """The unknowns of a block with RPC images: the rigorous composite's parameter set (None without
    rigorous scenes) and the RPC images' corrections, as one list (the same Parameter objects)."""

    def __init__(self, scene: MixedBlock, rigorous: ParameterSet | None, images: list[RpcImage]):
        self.scene, self.rigorous, self.images = scene, rigorous, images
        self.params = (list(rigorous.params) if rigorous is not None else []) + \
            [p for img in images for p in img.params.params]
        self.index = {p.name: i for i, p in enumerate(self.params)}
        sizes = [len(img.params.params) for img in images]
        # each RPC image's first term in params: after the rigorous parameters and the images before it
        self.image_offsets = len(self.params) - sum(sizes) + np.cumsum([0] + sizes[:-1], dtype=np.int64)
        self.bases = rigorous.bases if rigorous is not None else {"position": [], "attitude": []}
        self.owners = rigorous.owners if rigorous is not None else []
        self.position_basis = rigorous.position_basis if rigorous is not None else None
        self.attitude_basis = rigorous.attitude_basis if rigorous is not None else None

    @property
    def trajectories(self) -> ParameterSet | None:
        return self.rigorous

    def owner_rows(self, block: str, owner: int) -> slice:
        return self.rigorous.owner_rows(block, owner)

    def imaged_by(self, camera: int) -> np.ndarray:
        """(len(params),) bool: the parameters that change what camera ``camera`` (index in the
        block) images: a rigorous camera's (:meth:`ParameterSet.imaged_by`), an RPC image's
        correction terms."""
        out = np.zeros(len(self.params), bool)
        if camera < self.scene.n_rigorous:
            out[:len(self.rigorous.params)] = self.rigorous.imaged_by(camera)
            return out
        j = camera - self.scene.n_rigorous
        out[self.image_offsets[j]:self.image_offsets[j] + len(self.images[j].params.params)] = True
        return out

    def adjusted_scene(self) -> MixedBlock:
        """The block with the current corrections: the rigorous composite's and each RPC image's."""
        return self.scene.with_parts(self.rigorous.adjusted_scene() if self.rigorous is not None else None,
                                     {name: img.params.adjusted_scene()
                                      for name, img in zip(self.scene.images, self.images)})


class BlockProblem(Problem):
    """The engine's problem of a block with RPC images (see the module docstring)."""

    def chosen_settings(self, settings: AdjustmentSettings, n_control: int) -> tuple[AdjustmentSettings, dict | None]:
        """RPC_CORRECTION=auto resolved for the RPC images (:func:`chosen_correction`); INTERIOR
        refused for a block without rigorous scenes."""
        if settings.interior and self.scene.rigorous is None:
            raise InputError("INTERIOR: a block of RPC images has no interior parameters; their correction is "
                             "chosen with RPC_CORRECTION", parameter="settings.interior")
        return chosen_correction(settings, n_control)

    def set_up(self, table: GcpTable, control: np.ndarray, point: np.ndarray, ids: np.ndarray, ties: TieSetUp,
               lines):
        """The rigorous composite's problem over its own observations (first, in its order), then
        each RPC image's correction terms and observations (``image_slices``: each image's
        observations); the unknowns as one :class:`BlockParameters`. A block takes no lines."""
        scene, settings = self.scene, self.settings
        camera = np.r_[camera_indices(scene, table.camera[control]), ties.camera].astype(np.int64)
        obs = RpcObservations(camera, np.zeros(camera.size, np.int64),
                              np.r_[point, ids.size + ties.point].astype(np.int64),
                              np.r_[table.sigma_px[control], ties.table.sigma_px[ties.rows]].astype(float),
                              np.r_[table.col[control], ties.table.col[ties.rows]],
                              np.r_[table.row[control], ties.table.row[ties.rows]])
        is_tie = np.repeat([False, True], [control.size, len(ties)])
        rows = np.r_[control, ties.rows]
        parts, self.rigorous = [], None
        if scene.rigorous is not None:
            self.rigorous, self.rigorous_ground, rig_obs, rig_is_tie, rig_rows = \
                _rigorous_part(scene, table, control, ids, ties, settings)
            parts.append((rig_obs, rig_is_tie, rig_rows))
        self.images = [RpcImage(img, settings.rpc_correction) for img in scene.images.values()]
        self.image_slices = []
        start = len(parts[0][0]) if parts else 0
        for j in range(len(self.images)):
            mine = obs.camera == scene.n_rigorous + j
            parts.append((obs.select(mine), is_tie[mine], rows[mine]))
            self.image_slices.append(slice(start, start + int(mine.sum())))
            start += int(mine.sum())
        all_obs = RpcObservations(*(np.concatenate([getattr(p[0], f) for p in parts])
                                    for f in ("camera", "chip", "point", "sigma", "col", "row")))
        params = BlockParameters(scene, self.rigorous.params if self.rigorous else None, self.images)
        return (params, all_obs, np.concatenate([p[1] for p in parts]), np.zeros(len(all_obs), bool),
                np.concatenate([p[2] for p in parts]))

    @property
    def n_rigorous_obs(self) -> int:
        return len(self.rigorous.obs) if self.rigorous is not None else 0

    def structure(self) -> None:
        """Unknown numbering (rigorous parameters first, as their own problem numbers them) and
        each observation's columns."""
        free = self.params.free
        self.unknown = -np.ones(len(self.params.params), dtype=np.int64)
        self.unknown[free] = np.arange(free.size)
        if self.rigorous is not None:
            self.rigorous.structure()
        self._columns()

    def _columns(self) -> None:
        """The observations' columns (n, q): the rigorous problem's (which change when an
        observation is imaged across a knot), then each RPC image's free terms; padded with -1."""
        blocks = [self.rigorous.columns] if self.rigorous is not None else []
        blocks += [np.broadcast_to(self.unknown[off + img.slots], (s.stop - s.start, img.slots.size))
                   for img, off, s in zip(self.images, self.params.image_offsets, self.image_slices)]
        width = max(b.shape[1] for b in blocks)
        self.columns = np.concatenate([np.pad(b, ((0, 0), (0, width - b.shape[1])), constant_values=-1)
                                       for b in blocks])
        self.groups = groups(self.columns)

    def _rigorous_at_block_ground(self) -> Problem:
        """The rigorous problem with its ground points where the block's are now."""
        self.rigorous.ground = self.ground[self.rigorous_ground]
        return self.rigorous

    def residuals(self) -> np.ndarray:
        r = np.empty((len(self.obs), 2))
        if self.rigorous is not None:
            r[:self.n_rigorous_obs] = self._rigorous_at_block_ground().residuals()
        for img, s in zip(self.images, self.image_slices):
            r[s] = img.residuals(self.ground[self.obs.point[s]], self.obs.col[s], self.obs.row[s])
        return r

    def linearize(self) -> tuple[Linearization, GroundPrior | None]:
        n = len(self.obs)
        parts = []
        if self.rigorous is not None:
            lin, _ = self._rigorous_at_block_ground().linearize()
            parts.append((slice(0, self.n_rigorous_obs), lin.r, lin.values, lin.jg))
        for img, s in zip(self.images, self.image_slices):
            what = "a tie point or control point observed"
            parts.append((s, *img.linearize(self.ground[self.obs.point[s]], self.obs.col[s], self.obs.row[s], what)))
        self._columns()  # the rigorous columns may have moved across a knot
        r, jg = np.empty((n, 2)), np.empty((n, 2, 3))
        values = np.zeros((n, 2, self.columns.shape[1]))
        for s, rs, vs, js in parts:
            r[s], jg[s], values[s, :, :vs.shape[2]] = rs, js, vs
        return Linearization(r, self.weights(), self.columns, values, jg,
                             self.ground_point[self.obs.point]), self.ground_prior()

    def stated_sigma(self, group: str) -> tuple[float | None, str]:
        """:meth:`Problem.stated_sigma`; of the RPC images' priors, the median of their scenes' own
        rpc_sigma (settings.scene_sigmas) or the global one."""
        if group == RPC_PRIOR_GROUP and self.settings.rpc_sigma is not None:
            return float(np.median([self.settings.sigma("rpc_sigma", name) for name in self.scene.images])), "px"
        return super().stated_sigma(group)

    def pseudo(self) -> list[Pseudo]:
        """The rigorous scenes' pseudo-observations (:meth:`Problem.pseudo`) and the RPC images'
        priors (each image's rpc_sigma: its scene's own in settings.scene_sigmas, or the global one)."""
        factor = self.scale.get(RPC_PRIOR_GROUP, 1.0)
        return super().pseudo() + [
            p for name, img, off in zip(self.scene.images, self.images, self.params.image_offsets)
            for p in img.prior(self.settings.sigma("rpc_sigma", name), factor, int(off))]


def _rigorous_part(scene: MixedBlock, table: GcpTable, control: np.ndarray, ids: np.ndarray, ties: TieSetUp,
                   settings: AdjustmentSettings) -> tuple[Problem, np.ndarray, RpcObservations, np.ndarray, np.ndarray]:
    """The problem of the block's rigorous composite over its own observations (control rows of
    ``table`` ``control`` in a rigorous camera, the tie observations of ``ties`` there), and how it
    maps to the block: (the problem, each of its ground points' index (k,) in the block's ground
    (control points ``ids`` first, then every tie point), its observations in its order with block
    point indices, whether each is a tie observation, its row in ``table`` or the tie table)."""
    names = np.array([c.name for c in scene.rigorous.cameras])
    mine = control[np.isin(table.camera[control], names)]
    tie_mine = ties.camera < scene.n_rigorous
    own_ties = TieSetUp(ties.table, ties.rows[tie_mine], ties.camera[tie_mine], ties.point[tie_mine], ties.ids,
                        ties.ground, {}, ties.before)
    problem = Problem(scene.rigorous, table.select(mine), settings, own_ties)
    own_ids = np.unique(table.id[mine])
    to_block = np.r_[np.searchsorted(ids, own_ids), ids.size + np.arange(ties.ids.size)].astype(np.int64)
    o = problem.obs
    obs = RpcObservations(o.camera, o.chip, to_block[o.point], o.sigma, o.col, o.row)
    rows = problem.rows.copy()
    gcp = ~problem.is_tie
    rows[gcp] = mine[problem.rows[gcp]]
    return problem, to_block, obs, problem.is_tie.copy(), rows
