"""pushbroom:matchgcps as a use case: ground control points matched between a raw image and a
reference orthoimage through the scene model (:func:`core.measure.matching.match_gcps`), checked
against the scene and written as the GCP layer the adjustment reads."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .. import measure
from ..errors import InputError
from ..log import LogLine
from ..measure.matching import MatchResult, MatchSettings, match_gcps
from ..observations import gcps
from .base import FilesInUse, RunResult, Terrain, camera_of, logged, scene_from, surface_from
from .layers import OUTPUT, check_gpkg, write_gcps

# The inputs errors name, beside core.runs.base's: the raw image and the reference orthoimage.
IMAGE, REFERENCE = "image", "reference"


@dataclass(frozen=True)
class MatchGcpsRequest:
    """GCPs of camera ``camera`` (a name or index, '' the first) of the scene file ``scene``, matched
    between its raw image ``image`` and the orthoimage ``reference`` over the terrain, with the
    matching settings ``matching`` ({:class:`core.measure.matching.MatchSettings` field: value});
    ``check_fraction`` of them made check points; written to ``output`` (.gpkg)."""
    output: str
    scene: str
    image: str
    reference: str
    terrain: Terrain = Terrain()
    camera: str = ""
    matching: dict = field(default_factory=dict)
    check_fraction: float = 0.0
    files: FilesInUse = field(default_factory=FilesInUse)


def match_settings(values: dict, **fixed) -> MatchSettings:
    """The checked :class:`core.measure.matching.MatchSettings` of ``values`` and ``fixed`` fields."""
    settings = MatchSettings(**values, **fixed)
    settings.validate()
    return settings


def run(request: MatchGcpsRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Match as ``request`` says: files {OUTPUT}, figures the table's summary
    (:func:`core.observations.gcps.summary`) with 'matched' and 'grid_points'."""
    check_gpkg(request.output, "GCP layers", request.files)
    for name, path in ((IMAGE, request.image), (REFERENCE, request.reference)):
        if not path:
            raise InputError("no raster given", parameter=name)
    scene, lines = scene_from(request.scene)
    camera = camera_of(scene, request.camera)
    surface, more = surface_from(request.terrain, scene)
    lines += more
    settings = match_settings(request.matching)
    with logged(measure.__name__, lines):
        result = match_gcps(scene, camera, request.image, request.reference, surface, settings, progress,
                            is_cancelled)
    table = gcps.check_against_scene(result.table, scene, request.scene, None, request.check_fraction)
    write_gcps(table, request.output, {"quality": result.quality, "peak_ratio": result.peak_ratio})
    figures = {**gcps.summary(table), "matched": len(result.table), "grid_points": result.grid_points}
    if progress is not None:
        progress(1.0, None)
    return RunResult({OUTPUT: request.output}, figures, lines + matching_lines(result))


def matching_lines(result: MatchResult) -> list[LogLine]:
    """What the matching found: points matched of the grid and how fast, rejections by reason, the
    onboard offset of the whole image, the correlation and the image sigmas."""
    n, c = len(result.table), result.coarse
    rejected = ", ".join(f"{v} {k}" for k, v in result.rejected.items() if v)
    return [LogLine(f"matched {n} of {result.grid_points} grid points in {result.seconds:.1f} s "
                    f"({n / max(result.seconds, 1e-9):.0f} points/s)"),
            LogLine(f"rejected: {rejected or 'none'}"),
            LogLine(f"onboard offset of the whole image (found at 1:{c['factor']}): {c['offset_px'][0]:.1f} px "
                    f"across, {c['offset_px'][1]:.1f} px along track; searched +-{c['search_m']:.0f} m"
                    f"{' (SEARCH_RANGE clipped to the image)' if c['clipped'] else ''}"),
            LogLine(f"quality (correlation) median {np.median(result.quality):.3f}; sigma_px median "
                    f"{np.median(result.table.sigma_px):.2f} px")]
