"""pushbroom:importgcps as a use case: ground control points from a CSV, a QGIS .points file or the
columns of a point layer, checked against one scene, or each row against the scene of a block it
names, and written as the GeoPackage GCP layer the adjustment reads."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .. import observations
from ..log import LogLine
from ..observations import gcps
from ..observations.blockscenes import check_against_block
from ..observations.tables import per_point_sigmas
from .base import FilesInUse, RunResult, logged, scene_from
from .layers import OUTPUT, PointHeights, check_cancelled, check_gpkg, gcp_lines, heights_of, write_gcps
from .scenes import block_from

# The inputs errors and log lines name, beside core.runs.base's and core.runs.scenes': the rows' scene
# and camera columns (as core.observations.gcps names them).
SCENE_COLUMN, CAMERA_COLUMN = "gcps.scene", "gcps.camera"


@dataclass(frozen=True)
class GcpColumns:
    """The GCPs of a point layer, one value per feature: ``ids``, image ``col``, ``row`` (px, NaN:
    none), ground ``x``, ``y`` in the request's CRS, ``z`` (None: no heights), the ``role``,
    ``camera`` and ``scene`` texts (None: no such field), ``sigmas`` {'sigma_px' | 'sigma_xy' |
    'sigma_z': (the field's texts, the field's name)} of per-point sigmas; ``source`` names the
    layer in messages."""
    ids: list
    col: np.ndarray
    row: np.ndarray
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray | None = None
    role: list | None = None
    camera: list | None = None
    scene: list | None = None
    sigmas: dict = field(default_factory=dict)
    source: str = "GCP layer"


@dataclass(frozen=True)
class ImportGcpsRequest:
    """GCPs from ``file`` (a CSV read with ``mapping``, or a .points file) or ``columns`` (a layer's),
    ground coordinates in ``crs`` (a text pyproj reads; a .points file's own CRS line wins; None:
    unknown, called ``crs_name`` in messages), heights as ``heights`` says, a-priori sigmas
    ``sigmas`` {'sigma_px', 'sigma_xy', 'sigma_z'} where a point has none. Checked against the scene
    file ``scene``, or, with ``scenes``, each row against the block's scene it names; ``camera``: one
    camera name or index for every row (None: the rows' own, or the scene's only camera);
    ``check_fraction``: the share of control points made check points. Written to ``output`` (.gpkg)."""
    output: str
    scene: str = ""
    scenes: tuple[str, ...] = ()
    file: str = ""
    mapping: gcps.CsvMapping | None = None
    columns: GcpColumns | None = None
    crs: str | None = None
    crs_name: str = ""
    heights: PointHeights = PointHeights()
    sigmas: dict = field(default_factory=dict)
    camera: str | None = None
    check_fraction: float = 0.0
    files: FilesInUse = field(default_factory=FilesInUse)


def run(request: ImportGcpsRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Import as ``request`` says: files {OUTPUT}, figures the table's summary
    (:func:`core.observations.gcps.summary`)."""
    report = progress or (lambda fraction, message=None: None)
    check_gpkg(request.output, "GCP layers", request.files)
    if request.scenes:
        block, lines = block_from(request.scenes)
        with logged(observations.__name__, lines):  # gcps, tables (cameras)
            table = _read(request, list(block.files))
            check_cancelled(is_cancelled)
            report(0.5, f"checking {len(table)} rows against the scene each names")
            table = check_against_block(table, block.scenes, block.files, request.camera, request.check_fraction)
    else:
        scene, lines = scene_from(request.scene)
        with logged(observations.__name__, lines):
            table = _read(request)
            lines += _several_scenes(table)
            check_cancelled(is_cancelled)
            report(0.5, f"checking {len(table)} points against {request.scene}")
            table = gcps.check_against_scene(table, scene, request.scene, request.camera, request.check_fraction)
    write_gcps(table, request.output)
    lines += gcp_lines(table)
    report(1.0)
    return RunResult({OUTPUT: request.output}, gcps.summary(table), lines)


def _several_scenes(table: gcps.GcpTable) -> list[LogLine]:
    """A warning when the rows of a single scene's table name several scenes (the members of a strip,
    or the products of a block): all are checked against the one scene."""
    named = sorted(set(table.scene) - {""})
    if len(named) < 2:
        return []
    return [LogLine(f"the rows name {len(named)} scenes ({', '.join(named)}): all are checked against SCENE, as the "
                    "members of one strip; the products of a block are checked each against its own scene with "
                    "SCENES", True, SCENE_COLUMN)]


def _read(request: ImportGcpsRequest, block: list[str] | None = None) -> gcps.GcpTable:
    """The request's table; ``block``: the names of the block's scenes, which every row's scene must
    be one of (checked before anything else about the rows)."""
    heights = heights_of(request.heights, request.crs, request.crs_name)
    sigmas = dict(request.sigmas)
    columns = request.columns
    if columns is None and request.file.lower().endswith(".points"):
        return gcps.read_points_file(request.file, heights, request.crs, **sigmas)
    if columns is None:
        return gcps.read_csv(request.file, request.mapping or gcps.CsvMapping(), request.crs, heights, block, **sigmas)
    ids = [str(i) for i in columns.ids]
    for key, (texts, name) in columns.sigmas.items():
        sigmas[key] = per_point_sigmas(texts, sigmas[key], name, ids, columns.source, key)
    return gcps.build_table(ids, columns.col, columns.row, columns.x, columns.y, crs=request.crs, heights=heights,
                            z=columns.z, role=columns.role, camera=columns.camera, scene=columns.scene, block=block,
                            source=columns.source, **sigmas)
