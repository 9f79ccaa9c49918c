"""What pushbroom:bundleadjust reads and checks, for one scene (:mod:`core.runs.bundleadjust`) and a
block of scenes (:mod:`core.runs.blockadjust`) alike: the request, the GCP, tie-point and control-line
tables read from their files, the INTERIOR names against the scene's, and the outputs asked for that
need an input not given."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from ..adjust.linepoints import ControlLines
from ..adjust.parameters import ParameterSet
from ..adjust.settings import AdjustmentSettings
from ..dem import Dem
from ..errors import Cancelled, InputError, PushbroomError
from ..model.timebasis import TimeBasis
from ..observations import gcps, tiepoints
from ..observations.lines import read_ground_lines, read_image_lines
from .base import FilesInUse, concerning
from .scenes import SCENES  # noqa: F401 (one of the inputs the request names, with GCPS, TIES, LINES)

# The inputs errors and log lines name (InputError.parameter, LogLine.parameter), beside core.runs.base's SCENE
GCPS, TIES, LINES = "gcps", "ties", "lines"
INTERIOR, SCENE_SIGMAS, REFERENCE_DEM = "settings.interior", "settings.scene_sigmas", "settings.dem"
# The outputs, by the names of the algorithm's parameters (files of the result; the errors that concern them)
OUTPUT_SCENE, OUTPUT_REPORT, OUTPUT_REPORT_JSON, OUTPUT_GCPS, OUTPUT_RESIDUALS = \
    "OUTPUT_SCENE", "OUTPUT_REPORT", "OUTPUT_REPORT_JSON", "OUTPUT_GCPS", "OUTPUT_RESIDUALS"
OUTPUT_TIE_POINTS, OUTPUT_RPC, OUTPUT_LINE_RESIDUALS = "OUTPUT_TIE_POINTS", "OUTPUT_RPC", "OUTPUT_LINE_RESIDUALS"
OUTPUT_FOLDER, WRITE_RPCS, ADJUSTED_SCENES = "OUTPUT_FOLDER", "WRITE_RPCS", "ADJUSTED_SCENES"
# One scene's outputs and the suffix each file must have
ONE_SCENE_SUFFIXES = {OUTPUT_SCENE: ".json", OUTPUT_REPORT: ".html", OUTPUT_GCPS: ".gpkg", OUTPUT_RESIDUALS: ".gpkg",
                      OUTPUT_TIE_POINTS: ".gpkg", OUTPUT_RPC: ".txt", OUTPUT_LINE_RESIDUALS: ".gpkg"}


@dataclass(frozen=True)
class LayerFile:
    """A layer of a vector file: ``path``, ``layer`` (its name; None: the first) and ``source``, how
    the caller shows it (QGIS's 'path|layername=...'; '': the path)."""
    path: str
    layer: str | None = None
    source: str = ""

    def shown(self) -> str:
        return self.source or self.path


@dataclass(frozen=True)
class AdjustRequest:
    """One bundle adjustment: of the scene file ``scene``, or of the block ``scenes`` ({name: scene
    file}, two or more, rigorous scenes and RPC products alike).

    ``gcps``: the GeoPackage GCP layer (None: none, only with tie points or control lines); ``ties``:
    the tie-point layer (a GeoPackage, or the simulator's CSV) or, with ``tie_rows``, the tie points a
    caller read from a layer without a file (``ties.source`` names it); ``lines``: the GeoPackage of
    control lines ('' none). ``settings``: how to adjust; ``scene_sigmas``: SCENE_SIGMAS as given (texts
    row by row, :func:`core.adjust.scenesigmas.read_scene_sigmas`; a block's only).
    ``outputs``: one scene's output files by name (ONE_SCENE_SUFFIXES; '' not asked; OUTPUT_SCENE always
    given); with ``scenes`` those the user gave, which a block refuses. ``folder``: a block's output
    folder (created when missing); with one scene a folder the user gave, refused like ``write_rpcs``
    (a refined RPC of each image of a block). ``residual_scale``: the exaggeration of the residual
    vectors. ``files``: the files around the run, which no output may replace."""
    scene: str = ""
    scenes: Mapping[str, str] | None = None
    gcps: LayerFile | None = None
    ties: LayerFile | None = None
    tie_rows: tiepoints.TieTable | None = None
    lines: str = ""
    settings: AdjustmentSettings = field(default_factory=AdjustmentSettings)
    scene_sigmas: tuple[str, ...] = ()
    outputs: Mapping[str, str] = field(default_factory=dict)
    folder: str = ""
    write_rpcs: bool = False
    residual_scale: float = 1000.0
    files: FilesInUse = field(default_factory=FilesInUse)


def no_gcps() -> gcps.GcpTable:
    """An empty GCP table (tie points or control lines alone)."""
    none = np.zeros(0)
    return gcps.GcpTable(*(np.zeros(0, str),) * 3, *(none,) * 8)


def read_gcps(layer: LayerFile | None, optional: bool) -> gcps.GcpTable:
    """The GCP table of ``layer`` (a GeoPackage layer); with ``optional`` (tie points or lines
    given) an empty one without a layer. Errors concern GCPS."""
    if layer is None and optional:
        return no_gcps()
    if layer is None:
        raise InputError("no GCP layer given (it may be left out only with TIE_POINTS)", parameter=GCPS)
    if not layer.path.lower().endswith(".gpkg"):
        raise InputError(f"{layer.shown()} is not a GeoPackage; write the GCPs with 'Import ground control points' "
                         "(pushbroom:importgcps) first", parameter=GCPS)
    with concerning(GCPS):
        return gcps.read_gpkg(layer.path, layer.layer)


def read_ties(request: AdjustRequest) -> tiepoints.TieTable | None:
    """The tie points of the request (None without): ``tie_rows`` as read by the caller, else the
    layer's file, a delimited text (the simulator's tie_points.csv) or a GeoPackage layer. Errors
    concern TIES."""
    if request.tie_rows is not None or request.ties is None:
        return request.tie_rows
    path = request.ties.path
    with concerning(TIES):
        return tiepoints.read_csv(path) if Path(path).suffix.lower() in (".csv", ".txt") else \
            tiepoints.read_gpkg(path, request.ties.layer)


def read_lines(path: str) -> ControlLines | None:
    """The control lines of the GeoPackage ``path`` (None: '' given); errors concern LINES."""
    if not path:
        return None
    with concerning(LINES):
        return ControlLines(read_ground_lines(path), read_image_lines(path))


def check_reference_dem(settings: AdjustmentSettings) -> None:
    """The reference DEM of TIE_HEIGHT_SIGMA (settings.dem) opened and its heights read (implausible
    ones refused) before the solution starts; errors concern the DEM."""
    if settings.dem:
        with concerning(REFERENCE_DEM):
            Dem(settings.dem, settings.dem_datum).height_range  # reads the DEM's overview


def check_interior(scene, interior: str) -> None:
    """INTERIOR's names and sigmas against a rigorous scene's (or rigorous block's) parameters; the
    error (concerning INTERIOR) lists the scene's cameras and CCD chips, whose names the patterns
    use. A scene with RPC images is left to the core, which names INTERIOR's errors there."""
    if scene.rpc_images():
        return
    t_min, t_max = scene.time_span()
    basis = TimeBasis.covering("polynomial", t_min, t_max, 0)
    try:
        ParameterSet(scene, basis, basis, interior)
    except PushbroomError as exc:
        names = "; ".join(f"camera {c.name} with chips " + ", ".join(ch.name or f"{c.name}-{k + 1}"
                                                                   for k, ch in enumerate(c.chips))
                          for c in scene.cameras)
        raise InputError(f"{exc}. This scene has {names}.", parameter=INTERIOR) from None


def check_needed_inputs(outputs: Mapping[str, str], ties, with_gcps: bool, with_lines: bool) -> None:
    """Outputs asked for that need an input that was not given: the adjusted tie points TIES, the
    GCP layers GCPS, the line residuals LINES."""
    if outputs.get(OUTPUT_TIE_POINTS) and ties is None:
        raise InputError("the adjusted tie points need TIE_POINTS", parameter=OUTPUT_TIE_POINTS)
    for name in (OUTPUT_GCPS, OUTPUT_RESIDUALS):
        if outputs.get(name) and not with_gcps:
            raise InputError("there are no GCPs to write (no GCPS given)", parameter=name)
    if outputs.get(OUTPUT_LINE_RESIDUALS) and not with_lines:
        raise InputError("no LINES given", parameter=OUTPUT_LINE_RESIDUALS)


def check_cancel(is_cancelled: Callable[[], bool] | None) -> None:
    """Stop between steps when the user cancelled."""
    if is_cancelled is not None and is_cancelled():
        raise Cancelled("cancelled by the user")
