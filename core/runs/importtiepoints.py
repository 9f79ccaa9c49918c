"""pushbroom:importtiepoints as a use case: tie points (image observations of unknown ground points)
from a CSV or the columns of a layer, checked against a scene, intersected with its onboard model
and written as the GeoPackage tie-point layer."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from ..observations import tiepoints
from ..observations.tables import per_point_sigmas
from .base import FilesInUse, RunResult, logged, scene_from
from .layers import OUTPUT, check_cancelled, check_gpkg, write_ties


@dataclass(frozen=True)
class TieColumns:
    """The observations of a layer, one value per feature: point ``ids``, ``camera`` texts (None: no
    such field), image ``col``, ``row`` (px, NaN: none), ``scene`` texts (None: no such field),
    ``sigmas``: (the per-point sigma_px texts, the field's name), or None; ``source`` names the layer."""
    ids: list
    camera: list | None
    col: object
    row: object
    scene: list | None = None
    sigmas: tuple | None = None
    source: str = "tie-point layer"


@dataclass(frozen=True)
class ImportTiesRequest:
    """Tie points from ``file`` (a CSV read with ``mapping``) or ``columns`` (a layer's), ``sigma_px``
    where an observation has none, checked and intersected against the scene file ``scene``, written
    to ``output`` (.gpkg); ``files``: the files around the run."""
    output: str
    scene: str
    file: str = ""
    mapping: tiepoints.CsvMapping | None = None
    columns: TieColumns | None = None
    sigma_px: float = tiepoints.DEFAULT_SIGMA_PX
    files: FilesInUse = field(default_factory=FilesInUse)


def run(request: ImportTiesRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Import as ``request`` says: files {OUTPUT}, figures the table's summary
    (:func:`core.observations.tiepoints.summary`)."""
    report = progress or (lambda fraction, message=None: None)
    check_gpkg(request.output, "tie-point layers", request.files)
    scene, lines = scene_from(request.scene)
    report(0.1)
    with logged(tiepoints.__name__, lines):
        table = _read(request)
        check_cancelled(is_cancelled)
        report(0.3, f"checking and intersecting {len(table)} observations against {request.scene}")
        table = tiepoints.check_against_scene(table, scene, request.scene)
    report(0.8)
    lines += write_ties(table, request.output)
    report(1.0)
    return RunResult({OUTPUT: request.output}, tiepoints.summary(table), lines)


def _read(request: ImportTiesRequest) -> tiepoints.TieTable:
    """The request's table, read from its file or built from its columns (both checked by the core)."""
    columns = request.columns
    if columns is None:
        return tiepoints.read_csv(request.file, request.mapping, request.sigma_px)
    sigma = request.sigma_px
    if columns.sigmas is not None:
        sigma = per_point_sigmas(columns.sigmas[0], sigma, columns.sigmas[1], columns.ids, columns.source, "sigma_px")
    return tiepoints.build_table(columns.ids, columns.camera, columns.col, columns.row, scene=columns.scene,
                                 sigma_px=sigma, source=columns.source)
