"""pushbroom:snaplines as a use case: image lines digitised on a raw image refined to a road's
centre or an edge with sub-pixel profiles across them (:mod:`core.measure.snapping`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..log import LogLine
from ..measure.snapping import SnapSettings, kept_reasons, snap_lines
from ..observations import lines as core_lines
from .base import FilesInUse, RunResult, concerning
from .layers import OUTPUT, check_gpkg

# The inputs errors name: the raw image, the image lines' layer, the snapping settings.
IMAGE, IMAGE_LINES, SETTINGS = "image", "image_lines", "snap settings"


@dataclass(frozen=True)
class SnapRequest:
    """The image lines of layer ``lines`` ((file, layer name or None for the first)) snapped on raw
    image ``image`` (band 1) as ``settings`` say, written to ``output`` (.gpkg)."""
    output: str
    image: str
    lines: tuple
    settings: SnapSettings = SnapSettings()
    files: FilesInUse = field(default_factory=FilesInUse)


def run(request: SnapRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Snap as ``request`` says: files {OUTPUT}, figures {'refined': vertices refined, 'vertices'}; a
    warning line per reason vertices kept their position."""
    check_gpkg(request.output, "snapped lines", request.files)
    settings = request.settings
    with concerning(SETTINGS):
        settings.validate()
    with concerning(IMAGE_LINES):
        lines = core_lines.read_image_lines(*request.lines)
    with concerning(IMAGE):
        result = snap_lines(request.image, lines, settings)
    refined = np.bincount(lines.vertex_part(), weights=result.refined, minlength=len(lines)).astype(int).tolist()
    with concerning(OUTPUT, OUTPUT):
        core_lines.write_gpkg(request.output, image=result.lines, extra_image={"refined": refined})
    n, moved = int(result.refined.sum()), result.moved[result.refined]
    log = [LogLine(f"{n} of {result.refined.size} vertices refined ({settings.mode}; median move "
                   f"{np.median(moved) if n else 0:.2f} px, median sigma "
                   f"{np.median(result.lines.sigma_px[result.refined]) if n else 0:.2f} px)")]
    log += [LogLine(f"{count} vertices kept their position: {reason}", True)
            for reason, count in kept_reasons(result, settings).items()]
    return RunResult({OUTPUT: request.output}, {"refined": n, "vertices": int(result.refined.size)}, log)
