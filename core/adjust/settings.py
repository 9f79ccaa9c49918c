"""How to adjust: the settings of one bundle adjustment and their checks."""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import InputError
from ..rotations import ARCSEC

ROBUST = ("none", "selection", "snooping")
# Plausible onboard sigmas (low, high, unit): from far better than any onboard GNSS / star tracker (0.1 mm,
# 1e-4 arcsec: the trajectory held fixed) to far worse than none (1000 km, 10 degrees); beyond them
# 1/sigma^2 heads for overflow or weighs nothing.
ONBOARD_SIGMAS = {"position_sigma": (1e-4, 1e6, "m"), "attitude_sigma": (1e-4 * ARCSEC, 3.6e4 * ARCSEC, "rad")}
CAMERA_TRAJECTORY = ("shared", "per_camera")
SELECTION = ("keep", "significant")


@dataclass
class AdjustmentSettings:
    """How to adjust.

    position_model / attitude_model: 'polynomial' (order 0-2), 'lagrange' (orientation
    images every *_interval s) or 'spline' (piecewise quadratics every *_interval s).
    position_sigma (m) / attitude_sigma (rad): accuracy of the onboard GPS / star trackers,
    pseudo-observations of the corrections at the knots; None: no pseudo-observations.
    camera_trajectory: 'shared' (one trajectory correction for all cameras; with installation
    angles free in ``interior`` this is seed 003's Plans B-D, by the attitude order 0/1/2) or
    'per_camera' (one correction per camera, each with its own pseudo-observations: Plan A). In a
    block of scenes (:mod:`core.adjust.block`) 'shared' is one correction per scene, each on its
    own scene's time span with its own pseudo-observations.
    interior: free/weighted interior and installation parameters (see
    :func:`core.adjust.parameters.parse_interior`). ground: 'weighted' (GCP sigmas) or 'fixed'.
    robust: 'none', 'selection' or 'snooping'; alpha: significance of the outlier test.
    on_singular: 'fix' (fix one parameter of each non-determinable set and go on) or 'stop'.
    max_iterations: Gauss-Newton iterations per solution; max_robust_iterations: passes of
    the robust / variance component loop. variance_components: estimate a factor on the stated
    sigmas per observation group and test outliers against it (see :mod:`core.adjust.robust`);
    False trusts the stated sigmas. interior_selection: 'significant' removes interior
    parameters the control cannot support and falls back to no self-calibration when it is
    not significantly better (:mod:`core.adjust.selection`); 'keep' keeps the set as given.
    rpc_correction: the image-space correction of RPC scenes, 'shift', 'drift' or 'affine'
    (:mod:`core.adjust.rpcbias`). rpc_sigma (px): the vendor's stated accuracy of RPC images, a
    pseudo-observation of 0 on each correction term (its displacement at the image's far edge, see
    :meth:`core.adjust.rpcbias.RpcImage.prior`), as the onboard sigmas are of the trajectories; None:
    none. A block of RPC images tied without control needs it: it holds where the block lies.
    """
    position_model: str = "polynomial"
    position_order: int = 1
    position_interval: float = 20.0
    attitude_model: str = "polynomial"
    attitude_order: int = 2
    attitude_interval: float = 20.0
    position_sigma: float | None = 100.0
    attitude_sigma: float | None = None
    camera_trajectory: str = "shared"
    interior: str = ""
    ground: str = "weighted"
    robust: str = "selection"
    alpha: float = 0.001
    on_singular: str = "fix"
    max_iterations: int = 30
    max_robust_iterations: int = 12
    variance_components: bool = True
    rpc_correction: str = "drift"
    rpc_sigma: float | None = None
    interior_selection: str = "significant"

    def validate(self) -> None:
        if self.ground not in ("weighted", "fixed"):
            raise InputError(f"ground must be 'weighted' or 'fixed' (got {self.ground!r})", parameter="settings.ground")
        if self.robust not in ROBUST:
            raise InputError(f"robust method must be one of {', '.join(ROBUST)} (got {self.robust!r})",
                             parameter="settings.robust")
        if self.camera_trajectory not in CAMERA_TRAJECTORY:
            raise InputError(f"camera trajectory must be one of {', '.join(CAMERA_TRAJECTORY)} "
                             f"(got {self.camera_trajectory!r})", parameter="settings.camera_trajectory")
        if self.on_singular not in ("fix", "stop"):
            raise InputError(f"on_singular must be 'fix' or 'stop' (got {self.on_singular!r})",
                             parameter="settings.on_singular")
        if not 0 < self.alpha < 0.5:
            raise InputError(f"alpha must be between 0 and 0.5 (got {self.alpha})", parameter="settings.alpha")
        for name, (low, high, unit) in ONBOARD_SIGMAS.items():
            v = getattr(self, name)
            if v is not None and not low <= v <= high:
                arcsec = f" ({low / ARCSEC:g} to {high / ARCSEC:g} arcsec)" if unit == "rad" else ""
                got = f"{v:g} {unit}" + (f", {v / ARCSEC:g} arcsec" if unit == "rad" else "")
                raise InputError(f"{name} must be empty (no pseudo-observations) or between {low:g} and {high:g} "
                                 f"{unit}{arcsec} (got {got}): beyond this range it weighs nothing or holds the "
                                 "trajectory fixed", parameter=f"settings.{name}")
        if self.rpc_correction not in ("shift", "drift", "affine"):
            raise InputError(f"RPC correction must be shift, drift or affine (got {self.rpc_correction!r})",
                             parameter="settings.rpc_correction")
        if self.rpc_sigma is not None and not 1e-3 <= self.rpc_sigma <= 1e5:
            raise InputError(f"rpc_sigma must be empty (no prior on the RPC corrections) or between 0.001 and 1e5 px "
                             f"(got {self.rpc_sigma:g})", parameter="settings.rpc_sigma")
        if self.interior_selection not in SELECTION:
            raise InputError(f"interior_selection must be one of {', '.join(SELECTION)} "
                             f"(got {self.interior_selection!r})", parameter="settings.interior_selection")

