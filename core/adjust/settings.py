"""How to adjust: the settings of one bundle adjustment and their checks."""
from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import InputError
from ..rotations import ARCSEC
from .tieheights import TIE_HEIGHT_SIGMA_RANGE

ROBUST = ("none", "selection", "snooping")
# Plausible onboard sigmas (low, high, unit): from far better than any onboard GNSS / star tracker (0.1 mm,
# 1e-4 arcsec: the trajectory held fixed) to far worse than none (1000 km, 10 degrees); beyond them
# 1/sigma^2 heads for overflow or weighs nothing.
ONBOARD_SIGMAS = {"position_sigma": (1e-4, 1e6, "m"), "attitude_sigma": (1e-4 * ARCSEC, 3.6e4 * ARCSEC, "rad")}
RPC_SIGMA_RANGE = (1e-3, 1e5)  # px: the RPC images' stated accuracy, from a thousandth of a pixel to the whole image
# The sigmas a block scene may state for itself (AdjustmentSettings.scene_sigmas): its onboard ones
# (rigorous scenes) and its vendor's (RPC products).
SCENE_SIGMA_KEYS = ("position_sigma", "attitude_sigma", "rpc_sigma")
CAMERA_TRAJECTORY = ("shared", "per_camera")
SELECTION = ("keep", "significant")
RPC_CORRECTIONS = ("auto", "shift", "drift", "affine")  # auto: core.adjust.rpcbias.chosen_correction
# The Processing parameter each setting is given by (ui/parameters.py): what a refusal names, never the field.
PARAMETERS = {"position_sigma": "POSITION_SIGMA", "attitude_sigma": "ATTITUDE_SIGMA", "rpc_sigma": "RPC_SIGMA",
              "scene_sigmas": "SCENE_SIGMAS", "ground": "GROUND", "robust": "ROBUST", "alpha": "ALPHA",
              "camera_trajectory": "CAMERA_TRAJECTORY", "on_singular": "ON_SINGULAR",
              "rpc_correction": "RPC_CORRECTION", "interior_selection": "INTERIOR_SELECTION", "dem": "DEM",
              "dem_datum": "DEM_DATUM", "tie_height_sigma": "TIE_HEIGHT_SIGMA"}


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
    (:mod:`core.adjust.rpcbias`), or 'auto': shift for a block with fewer than 3 control points
    (its ties do not determine the height tilt the drift terms let in), drift otherwise
    (:func:`core.adjust.rpcbias.chosen_correction`). rpc_sigma (px): the vendor's stated accuracy of RPC images, a
    pseudo-observation of 0 on each correction term (its displacement at the image's far edge, see
    :meth:`core.adjust.rpcbias.RpcImage.prior`), as the onboard sigmas are of the trajectories; None:
    none. A block of RPC images tied without control needs it: it holds where the block lies.
    scene_sigmas: per block scene name (:func:`core.adjust.block.adjust_block`), its own
    position_sigma (m), attitude_sigma (rad) or rpc_sigma (px), overriding the global value for that
    scene's pseudo-observations or prior (a block mixes products of different accuracy); a key left
    out keeps the global value. Only where the global sigma is given (it decides how the datum is
    held), see :func:`core.adjust.scenesigmas.check_scene_sigmas`.
    dem, dem_datum, tie_height_sigma (m): a reference DEM (file; its heights 'geoid' EGM96 or
    'ellipsoid') that holds the tie points' heights at its stated accuracy tie_height_sigma
    (:mod:`core.adjust.tieheights`); '' and None: none.
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
    rpc_correction: str = "auto"
    rpc_sigma: float | None = None
    interior_selection: str = "significant"
    scene_sigmas: dict[str, dict[str, float]] = field(default_factory=dict)
    dem: str = ""
    dem_datum: str = "geoid"
    tie_height_sigma: float | None = None

    def sigma(self, name: str, scene: str = "") -> float | None:
        """The sigma ``name`` (one of SCENE_SIGMA_KEYS; m, rad or px) of block scene ``scene``: its
        override in scene_sigmas, else the global value ('' or a scene without one)."""
        return self.scene_sigmas.get(scene, {}).get(name, getattr(self, name))

    def validate(self) -> None:
        if self.ground not in ("weighted", "fixed"):
            raise InputError(f"GROUND must be 'weighted' or 'fixed' (got {self.ground!r})", parameter="settings.ground")
        if self.robust not in ROBUST:
            raise InputError(f"ROBUST must be one of {', '.join(ROBUST)} (got {self.robust!r})",
                             parameter="settings.robust")
        if self.camera_trajectory not in CAMERA_TRAJECTORY:
            raise InputError(f"CAMERA_TRAJECTORY must be one of {', '.join(CAMERA_TRAJECTORY)} "
                             f"(got {self.camera_trajectory!r})", parameter="settings.camera_trajectory")
        if self.on_singular not in ("fix", "stop"):
            raise InputError(f"ON_SINGULAR must be 'fix' or 'stop' (got {self.on_singular!r})",
                             parameter="settings.on_singular")
        if not 0 < self.alpha < 0.5:
            raise InputError(f"ALPHA must be between 0 and 0.5 (got {self.alpha})", parameter="settings.alpha")
        for name in SCENE_SIGMA_KEYS:
            check_sigma(name, getattr(self, name))
        if self.rpc_correction not in RPC_CORRECTIONS:
            raise InputError(f"RPC_CORRECTION must be one of {', '.join(RPC_CORRECTIONS)} "
                             f"(got {self.rpc_correction!r})",
                             parameter="settings.rpc_correction")
        self._validate_scene_sigmas()
        self._validate_reference()
        if self.interior_selection not in SELECTION:
            raise InputError(f"INTERIOR_SELECTION must be one of {', '.join(SELECTION)} "
                             f"(got {self.interior_selection!r})", parameter="settings.interior_selection")

    def _validate_reference(self) -> None:
        """DEM and TIE_HEIGHT_SIGMA go together; the sigma within TIE_HEIGHT_SIGMA_RANGE."""
        low, high = TIE_HEIGHT_SIGMA_RANGE
        if self.tie_height_sigma is not None and not self.dem:
            raise InputError("TIE_HEIGHT_SIGMA holds the tie points' heights to a reference DEM: give the DEM",
                             parameter="settings.dem")
        if self.dem and self.tie_height_sigma is None:
            raise InputError(f"a reference DEM ({self.dem}) needs its stated accuracy TIE_HEIGHT_SIGMA (m): e.g. "
                             "about 5 m for Copernicus GLO-30 or SRTM on moderate relief",
                             parameter="settings.tie_height_sigma")
        value = self.tie_height_sigma
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float)) or
                                  not low <= value <= high):
            raise InputError(f"TIE_HEIGHT_SIGMA must be between {low:g} and {high:g} m (got "
                             f"{self.tie_height_sigma!r}): the stated accuracy of the reference DEM's heights",
                             parameter="settings.tie_height_sigma")
        if self.dem_datum not in ("geoid", "ellipsoid"):
            raise InputError(f"DEM_DATUM must be 'geoid' or 'ellipsoid' (got {self.dem_datum!r})",
                             parameter="settings.dem_datum")

    def _validate_scene_sigmas(self) -> None:
        """scene_sigmas: a dict of scene name -> {key of SCENE_SIGMA_KEYS: number}, each within the
        bounds of its global sigma; InputError (parameter settings.scene_sigmas) naming the scene
        and the key."""
        if not isinstance(self.scene_sigmas, dict):
            raise InputError("SCENE_SIGMAS must map scene names to their sigmas (got "
                             f"{type(self.scene_sigmas).__name__})", parameter="settings.scene_sigmas")
        for scene, sigmas in self.scene_sigmas.items():
            if not isinstance(scene, str) or not scene.strip() or not isinstance(sigmas, dict) or not sigmas:
                raise InputError(f"SCENE_SIGMAS: scene {scene!r} needs a name and at least one of "
                                 f"{', '.join(PARAMETERS[k] for k in SCENE_SIGMA_KEYS)}",
                                 parameter="settings.scene_sigmas")
            unknown = sorted(set(sigmas) - set(SCENE_SIGMA_KEYS))
            if unknown:
                raise InputError(f"SCENE_SIGMAS: scene {scene!r} has unknown key(s) {', '.join(map(repr, unknown))} "
                                 f"(known: {', '.join(SCENE_SIGMA_KEYS)}: its own "
                                 f"{', '.join(PARAMETERS[k] for k in SCENE_SIGMA_KEYS)})",
                                 parameter="settings.scene_sigmas")
            for name, value in sigmas.items():
                check_sigma(name, value, scene)


def check_sigma(name: str, value, scene: str | None = None) -> None:
    """InputError unless the sigma ``name`` (one of SCENE_SIGMA_KEYS) is None (global only: no
    pseudo-observations) or a number within its bounds (ONBOARD_SIGMAS, RPC_SIGMA_RANGE); a
    ``scene``'s override (settings.scene_sigmas) must be a number."""
    low, high, unit = ONBOARD_SIGMAS.get(name, (*RPC_SIGMA_RANGE, "px"))
    if value is None and scene is None:
        return
    where = "" if scene is None else f"SCENE_SIGMAS: scene {scene!r}: "
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
        arcsec = f" ({low / ARCSEC:g} to {high / ARCSEC:g} arcsec)" if unit == "rad" else ""
        got = f"{value:g} {unit}" + (f", {value / ARCSEC:g} arcsec" if unit == "rad" else "") \
            if isinstance(value, (int, float)) and not isinstance(value, bool) else repr(value)
        none = "no prior on the RPC corrections" if unit == "px" else "no pseudo-observations"
        empty = f"empty ({none}) or " if scene is None else ""
        why = "it weighs nothing or holds the trajectory fixed" if unit != "px" else "it is no stated accuracy"
        raise InputError(f"{where}{PARAMETERS[name]} must be {empty}between {low:g} and {high:g} {unit}{arcsec} "
                         f"(got {got}): beyond this range {why}",
                         parameter="settings.scene_sigmas" if scene is not None else f"settings.{name}")
