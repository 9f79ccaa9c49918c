"""Bias compensation of RPC scenes (Grodecki & Dial 2003): the image-space correction of a
:class:`core.rpcscene.RpcScene` as the parameter block of the bundle adjustment.

The correction (see core.rpcscene) is
    col' = col + a0 + a1 * col + a2 * row,    row' = row + b0 + b1 * col + b2 * row
with (col, row) the RPC's own image position. Modes (RPC_CORRECTION): ``shift`` (a0, b0),
``drift`` (shift + drift along the row, i.e. with time: a0, a2, b0, b2) and ``affine`` (all six).
Parameter names ``<image>.a0`` ...; units px (a0, b0) and px per px (the rest).

The engine (:mod:`core.adjust.engine`) runs unchanged: :class:`RpcProblem` offers what it uses
of a :class:`core.adjust.problem.Problem` (observations, parameter columns, linearisation; ground points eliminated,
weighted or fixed, as for a rigorous scene) with the correction instead of the trajectory and
interior blocks. Residuals are predicted - measured, in pixels, with the RPC's own Jacobian
with respect to the ground point (central differences of 0.1 m: the RPC is a cubic ratio).
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..errors import InputError
from ..model.rpcscene import RpcScene
from .normal import GroundPrior, Linearization, groups
from .parameters import Parameter, ParameterSet
from .problem import Problem
from .settings import AdjustmentSettings
from .ties import TieSetUp

TERMS = ("a0", "a1", "a2", "b0", "b1", "b2")
MODES = {"shift": ("a0", "b0"), "drift": ("a0", "a2", "b0", "b2"), "affine": TERMS}
GROUND_STEP = 0.1  # m: central differences of the RPC with respect to the ground point


@dataclass
class RpcObservations:
    """Image observations of ground points in an RPC scene: camera and chip (0: one image),
    point (index of the ground point), sigma (px), measured col, row (px); all (n,)."""
    camera: np.ndarray
    chip: np.ndarray
    point: np.ndarray
    sigma: np.ndarray
    col: np.ndarray
    row: np.ndarray

    def __len__(self) -> int:
        return int(self.col.size)

    def select(self, m) -> "RpcObservations":
        return RpcObservations(**{f.name: getattr(self, f.name)[m] for f in fields(self)})


class BiasParameters(ParameterSet):
    """The correction terms of one RPC scene (those of ``mode`` free, the others fixed at the
    scene's current values), with the ParameterSet interface the engine uses."""

    def __init__(self, scene: RpcScene, mode: str):
        if mode not in MODES:
            raise InputError(f"RPC correction must be one of {', '.join(MODES)} (got {mode!r})",
                             parameter="settings.rpc_correction")
        self.scene, self.mode = scene, mode
        self.position_basis = self.attitude_basis = None
        units = {"a0": "px", "b0": "px"}
        start = scene.correction.ravel()
        self.params = [Parameter(f"{scene.camera.name}.{t}", "rpc_correction", float(v),
                                 "free" if t in MODES[mode] else "fixed", unit=units.get(t, "px/px"), camera=0, term=t)
                       for t, v in zip(TERMS, start)]
        self.index = {p.name: i for i, p in enumerate(self.params)}

    def adjusted_scene(self) -> RpcScene:
        """A copy of the scene with the adjusted correction."""
        s = self.scene
        return RpcScene(s.rpc, s.camera, self.values().reshape(2, 3), dict(s.info))


class RpcProblem(Problem):
    """The engine's problem for an RPC scene (see the module docstring)."""

    def __init__(self, scene: RpcScene, table, settings: AdjustmentSettings):
        if settings.interior:
            raise InputError("INTERIOR: an RPC scene has no interior parameters; its correction is chosen with "
                             "RPC_CORRECTION")
        self.scene, self.settings = scene, settings
        self.params = BiasParameters(scene, settings.rpc_correction)
        control = np.nonzero(table.role == "control")[0]
        _, first, point = np.unique(table.id[control], return_index=True, return_inverse=True)
        self._set_up_ground(table, control[first])
        n = control.size
        self.obs = RpcObservations(np.zeros(n, np.int64), np.zeros(n, np.int64), point.astype(np.int64),
                                   np.asarray(table.sigma_px[control], dtype=float), table.col[control],
                                   table.row[control])
        self.rows = control
        self.is_tie = self.is_line = np.zeros(n, bool)
        self.ties = TieSetUp.empty()
        self.factor = np.ones((n, 2))
        self.scale = {}
        self.rescaled()
        self.structure()

    def structure(self) -> None:
        free = self.params.free
        self.unknown = -np.ones(len(self.params.params), dtype=np.int64)
        self.unknown[free] = np.arange(free.size)
        self.slots = free
        self.columns = np.broadcast_to(self.unknown[free], (len(self.obs), free.size)).copy()
        self.groups = groups(self.columns)

    def pseudo(self) -> list:
        return []

    def _predicted(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(corrected col, row, the RPC's own col, row) (n,) of ground points x (n, 3)."""
        scene = self.params.adjusted_scene()
        c, r = scene.ground_to_image(x)
        return c, r, *scene.uncorrect(c, r)

    def residuals(self) -> np.ndarray:
        c, r, _, _ = self._predicted(self.ground[self.obs.point])
        return np.stack([c - self.obs.col, r - self.obs.row], axis=1)

    def linearize(self) -> tuple[Linearization, GroundPrior | None]:
        x = self.ground[self.obs.point]
        c, r, c0, r0 = self._predicted(x)
        res = np.stack([c - self.obs.col, r - self.obs.row], axis=1)
        if not np.all(np.isfinite(res)):
            raise InputError("a control point lies outside the RPC's ground domain; is the GCP layer from another "
                             "scene?", parameter="gcps")
        jg = np.empty((len(self.obs), 2, 3))
        for k in range(3):
            step = np.zeros(3)
            step[k] = GROUND_STEP
            cp, rp, _, _ = self._predicted(x + step)
            cm, rm, _, _ = self._predicted(x - step)
            jg[:, 0, k], jg[:, 1, k] = (cp - cm) / (2 * GROUND_STEP), (rp - rm) / (2 * GROUND_STEP)
        one, zero = np.ones_like(c0), np.zeros_like(c0)
        full = np.stack([np.stack([one, c0, r0, zero, zero, zero], axis=1),
                         np.stack([zero, zero, zero, one, c0, r0], axis=1)], axis=1)  # (n, 2, 6)
        return Linearization(res, self.weights(), self.columns, full[:, :, self.slots], jg,
                             self.ground_point[self.obs.point]), self.ground_prior()
