"""pushbroom:bundleadjust on a block of scenes (SCENES) as a use case: the scenes adjusted together by
:func:`core.adjust.block.adjust_checked_block` with the GCPs, tie points and control lines that name
their scene, written into one folder: an adjusted scene JSON per input (``<name>_adjusted.json``), the
block report (``block_report.html`` and ``.json``), the adjusted GCP and tie-point layers, with control
lines the line residuals and, with ``write_rpcs``, a refined RPC of each image. Every file or none.

A block's tie points name their scene (pushbroom:matchtiepoints with SCENES): the checks against one
scene that importtiepoints makes do not apply; :func:`core.adjust.block.block_inputs` checks each
observation's scene and camera, once, and :func:`check_joined` that the tie points join the block.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable

from ..adjust.block import adjust_checked_block, block_inputs
from ..adjust.outputs import ground_residuals, write_adjusted_gcps, write_block_tie_points, write_line_residuals
from ..adjust.report import log_lines, write_report_json
from ..adjust.report_html import block_section, write_report_html
from ..adjust.scenesigmas import check_scene_sigmas, read_scene_sigmas
from ..errors import InputError
from ..files import Output, atomic_outputs, check_folder_destination, new_folder
from ..formats.rpcfiles import report_path, write_rpc
from ..formats.scene_json import save_scene
from ..log import LogLine
from ..observations.blockscenes import rpc_product_cameras, scene_groups
from ..observations.lines import IMAGE_LAYER
from ..observations.tables import scene_of_rows
from ..products.rpcfit import fit_rpc, refined_rpcs
from ..vector_io import layer_fields
from .adjustinputs import (ADJUSTED_SCENES, GCPS, LINES, OUTPUT_FOLDER, OUTPUT_REPORT_JSON, SCENES, TIES,
                           AdjustRequest, check_cancel, check_interior, check_reference_dem, read_gcps, read_lines,
                           read_ties)
from .base import RunResult, concerning
from .scenes import read_block

SCENE_SUFFIX = "_adjusted.json"  # <name>_adjusted.json: a scene's adjusted model in the folder
REPORT, GCP_LAYER, TIE_LAYER = "block_report.html", "adjusted_gcps.gpkg", "adjusted_tie_points.gpkg"
LINE_LAYER = "line_residuals.gpkg"
# The outputs of one scene, which a block writes into OUTPUT_FOLDER instead (or not at all)
ONE_SCENE_OUTPUTS = {"OUTPUT_SCENE": f"<name>{SCENE_SUFFIX}", "OUTPUT_REPORT": REPORT, "OUTPUT_GCPS": GCP_LAYER,
                     "OUTPUT_TIE_POINTS": TIE_LAYER, "OUTPUT_RPC": "<name>_RPC.TXT with WRITE_RPCS",
                     "OUTPUT_RESIDUALS": "", "OUTPUT_LINE_RESIDUALS": f"{LINE_LAYER} with LINES"}


def run(request: AdjustRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Adjust the block ``request.scenes`` into ``request.folder``. Files {OUTPUT_FOLDER, ADJUSTED_SCENES
    (the scene JSONs, in the block's order), OUTPUT_REPORT_JSON, and None for each of ONE_SCENE_OUTPUTS};
    figures {'report': the :class:`core.adjust.report_types.BlockReport`, 'adjustment': the composite's
    :class:`core.adjust.results.AdjustmentResult`}; lines: what was read, the adjustment's log, then per
    scene and for the block the figures a user reads first."""
    report_progress = progress or (lambda fraction, message=None: None)
    _refuse_one_scene_outputs(request.outputs)
    scenes, lines = _scenes(request.scenes)
    folder = Path(request.folder)
    with concerning(OUTPUT_FOLDER):
        check_folder_destination(folder)
    control_lines = _lines(request.lines, scenes)
    table, ties = _observations(request, scenes, control_lines is not None, lines)
    settings = request.settings
    if request.scene_sigmas:
        settings = replace(settings, scene_sigmas=read_scene_sigmas(request.scene_sigmas, list(scenes)))
    check_scene_sigmas(scenes, settings)  # before the (long) solution: an override the block cannot take
    with concerning(GCPS):
        checked = block_inputs(scenes, table, ties, control_lines)
    check_joined(scenes, checked.ties)
    check_interior(checked.composite, settings.interior)
    check_reference_dem(settings)
    lines += [LogLine(f"scene {name}: {path}") for name, path in request.scenes.items()]
    with new_folder(folder):
        planned = planned_files(folder, scenes, request.write_rpcs, request.gcps is not None, ties is not None,
                                control_lines is not None)
        request.files.check({OUTPUT_FOLDER: listed_outputs(planned)})
        result = adjust_checked_block(scenes, checked, settings, progress, is_cancelled)
        check_cancel(is_cancelled)
        report_progress(0.99, "writing the outputs")
        with concerning(OUTPUT_FOLDER), atomic_outputs() as files:  # every output or none
            lines += write_block(result, planned, table, request, checked.ties, files, control_lines)
    lines += log_lines(result.adjustment.report, None if ties is None else len(ties))
    lines += result.report.log_lines()
    report_progress(1.0)
    return RunResult({OUTPUT_FOLDER: str(folder), ADJUSTED_SCENES: [str(p) for p in planned["scenes"].values()],
                      OUTPUT_REPORT_JSON: str(planned["report"].with_suffix(".json")),
                      **{name: None for name in ONE_SCENE_OUTPUTS}},
                     {"report": result.report, "adjustment": result.adjustment}, lines)


def _refuse_one_scene_outputs(outputs) -> None:
    """The outputs of one scene, given with SCENES, are refused naming what a block writes instead."""
    for name, instead in ONE_SCENE_OUTPUTS.items():
        if outputs.get(name):
            where = f" (it writes {instead} there)" if instead else " (a block does not write it)"
            raise InputError(f"with SCENES the block's outputs go to OUTPUT_FOLDER{where}; leave {name} empty",
                             parameter=name)


def _scenes(files) -> tuple[dict, list]:
    """({name: scene}, log lines) of the block's scene files {name: file}: two or more; rigorous
    scenes and RPC products alike."""
    if len(files) < 2:
        raise InputError(f"{len(files)} scene given; a block needs two or more (one scene: SCENE)", parameter=SCENES)
    block, lines = read_block(files)
    return block.scenes, lines


def _lines(path: str, scenes: dict):
    """The control lines of the GeoPackage ``path`` (None: '' given), its image lines naming their
    scene (field ``scene`` of the layer image_lines, required in a block of several scenes)."""
    if not path:
        return None
    with concerning(LINES):
        fields = layer_fields(path, IMAGE_LAYER)
    if len(scenes) > 1 and "scene" not in fields:
        raise InputError(f"the layer {IMAGE_LAYER} of {path} has no field 'scene'; in a block of {len(scenes)} "
                         f"scenes ({', '.join(scenes)}) every image line names the scene it was measured in: add a "
                         "text field scene holding that name (as SCENES names the scene: its file's stem), or "
                         "digitise the lines with the scene file given (Digitise control lines writes it)",
                         parameter=LINES)
    return read_lines(path)


def _observations(request: AdjustRequest, scenes: dict, with_lines: bool, lines: list) -> tuple:
    """(GCP table, tie table or None) of the request, every row naming a scene of the block; GCPS may
    be left out with tie points or control lines. The rows of an RPC product get its image's camera
    (a line says so)."""
    ties = read_ties(request)
    layer = request.gcps
    if layer is not None and len(scenes) > 1 and layer.path.lower().endswith(".gpkg"):
        with concerning(GCPS):
            fields = layer_fields(layer.path, layer.layer)
        if "scene" not in fields:
            raise InputError(f"the layer has no field 'scene'; in a block of {len(scenes)} scenes "
                             f"({', '.join(scenes)}) every GCP row names the scene it was measured in: import the "
                             "GCPs with SCENES (pushbroom:importgcps, SCENE_FIELD)", parameter=GCPS)
    table = read_gcps(layer, ties is not None or with_lines)
    for name, rows, scene_of in ((GCPS, table, table.scene), (TIES, ties, None if ties is None else ties.scene)):
        if rows is not None and len(rows):
            with concerning(name):
                scene_of_rows(scene_of, rows.id, scenes)
    if ties is not None:
        ties, renamed = rpc_product_cameras(ties, ties.scene, scenes)
        lines += [LogLine(f"scene {name} is an RPC product of one image: its observations are measurements in that "
                          f"image (camera {scenes[name].cameras[0].name})", False, TIES) for name in renamed]
    return table, ties


def check_joined(scenes: dict, ties) -> None:
    """Tie points join all scenes into one block (:func:`core.adjust.block.block_inputs` has refused a
    scene without any control or tie observation). ``ties``: the tie table block_inputs checked."""
    if ties is None:
        return
    groups = scene_groups(list(scenes), ties.id, ties.scene)
    if len(groups) > 1:
        parts = "; ".join(", ".join(g) for g in groups)
        raise InputError(f"no tie point joins the scenes of these groups to each other: {parts}. A block's scenes are "
                         "adjusted together through the tie points they share: match tie points between them "
                         "(pushbroom:matchtiepoints with SCENES) or adjust the groups apart", parameter=TIES)


def planned_files(folder: Path, scenes: dict, write_rpcs: bool, with_gcps: bool, with_ties: bool,
                  with_lines: bool = False) -> dict:
    """The files the block writes into ``folder``: scenes {name: path}, rpcs {(name, camera index):
    path} (RPCs fitted to rigorous scenes, their fit check beside), refined {name: path} (RPC
    products' refined RPCs), report (HTML; its JSON beside), gcps, ties, lines (the line residuals)
    ('' when not written)."""
    rpcs, refined = {}, {}
    for name, scene in scenes.items():
        if write_rpcs and scene.rpc_images():
            refined[name] = folder / f"{name}_RPC.TXT"
        for k, cam in enumerate(scene.cameras if write_rpcs and not scene.rpc_images() else []):
            rpcs[name, k] = folder / (f"{name}_RPC.TXT" if len(scene.cameras) == 1 else f"{name}_{cam.name}_RPC.TXT")
    return {"scenes": {name: folder / f"{name}{SCENE_SUFFIX}" for name in scenes}, "rpcs": rpcs, "refined": refined,
            "report": folder / REPORT, "gcps": folder / GCP_LAYER if with_gcps else "",
            "ties": folder / TIE_LAYER if with_ties else "", "lines": folder / LINE_LAYER if with_lines else ""}


def listed_outputs(planned: dict) -> list:
    """Every file of :func:`planned_files`, derived ones labelled, for :meth:`FilesInUse.check`."""
    out = [*planned["scenes"].values(), planned["report"],
           Output(planned["report"].with_suffix(".json"), "its JSON report")]
    out += [f for path in planned["rpcs"].values() for f in (path, Output(report_path(path), "its RPC fit report"))]
    out += list(planned["refined"].values())
    return out + [f for f in (planned["gcps"], planned["ties"], planned["lines"]) if f]


def write_block(result, planned: dict, table, request: AdjustRequest, ties, files, control_lines=None) -> list:
    """Every output of :func:`planned_files` as part of the OutputSet ``files`` (``table``: the GCPs as
    read; ``ties``: the tie table block_inputs checked; ``control_lines``: the lines given); the lines
    saying which RPCs were written."""
    adjustment, lines = result.adjustment, []
    for name, scene in result.scenes.items():
        save_scene(scene, planned["scenes"][name], files)
    for (name, k), path in planned["rpcs"].items():
        rpc, fit = fit_rpc(result.scenes[name], k)
        write_rpc(rpc, path, fit, files)
        lines.append(LogLine(f"refined RPC of scene {name}, camera {result.scenes[name].cameras[k].name}: {path} "
                             f"(fit check {fit['check']['rms_px']:.2g} px RMS, {fit['check']['max_px']:.2g} px at "
                             "most)"))
    refined = refined_rpcs(result.scenes) if planned["refined"] else {}
    for name, path in planned["refined"].items():
        write_rpc(refined[name][0], path, files=files)
        lines.append(LogLine(f"refined RPC of the RPC product {name} ({refined[name][1]}): {path}"))
    write_report_json(result.report, planned["report"].with_suffix(".json"), files)
    write_report_html(adjustment.report, adjustment.points, planned["report"],
                      title=f"Bundle adjustment of a block of {len(result.scenes)} scenes", files=files,
                      preface=block_section(result.report))
    if planned["gcps"]:
        cameras = adjustment.points["camera"]  # <scene>/<camera>, as the composite names them
        en = ground_residuals(adjustment.scene, table, cameras)
        points = {k: v for k, v in adjustment.points.items() if k != "camera"}  # the layer keeps its own names
        write_adjusted_gcps(table, points, planned["gcps"], en=en, source=request.gcps.path,
                            source_layer=request.gcps.layer, files=files)
    if planned["ties"]:
        write_block_tie_points(adjustment.tie_points, result.tie_points, ties.scene, planned["ties"], files=files)
    if planned["lines"]:
        write_line_residuals(planned["lines"], control_lines, result.line_points, adjustment.report["lines"], files)
    return lines
