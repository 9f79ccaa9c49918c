"""pushbroom:sensorcorrect as a use case: a raw multi-CCD image resampled onto one straight,
distortion-free virtual detector line (:func:`core.products.sensorcorrect.sensor_correct`), with its
scene model and an RPC exact to hundredths of a pixel."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from ..errors import InputError
from ..files import Output
from ..log import LogLine
from ..products import rpcfit
from ..products.sensorcorrect import output_files, sensor_correct
from .base import DEM, SCENE, FilesInUse, RunResult, Terrain, camera_of, logged, scene_from, surface_from

# The outputs (files of the result) and the inputs errors name, beside core.runs.base's.
OUTPUT, OUTPUT_SCENE, RPC, REPORT, IMAGE_WITH_RPC = "OUTPUT", "OUTPUT_SCENE", "RPC", "REPORT", "IMAGE_WITH_RPC"
IMAGE = "image"


@dataclass(frozen=True)
class SensorCorrectRequest:
    """The raw image ``image`` of camera ``camera`` (a name or index, '' the first) of the scene file
    ``scene`` resampled with ``resampling`` over ``terrain`` into the GeoTIFF ``output`` (its RPC, the
    RPC's report and a VRT beside it, :func:`core.products.sensorcorrect.output_files`) and the virtual
    scene JSON ``scene_output``. ``files``: the files around the run, which the outputs may not replace."""
    scene: str
    image: str
    output: str
    scene_output: str
    terrain: Terrain = Terrain()
    camera: str = ""
    resampling: str = "bilinear"
    files: FilesInUse = field(default_factory=FilesInUse)


def run(request: SensorCorrectRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Files {OUTPUT, OUTPUT_SCENE, RPC, REPORT, IMAGE_WITH_RPC}; figures those of
    :func:`core.products.sensorcorrect.sensor_correct`; all files or none."""
    output, scene_out = Path(request.output), Path(request.scene_output)
    if output.suffix.lower() not in (".tif", ".tiff"):
        raise InputError(f"the sensor-corrected image is written as GeoTIFF; use a .tif file (got {output})",
                         parameter=OUTPUT)
    derived = output_files(output)
    beside = [Output(derived["rpc"], "its RPC"), Output(derived["report"], "its RPC report"),
              Output(derived["vrt"], "its VRT with the RPC")]
    request.files.check({OUTPUT: [output, *beside], OUTPUT_SCENE: [scene_out]})
    if not request.image:
        raise InputError("no raw image given", parameter=IMAGE)
    scene, lines = scene_from(request.scene)
    if scene.rpc_images():  # an RPC scene (or a block holding one): no physical camera
        raise InputError(f"{request.scene} is an RPC scene: it has no physical camera whose chips could be resampled "
                         "onto a straight line, and its image already has one smooth RPC. Sensor correction needs a "
                         "rigorous model (scene JSON of a rigorous scene, DIMAP or Maxar metadata)", parameter=SCENE)
    camera = camera_of(scene, request.camera)
    surface, more = surface_from(request.terrain)
    lines += more
    with logged(rpcfit.__name__, lines):
        figures = sensor_correct(scene, camera, request.image, surface, output, scene_out, request.resampling,
                                 info={"source_scene": str(request.scene), "source_image": request.image},
                                 progress=progress, is_cancelled=is_cancelled)
    lines.append(LogLine(f"sensor-corrected image {figures['cols']} x {figures['rows']} px written in "
                         f"{figures['seconds']:.1f} s; {figures['mapping']}"))
    if figures.get("holes"):
        lines.append(LogLine(figures["holes"], True, DEM))
    low, high = figures["height_range"]
    lines.append(LogLine(f"RPC fitted to the virtual camera over heights {low:.0f} to {high:.0f} m: independent "
                         f"check RMS {figures['rpc_check_rms_px']:.4f} px, max {figures['rpc_check_max_px']:.4f} px"))
    return RunResult({OUTPUT: str(output), OUTPUT_SCENE: str(scene_out), RPC: figures["rpc"],
                      REPORT: figures["report"], IMAGE_WITH_RPC: figures["vrt"]}, figures, lines)
