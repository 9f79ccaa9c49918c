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
with respect to the ground point (analytic: :meth:`core.model.rpcscene.RpcScene.ground_to_image_jacobian`).
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from ..errors import InputError
from ..model.rpcscene import RpcScene
from .normal import GroundPrior, Linearization, groups
from .parameters import Parameter, ParameterSet
from .problem import RPC_PRIOR_GROUP, Problem, Pseudo
from .settings import AdjustmentSettings

TERMS = ("a0", "a1", "a2", "b0", "b1", "b2")
# RPC_CORRECTION=auto: control points that hold the block's height tilt, and so its drift terms; with
# fewer, shift. Measured (tests/bench/bench_rpc_datum.py, docs/accuracy.md): ties alone determine the
# tilt the drift terms let in only through the second-order part of its image displacement the
# drift cannot follow, and it runs away: on simulated RPC tri-stereos tied without control the
# heights tilted by 78 to 190 m across 5 km with drift (0.0 to 0.02 m with shift), at the same tie RMS.
AUTO_CONTROL = 3
MODES = {"shift": ("a0", "b0"), "drift": ("a0", "a2", "b0", "b2"), "affine": TERMS}


@dataclass
class RpcObservations:
    """Image observations of ground points by camera index (an RPC scene's: 0), chip (an RPC
    image's: 0), point (index of the ground point), sigma (px), measured col, row (px); all (n,).
    Also the observations of a block with RPC images (:mod:`core.adjust.blockproblem`)."""
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


def chosen_correction(settings: AdjustmentSettings, n_control: int) -> tuple[AdjustmentSettings, dict | None]:
    """``settings`` with RPC_CORRECTION=auto resolved for ``n_control`` control points (shift with
    fewer than AUTO_CONTROL, drift with more), and what was chosen and why, for the report and the
    log (None when RPC_CORRECTION was given)."""
    if settings.rpc_correction != "auto":
        return settings, None
    mode = "shift" if n_control < AUTO_CONTROL else "drift"
    why = (f"the default for a block with fewer than {AUTO_CONTROL} control points: its tie points do not "
           "determine the height tilt drift terms would let in" if mode == "shift" else
           f"the default with {AUTO_CONTROL} or more control points, which hold the drift terms")
    return replace(settings, rpc_correction=mode), {"mode": mode, "default": True,
                                                    "sentence": f"RPC_CORRECTION: {mode}, {why}"}


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


class RpcImage:
    """One RPC image's correction (:class:`BiasParameters`) and how it images ground points: the
    residuals and Jacobians of its observations, for :class:`RpcProblem` and for the RPC images of
    a block (:mod:`core.adjust.blockproblem`)."""

    def __init__(self, scene: RpcScene, mode: str):
        self.params = BiasParameters(scene, mode)

    @property
    def slots(self) -> np.ndarray:
        """Indices (k,) into TERMS of the free terms (the Jacobian's columns)."""
        return self.params.free

    def residuals(self, x: np.ndarray, col: np.ndarray, row: np.ndarray) -> np.ndarray:
        """(n, 2) px: where the corrected RPC images x (n, 3) minus the measured (col, row) (n,)."""
        c, r = self.params.adjusted_scene().ground_to_image(x)
        return np.stack([c - col, r - row], axis=1)

    def linearize(self, x: np.ndarray, col: np.ndarray, row: np.ndarray,
                  what: str = "a control point") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(residuals (n, 2) px, derivatives (n, 2, k) px per unit of the free terms, derivatives
        (n, 2, 3) px/m by the ground points) of observations (col, row) (n,) of ground points x
        (n, 3) ECEF m. InputError when one lies outside the RPC's ground domain (``what``: the
        kind of point, for the message)."""
        c, r, c0, r0, jg = self.params.adjusted_scene().ground_to_image_jacobian(x)
        res = np.stack([c - col, r - row], axis=1)
        if not np.all(np.isfinite(res)):
            raise InputError(f"{what} lies outside the ground domain of the RPC of {self.params.scene.camera.name}; "
                             "is the GCP layer from another scene?", parameter="gcps")
        one, zero = np.ones_like(c0), np.zeros_like(c0)
        full = np.stack([np.stack([one, c0, r0, zero, zero, zero], axis=1),
                         np.stack([zero, zero, zero, one, c0, r0], axis=1)], axis=1)  # (n, 2, 6)
        return res, full[:, :, self.slots], jg

    def prior(self, sigma: float | None, factor: float, offset: int = 0) -> list[Pseudo]:
        """The vendor's stated accuracy as pseudo-observations of value 0 on the free terms (none
        when ``sigma`` is None): the shift terms with ``sigma`` px, the others with ``sigma`` over
        the image's columns (a1, b1) or rows (a2, b2), so that each term moves the far edge of the
        image by at most sigma; times ``factor`` (the group's variance component factor). Indices
        into the parameters start at ``offset`` (the image's first term in a block)."""
        if sigma is None or self.slots.size == 0:
            return []
        cam = self.params.scene.camera
        extent = np.array([1.0, cam.cols, cam.rows, 1.0, cam.cols, cam.rows])[self.slots]
        return [Pseudo(RPC_PRIOR_GROUP, offset + self.slots, np.eye(self.slots.size),
                       1.0 / (sigma * factor / extent) ** 2)]


class RpcProblem(Problem):
    """The engine's problem for an RPC scene (see the module docstring)."""

    def chosen_settings(self, settings: AdjustmentSettings, n_control: int) -> tuple[AdjustmentSettings, dict | None]:
        """RPC_CORRECTION=auto resolved (:func:`chosen_correction`); INTERIOR refused."""
        if settings.interior:
            raise InputError("INTERIOR: an RPC scene has no interior parameters; its correction is chosen with "
                             "RPC_CORRECTION")
        return chosen_correction(settings, n_control)

    def set_up(self, table, control, point, ids, ties, lines):
        """The RPC scene's correction terms and its control observations, in the table's order (an
        RPC scene alone takes neither tie points nor lines)."""
        self.image = RpcImage(self.scene, self.settings.rpc_correction)
        n = control.size
        obs = RpcObservations(np.zeros(n, np.int64), np.zeros(n, np.int64), point.astype(np.int64),
                              np.asarray(table.sigma_px[control], dtype=float), table.col[control],
                              table.row[control])
        return self.image.params, obs, np.zeros(n, bool), np.zeros(n, bool), control

    def structure(self) -> None:
        free = self.params.free
        self.unknown = -np.ones(len(self.params.params), dtype=np.int64)
        self.unknown[free] = np.arange(free.size)
        self.slots = free
        self.columns = np.broadcast_to(self.unknown[free], (len(self.obs), free.size)).copy()
        self.groups = groups(self.columns)

    def pseudo(self) -> list:
        return self.image.prior(self.settings.rpc_sigma, self.scale.get(RPC_PRIOR_GROUP, 1.0))

    def residuals(self) -> np.ndarray:
        return self.image.residuals(self.ground[self.obs.point], self.obs.col, self.obs.row)

    def linearize(self) -> tuple[Linearization, GroundPrior | None]:
        res, values, jg = self.image.linearize(self.ground[self.obs.point], self.obs.col, self.obs.row)
        return Linearization(res, self.weights(), self.columns, values, jg,
                             self.ground_point[self.obs.point]), self.ground_prior()
