"""pushbroom:importlines as a use case: control lines, ground lines of any line layer paired by id
with the image lines digitised on the raw image, checked against a scene and written as the one
GeoPackage the adjustment reads (bundle adjustment's LINES)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..adjust.linepoints import ControlLines, check_against_scene
from ..errors import InputError
from ..log import LogLine
from ..observations import lines as core_lines
from .base import FilesInUse, RunResult, concerning, scene_from
from .layers import OUTPUT, PointHeights, check_cancelled, check_gpkg, heights_of

# The inputs errors name, beside core.runs.base's: the ground lines' layer and the image lines' layer.
GROUND_LINES, IMAGE_LINES = "ground_lines", "image_lines"


@dataclass(frozen=True)
class ImportLinesRequest:
    """Ground lines of layer ``ground`` ((file, layer name or None for the first)) in CRS ``crs`` (a
    text pyproj reads, called ``crs_name`` in messages), ids in field ``id_field`` (None: the feature
    ids), heights as ``heights`` says, sigmas ``sigma_across``, ``sigma_h`` (m) where a line has none;
    image lines of layer ``image``, paired by field ``image_id_field``; checked against the scene
    file ``scene`` and written to ``output`` (.gpkg)."""
    output: str
    scene: str
    ground: tuple
    image: tuple
    crs: str | None = None
    crs_name: str = ""
    id_field: str | None = "line_id"
    image_id_field: str = "line_id"
    heights: PointHeights = PointHeights()
    sigma_across: float = core_lines.DEFAULT_SIGMA_ACROSS
    sigma_h: float = core_lines.DEFAULT_SIGMA_H
    files: FilesInUse = field(default_factory=FilesInUse)


def run(request: ImportLinesRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Import as ``request`` says: files {OUTPUT}, figures {'outside': ids of ground lines outside the
    scene, 'rms_across_m': {line id: a-priori RMS across the line (m)}}."""
    report = progress or (lambda fraction, message=None: None)
    check_gpkg(request.output, "control lines", request.files)
    scene, lines = scene_from(request.scene)
    control = _read(request)
    check_cancelled(is_cancelled)
    report(0.4)
    points, table, outside = check_against_scene(scene, control)
    ids, ground = table["line_id"].tolist(), control.ground
    row = {i: ids.index(i) for i in ground.id if i in ids}
    extra_ground = {"outside": [int(i in set(outside.tolist())) for i in ground.id],
                    **{f"apriori_{k}_m": [float(table[f"{k}_across_m"][row[i]]) if i in row else None
                                          for i in ground.id] for k in ("rms", "max")}}
    with concerning(OUTPUT, OUTPUT):
        core_lines.write_gpkg(request.output, ground, control.image, extra_ground=extra_ground,
                              extra_image={"apriori_rms_m": _per_image_line(control.image, points["across_m"])})
    lines.append(LogLine(f"{len(ground)} ground line part(s), {len(control.image)} image line(s) with "
                         f"{len(points['line_id'])} points; a-priori across-line offsets (onboard model): "
                         + ", ".join(f"{i} {r:.1f} m" for i, r in list(zip(ids, table["rms_across_m"]))[:20])))
    if outside.size:
        lines.append(LogLine(f"{outside.size} ground line(s) outside the scene (no image line pairs them; kept, "
                             f"outside = 1): {', '.join(outside[:20].tolist())}", True))
    report(1.0)
    return RunResult({OUTPUT: request.output}, {"outside": outside.tolist(), "rms_across_m": dict(
        zip(ids, np.asarray(table["rms_across_m"], float).tolist()))}, lines)


def _read(request: ImportLinesRequest) -> ControlLines:
    """The request's ground and image lines, read from their layers (errors naming which)."""
    (path, name), (image_path, image_name) = request.ground, request.image
    if Path(path).resolve() == Path(image_path).resolve() and name == image_name:
        raise InputError("the same layer as INPUT; give the image lines digitised on the raw image",
                         parameter=IMAGE_LINES)
    heights = heights_of(request.heights, request.crs, request.crs_name)
    with concerning(GROUND_LINES):
        ground = core_lines.read_ground_lines(path, name, request.id_field, heights, request.sigma_across,
                                              request.sigma_h)
    with concerning(IMAGE_LINES):
        image = core_lines.read_image_lines(image_path, image_name, request.image_id_field)
    return ControlLines(ground, image)


def _per_image_line(image: core_lines.ImageLines, across) -> list[float]:
    """RMS (m) of the a-priori across-line offsets ``across`` (n vertices,) per image line part."""
    part = image.vertex_part()
    n = np.bincount(part, minlength=len(image))
    return (np.sqrt(np.bincount(part, weights=across ** 2, minlength=len(image)) / np.maximum(n, 1))).tolist()
