"""The unknowns of a bundle adjustment and how they change a scene.

Blocks (values are corrections to the input scene, SI units):
- ``position``: coefficients (m, 3) of the position-correction basis, ECEF metres;
- ``attitude``: coefficients (m, 3) of the attitude-angle basis (roll, pitch, yaw), radians,
  applied in the body frame: rotation = measured @ rotation_from_angles(angles);
- ``installation``: per camera, (roll, pitch, yaw) rad: installation = nominal @ R(angles);
- ``chip``: per focal-plane chip ``dx, dy`` (m on the focal plane) and ``theta`` (rad), seed
  000 eq. 4; per look-angle chip ``ux0, uy0`` (offsets) and ``ux1, uy1`` (change across the
  chip), radians;
- ``camera``: per focal-plane camera the 10 terms of seed 001 eq. 7: ``f`` (its df, m),
  ``dxp, dyp`` (m), ``k1`` (1/m^2), ``k2`` (1/m^4), ``p1, p2`` (1/m), ``b1, b2, b3``.

Trajectory corrections: one per measured trajectory the cameras see (one for a scene; one per
scene of a block's composite, :mod:`core.model.block`, each on a basis over its own scene's time
span), or with one per camera (seed 003 Plan A) one per camera on its trajectory's basis. The
position and attitude blocks hold their (m_o, 3) sets one after the other, named
``<camera>.position.X.bias`` (per camera) or ``<scene>.position.X.bias`` (per block scene); an
observation's basis window starts at its correction's offset (:attr:`ParameterSet.offsets`).

Names: ``position.X.bias``, ``attitude.pitch.OI3 t=12.0s``, ``<camera>.roll``,
``<chip>.dx``, ``<camera>.k1``. Trajectory coefficients are always free (onboard GPS and
star-tracker values enter as pseudo-observations); every other parameter is fixed unless
the settings make it free or weighted (a pseudo-observation of value 0 with a sigma).
"""
from __future__ import annotations

import fnmatch
import logging
from dataclasses import dataclass, replace

import numpy as np

from ..errors import InputError
from ..model.camera import CAMERA_TERMS, CHIP_TERMS, LOOK_TERMS, UNITS, corrected_image_plane
from ..model.sensor import SceneModel
from ..model.timebasis import TimeBasis
from ..model.trajectory import Platform, TrajectoryCorrection
from ..rotations import ARCSEC, rotation_from_angles

log = logging.getLogger(__name__)

AXES = ("X", "Y", "Z")
ANGLES = ("roll", "pitch", "yaw")


@dataclass
class Parameter:
    """One unknown: name, block, current value (SI), mode ('free', 'fixed', 'weighted'),
    sigma of its pseudo-observation (weighted), unit; camera/chip indices where relevant."""
    name: str
    block: str
    value: float = 0.0
    mode: str = "fixed"
    sigma: float = 0.0
    unit: str = ""
    camera: int = -1
    chip: int = -1
    term: str = ""


SIGMA_UNITS = ("px", "arcsec")  # besides the parameter's SI unit (no suffix)
# INTERIOR=default (see :func:`default_selection`): priors of the preset, in image terms.
DEFAULT_CAMERA_PX = 3.0
DEFAULT_CHIP_PX = 2.0
DEFAULT_INSTALLATION_ARCSEC = 30.0


def parse_interior(spec: str | list | None) -> list[tuple[str, float | None, str]]:
    """Interior/installation selections: comma-separated ``pattern`` (free) or
    ``pattern=sigma`` (weighted), patterns with shell wildcards matched against parameter
    names, e.g. ``"HRC-1.*, HRC-3.*, HRC.f=1e-5"``. The sigma is in the parameter's SI unit,
    or in image terms with a unit suffix: ``px`` (the parameter's largest displacement at the
    ends of the detector array, see :func:`image_effect`) or ``arcsec`` (angles only), e.g.
    ``NAD.k1=2px, FWD.roll=30arcsec``. The word ``default`` stands for
    :func:`default_selection`. Returns (pattern, sigma or None, unit: '' (SI), 'px' or 'arcsec')."""
    if spec is None:
        return []
    items = spec if isinstance(spec, list) else [s for s in str(spec).replace(";", ",").split(",")]
    out = []
    for item in (s.strip() for s in items):
        if not item:
            continue
        pattern, _, sigma = item.partition("=")
        sigma = sigma.strip().replace(" ", "")
        if not sigma:
            out.append((pattern.strip(), None, ""))
            continue
        unit = next((u for u in SIGMA_UNITS if sigma.lower().endswith(u)), "")
        try:
            value = float(sigma[:len(sigma) - len(unit)])
        except ValueError:
            raise InputError(f"interior parameter {item!r}: the sigma after '=' must be a number, optionally "
                             f"followed by px or arcsec (e.g. 2px, 30arcsec, 1e-5)",
                             parameter="settings.interior") from None
        if not value > 0 or not np.isfinite(value):
            raise InputError(f"interior parameter {item!r}: the sigma must be positive", parameter="settings.interior")
        out.append((pattern.strip(), value, unit))
    return out


def default_selection(scene: SceneModel) -> list[tuple[str, float | None, str]]:
    """``INTERIOR=default``: every focal-plane camera's 10 terms (Zhang et al. 2015, eq. 7)
    weighted with DEFAULT_CAMERA_PX px at the array end; the installation angles of every
    camera but the first (the reference, as the nadir camera in Zhang et al. 2024) with
    DEFAULT_INSTALLATION_ARCSEC arcsec; the shifts and rotation of every chip of a
    multi-chip focal plane but its middle (reference) one, DEFAULT_CHIP_PX px (Zheng et al.
    2015). Magnitudes: seed 001's principal-point and decentring terms displace the image by
    one to a few pixels at the array end and seed 000's CCD shifts by a few pixels; seed 003's
    installation corrections are tens of arcseconds. The priors are wide enough not to bias
    such values and keep weak terms from running away with a handful of GCPs."""
    out: list[tuple[str, float | None, str]] = []
    for c, cam in enumerate(scene.cameras):
        if c > 0:
            out += [(f"{cam.name}.{a}", DEFAULT_INSTALLATION_ARCSEC, "arcsec") for a in ANGLES]
        if all(ch.kind == "focal_plane" for ch in cam.chips):
            out += [(f"{cam.name}.{t}", DEFAULT_CAMERA_PX, "px") for t in CAMERA_TERMS]
        if len(cam.chips) > 1:
            out += [(f"{ch.name or f'{cam.name}-{k + 1}'}.{t}", DEFAULT_CHIP_PX, "px")
                    for k, ch in enumerate(cam.chips) if k != len(cam.chips) // 2
                    for t in (CHIP_TERMS if ch.kind == "focal_plane" else LOOK_TERMS)]
    return out


def _px_per_normalised(cam, chip) -> float:
    """Pixels per unit of normalised image coordinate on a chip: the focal length over the
    pitch (focal plane), or one over the angle between neighbouring detectors at the chip's
    middle (look angles)."""
    if chip.kind == "focal_plane":
        return cam.focal_length / chip.pitch
    d = np.array([0.5 * chip.n_pixels, 0.5 * chip.n_pixels + 1.0])
    ux, uy = chip.look(d)
    return 1.0 / float(np.hypot(ux[1] - ux[0], uy[1] - uy[0]))


def _array_ends(cam) -> list[tuple[object, np.ndarray]]:
    """(chip, detector indices of its two ends (2,)) for every chip of a camera."""
    return [(ch, np.array([0.0, float(ch.n_pixels)])) for ch in cam.chips]


def image_effect(scene: SceneModel, p: Parameter) -> float:
    """Pixels by which a change of one SI unit of ``p`` moves the image point where it moves
    it most among the end detectors of the array (each chip's first and last detector):

    - camera terms (f m, dxp/dyp m, k1 1/m^2, k2 1/m^4, p1/p2 1/m, b1-b3 1): the length of
      their column of d(ux, uy)/d(term) (Zhang et al. 2015, eq. 7, as in the adjustment)
      times f / pitch; e.g. k1: r^3 / pitch, f: r / pitch with r the end's distance from
      the principal point on the focal plane (m);
    - chip terms: dx, dy (m on the focal plane): about 1 / pitch; theta (rad): the chip's
      length in px at its last detector (the rotation is about the first); look-angle
      ux0/uy0 and ux1/uy1 (rad): one over the detector angle (ux1 acts fully at the last
      detector);
    - installation roll/pitch/yaw (rad, camera axes): the change of the end detectors' rays
      under a rotation about that axis, in px (f / pitch for roll and pitch, the array's
      half length in px for yaw at a centred array).
    A value of 0 means the parameter does not move any end detector (e.g. b1 on an array
    through the principal point)."""
    cam = scene.cameras[p.camera]
    effects = []
    for k, (chip, d) in enumerate(_array_ends(cam)):
        if p.block == "chip" and k != p.chip:
            continue
        scale = _px_per_normalised(cam, chip)
        if chip.kind == "look_angle":
            if p.block == "chip":
                effects.append(scale)  # ux0/uy0 everywhere, ux1/uy1 (times d / n) at the last detector
                continue
            ux, uy = chip.look(d)
        else:
            u, jc, jk = corrected_image_plane(cam, chip, np.zeros(3), np.zeros(len(CAMERA_TERMS)), d, True)
            ux, uy = u[:, 0], u[:, 1]
            if p.block == "camera":
                effects += list(scale * np.hypot(*jk[:, :, CAMERA_TERMS.index(p.term)].T))
                continue
            if p.block == "chip":
                effects += list(scale * np.hypot(*jc[:, :, CHIP_TERMS.index(p.term)].T))
                continue
        if p.block == "installation":
            v = np.stack([ux, uy, np.ones_like(ux)], axis=1)
            dv = np.cross(np.eye(3)[ANGLES.index(p.term)], v)     # (2, 3) ray change per rad
            du = dv[:, :2] - v[:, :2] * dv[:, 2:3]                # projected back to w2 = 1
            effects += list(scale * np.hypot(du[:, 0], du[:, 1]))
    return float(max(effects, default=0.0))


# A term moving the array ends by less than this share of what its block's terms of the same unit
# do (b1 against b2, b3) moves them by rounding only: b1 (x b1) of an array on the line x = 0 comes
# out at ~1e-12 px per unit from sin(pi) ~ 1e-16; a px prior would make its sigma ~1e12 and the
# step it allows (~1e11) wrecks the linearisation of every other term (ZY-3 INTERIOR=default).
ROUNDING_EFFECT_SHARE = 1e-9


def moves_image(scene: SceneModel, p: Parameter) -> bool:
    """Whether ``p`` moves the end detectors of its camera at all (beyond rounding): its
    :func:`image_effect` is above ROUNDING_EFFECT_SHARE of the largest effect among the terms of
    its block (camera terms, the chip's terms, installation angles) that share its unit."""
    effect = image_effect(scene, p)
    terms = {"camera": CAMERA_TERMS, "installation": ANGLES}.get(p.block)
    if terms is None:
        terms = CHIP_TERMS if scene.cameras[p.camera].chips[p.chip].kind == "focal_plane" else LOOK_TERMS
    unit = UNITS.get(p.term, "rad")
    siblings = [replace(p, term=t) for t in terms if UNITS.get(t, "rad") == unit]
    largest = max([image_effect(scene, q) for q in siblings] + [effect])
    return effect > ROUNDING_EFFECT_SHARE * largest and effect > 0


MIN_PRIOR_PX = 1e-6  # px at the array end: a prior tighter than this holds its parameter fixed
MAX_PRIOR_PX = 1e6   # px at the array end: a prior looser than this weighs nothing (no sigma: free)


def check_prior(scene: SceneModel, p: Parameter, pattern: str, value: float, unit: str) -> None:
    """A prior sigma (``p.sigma``, SI) must weigh something finite and non-zero and let its parameter
    move the image by MIN_PRIOR_PX to MAX_PRIOR_PX at the array end: a tighter one (e.g. HRC.f=1e-300)
    holds the parameter fixed and overflowed the normal equations, a looser one (HRC.f=1e300) weighs
    nothing and overflowed 1/sigma^2. InputError naming the INTERIOR item and the plausible range (in
    px and in the item's own unit)."""
    effect = image_effect(scene, p)
    moves = p.sigma * effect
    with np.errstate(all="ignore"):
        weight = 1.0 / np.float64(p.sigma) ** 2
    small = not np.isfinite(weight) or 0 < moves < MIN_PRIOR_PX
    if not small and weight > 0 and not moves > MAX_PRIOR_PX:
        return
    per_unit = {"px": 1.0, "arcsec": effect * ARCSEC}.get(unit, effect)  # px per unit of the item's sigma
    plausible = f"{MIN_PRIOR_PX:g} to {MAX_PRIOR_PX:g} px at the array end"
    if unit != "px" and per_unit > 0:
        shown = unit or (f" {p.unit}" if p.unit else "")
        plausible += f", i.e. {pattern}={MIN_PRIOR_PX / per_unit:.3g}{shown} to {MAX_PRIOR_PX / per_unit:.3g}{shown}"
    what = f"holds {p.name} fixed" if small else f"weighs nothing: leave the sigma out to free {p.name}"
    raise InputError(f"interior parameter {pattern}={value:g}{unit}: a sigma this {'small' if small else 'large'} "
                     f"{what} ({moves:.2g} px at the array end); a plausible sigma moves the image by {plausible} "
                     "(e.g. 1px), or leave the item out to keep the scene's value", parameter="settings.interior")


def sigma_in_si(scene: SceneModel, p: Parameter, value: float, unit: str) -> float:
    """A prior sigma given in ``unit`` ('' SI, 'px' at the array end, 'arcsec') in the
    parameter's SI unit (``p.unit``): px / :func:`image_effect`, arcsec * pi / 648000."""
    if unit == "":
        return value
    if unit == "arcsec":
        if p.unit != "rad":
            raise InputError(f"interior parameter {p.name}: arcsec applies to angles only (its unit is "
                             f"{p.unit or 'none'}); give px or its SI unit", parameter="settings.interior")
        return value * ARCSEC
    effect = image_effect(scene, p)
    if not moves_image(scene, p):
        raise InputError(f"interior parameter {p.name} does not move the image at the array ends; a sigma in px "
                         "cannot be converted (leave it out or give its SI unit)", parameter="settings.interior")
    return value / effect


def trajectory_groups(scene: SceneModel) -> list[list[int]]:
    """Camera indices of each measured trajectory the scene's cameras see, in camera order: one
    for a scene, one per scene of a block's composite (:meth:`Platform.trajectory_of`)."""
    groups: dict[int, list[int]] = {}
    for c, cam in enumerate(scene.cameras):
        groups.setdefault(id(scene.platform.trajectory_of(cam.name)), []).append(c)
    return list(groups.values())


class ParameterSet:
    """All unknowns of an adjustment of one scene (or a block's composite), with the trajectory
    bases. position / attitude: one TimeBasis for every trajectory, or a list with one per
    trajectory group (:func:`trajectory_groups`); ``per_camera``: one trajectory correction per
    camera (a single-camera scene has one either way), else one per trajectory group."""

    def __init__(self, scene: SceneModel, position: TimeBasis | list[TimeBasis], attitude: TimeBasis | list[TimeBasis],
                 interior=None, per_camera: bool = False):
        self.scene = scene
        groups = trajectory_groups(scene)
        bases = [(position[g] if isinstance(position, list) else position,
                  attitude[g] if isinstance(attitude, list) else attitude) for g in range(len(groups))]
        self.per_camera = per_camera and len(scene.cameras) > 1
        owners = [([c], g) for g, cams in enumerate(groups) for c in cams] if self.per_camera else \
            [(cams, g) for g, cams in enumerate(groups)]
        owners.sort()
        # the cameras of each trajectory correction, its bases, and each camera's correction
        self.owners = [np.array(cams, dtype=np.int64) for cams, _ in owners]
        self.bases = {"position": [bases[g][0] for _, g in owners], "attitude": [bases[g][1] for _, g in owners]}
        self.position_basis, self.attitude_basis = self.bases["position"][0], self.bases["attitude"][0]
        self.owner_of = np.empty(len(scene.cameras), dtype=np.int64)
        for o, cams in enumerate(self.owners):
            self.owner_of[cams] = o
        # first row of each correction in the (sum m_o, 3) position / attitude block
        self.offsets = {b: np.cumsum([0] + [basis.size for basis in v])[:-1] for b, v in self.bases.items()}
        self.params: list[Parameter] = []
        for block, terms, unit in (("position", AXES, "m"), ("attitude", ANGLES, "rad")):
            for o, cams in enumerate(self.owners):
                prefix = f"{self.owner_name(o)}." if len(self.owners) > 1 else ""
                for label in self.bases[block][o].labels():
                    for term in terms:
                        self.params.append(Parameter(f"{prefix}{block}.{term}.{label}", block, mode="free", unit=unit,
                                                     camera=int(cams[0]) if len(self.owners) > 1 else -1, term=term))
        for c, cam in enumerate(scene.cameras):
            for term in ANGLES:
                self.params.append(Parameter(f"{cam.name}.{term}", "installation", unit="rad", camera=c, term=term))
            focal = all(ch.kind == "focal_plane" for ch in cam.chips)
            if focal:
                for term in CAMERA_TERMS:
                    self.params.append(Parameter(f"{cam.name}.{term}", "camera", unit=UNITS[term], camera=c,
                                                 term=term))
            for k, chip in enumerate(cam.chips):
                name = chip.name or f"{cam.name}-{k + 1}"
                for term in (CHIP_TERMS if chip.kind == "focal_plane" else LOOK_TERMS):
                    self.params.append(Parameter(f"{name}.{term}", "chip", unit=UNITS[term], camera=c, chip=k,
                                                 term=term))
        names = [p.name for p in self.params]
        if len(set(names)) != len(names):
            raise InputError("the scene's camera and chip names are not unique; parameters cannot be named",
                             parameter="scene")
        self._select(parse_interior(interior))
        self.index = {p.name: i for i, p in enumerate(self.params)}

    def _select(self, selections) -> None:
        selectable = [p for p in self.params if p.block not in ("position", "attitude")]
        expanded = []  # (pattern, sigma, unit, from the default set)
        for pattern, sigma, unit in selections:
            expanded += [(*d, True) for d in default_selection(self.scene)] \
                if pattern.lower() == "default" and sigma is None else [(pattern, sigma, unit, False)]
        for pattern, sigma, unit, default in expanded:
            hits = [p for p in selectable if fnmatch.fnmatchcase(p.name, pattern)]
            if not hits:
                raise InputError(f"interior parameter {pattern!r} matches none of this scene's parameters "
                                 f"(e.g. {', '.join(p.name for p in selectable[:12])}, ...)",
                                 parameter="settings.interior")
            for p in hits:
                if default and unit == "px" and not moves_image(self.scene, p):
                    p.mode, p.sigma = "fixed", 0.0  # e.g. b1 of an array through the principal point
                    log.info("%s does not move this camera's image at the array ends: left fixed", p.name)
                    continue
                p.mode, p.sigma = ("weighted", sigma_in_si(self.scene, p, sigma, unit)) if sigma else ("free", 0.0)
                if sigma:
                    check_prior(self.scene, p, pattern, sigma, unit)

    @property
    def trajectories(self) -> "ParameterSet | None":
        """The parameter set of the trajectory corrections: this one (a block with RPC images: its
        rigorous scenes', :class:`core.adjust.blockproblem.BlockParameters`)."""
        return self

    # --- the unknown vector ------------------------------------------------------------------
    @property
    def free(self) -> np.ndarray:
        """Indices (into params) of the unknowns (free and weighted), in order."""
        return np.array([i for i, p in enumerate(self.params) if p.mode != "fixed"], dtype=np.int64)

    def values(self) -> np.ndarray:
        return np.array([p.value for p in self.params])

    def set_values(self, values: np.ndarray) -> None:
        for p, v in zip(self.params, values):
            p.value = float(v)

    def fix(self, names) -> None:
        for n in names:
            self.params[self.index[n]].mode = "fixed"

    def block_values(self, block: str) -> np.ndarray:
        """(m, 3) coefficients of the position or attitude block."""
        return np.array([p.value for p in self.params if p.block == block]).reshape(-1, 3)

    def block_indices(self, block: str) -> np.ndarray:
        """(m, 3) parameter indices of the position or attitude block."""
        return np.array([i for i, p in enumerate(self.params) if p.block == block], dtype=np.int64).reshape(-1, 3)

    def owner_name(self, owner: int) -> str:
        """The name of trajectory correction ``owner``: its camera's (one per camera), else its
        scene's in a block's composite (the camera names' part before the first '/')."""
        name = self.scene.cameras[int(self.owners[owner][0])].name
        return name if self.per_camera else name.split("/")[0]

    def window(self, block: str, t: np.ndarray, camera: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(first (n,), weights (n, w)): the rows of the position or attitude block that times t
        (n,) s of observations in cameras ``camera`` (n,) use, and their basis weights, on the
        basis of each camera's trajectory correction (all of one width w)."""
        bases, offsets = self.bases[block], self.offsets[block]
        if len(bases) == 1:
            return bases[0].window(t)
        first, weights = np.empty(t.size, dtype=np.int64), np.empty((t.size, bases[0].width))
        for o, m in owner_slices(self.owner_of[camera], len(bases)):
            f, weights[m] = bases[o].window(t[m])
            first[m] = f + offsets[o]
        return first, weights

    def window_weights(self, block: str, t: np.ndarray, first: np.ndarray, rates: bool = False) -> np.ndarray:
        """(n, w) the basis weights (``rates``: their time derivatives, 1/s, as the written
        correction takes them, :meth:`core.model.timebasis.TimeBasis.derivative`) at times t (n,) s
        of the rows ``first`` (n,) .. first + w - 1 of a :meth:`window`, wherever t lies: an
        observation imaged across a knot keeps the columns of its measured time."""
        bases, offsets = self.bases[block], self.offsets[block]
        owner = np.searchsorted(offsets, first, side="right") - 1
        out = np.empty((t.size, bases[0].width))
        for o, m in owner_slices(owner, len(bases)):
            basis = bases[o]
            if not rates and basis.kind == "polynomial":
                out[m] = basis.window(t[m])[1]
                continue
            full = basis.derivative(t[m]) if rates else basis.matrix(t[m])
            out[m] = np.take_along_axis(full, (first[m] - offsets[o])[:, None] + np.arange(basis.width), axis=1)
        return out

    def owner_rows(self, block: str, owner: int) -> slice:
        """The rows of trajectory correction ``owner`` in the position or attitude block."""
        first = int(self.offsets[block][owner])
        return slice(first, first + self.bases[block][owner].size)

    def trajectory_correction(self, camera: int = 0, blocks: tuple | None = None) -> TrajectoryCorrection:
        """The correction camera ``camera`` sees, of ``blocks`` (position, attitude :meth:`block_values`; None: now)."""
        o, blocks = int(self.owner_of[camera]), blocks or (self.block_values("position"), self.block_values("attitude"))
        pos, att = (v[self.owner_rows(b, o)] for b, v in zip(("position", "attitude"), blocks))
        return TrajectoryCorrection(self.bases["position"][o], pos, self.bases["attitude"][o], att)

    def imaged_by(self, camera: int) -> np.ndarray:
        """(len(params),) bool: the parameters that change what camera ``camera`` (index) images:
        its trajectory correction's and its own installation, camera and chip terms."""
        first = int(self.owners[self.owner_of[camera]][0])
        return np.array([p.camera == camera if p.block not in ("position", "attitude") else p.camera in (-1, first)
                         for p in self.params])

    def camera_indices(self, camera: int, block: str, terms) -> np.ndarray:
        """Parameter indices (len(terms),) of a camera's installation or camera terms (-1: none)."""
        return np.array([self.index.get(f"{self.scene.cameras[camera].name}.{t}", -1) for t in terms]
                        if block in ("installation", "camera") else [], dtype=np.int64)

    def chip_indices(self, camera: int, chip: int) -> tuple[tuple[str, ...], np.ndarray]:
        """(terms, parameter indices) of one chip."""
        ch = self.scene.cameras[camera].chips[chip]
        terms = CHIP_TERMS if ch.kind == "focal_plane" else LOOK_TERMS
        name = ch.name or f"{self.scene.cameras[camera].name}-{chip + 1}"
        return terms, np.array([self.index[f"{name}.{t}"] for t in terms], dtype=np.int64)

    # --- the adjusted scene ------------------------------------------------------------------
    def adjusted_scene(self) -> SceneModel:
        """A copy of the input scene with the current corrections baked in: the trajectory
        correction on the platform (or one per camera among its camera corrections; in a block's
        composite, each scene's on its own platform), chip/camera terms and installation in the
        cameras."""
        s, blocks = self.scene, (self.block_values("position"), self.block_values("attitude"))
        platforms = []
        for cams in trajectory_groups(s):
            measured = s.platform.trajectory_of(s.cameras[cams[0]].name)
            owners = np.unique(self.owner_of[cams])
            if owners.size == 1:
                platform = Platform(measured.ephemeris, measured.attitude,
                                    self.trajectory_correction(cams[0], blocks), s.platform.cache_step)
            else:
                platform = Platform(measured.ephemeris, measured.attitude, None, s.platform.cache_step,
                                    {s.cameras[c].name: self.trajectory_correction(c, blocks) for c in cams})
            platforms += [(c, platform) for c in cams]
        platform = platforms[0][1]
        if len({id(p) for _, p in platforms}) > 1:
            platform = Platform(s.platform.ephemeris, s.platform.attitude, None, s.platform.cache_step,
                                camera_platforms={s.cameras[c].name: p for c, p in platforms})
        own: list[dict] = [{} for _ in s.cameras]  # each camera's installation and camera terms
        for p in self.params:
            if p.block in ("installation", "camera"):
                own[p.camera][p.term] = p.value
        cameras = []
        for c, cam in enumerate(s.cameras):
            v = own[c]
            chips = []
            for k, ch in enumerate(cam.chips):
                terms, idx = self.chip_indices(c, k)
                cv = dict(zip(terms, (self.params[i].value for i in idx)))
                if ch.kind == "focal_plane":
                    chips.append(replace(ch, x0=ch.x0 + cv["dx"], y0=ch.y0 + cv["dy"], theta=ch.theta + cv["theta"]))
                else:
                    chips.append(_shift_look_angles(ch, cv))
            distortion = dict(cam.distortion)
            for term in CAMERA_TERMS[1:]:
                if v.get(term, 0.0) != 0.0:
                    distortion[term] = distortion.get(term, 0.0) + v[term]
            cameras.append(replace(cam, chips=chips, focal_length=cam.focal_length + v.get("f", 0.0),
                                   distortion=distortion,
                                   installation=cam.installation @ rotation_from_angles(
                                       v["roll"], v["pitch"], v["yaw"])))
        return SceneModel(s.epoch, platform, cameras, s.aberration, s.refraction, dict(s.info))


def _shift_look_angles(chip, cv: dict):
    """A look-angle chip with ux += ux0 + ux1 * d/n and likewise uy (d: detector index)."""
    n = float(chip.n_pixels)
    if chip.ux_table is not None:
        d = np.arange(chip.ux_table.size, dtype=float)
        return replace(chip, ux_table=chip.ux_table + cv["ux0"] + cv["ux1"] * d / n,
                       uy_table=chip.uy_table + cv["uy0"] + cv["uy1"] * d / n)
    ux = np.zeros(max(chip.ux_poly.size, 2))
    uy = np.zeros(max(chip.uy_poly.size, 2))
    ux[:chip.ux_poly.size] = chip.ux_poly
    uy[:chip.uy_poly.size] = chip.uy_poly
    ux[:2] += (cv["ux0"], cv["ux1"] / n)
    uy[:2] += (cv["uy0"], cv["uy1"] / n)
    return replace(chip, ux_poly=ux, uy_poly=uy)


def owner_slices(owner: np.ndarray, n_owners: int) -> list[tuple[int, np.ndarray]]:
    """(o, indices of the elements of ``owner`` (n,) equal to o) per owner present: one sort, no mask per owner."""
    order = np.argsort(owner, kind="stable")
    bounds = np.searchsorted(owner[order], np.arange(n_owners + 1))
    return [(o, order[a:b]) for o, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])) if b > a]
