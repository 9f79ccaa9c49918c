"""The members of a simulated block (:mod:`simulation.block`): what a user describes
(:class:`BlockMember`), its checks, where each member's platform must fly and look to see the
block's ground centre, and the names of its files.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from datetime import datetime, timedelta

import numpy as np

from ..core.errors import InputError
from .geometry import EPOCH, Pointing, SimulatedScenes, aim_pass_point, circular_orbit
from .presets import PRESETS, ErrorSettings, Preset, resolve_errors
from .texture import plane_to_lonlat, texture_plane

MAX_VIEW_DEG = 45.0            # platform pitch / roll: agile satellites point up to about 45 deg
MAX_ORBIT_OFFSET_KM = 1000.0
MAX_ALONG_TRACK_KM = 2000.0    # a strip of products along one pass: a few hundred km in practice
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,39}")  # safe as a folder name on every system
EPOCH_FORMAT = "%Y-%m-%dT%H:%M:%S.%fZ"


@dataclass
class BlockMember:
    """One scene of a block.

    name: the member's folder and scene name (letters, digits, '_' and '-', up to 40; unique
    regardless of case). preset: a name of :data:`simulation.presets.PRESETS` or a :class:`Preset`
    (e.g. a :func:`simulation.presets.cut_preset` for tests); its centre is replaced by the block's
    (the first member's). view: (pitch, roll) degrees of the whole platform
    (:class:`simulation.geometry.Pointing`: pitch > 0 forward, roll > 0 to the left of the track),
    at most 45 each; the member's orbit and imaging time are chosen so that its reference camera's
    image centre still sees the block centre. orbit_offset_km: the acquisition moved across track
    (km, > 0 to the right of the track): its strip and the ground it sees move with it (side-lap).
    along_track_km: the ground it sees moved along the track (km, > 0 forward): the products of one
    strip, imaged one after the other (forward overlap). date: a label; members of one date share a
    radiometry, each later date (in order of first appearance) draws its own; None is the first
    member's date. A date written YYYY-MM-DD also dates the member's epoch. errors: the preset's
    :class:`ErrorSettings` (None), another, or a dict overriding some fields. rpc: deliver the
    member as an RPC product (:mod:`simulation.block`).
    """
    name: str
    preset: "str | Preset"
    view: tuple[float, float] = (0.0, 0.0)
    orbit_offset_km: float = 0.0
    date: str | None = None
    errors: ErrorSettings | dict | None = None
    rpc: bool = False
    along_track_km: float = 0.0


@dataclass
class ResolvedMember:
    """A checked member: its preset (``spec``, centred on the block), error settings, view
    (degrees), and once built its pointing, epoch, scene models (``geo``) and rendering figures."""
    index: int
    name: str
    spec: Preset
    errors: ErrorSettings
    view: tuple[float, float]
    orbit_offset_km: float
    date: str | None
    rpc: bool
    along_track_km: float = 0.0
    pointing: Pointing = field(default_factory=Pointing)
    epoch: str = EPOCH
    geo: SimulatedScenes | None = None
    interpolation_error_px: dict = field(default_factory=dict)

    @property
    def date_key(self) -> str | None:
        """The key of the member's radiometry: its date label."""
        return self.date


def _number(value, where: str, limit: float, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and abs(v) <= limit):
        raise InputError(f"{where}: {what} must be a number between -{limit:g} and {limit:g} (got {value!r})",
                         parameter=where)
    return v


def check_members(members) -> list[ResolvedMember]:
    """The checked members of a block; InputError naming the field at fault (members[i].field)."""
    if not isinstance(members, (list, tuple)):
        raise InputError(f"members must be a list of BlockMember (got {type(members).__name__})", parameter="members")
    if not members:
        raise InputError("members: a block needs at least one member (got an empty list)", parameter="members")
    out: list[ResolvedMember] = []
    names: dict[str, int] = {}
    for i, m in enumerate(members):
        where = f"members[{i}]"
        if not isinstance(m, BlockMember):
            raise InputError(f"{where} must be a BlockMember (got {type(m).__name__})", parameter=where)
        if not isinstance(m.name, str) or not NAME.fullmatch(m.name):
            raise InputError(f"{where}.name {m.name!r} is not safe as a folder name: use 1 to 40 letters, digits, "
                             "'_' or '-', starting with a letter or digit", parameter=f"{where}.name")
        if m.name.casefold() in names:
            raise InputError(f"{where}.name {m.name!r} is already the name of members[{names[m.name.casefold()]}] "
                             "(names are folder names: unique regardless of case)", parameter=f"{where}.name")
        names[m.name.casefold()] = i
        if not isinstance(m.preset, Preset) and m.preset not in PRESETS:
            raise InputError(f"{where}.preset: unknown preset {m.preset!r} (choose one of {', '.join(PRESETS)} or "
                             "give a Preset)", parameter=f"{where}.preset")
        spec = m.preset if isinstance(m.preset, Preset) else PRESETS[m.preset]
        try:
            pitch, roll = m.view
        except (TypeError, ValueError):
            raise InputError(f"{where}.view must be (pitch, roll) in degrees (got {m.view!r})",
                             parameter=f"{where}.view") from None
        view = (_number(pitch, f"{where}.view", MAX_VIEW_DEG, "the pitch"),
                _number(roll, f"{where}.view", MAX_VIEW_DEG, "the roll"))
        offset = _number(m.orbit_offset_km, f"{where}.orbit_offset_km", MAX_ORBIT_OFFSET_KM, "the offset (km)")
        along = _number(m.along_track_km, f"{where}.along_track_km", MAX_ALONG_TRACK_KM, "the offset (km)")
        date = _check_date(m.date, f"{where}.date")
        try:
            errors = resolve_errors(spec, m.errors)
        except InputError as exc:
            raise InputError(f"{where}.errors: {exc}", parameter=f"{where}.errors") from None
        if not isinstance(m.rpc, (bool, np.bool_)):
            raise InputError(f"{where}.rpc must be True or False (got {m.rpc!r})", parameter=f"{where}.rpc")
        centre = out[0].spec.centre if out else spec.centre
        out.append(ResolvedMember(i, m.name, replace(spec, centre=centre), errors, view, offset,
                                  date if date is not None or not out else out[0].date, bool(m.rpc), along))
    return out


def _check_date(date, where: str) -> str | None:
    if date is None:
        return None
    if not isinstance(date, str) or not 0 < len(date) <= 40 or not date.isprintable():
        raise InputError(f"{where} must be a label of 1 to 40 printable characters or None (got {date!r})",
                         parameter=where)
    if re.fullmatch(r"\d{4}-\d{2}-\d{2}", date):
        try:
            datetime.strptime(date, "%Y-%m-%d")
        except ValueError:
            raise InputError(f"{where} {date!r} is not a calendar date", parameter=where) from None
    return date


def member_epoch(date: str | None, seconds: float) -> str:
    """UTC epoch of a member: the simulator's EPOCH, on ``date`` when it is YYYY-MM-DD, plus
    ``seconds``."""
    base = datetime.strptime(EPOCH, EPOCH_FORMAT)
    if date and re.fullmatch(r"\d{4}-\d{2}-\d{2}", date):
        day = datetime.strptime(date, "%Y-%m-%d")
        base = base.replace(year=day.year, month=day.month, day=day.day)
    return (base + timedelta(seconds=round(seconds, 6))).strftime(EPOCH_FORMAT)


def _track(spec: Preset, lon: float, lat: float) -> tuple[np.ndarray, float]:
    """(unit vector (east, north) of the ground track where the member's orbit passes over (lon,
    lat) degrees, ground speed m/s there)."""
    p, v = circular_orbit(spec.altitude, spec.inclination, lon, lat, np.array([0.0]))
    lo, la = math.radians(lon), math.radians(lat)
    east = np.array([-math.sin(lo), math.cos(lo), 0.0])
    north = np.array([-math.sin(la) * math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la)])
    direction = np.array([v[0] @ east, v[0] @ north])
    r = float(np.linalg.norm(p[0]))
    return direction / np.linalg.norm(direction), float(np.linalg.norm(v[0]) * (r - spec.altitude) / r)


def aim_member(m: ResolvedMember, target: tuple[float, float, float]) -> None:
    """Set ``m.pointing`` and ``m.epoch``: the orbit passes where its pitched and rolled view sees
    ``target`` (lon, lat degrees, ellipsoidal height m) moved across track by the member's orbit
    offset and along it by its along-track offset, at t = 0. The epoch is EPOCH (on the member's
    date) shifted by the time the platform takes from passing abeam of the target (before its
    along-track offset) to its pass point, so that the members of one pass are dated in the order
    they image (forward-looking first, and a strip's products one after the other)."""
    lon, lat, h = target
    centre = (lon, lat)
    along, speed = _track(m.spec, lon, lat)
    right = np.array([along[1], -along[0]])  # the track turned clockwise: to its right
    across = right * m.orbit_offset_km * 1e3
    x, y = across + along * m.along_track_km * 1e3
    aim_lon, aim_lat = (float(v) for v in plane_to_lonlat(x, y, centre))
    pitch, roll = (math.radians(v) for v in m.view)
    try:
        pass_point = aim_pass_point(m.spec, pitch, roll, (aim_lon, aim_lat, h))
    except InputError as exc:
        raise InputError(f"members[{m.index}].view: {exc}", parameter=f"members[{m.index}].view") from None
    m.pointing = Pointing(pitch, roll, pass_point)
    px, py = texture_plane(*pass_point, centre)
    m.epoch = member_epoch(m.date, float((np.array([px, py]) - across) @ along) / speed)


def member_files(m: ResolvedMember, render: bool) -> dict:
    """Paths (relative to the block folder) of a member's files: true_scene, onboard_scene,
    images ({camera: path}; only rendered) and rpc ({camera: path}; RPC members). An RPC member's
    images are named after it so that GDAL pairs each with its RPC file."""
    cams = [c.name for c in m.spec.cameras]
    if m.rpc:
        stems = {c: m.name if len(cams) == 1 else f"{m.name}_{c}" for c in cams}
        images = {c: f"{m.name}/{s}.tif" for c, s in stems.items()}
        rpc = {c: f"{m.name}/{s}_RPC.TXT" for c, s in stems.items()}
    else:
        images, rpc = {c: f"{m.name}/image_{c}.tif" for c in cams}, {}
    return {"true_scene": f"{m.name}/true_scene.json", "onboard_scene": f"{m.name}/onboard_scene.json",
            "images": images if render else {}, "rpc": rpc}

