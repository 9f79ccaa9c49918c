"""pushbroom:bundleadjust on a block of scenes (SCENES instead of SCENE, issue 23): the scenes
named by :func:`ui.inputs.block_scene_names`, adjusted together by
:func:`core.adjust.block.adjust_block` with the GCPs and tie points that name their scene, and
written into OUTPUT_FOLDER: one adjusted scene JSON per input (``<name>_adjusted.json``), the
block report (``block_report.html`` and ``.json``), the adjusted GCP and tie-point layers, with
LINES the line residuals and, with WRITE_RPCS, a refined RPC per camera of each scene. Every file
or none. Rigorous scenes and RPC products may be mixed (:class:`core.model.mixedblock.MixedBlock`;
control lines need rigorous scenes, which the core says naming the RPC products).

Control lines (LINES, Tommaselli & Marcato Junior 2012): the ground lines are shared by the block's
scenes and each image line names the scene it was measured in (the field ``scene`` of the layer
image_lines, required with several scenes).

A block's tie points come from pushbroom:matchtiepoints with SCENES (or any layer or table with
the fields id, camera, col, row, scene): the checks against one scene that importtiepoints makes
do not apply; the core checks each observation's scene and camera.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from qgis.core import (QgsProcessingException, QgsProcessingOutputMultipleLayers, QgsProcessingParameterBoolean,
                       QgsProcessingParameterFolderDestination, QgsProcessingUtils)

from ..core.adjust.block import adjust_block, block_inputs
from ..core.adjust.linepoints import ControlLines
from ..core.adjust.outputs import ground_residuals, write_adjusted_gcps, write_block_tie_points, write_line_residuals
from ..core.adjust.report import log_lines, write_report_json
from ..core.adjust.report_html import block_section, write_report_html
from ..core.adjust.scenesigmas import check_scene_sigmas
from ..core.errors import InputError
from ..core.files import Output, atomic_outputs, check_folder_destination
from ..core.formats.rpcfiles import report_path, write_rpc
from ..core.formats.scene_json import save_scene
from ..core.model.mixedblock import MixedBlock
from ..core.model.rpcscene import RpcScene
from ..core.observations import tiepoints
from ..core.observations.blockscenes import rpc_product_cameras, scene_groups
from ..core.observations.lines import IMAGE_LAYER, read_ground_lines, read_image_lines
from ..core.observations.tables import scene_of_rows
from ..core.products.rpcfit import fit_rpc, refined_rpcs
from ..core.vector_io import layer_fields
from ..simulation.simulator import new_folder
from .blockmatch import scene_files
from .feedback import check_cancelled, feedback_callbacks, processing_errors
from .inputs import attribute_floats, attribute_texts, block_scene_names, load_scene_for, ogr_source, split_ogr_source
from .outputs import check_outputs
from .parameters import SCENE, SCENES, tr
from .scenesigmas import scene_sigmas

OUTPUT_FOLDER, WRITE_RPCS, ADJUSTED_SCENES = "OUTPUT_FOLDER", "WRITE_RPCS", "ADJUSTED_SCENES"
SCENE_SUFFIX = "_adjusted.json"  # <name>_adjusted.json: a scene's adjusted model in OUTPUT_FOLDER
REPORT, GCP_LAYER, TIE_LAYER = "block_report.html", "adjusted_gcps.gpkg", "adjusted_tie_points.gpkg"
LINE_LAYER = "line_residuals.gpkg"
# The algorithm's outputs of one scene, which a block writes into OUTPUT_FOLDER instead (or not at all)
ONE_SCENE_OUTPUTS = {"OUTPUT_SCENE": f"<name>{SCENE_SUFFIX}", "OUTPUT_REPORT": REPORT, "OUTPUT_GCPS": GCP_LAYER,
                     "OUTPUT_TIE_POINTS": TIE_LAYER, "OUTPUT_RPC": "<name>_RPC.TXT with WRITE_RPCS",
                     "OUTPUT_RESIDUALS": "", "OUTPUT_LINE_RESIDUALS": f"{LINE_LAYER} with LINES"}


# --- parameters ------------------------------------------------------------------------------
FOLDER_HELP = (
    "With SCENES: the folder (created if missing) the block's outputs go to, every file or none: "
    f"<name>{SCENE_SUFFIX} per scene, block_report.html/.json, adjusted_gcps.gpkg, adjusted_tie_points.gpkg, "
    "line_residuals.gpkg (docs page, A block of scenes). Files of these names are replaced. Empty: a temporary "
    "folder.")
RPCS_HELP = (
    "With SCENES: also write into OUTPUT_FOLDER an RPC00B fitted to each adjusted rigorous scene, <name>_RPC.TXT "
    "(<name>_<CAMERA>_RPC.TXT for several cameras) with its fit check (.json), and an RPC product's refined RPC; "
    "copy it beside the image as <image>_RPC.TXT.")


def add_block_parameters(alg) -> None:
    """OUTPUT_FOLDER, WRITE_RPCS and the output ADJUSTED_SCENES of the block (SCENES is added with SCENE)."""
    alg.add_parameter(QgsProcessingParameterFolderDestination(OUTPUT_FOLDER, tr("Block output folder"), optional=True),
                      tr(FOLDER_HELP))
    # optional, so that graphical models saved before it need no value for it
    alg.add_parameter(QgsProcessingParameterBoolean(WRITE_RPCS, tr("Refined RPC of each image (block)"),
                                                    defaultValue=False, optional=True), tr(RPCS_HELP), advanced=True)
    alg.addOutput(QgsProcessingOutputMultipleLayers(ADJUSTED_SCENES, tr("Adjusted scenes of the block (scene JSON, "
                                                                        "SCENES order)")))


# --- inputs ----------------------------------------------------------------------------------
def read_tie_layer(layer) -> tiepoints.TieTable:
    """The observations of a tie-point layer: a delimited text file (the simulator's
    tie_points.csv) read by core.tiepoints.read_csv, another file layer by
    core.tiepoints.read_gpkg, any other layer or table from its fields id, camera, col, row
    (optional sigma_px, scene)."""
    if layer.providerType() == "ogr":
        path, name = split_ogr_source(layer.source())
        return tiepoints.read_csv(path) if Path(path).suffix.lower() in (".csv", ".txt") else \
            tiepoints.read_gpkg(path, name)
    names = layer.fields().names()
    missing = [f for f in ("id", "camera", "col", "row") if f not in names]
    if missing:
        raise InputError(f"{layer.source()} lacks tie-point field(s) {', '.join(missing)} (fields: "
                         f"{', '.join(names)})")
    features = list(layer.getFeatures())
    column = {f: [feature[f] for feature in features] if f in names else None
              for f in ("id", "camera", "col", "row", "sigma_px", "scene")}
    sigma = attribute_floats(column["sigma_px"] or [None] * len(features))
    return tiepoints.build_table(attribute_texts(column["id"]), attribute_texts(column["camera"]),
                                 attribute_floats(column["col"]), attribute_floats(column["row"]),
                                 scene=attribute_texts(column["scene"]), source=layer.source(),
                                 sigma_px=np.where(np.isfinite(sigma), sigma, tiepoints.DEFAULT_SIGMA_PX))


def block_scenes(alg, parameters, context, feedback) -> tuple[dict[str, str], dict]:
    """({name: file}, {name: scene}) of SCENES: two or more, each named once
    (:func:`ui.inputs.block_scene_names`); rigorous scenes and RPC products alike."""
    paths = scene_files(alg, parameters, context)
    if len(paths) < 2:
        raise QgsProcessingException(f"{SCENES}: {len(paths)} scene given; a block needs two or more (one scene: "
                                     f"{SCENE})")
    files = dict(zip(block_scene_names(paths), paths))
    return files, {name: load_scene_for(SCENES, path, feedback) for name, path in files.items()}


def user_destination(alg, parameters, context, name: str) -> str:
    """The file output ``name`` was given by the user; '' when not given or temporary (the
    dialog's '[Save to temporary file]', a graphical model's file for an output nobody takes)."""
    if parameters.get(name) in (None, ""):
        return ""
    path = alg.parameterAsFileOutput(parameters, name, context) if alg.parameterDefinition(name).type() == \
        "fileDestination" else alg.parameterAsOutputLayer(parameters, name, context)
    temporary = Path(QgsProcessingUtils.tempFolder()).resolve()
    return "" if not path or temporary in Path(path).resolve().parents else path


def refuse_one_scene_parameters(alg, parameters, context) -> None:
    """The outputs of one scene, given with SCENES, are refused naming what a block writes instead."""
    for name, instead in ONE_SCENE_OUTPUTS.items():
        if user_destination(alg, parameters, context, name):
            where = f" (it writes {instead} there)" if instead else " (a block does not write it)"
            raise QgsProcessingException(f"{name}: with {SCENES} the block's outputs go to {OUTPUT_FOLDER}{where}; "
                                         f"leave {name} empty")


def gcp_scene_field(alg, parameters, context, gcp_name: str, scenes: dict) -> None:
    """A GCP layer for a block of several scenes must say which scene each row was measured in."""
    layer = alg.parameterAsVectorLayer(parameters, gcp_name, context)
    if layer is not None and len(scenes) > 1 and "scene" not in layer.fields().names():
        raise QgsProcessingException(f"{gcp_name}: the layer has no field 'scene'; in a block of {len(scenes)} "
                                     f"scenes ({', '.join(scenes)}) every GCP row names the scene it was measured "
                                     f"in: import the GCPs with {SCENES} (pushbroom:importgcps, SCENE_FIELD)")


def block_lines_input(alg, parameters, context, scenes: dict) -> ControlLines | None:
    """The control lines of LINES (None without): the ground lines and the image lines with the
    scene each names (field ``scene`` of the layer image_lines; a layer without it is refused in a
    block of several scenes, as a GCP layer is by :func:`gcp_scene_field`)."""
    layer = alg.parameterAsVectorLayer(parameters, alg.LINES, context)
    if layer is None:
        return None
    path, _ = ogr_source(alg.LINES, layer, "control lines")
    with processing_errors(f"{alg.LINES}: "):
        fields = layer_fields(path, IMAGE_LAYER)
    if len(scenes) > 1 and "scene" not in fields:
        raise QgsProcessingException(f"{alg.LINES}: the layer {IMAGE_LAYER} of {path} has no field 'scene'; in a "
                                     f"block of {len(scenes)} scenes ({', '.join(scenes)}) every image line names the "
                                     "scene it was measured in: add a text field scene holding that name (as SCENES "
                                     "names the scene: its file's stem), or digitise the lines with the scene file "
                                     "given (Digitise control lines writes it)")
    with processing_errors(f"{alg.LINES}: "):
        return ControlLines(read_ground_lines(path), read_image_lines(path))


def block_observations(alg, parameters, context, scenes: dict, feedback, with_lines: bool = False) -> tuple:
    """(GCP table, (its GeoPackage, layer name), tie table or None) of GCPS and TIE_POINTS, every
    row naming a scene of the block (errors name the parameter); GCPS may be left out with tie
    points or control lines (``with_lines``)."""
    tie_layer = alg.parameterAsVectorLayer(parameters, alg.TIE_POINTS, context)
    if parameters.get(alg.TIE_POINTS) not in (None, "") and tie_layer is None:
        raise QgsProcessingException(f"{alg.TIE_POINTS}: {parameters[alg.TIE_POINTS]} is not a vector layer or table")
    with processing_errors(f"{alg.TIE_POINTS}: "):
        ties = None if tie_layer is None else read_tie_layer(tie_layer)
    gcp_scene_field(alg, parameters, context, alg.GCPS, scenes)
    table, gcp_path, gcp_layer = alg.gcp_table(parameters, context, ties is not None or with_lines)
    for name, rows in ((alg.GCPS, table), (alg.TIE_POINTS, ties)):
        if rows is not None and len(rows):
            with processing_errors(f"{name}: "):
                scene_of_rows(rows.block_scene if name == alg.GCPS else rows.scene, rows.id, scenes)
    if ties is not None:
        ties, renamed = rpc_product_cameras(ties, ties.scene, scenes)
        for name in renamed:
            feedback.pushInfo(f"{alg.TIE_POINTS}: scene {name} is an RPC product of one image: its observations are "
                              f"measurements in that image (camera {scenes[name].cameras[0].name})")
    return table, (gcp_path, gcp_layer), ties


def check_joined(scenes: dict, ties, tie_name: str) -> None:
    """Tie points join all scenes into one block (core.adjust.block.block_inputs has refused a
    scene without any control or tie observation). ``ties``: the tie table of block_inputs."""
    if ties is None:
        return
    groups = scene_groups(list(scenes), ties.id, ties.scene)
    if len(groups) > 1:
        parts = "; ".join(", ".join(g) for g in groups)
        raise QgsProcessingException(f"{tie_name}: no tie point joins the scenes of these groups to each other: "
                                     f"{parts}. A block's scenes are adjusted together through the tie points they "
                                     "share: match tie points between them (pushbroom:matchtiepoints with SCENES) "
                                     "or adjust the groups apart")


# --- outputs ---------------------------------------------------------------------------------
def output_folder(alg, parameters, context) -> Path:
    """OUTPUT_FOLDER, or a new temporary folder when it is not given."""
    folder = alg.parameterAsFileOutput(parameters, OUTPUT_FOLDER, context)
    return Path(folder or QgsProcessingUtils.generateTempFilename("block_adjustment"))


def planned_files(folder: Path, scenes: dict, write_rpcs: bool, with_gcps: bool, with_ties: bool,
                  with_lines: bool = False) -> dict:
    """The files the block writes into ``folder``: scenes {name: path}, rpcs {(name, camera
    index): path} (RPCs fitted to rigorous scenes, their fit check beside), refined {name: path}
    (RPC products' refined RPCs), report (HTML; its JSON beside), gcps, ties, lines (the line
    residuals) ('' when not written)."""
    rpcs = {}
    for name, scene in scenes.items():
        for k, cam in enumerate(scene.cameras if write_rpcs and not isinstance(scene, RpcScene) else []):
            rpcs[name, k] = folder / (f"{name}_RPC.TXT" if len(scene.cameras) == 1 else f"{name}_{cam.name}_RPC.TXT")
    refined = {name: folder / f"{name}_RPC.TXT" for name, scene in scenes.items()
               if write_rpcs and isinstance(scene, RpcScene)}
    return {"scenes": {name: folder / f"{name}{SCENE_SUFFIX}" for name in scenes}, "rpcs": rpcs, "refined": refined,
            "report": folder / REPORT, "gcps": folder / GCP_LAYER if with_gcps else "",
            "ties": folder / TIE_LAYER if with_ties else "", "lines": folder / LINE_LAYER if with_lines else ""}


def listed_outputs(planned: dict) -> list:
    """Every file of :func:`planned_files`, derived ones labelled, for ui.outputs.check_outputs."""
    out = [*planned["scenes"].values(), planned["report"],
           Output(planned["report"].with_suffix(".json"), "its JSON report")]
    out += [f for path in planned["rpcs"].values() for f in (path, Output(report_path(path), "its RPC fit report"))]
    out += list(planned["refined"].values())
    return out + [f for f in (planned["gcps"], planned["ties"], planned["lines"]) if f]


def write_block(result, planned: dict, table, gcp_source: tuple, ties, files, feedback,
                lines: ControlLines | None = None) -> None:
    """Every output of :func:`planned_files` as part of the OutputSet ``files`` (``lines``: the
    control lines given, for the line residuals)."""
    adjustment = result.adjustment
    for name, scene in result.scenes.items():
        save_scene(scene, planned["scenes"][name], files)
    for (name, k), path in planned["rpcs"].items():
        rpc, fit = fit_rpc(result.scenes[name], k)
        write_rpc(rpc, path, fit, files)
        feedback.pushInfo(f"refined RPC of scene {name}, camera {result.scenes[name].cameras[k].name}: {path} (fit "
                          f"check {fit['check']['rms_px']:.2g} px RMS, {fit['check']['max_px']:.2g} px at most)")
    refined = refined_rpcs(result.scenes) if planned["refined"] else {}
    for name, path in planned["refined"].items():
        write_rpc(refined[name][0], path, files=files)
        feedback.pushInfo(f"refined RPC of the RPC product {name} ({refined[name][1]}): {path}")
    write_report_json(result.report, planned["report"].with_suffix(".json"), files)
    write_report_html(adjustment.report, adjustment.points, planned["report"],
                      title=f"Bundle adjustment of a block of {len(result.scenes)} scenes", files=files,
                      preface=block_section(result.report))
    if planned["gcps"]:
        cameras = adjustment.points["camera"]  # <scene>/<camera>, as the composite names them
        en = ground_residuals(adjustment.scene, table, cameras)
        points = {k: v for k, v in adjustment.points.items() if k != "camera"}  # the layer keeps its own names
        write_adjusted_gcps(table, points, planned["gcps"], en=en, source=gcp_source[0], source_layer=gcp_source[1],
                            files=files)
    if planned["ties"]:
        write_block_tie_points(adjustment.tie_points, result.tie_points, ties.scene, planned["ties"], files=files)
    if planned["lines"]:
        write_line_residuals(planned["lines"], lines, result.line_points, adjustment.report["lines"], files)


def log_block(result, n_ties: int | None, alg, feedback) -> None:
    """The adjustment's log sentences, then per scene and for the block the figures a user reads
    first and the block's own warnings (:meth:`core.adjust.report_types.BlockReport.log_lines`)."""
    alg.push_core_lines(feedback, log_lines(result.adjustment.report, n_ties))
    alg.push_core_lines(feedback, result.report.log_lines())


# --- the run -----------------------------------------------------------------------------------
def run_block(alg, parameters, context, feedback) -> dict:
    """pushbroom:bundleadjust with SCENES: the block's checks, adjustment and outputs; the
    algorithm's results (OUTPUT_FOLDER, ADJUSTED_SCENES in SCENES order, OUTPUT_REPORT_JSON)."""
    refuse_one_scene_parameters(alg, parameters, context)
    paths, scenes = block_scenes(alg, parameters, context, feedback)
    folder = output_folder(alg, parameters, context)
    with processing_errors(f"{OUTPUT_FOLDER}: "):
        check_folder_destination(folder)
    lines = block_lines_input(alg, parameters, context, scenes)
    table, (gcp_path, gcp_layer), ties = block_observations(alg, parameters, context, scenes, feedback,
                                                            lines is not None)
    settings = replace(alg.adjustment_settings(parameters, context),
                       scene_sigmas=scene_sigmas(alg, parameters, context, list(paths)))
    with alg.core_errors():  # before the (long) solution: an override the block cannot take
        check_scene_sigmas(scenes, settings)
    with alg.core_errors(alg.GCPS):
        composite, _, ties_in_block, _ = block_inputs(scenes, table, ties, lines)
    check_joined(scenes, ties_in_block, alg.TIE_POINTS)
    if not isinstance(composite, MixedBlock):  # a block with RPC products: the core names INTERIOR's errors
        alg.check_interior(composite, settings.interior)
    for name, path in paths.items():
        feedback.pushInfo(f"scene {name}: {path}")
    with new_folder(folder):
        planned = planned_files(folder, scenes, alg.parameterAsBoolean(parameters, WRITE_RPCS, context),
                                bool(gcp_path), ties is not None, lines is not None)
        check_outputs(alg, parameters, context, {OUTPUT_FOLDER: listed_outputs(planned)})
        progress, is_cancelled = feedback_callbacks(feedback)
        with alg.core_errors():
            result = adjust_block(scenes, table, ties, settings, progress, is_cancelled, lines=lines)
        check_cancelled(feedback)
        feedback.setProgressText("writing the outputs")
        with processing_errors(f"{OUTPUT_FOLDER}: "), atomic_outputs() as files:  # every output or none
            write_block(result, planned, table, (gcp_path, gcp_layer), ties_in_block, files, feedback, lines)
    log_block(result, None if ties is None else len(ties), alg, feedback)
    feedback.setProgress(100)
    return {OUTPUT_FOLDER: str(folder), ADJUSTED_SCENES: [str(p) for p in planned["scenes"].values()],
            alg.OUTPUT_REPORT_JSON: str(planned["report"].with_suffix(".json")),
            **{name: None for name in ONE_SCENE_OUTPUTS}}
