"""pushbroom:preparedigitising as a use case: a display copy (VRT) of a camera's raw image in the
pixel frame, naming its scene and camera for the digitising dock, and optionally an empty
image-line layer to digitise in (:mod:`core.measure.display`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from ..files import atomic_outputs
from ..measure.display import check_image_size, write_display_vrt, write_empty_lines
from .base import FilesInUse, RunResult, camera_of, concerning, scene_from

# The outputs (files of the result) and the input errors name, beside core.runs.base's.
OUTPUT, OUTPUT_LINES, IMAGE = "OUTPUT", "OUTPUT_LINES", "image"


@dataclass(frozen=True)
class PrepareRequest:
    """The display copy ``output`` (.vrt) of raw image ``image`` of camera ``camera`` (a name or index,
    '' the first) of the scene file ``scene``; ``lines``: the empty image-line GeoPackage ('' for
    none); ``files``: the files around the run (the destinations among them)."""
    scene: str
    image: str
    output: str
    lines: str = ""
    camera: str = ""
    files: FilesInUse = field(default_factory=FilesInUse)


def run(request: PrepareRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Write as ``request`` says, both files or neither: files {OUTPUT, OUTPUT_LINES ('' for none)},
    figures {'camera': the camera's name}."""
    request.files.check({})
    scene, lines = scene_from(request.scene)
    camera = scene.cameras[camera_of(scene, request.camera)]
    with concerning(IMAGE):
        check_image_size(request.image, camera)
    with atomic_outputs() as files:
        write_display_vrt(request.image, request.output, request.scene, camera.name, files)
        if request.lines:
            write_empty_lines(request.lines, files)
    return RunResult({OUTPUT: request.output, OUTPUT_LINES: request.lines}, {"camera": camera.name}, lines)
