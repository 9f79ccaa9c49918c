"""pushbroom:exportrpc as a use case: RPC00B rational polynomials fitted to one camera of the scene
model, written where GDAL and QGIS read them (with the fit report beside, and a VRT of the camera's
image with the RPC when an image is given), with the fit's check figures per CCD."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from ..dem import ConstantHeight
from ..errors import Cancelled, InputError
from ..files import Output, atomic_outputs
from ..formats.rpcfiles import image_vrt_with_rpc, report_path, write_rpc
from ..log import LogLine
from ..products import rpcfit
from ..products.rpcfit import dem_height_range, fit_rpc
from .base import DEM, FilesInUse, RunResult, Terrain, camera_of, concerning, logged, scene_from, surface_from

# The outputs (files of the result) and the inputs errors name, beside core.runs.base's.
OUTPUT, REPORT, IMAGE_WITH_RPC = "OUTPUT", "REPORT", "IMAGE_WITH_RPC"
IMAGE = "image"
SUB_PIXEL = 0.1  # px: an RPC worse than this at the chip seams is not the sub-pixel model users expect


@dataclass(frozen=True)
class RpcRequest:
    """The RPC of camera ``camera`` (a name or index, '' the first) of the scene file ``scene``, written
    to ``output`` (a name ending in _RPC.TXT: GDAL's RPC text; .RPB: the RPB layout). Heights: the
    terrain's DEM over the image, else its height ± ``height_span`` (m). ``grid`` image columns and rows
    at ``levels`` heights are fitted with Tikhonov weight ``regularisation``
    (:func:`core.products.rpcfit.fit_rpc`). ``image``: the camera's raw image ('' none), for a VRT of
    it with the RPC beside ``output``. ``files``: the files around the run, which the outputs may not
    replace."""
    scene: str
    output: str
    terrain: Terrain = Terrain()
    camera: str = ""
    height_span: float = 500.0
    grid: int = 31
    levels: int = 7
    regularisation: float = 1e-12
    image: str = ""
    files: FilesInUse = field(default_factory=FilesInUse)


def run(request: RpcRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Files {OUTPUT, REPORT, IMAGE_WITH_RPC (None without an image)}, figures {'report': the fit
    report as written, 'rms_px' and 'max_px' of its independent check}; the RPC file, its report and the
    VRT are written all or none."""
    report_progress = progress or (lambda fraction, message=None: None)
    out, vrt, lines = _planned(request)
    scene, more = scene_from(request.scene)
    lines += more
    camera = camera_of(scene, request.camera)
    surface, more = surface_from(request.terrain, scene)
    lines += more
    if isinstance(surface, ConstantHeight):
        heights = (surface.value - request.height_span, surface.value + request.height_span)
    else:
        report_progress(0.0, "height range of the DEM over the image")
        with concerning(DEM, request.terrain.dem_name), logged(rpcfit.__name__, lines):
            heights = dem_height_range(scene, surface, camera)
    _check_cancel(is_cancelled)
    rpc, report = fit_rpc(scene, camera, heights, grid=(request.grid, request.grid, request.levels),
                          regularisation=request.regularisation,
                          progress=lambda f, m=None: report_progress(0.9 * f, m))
    _check_cancel(is_cancelled)
    report["scene"] = str(request.scene)
    lines += fit_lines(report)
    cam = scene.cameras[camera]
    with concerning(OUTPUT), atomic_outputs() as files:  # all three files or none
        if vrt is not None:
            with concerning(IMAGE):
                image_vrt_with_rpc(rpc, request.image, vrt, cam.cols, cam.rows, files)
            report["image"] = request.image
            report["image_with_rpc"] = str(vrt)
        write_rpc(rpc, out, report, files)
    lines.append(LogLine(f"RPC written to {out} (report {report_path(out)})"
                         + (f"; image with RPC: {vrt}" if vrt else "")))
    report_progress(1.0)
    check = report["check"]
    return RunResult({OUTPUT: str(out), REPORT: str(report_path(out)), IMAGE_WITH_RPC: str(vrt) if vrt else None},
                     {"report": report, "rms_px": check["rms_px"], "max_px": check["max_px"]}, lines)


def _planned(request: RpcRequest) -> tuple:
    """(RPC file, VRT or None, log lines): the output's name checked (a warning line when GDAL will
    not find it by itself), the RPC, its report and the VRT checked against the files in use."""
    out = Path(request.output)
    name = out.name.lower()
    if not (name.endswith(".txt") or name.endswith(".rpb")):
        raise InputError(f"{out} must end in _RPC.TXT (GDAL's RPC text) or .RPB", parameter=OUTPUT)
    lines = []
    if name.endswith(".txt") and not name.endswith("_rpc.txt"):
        lines.append(LogLine(f"{out.name} does not end in _RPC.TXT: GDAL will not find it beside an image by itself",
                             True))
    stem = out.name[:-len("_RPC.TXT")] if name.endswith("_rpc.txt") else out.stem
    vrt = out.with_name(stem + ".vrt") if request.image else None
    request.files.check({OUTPUT: [out, Output(report_path(out), "its fit report"),
                                  Output(vrt, "the VRT of IMAGE with the RPC")]})
    return out, vrt, lines


def _check_cancel(is_cancelled: Callable[[], bool] | None) -> None:
    if is_cancelled is not None and is_cancelled():
        raise Cancelled("cancelled by the user")


def fit_lines(report: dict) -> list[LogLine]:
    """The log of an RPC fit (its ``report``, :func:`core.products.rpcfit.fit_rpc`): the fit, the
    independent check overall, at the height-range ends, per CCD and at the seams; the check's note and
    the way to a sub-pixel RPC as warnings."""
    check = report["check"]
    lo, hi = report["height_range"]
    lines = [LogLine(f"camera {report['camera']}: RPC00B fitted on {report['fit']['points']} points, heights "
                     f"{lo:.0f} to {hi:.0f} m (ellipsoidal); regularisation used {report['regularisation_used']:g}"),
             LogLine(f"check on {check['points']} independent points: RMS {check['rms_px']:.4f} px, "
                     f"max {check['max_px']:.4f} px")]
    lines += [LogLine(f"  at the {end} end ({fig['height_m']:.0f} m): RMS {fig['rms_px']:.4f} px, "
                      f"max {fig['max_px']:.4f} px") for end, fig in check["heights"].items()]
    lines += [LogLine(f"  CCD {chip['name']} (cols {chip['cols'][0]:.0f}-{chip['cols'][1]:.0f}): "
                      f"RMS {chip['rms_px']:.4f} px, max {chip['max_px']:.4f} px")
              for chip in check["chips"] if chip["rms_px"] is not None]
    lines += [LogLine(f"  seam at col {step['col']:.0f}: the rigorous model steps by {step['mean_px']:.3f} px")
              for step in check.get("seam_steps", [])]
    lines += [LogLine(check["note"], True)] if "note" in check else []
    hint = sensor_corrected_hint(report)
    return lines + ([LogLine(hint, True)] if hint else [])


def sensor_corrected_hint(report: dict) -> str | None:
    """For a camera of several chips whose RPC misses the rigorous model at the seams by more
    than SUB_PIXEL (max), the way to a sub-pixel RPC: the sensor-corrected product."""
    seams = report["check"].get("seams")
    if len(report["check"]["chips"]) < 2 or not seams or seams["max_px"] <= SUB_PIXEL:
        return None
    return (f"camera {report['camera']}: this RPC misses the rigorous model by up to {seams['max_px']:.2f} px at the "
            f"CCD seams (RMS {seams['rms_px']:.2f} px), which no RPC of the raw image can avoid. For a sub-pixel "
            "RPC, make the sensor-corrected product with pushbroom:sensorcorrect (the chips resampled onto one "
            "straight virtual detector line, which one RPC fits to hundredths of a pixel) "
            "and export the RPC of that product (its own SCENE) instead")
