"""What the observation tables (GCPs, tie points, control lines) share: messages naming points,
checks of their columns, ground CRSs and heights, delimited text files and per-point sigmas, and the
cameras of a scene the points belong to.

Conventions as in :mod:`core.observations.gcps`: ground coordinates are WGS84 longitude/latitude
in degrees and ellipsoidal heights in metres; ``ids`` are (n,) string arrays naming the points (or
lines) in messages; ``source`` names the input (a file, a layer, a parameter) in them.
"""
from __future__ import annotations

import csv
import logging
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError

from ..dem import Dem, no_height_words, surface_name, to_ellipsoidal
from ..errors import InputError
from ..model.sensor import rows_by
from ..validation import PLAUSIBLE_HEIGHTS, implausible_heights

log = logging.getLogger(__name__)

MAX_LISTED = 10  # ids named in a message
# The code points Python's str.strip removes (none above U+3000)
WHITESPACE = np.array([c for c in range(0x3001) if chr(c).isspace()], dtype=np.uint32)
SCENE_METADATA_KEY = "PUSHBROOM_SCENE"  # layer metadata item: the scene file a layer was checked against
HEIGHT_SOURCES = ("z", "dem", "constant")
# Largest a-priori sigmas accepted: beyond them a point carries no information (and a typo is likelier).
# Ground sigmas may be 0 (ground fixed); the image sigma may not.
MAX_SIGMA = {"sigma_px": 1e4, "sigma_xy": 1e5, "sigma_z": 1e5}


# --- messages and column checks -------------------------------------------------------------
def listed(ids) -> str:
    """The first MAX_LISTED ids, comma separated, and how many more there are."""
    ids = [str(i) for i in ids]
    more = f" and {len(ids) - MAX_LISTED} more" if len(ids) > MAX_LISTED else ""
    return ", ".join(ids[:MAX_LISTED]) + more


def require_finite(ids, source: str, **columns) -> None:
    """InputError naming the points where a column {name: (n,) floats} is NaN or infinite."""
    for name, values in columns.items():
        bad = ~np.isfinite(values)
        if bad.any():
            raise InputError(f"{source}: {name} is missing or not a number for point(s) {listed(ids[bad])}")


def require_unique(ids, camera, source: str, scene=None) -> None:
    """InputError naming the point ids that occur more than once for one camera ((n,) strings each);
    with ``scene`` ((n,) strings: the product of a block each row was measured in) once per camera of
    one scene, so that one point measured by camera ``P`` of two products is two rows."""
    keys = np.char.add(np.char.add(ids, "\x1f"), camera)  # numpy strings drop NUL characters
    if scene is not None:
        keys = np.char.add(np.char.add(keys, "\x1f"), np.asarray(scene, dtype=str))
    uniq, counts = np.unique(keys, return_counts=True)
    if (counts > 1).any():
        dup = list(dict.fromkeys(k.split("\x1f")[0] for k in uniq[counts > 1]))
        where = "the same camera of the same scene" if scene is not None else "the same camera"
        raise InputError(f"{source}: point id(s) {listed(dup)} occur more than once for {where}")


def stripped(values) -> np.ndarray:
    """``values`` as a str array with each cell's leading and trailing whitespace removed (str.strip),
    the cells as they are when none has any: np.char.strip costs a Python call per cell (2,000,000 tie
    observations: 0.7 s a column), the test below a few array passes over the characters."""
    text = np.ascontiguousarray(np.asarray(values, dtype=str))
    if text.size == 0 or text.dtype.itemsize == 0:
        return text
    codes = text.reshape(-1).view(np.uint32).reshape(text.size, -1)  # numpy pads a cell with NULs
    last = codes.shape[1] - 1 - np.argmax(codes[:, ::-1] != 0, axis=1)
    ends = np.concatenate([codes[:, 0], codes[np.arange(text.size), last]])
    return np.char.strip(text) if np.isin(ends, WHITESPACE).any() else text


def scene_of_rows(names, ids, scenes, source: str = "", parameter: str | None = None) -> np.ndarray:
    """The scene name of every row ((n,) str) checked against the block's scene names ``scenes``
    (a sequence): InputError (its message starting with ``source`` when given; concerning
    ``parameter``) naming the rows' points when a name is not one of the block's, or when rows name
    none in a block of several scenes (a block of one takes its name)."""
    names, ids, scenes = stripped(names), np.asarray(ids, dtype=str), list(scenes)
    source = f"{source}: " if source else ""
    if len(scenes) == 1:
        names = np.where(names == "", scenes[0], names)
    missing = names == ""
    if missing.any():
        raise InputError(f"{source}point(s) {listed(np.unique(ids[missing]))} name no scene; in a block of "
                         f"{len(scenes)} scenes ({', '.join(scenes)}) every row names the scene it was measured in "
                         "(a field 'scene')", parameter=parameter)
    unknown = ~np.isin(names, scenes)
    if unknown.any():
        raise InputError(f"{source}scene(s) {listed(np.unique(names[unknown]))} of point(s) "
                         f"{listed(np.unique(ids[unknown]))} are not scenes of the block ({', '.join(scenes)})",
                         parameter=parameter)
    return names


def rows_of_scenes(scene_of, scenes) -> dict[str, np.ndarray]:
    """{name: the rows (ascending indices) of ``scene_of`` (n,) str naming it} for each of the block's
    scene names ``scenes`` (a sequence; rows naming none of them in none): one sort, as
    :func:`core.model.sensor.rows_by`, rather than a comparison of every row per scene (a region has
    a thousand)."""
    scenes = list(scenes)
    if not scenes:
        return {}
    names, scene_of = np.asarray(scenes, dtype=str), np.asarray(scene_of, dtype=str)
    order = np.argsort(names)
    key = order[np.searchsorted(names, scene_of, sorter=order).clip(max=len(scenes) - 1)]
    key = np.where(names[key] == scene_of, key, len(scenes))
    return dict(zip(scenes, rows_by(key, len(scenes) + 1)))


# --- ground coordinates and heights ---------------------------------------------------------
def parse_crs(crs, source: str = "GCP input") -> CRS:
    """A pyproj CRS from any user string (EPSG:xxxx, WKT, PROJ); InputError naming it if unknown."""
    if crs is None or not str(crs).strip():
        raise InputError(f"{source}: no ground CRS given; state the CRS of the ground coordinates (e.g. EPSG:4326)")
    try:
        parsed = CRS.from_user_input(str(crs).strip())
    except CRSError:
        text = str(crs).strip()
        raise InputError(f"{source}: unknown ground CRS {text[:200]!r} (expected an EPSG code, WKT or PROJ string)") \
            from None
    if parsed.is_compound:
        parsed = parsed.sub_crs_list[0]
    if not (parsed.is_geographic or parsed.is_projected):
        raise InputError(f"{source}: ground CRS {parsed.name!r} is not a horizontal (geographic or projected) CRS")
    return parsed


def to_lonlat(x, y, crs, ids, source: str) -> tuple[np.ndarray, np.ndarray]:
    """(lon, lat) WGS84 degrees of (x, y) in crs (axis order: easting/longitude first)."""
    tr = Transformer.from_crs(parse_crs(crs, source), CRS.from_epsg(4326), always_xy=True)
    lon, lat = (np.asarray(v, dtype=float) for v in tr.transform(x, y))
    bad = ~(np.isfinite(lon) & np.isfinite(lat) & (np.abs(lat) <= 90.0) & (np.abs(lon) <= 360.0))
    if bad.any():
        raise InputError(f"{source}: ground coordinates of point(s) {listed(ids[bad])} cannot be converted "
                         f"from {tr.source_crs.name!r} to WGS84 (outside the CRS's area or wrong axis order?)")
    return lon, lat


@dataclass
class Heights:
    """Where the heights of points (or line vertices) come from.

    source: 'z' (the input's Z values / Z field), 'dem' (sampled from ``dem``) or 'constant'
    (``value`` for every point). datum: 'ellipsoid' or 'geoid' (EGM96) for the Z values, the
    DEM and the constant alike. dem: a raster path, or an already loaded :class:`core.dem.Dem`.
    """
    source: str = "z"
    datum: str = "ellipsoid"
    dem: object = None
    value: float = 0.0


def ellipsoidal_heights(lon, lat, heights: Heights, z, ids, source: str) -> np.ndarray:
    """Ellipsoidal heights (m) of the points at lon, lat (deg), from the source ``heights`` names
    (z: (n,) Z values for source 'z', else unused)."""
    if heights.source == "z":
        if z is None:
            raise InputError(f"{source}: heights from Z were requested but the input has no Z values; "
                             "name a Z field, or take heights from a DEM or a constant")
        z = np.asarray(z, dtype=float)
        require_finite(ids, source, z=z)
        return to_ellipsoidal(lon, lat, z, heights.datum)
    if heights.source == "constant":
        if not np.isfinite(heights.value):
            raise InputError(f"{source}: the constant height must be a number (got {heights.value})")
        return to_ellipsoidal(lon, lat, np.full(lon.shape, float(heights.value)), heights.datum)
    if heights.source == "dem":
        if heights.dem is None:
            raise InputError(f"{source}: heights from a DEM were requested but no DEM was given")
        dem = Dem(heights.dem, heights.datum) if isinstance(heights.dem, (str, Path)) else heights.dem
        h = dem.height(lon, lat)
        bad = ~np.isfinite(h)
        if bad.any():
            raise InputError(f"{source}: {no_height(dem, lon, lat, bad)}: point(s) {listed(ids[bad])}; take their "
                             "heights from Z or a constant, or give a DEM that covers them")
        return h
    raise InputError(f"height source must be one of {', '.join(HEIGHT_SOURCES)} (got {heights.source!r})")


def point_heights(lon: np.ndarray, lat: np.ndarray, z: np.ndarray, datum: str | None, surface: Callable[[], object],
                  ids, source: str, remedy: str) -> np.ndarray:
    """Ellipsoidal heights (n,) m of points at lon, lat (n,) deg (features of a layer): their Z
    value (n,) m in ``datum`` ('ellipsoid' or 'geoid') where it is finite (NaN: no Z, or Z not
    used), else the height of the terrain ``surface()`` returns (a :class:`core.dem.Dem` or
    ``ConstantHeight``; called only when some point has no Z, so a DEM is opened only then).

    InputError naming ``source`` and (the first 5 of) the ``ids``: Z values that are no terrain
    height (the message ends with ``remedy``: how to take heights elsewhere), points the surface
    gives no height (off the DEM or on its nodata)."""
    n = lon.size
    ids = np.asarray(ids)
    use_z = np.isfinite(z)
    h = np.full(n, np.nan)
    if use_z.any():
        h[use_z] = to_ellipsoidal(lon[use_z], lat[use_z], z[use_z], datum)
        implausible = use_z & implausible_heights(h)
        if implausible.any():
            raise InputError(f"{source}: the Z values of {int(implausible.sum())} points are not terrain heights "
                             f"({PLAUSIBLE_HEIGHTS[0]:g} to {PLAUSIBLE_HEIGHTS[1]:g} m ellipsoidal; feature ids "
                             f"{', '.join(str(i) for i in ids[implausible][:5])}); {remedy}")
    if (~use_z).any():
        terrain = surface()
        h[~use_z] = terrain.height(lon[~use_z], lat[~use_z])
        off = ~use_z & ~np.isfinite(h)
        if off.any():
            first = ", ".join(str(i) for i in ids[off][:5])
            raise InputError(f"{source}: {no_height(terrain, lon, lat, off)} (feature ids {first}"
                             f"{', ...' if off.sum() > 5 else ''}); give those points Z values, or a DEM that "
                             "covers them")
    return h


def no_height(surface, lon: np.ndarray, lat: np.ndarray, missing: np.ndarray) -> str:
    """'<DEM> gives no height for <n> of <total> points (<k> off its extent, <m> on its nodata
    holes)': the ``missing`` (bool (n,)) of the points at lon, lat (n,) deg."""
    off, hole = surface.no_height(lon[missing], lat[missing])
    return f"{surface_name(surface)} {no_height_words(int(off.sum()), int(hole.sum()), lon.size, 'points')}"


# --- delimited text files and per-point columns ---------------------------------------------
def read_delimited(path: Path) -> tuple[list[str], np.ndarray]:
    """(header names, string array (n_rows, n_cols)) of a delimited text file with a header row:
    delimiter , ; TAB or | (the header's most frequent), decimal commas turned into points when
    the delimiter is not a comma, short rows padded with empty cells."""
    try:
        lines = [ln for ln in path.read_text(encoding="utf-8-sig").splitlines() if ln.strip()]
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot be read as a text file ({exc})") from None
    if len(lines) < 2:
        raise InputError(f"{path}: needs a header line and at least one point")
    delimiter = max(",;\t|", key=lines[0].count)
    header = [h.strip() for h in next(csv.reader(lines[:1], delimiter=delimiter))]
    width = len(header)
    if not any('"' in ln for ln in lines) and all(ln.count(delimiter) == width - 1 for ln in lines[1:]):
        # no quoting and every row full: the cells are the lines split, in one string (a list per row costs more)
        values = np.array(delimiter.join(lines[1:]).split(delimiter)).reshape(len(lines) - 1, width)
    else:
        body = [r + [""] * (width - len(r)) if len(r) < width else r[:width]
                for r in csv.reader(lines[1:], delimiter=delimiter)]
        values = np.array(body, dtype=str)
    if delimiter != ",":
        values = np.char.replace(values, ",", ".")
    return header, values


def present(header: list[str], name: str) -> str | None:
    """``name`` when the header (or a layer's field list) has that column, else None: the optional
    columns ``camera`` and ``role`` are read under these names when nothing else is named (the
    simulator, the plugin's own layers and most exports call them so)."""
    return name if name in header else None


def csv_column(header: list[str], cells: np.ndarray, name: str, source: str) -> np.ndarray:
    """The stripped text (n,) of column ``name`` of :func:`read_delimited`'s cells; InputError
    naming the file and listing its columns when there is none of that name."""
    if name not in header:
        raise InputError(f"{source}: no column {name!r} (columns: {', '.join(header)})")
    return stripped(cells[:, header.index(name)])


def parse_numbers(values, name: str, ids, source: str) -> np.ndarray:
    """Floats of a string column; empty cells become NaN (reported later with the ids)."""
    text = stripped(values)
    text = np.where(text == "", "nan", text)
    try:
        return text.astype(float)
    except ValueError:
        ok = np.array([is_number(t) for t in text])
        raise InputError(f"{source}: column {name!r} is not a number for point(s) {listed(np.asarray(ids)[~ok])}") \
            from None


def is_number(text: str) -> bool:
    """Whether Python reads ``text`` as a float."""
    try:
        float(text)
        return True
    except ValueError:
        return False


def nullable_floats(values, default: float = np.nan) -> np.ndarray:
    """Float array of ``values`` (field values of a layer), None (NULL) taking ``default``."""
    return np.array([default if v is None else v for v in values], dtype=float)


def per_point_sigmas(values, default: float, name: str, ids, source: str, key: str) -> np.ndarray:
    """(n,) sigmas ``key`` (sigma_px, sigma_xy or sigma_z) from a column of per-point values (text, numbers,
    or None); empty cells and None take ``default``. Every given value must be a number in
    (0, MAX_SIGMA[key]): InputError naming the
    column ``name`` and the points otherwise (an exact point is not a sigma of 0 but GROUND =
    fixed in the adjustment)."""
    ids = np.asarray(ids, dtype=str)
    raw = np.char.strip(np.array(["" if v is None else str(v) for v in values], dtype=str))
    given = raw != ""
    numeric = np.array([is_number(t) for t in np.char.replace(raw, ",", ".")], dtype=bool)
    out = np.full(raw.size, float(default))
    ok = given & numeric
    out[ok] = np.char.replace(raw[ok], ",", ".").astype(float)
    bad = given & ~(numeric & (out > 0) & (out < MAX_SIGMA[key]))
    if bad.any():
        shown = ", ".join(f"{i}: {t!r}" for i, t in zip(ids[bad][:MAX_LISTED], raw[bad][:MAX_LISTED]))
        more = f" and {int(bad.sum()) - MAX_LISTED} more" if bad.sum() > MAX_LISTED else ""
        raise InputError(f"{source}: per-point sigma field {name!r} must hold numbers > 0 and below "
                         f"{MAX_SIGMA[key]:g} (or stay empty for the default {default:g}); point(s) {shown}{more}. "
                         "A sigma of 0 is not possible in a weighted adjustment: give exact points a small sigma, "
                         "or fix all ground coordinates (GROUND)")
    return out


# --- cameras --------------------------------------------------------------------------------
def resolve_cameras(table, scene, camera: str | None = None):
    """The table (a GCP or tie-point table: ``id`` and ``camera`` (n,) strings, a dataclass)
    with every point given a camera name of ``scene``.

    camera: a name (or index) for all points, overriding the table's. Otherwise points with
    an empty camera get the scene's only camera; a camera given as an index (e.g. '1') that is
    no camera name is taken as an index. A scene of one camera takes every point when the table
    names one other camera for all of them (the simulator's 'HRC' against an RPC product's camera),
    and logs a warning saying so. InputError for unknown cameras (of a multi-camera scene, or
    among several names), or points without one in a multi-camera scene.
    """
    names = [c.name for c in scene.cameras]
    if camera not in (None, ""):
        key = int(camera) if isinstance(camera, int) or (str(camera).isdigit() and camera not in names) else camera
        return replace(table, camera=np.full(len(table), names[scene.camera_index(key)]))
    cams = table.camera
    named = set(np.unique(cams).tolist()) - {""}
    if len(names) == 1 and len(named) == 1 and not named & {names[0]} and not next(iter(named)).isdigit():
        log.warning("the camera column names camera %r for the points, but the scene has one camera, %r: all %d "
                    "point(s) are taken as measured in it", next(iter(named)), names[0], len(table))
        return replace(table, camera=np.full(len(table), names[0]))
    missing = cams == ""
    if missing.any():
        if len(names) > 1:
            raise InputError(f"point(s) {listed(table.id[missing])} have no camera and the scene has several "
                             f"({', '.join(names)}); give a camera field or choose a camera")
        cams = np.where(missing, names[0], cams)
    for value in set(np.unique(cams)) - set(names):
        try:
            cams = np.where(cams == value, names[scene.camera_index(int(value))], cams)
        except ValueError:
            raise InputError(f"camera {value!r} of point(s) {listed(table.id[cams == value])} is not in the scene "
                             f"(cameras: {', '.join(names)})") from None
    return replace(table, camera=cams)
