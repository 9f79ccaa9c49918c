"""pushbroom:footprint as a use case: the ground outline of each camera's image on the terrain."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from ..errors import Cancelled
from ..log import LogLine
from ..products.footprint import footprints
from .base import DEM, FilesInUse, RunResult, Terrain, scene_from, surface_from


@dataclass(frozen=True)
class FootprintRequest:
    """The outlines of every camera of the scene file ``scene`` on ``terrain``, each image edge divided
    into ``samples`` intervals; ``files``: the files around the run (the outputs are checked first)."""
    scene: str
    terrain: Terrain = Terrain()
    samples: int = 256
    files: FilesInUse = field(default_factory=FilesInUse)


def run(request: FootprintRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Figures {'footprints': [core.products.footprint.Footprint per camera, in camera order]}; a warning
    line (about the DEM) for each outline the terrain leaves partly without heights. No files: the
    caller writes the outlines where it wants them."""
    request.files.check({})
    scene, lines = scene_from(request.scene)
    surface, more = surface_from(request.terrain, scene)
    lines += more
    outlines = []
    for k, camera in enumerate(scene.cameras):
        if is_cancelled is not None and is_cancelled():
            raise Cancelled("cancelled by the user")
        if progress is not None:
            progress(k / len(scene.cameras), f"camera {camera.name}")
        (outline,) = footprints(scene, surface, cameras=[k], samples_per_edge=request.samples)
        lines += [LogLine(outline.note, True, DEM)] if outline.note else []
        outlines.append(outline)
    return RunResult({}, {"footprints": outlines}, lines)
