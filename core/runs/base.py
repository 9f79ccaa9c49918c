"""What the use cases share: their result, the inputs every one reads first (the scene file, the
terrain), the check of the files they write against the files they read, and the naming of the
input an error concerns."""
from __future__ import annotations

import logging
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np
from pyproj import CRS, Transformer

from ..dem import ConstantHeight, Dem
from ..errors import Cancelled, InputError, PushbroomError
from ..files import check_outputs
from ..formats import load_scene
from ..log import LogLine
from ..validation import check_terrain_height

# The inputs the use cases' errors and log lines name (InputError.parameter, LogLine.parameter).
SCENE, CAMERA, DEM, IMAGES = "scene", "camera", "dem", "images"


@dataclass(frozen=True)
class RunResult:
    """What a use case did: ``files`` {output name: the file (or files) written}, ``figures`` (numbers
    about the result, by name) and ``lines``, the sentences for the log in order."""
    files: dict = field(default_factory=dict)
    figures: dict = field(default_factory=dict)
    lines: list[LogLine] = field(default_factory=list)


@dataclass(frozen=True)
class Terrain:
    """Where heights come from: ``dem`` (a raster file; '' for none) with its ``datum`` ('geoid' or
    'ellipsoid'), else the constant ``height`` (m, ellipsoidal); ``height_name``: how the caller
    calls the height and ``dem_name`` the DEM, for their refusals (e.g. 'HEIGHT', 'DEM')."""
    dem: str = ""
    datum: str = "geoid"
    height: float = 0.0
    height_name: str = "HEIGHT"
    dem_name: str = "DEM"


@dataclass(frozen=True)
class FilesInUse:
    """The files around a run, by the caller's parameter names: ``reads`` {input: files it reads},
    ``writes`` {output: files} of outputs the run does not plan itself. None of the run's outputs may
    replace one of them (:func:`core.files.check_outputs`)."""
    reads: Mapping[str, Sequence] = field(default_factory=dict)
    writes: Mapping[str, Sequence] = field(default_factory=dict)

    def check(self, planned: Mapping[str, Sequence]) -> None:
        """Refuse, before any work, ``planned`` outputs {name: [file, Output...]} that would replace an
        input or another output, and destinations that cannot be written."""
        others = {name: files for name, files in self.writes.items() if name not in planned}
        check_outputs(self.reads, {**planned, **others})


@contextmanager
def concerning(parameter: str, name: str = ""):
    """A core error raised inside concerns input ``parameter`` (core terms): re-raised as an
    InputError naming it, its message after ``name`` and ': ' when given (the reader's message may
    start with the input's name itself), unless it names its input itself (parameter '' for several)
    or is a cancel."""
    try:
        yield
    except PushbroomError as exc:
        if getattr(exc, "parameter", None) is not None or isinstance(exc, Cancelled):
            raise
        raise InputError(f"{name}: {exc}" if name else str(exc), parameter=parameter) from None


class _ToLines(logging.Handler):
    """A logging handler that appends each message to a list of LogLines."""

    def __init__(self, lines: list):
        super().__init__(logging.INFO)
        self.lines = lines

    def emit(self, record):
        self.lines.append(LogLine(record.getMessage(), record.levelno >= logging.WARNING))


@contextmanager
def logged(logger_name: str, lines: list):
    """The messages a core module logs inside (at INFO and above) appended to ``lines`` as LogLines,
    warnings as warnings: what it noticed about the input, for the run's log."""
    logger, handler = logging.getLogger(logger_name), _ToLines(lines)
    previous = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        yield lines
    finally:
        logger.removeHandler(handler)
        logger.setLevel(previous)


def scene_from(path: str, parameter: str = SCENE) -> tuple:
    """(scene, log lines) of a scene file (any format :func:`core.formats.load_scene` reads); errors
    and lines concern ``parameter`` (SCENE; a block's 'scenes'). The lines: the reader's warnings (what
    it assumed about the file) and the check of a vendor product against its own RPC
    (:mod:`core.formats.vendorcheck`)."""
    if not path:
        raise InputError("no scene file given", parameter=parameter)
    with concerning(parameter):
        scene = load_scene(path)
    lines = [LogLine(warning, True, parameter) for warning in scene.info.get("warnings", [])]
    if "rpc_check" in scene.info and scene.info.get("source") == str(path):
        lines.append(LogLine(scene.info["rpc_check"]["summary"], False, parameter))
    return scene, lines


def camera_of(scene, text: str | None) -> int:
    """Camera index of ``scene`` from a camera name or index ('' or None: the first); errors concern CAMERA."""
    text = (text or "").strip()
    if not text:
        return 0
    with concerning(CAMERA):
        return scene.camera_index(int(text) if text.isdigit() else text)


def surface_from(terrain: Terrain, scene=None) -> tuple:
    """(surface, log lines): :class:`core.dem.Dem` of the terrain's DEM (its heights read, so that
    implausible ones are refused before any output), or :class:`core.dem.ConstantHeight`. With an RPC
    ``scene``, heights that miss the RPC's height range are refused, heights partly outside it are a
    warning line."""
    if not terrain.dem:
        surface = ConstantHeight(check_terrain_height(terrain.height, terrain.height_name))
        what = f"{terrain.height_name} {surface.value:g} m"
    else:
        with concerning(DEM, terrain.dem_name):
            surface = Dem(terrain.dem, terrain.datum)
            surface.height_range  # reads the DEM's overview: implausible heights are refused before any output
        what = f"{terrain.dem_name} {terrain.dem}"
    warning = scene.check_surface(surface.height_range, what) if hasattr(scene, "check_surface") else None
    return surface, [LogLine(warning, True)] if warning else []


def camera_images(scene, files) -> dict[int, str]:
    """{camera index: file} of one raw image per camera of ``scene`` in its camera order; errors
    concern IMAGES, naming the cameras, when the count differs or an image is not a file ('')."""
    names = [cam.name for cam in scene.cameras]
    if len(files) != len(names):
        raise InputError(f"{len(files)} raw image(s) given, but the scene has {len(names)} camera(s) "
                         f"({', '.join(names)}): give one image per camera, in that order", parameter=IMAGES)
    missing = [names[k] for k, path in enumerate(files) if not path]
    if missing:
        raise InputError(f"the image(s) of camera(s) {', '.join(missing)} are not files (memory or service "
                         "layers); save them as GeoTIFF first", parameter=IMAGES)
    return dict(enumerate(files))


def nonfinite_text(what: str, ids, bad) -> str:
    """Sentence naming (the first 5 of) the features ``ids`` (n,) whose ``what`` are NaN, missing or
    infinite (``bad``: mask (n,))."""
    first = ", ".join(str(i) for i in np.asarray(ids)[bad][:5])
    return f"{int(np.sum(bad))} features have missing or non-finite {what} (feature ids {first}...)"


def lonlat_from(crs: CRS, x, y, crs_name: str) -> tuple[np.ndarray, np.ndarray]:
    """WGS84 (lon, lat) (n,) degrees of coordinates ``x``, ``y`` (n,) in ``crs`` (called ``crs_name`` in
    the refusal of points that cannot be converted)."""
    lon, lat = Transformer.from_crs(crs, CRS.from_epsg(4326), always_xy=True).transform(x, y)
    lon, lat = np.asarray(lon, dtype=float), np.asarray(lat, dtype=float)
    bad = ~(np.isfinite(lon) & np.isfinite(lat))
    if bad.any():
        raise InputError(f"{bad.sum()} points cannot be converted from {crs_name} to WGS84 longitude/latitude")
    return lon, lat


def z_datum_of(crs: CRS) -> str | None:
    """What Z values in ``crs`` are measured from, when the CRS says it: 'ellipsoid' for a 3D geographic
    CRS (EPSG:4979), 'geoid' for a compound CRS with EGM96 heights (EPSG:4326+5773); else None."""
    if crs.is_geographic and len(crs.axis_info) == 3:
        return "ellipsoid"
    if crs.is_compound and any("EGM96" in (sub.name or "") for sub in crs.sub_crs_list[1:]):
        return "geoid"
    return None
