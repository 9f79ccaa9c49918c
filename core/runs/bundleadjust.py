"""pushbroom:bundleadjust as a use case: the self-calibrating bundle adjustment of one scene from its
GCPs, tie points and control lines, written as the adjusted scene JSON, the JSON and HTML reports,
the GCP and tie-point layers with residuals and flags, the residual vectors, the line residuals and
(an RPC scene) the refined RPC, every file or none; or of a block of scenes
(:mod:`core.runs.blockadjust`). The inputs are read and checked, and the outputs planned and checked,
before the solution starts."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from ..adjust.checks import check_inputs
from ..adjust.engine import adjust_checked
from ..adjust.outputs import (ground_residuals, write_adjusted_gcps, write_adjusted_tie_points,
                              write_line_residuals, write_residual_vectors)
from ..adjust.report import log_lines, write_report_json
from ..adjust.report_html import write_report_html
from ..errors import InputError
from ..files import Output, atomic_outputs
from ..formats.rpcfiles import write_rpc
from ..formats.scene_json import save_scene
from ..log import LogLine
from ..observations import tiepoints
from ..products.rpcfit import refined_rpc
from . import blockadjust
from .adjustinputs import (GCPS, ONE_SCENE_SUFFIXES, OUTPUT_FOLDER, OUTPUT_GCPS, OUTPUT_LINE_RESIDUALS, OUTPUT_REPORT,
                           OUTPUT_REPORT_JSON, OUTPUT_RESIDUALS, OUTPUT_RPC, OUTPUT_SCENE, OUTPUT_TIE_POINTS,
                           SCENE_SIGMAS, TIES, WRITE_RPCS, AdjustRequest, check_cancel, check_interior,
                           check_needed_inputs, check_reference_dem, read_gcps, read_lines, read_ties)
from .base import RunResult, concerning, logged, scene_from

__all__ = ["AdjustRequest", "run"]


def run(request: AdjustRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Adjust as ``request`` says: one scene, or with ``request.scenes`` a block
    (:func:`core.runs.blockadjust.run`). One scene's files: every output of ONE_SCENE_SUFFIXES and
    OUTPUT_REPORT_JSON (None: not written); figures {'report': the adjustment's
    :class:`core.adjust.report_types.AdjustmentReport`, 'points': its per-GCP arrays}; lines: what
    was read, then the adjustment's log (:func:`core.adjust.report.log_lines`)."""
    if request.scenes:
        return blockadjust.run(request, progress, is_cancelled)
    report_progress = progress or (lambda fraction, message=None: None)
    outputs, report_json = _planned(request)
    scene, lines = scene_from(request.scene)
    if outputs[OUTPUT_RPC] and not scene.rpc_images():
        raise InputError("only for a SCENE given by its RPC; the RPC of an adjusted rigorous scene is written by "
                         "'Export RPC' (pushbroom:exportrpc)", parameter=OUTPUT_RPC)
    ties = _ties(request, scene, lines)
    table = read_gcps(request.gcps, ties is not None)
    control_lines = read_lines(request.lines)
    check_needed_inputs(outputs, ties, request.gcps is not None, control_lines is not None)
    settings = request.settings
    with concerning(GCPS):  # the core's checks before the (long) solution; what it does not place is the GCPs'
        checked = check_inputs(scene, table, settings, ties, control_lines)
    check_interior(scene, settings.interior)
    check_reference_dem(settings)
    if request.gcps is not None:
        lines.append(LogLine(f"{len(table)} points from {request.gcps.path}: {int((table.role == 'control').sum())} "
                             f"control, {int((table.role == 'check').sum())} check"))
    result = adjust_checked(scene, checked, settings, progress, is_cancelled, ties=ties, lines=control_lines)
    check_cancel(is_cancelled)
    report_progress(0.99, "writing the outputs")
    en = ground_residuals(result.scene, table, result.points["camera"])
    with atomic_outputs() as files:  # every output or none
        with concerning(OUTPUT_SCENE):
            save_scene(result.scene, outputs[OUTPUT_SCENE], files)
        if outputs[OUTPUT_RPC]:
            with concerning(OUTPUT_RPC):
                rpc, how = refined_rpc(result.scene)
                write_rpc(rpc, outputs[OUTPUT_RPC], files=files)
            lines.append(LogLine(f"refined RPC ({how}) written to {outputs[OUTPUT_RPC]}"))
        if outputs[OUTPUT_REPORT]:
            with concerning(OUTPUT_REPORT):
                write_report_json(result.report, report_json, files)
                write_report_html(result.report, result.points, outputs[OUTPUT_REPORT],
                                  title=f"Bundle adjustment of {Path(request.scene).name}", files=files)
        if outputs[OUTPUT_GCPS]:
            with concerning(OUTPUT_GCPS):
                write_adjusted_gcps(table, result.points, outputs[OUTPUT_GCPS], en=en,
                                    scene_path=outputs[OUTPUT_SCENE], source=request.gcps.path,
                                    source_layer=request.gcps.layer, files=files)
        if outputs[OUTPUT_LINE_RESIDUALS]:
            with concerning(OUTPUT_LINE_RESIDUALS):
                write_line_residuals(outputs[OUTPUT_LINE_RESIDUALS], control_lines, result.lines,
                                     result.report["lines"], files)
        if outputs[OUTPUT_RESIDUALS]:
            with concerning(OUTPUT_RESIDUALS):
                write_residual_vectors(result.scene, table, result.points, outputs[OUTPUT_RESIDUALS],
                                       request.residual_scale, en=en, files=files)
        if outputs[OUTPUT_TIE_POINTS]:
            with concerning(OUTPUT_TIE_POINTS):
                write_adjusted_tie_points(result.tie_points, outputs[OUTPUT_TIE_POINTS],
                                          scene_path=outputs[OUTPUT_SCENE], files=files)
    lines += log_lines(result.report, None if ties is None else len(ties))
    report_progress(1.0)
    files_written = {**{name: path or None for name, path in outputs.items()}, OUTPUT_REPORT_JSON: report_json or None}
    return RunResult(files_written, {"report": result.report, "points": result.points}, lines)


def _planned(request: AdjustRequest) -> tuple[dict, str]:
    """(one scene's outputs {name: file, '' not asked}, the JSON report's file ('' without the HTML
    one)): a block's outputs refused, each file's suffix checked, and every file checked against the
    files in use."""
    if request.scene_sigmas:
        raise InputError("SCENE_SIGMAS: per-scene sigmas are for a block of scenes (SCENES); one SCENE takes "
                         "POSITION_SIGMA, ATTITUDE_SIGMA and RPC_SIGMA: leave SCENE_SIGMAS empty",
                         parameter=SCENE_SIGMAS)
    for name, given in ((OUTPUT_FOLDER, request.folder), (WRITE_RPCS, request.write_rpcs)):
        if given:
            raise InputError("for a block of scenes (SCENES) only; the outputs of one SCENE are OUTPUT_SCENE, "
                             "OUTPUT_REPORT..., its refined RPC OUTPUT_RPC (RPC scenes) or pushbroom:exportrpc",
                             parameter=name)
    outputs = {name: request.outputs.get(name) or "" for name in ONE_SCENE_SUFFIXES}
    for name, suffix in ONE_SCENE_SUFFIXES.items():
        if outputs[name] and Path(outputs[name]).suffix.lower() != suffix:
            raise InputError(f"expected a {suffix} file (got {outputs[name]})", parameter=name)
    report_json = str(Path(outputs[OUTPUT_REPORT]).with_suffix(".json")) if outputs[OUTPUT_REPORT] else ""
    request.files.check({**{name: [path] for name, path in outputs.items()},
                         OUTPUT_REPORT: [outputs[OUTPUT_REPORT], Output(report_json, "its JSON report")]})
    return outputs, report_json


def _ties(request: AdjustRequest, scene, lines: list) -> tiepoints.TieTable | None:
    """The tie points of the request (None without) checked against the one ``scene`` as 'Import tie
    points' checks them (cameras, duplicates, image, spread; what it notices goes to ``lines``); a
    warning line when the layer was checked against another scene file."""
    if request.ties is None and request.tie_rows is None:
        return None
    if scene.rigorous_part() is None:
        raise InputError("tie points need a rigorous (physical) scene model with several cameras; this SCENE is "
                         "given by its RPC (one image)", parameter=TIES)
    table = read_ties(request)
    made_for = table.scene_path
    if made_for and Path(made_for).resolve() != Path(request.scene).resolve():
        lines.append(LogLine(f"the layer was checked against the scene {made_for}, not SCENE {request.scene}; its "
                             "cameras and image positions must be this scene's", True, TIES))
    source = request.ties.shown() if request.ties is not None else "tie points"
    lines.append(LogLine(f"{len(table)} tie observations from {source}"))
    with logged(tiepoints.__name__, lines), concerning(TIES):
        return tiepoints.check_against_scene(table, scene, request.scene, source=source)
