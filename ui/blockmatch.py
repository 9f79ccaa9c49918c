"""pushbroom:matchtiepoints between the raw images of several scenes of a block (SCENES): each
scene's image given to its camera, the block matched by
core.measure.tiematching.match_block_tiepoints and reported per scene pair.

A block's scenes are independent sensor models, so the checks and the forward intersection of
core.observations.tiepoints.check_against_scene (made against one scene) do not apply: the
layer is written without a-priori intersection, its observations naming their scene.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from qgis.core import QgsProcessingException

from ..core import measure
from ..core.measure.tiematching import View, match_block_tiepoints
from ..core.model.rpcscene import size_note
from ..core.observations import tiepoints
from ..core.products.ortho import check_images
from ..core.rasters import check_input_raster
from .feedback import check_cancelled, core_log_to, feedback_callbacks, processing_errors
from .inputs import block_scene_names, dem_from_parameters, load_scene_for, matching_settings, raster_files
from .parameters import INPUTS, SCENE, SCENES

# The core's names of the block's inputs (InputError.parameter) -> the algorithm's parameters
CORE_PARAMETERS = {"scenes": SCENES, "images": INPUTS, "base": SCENES}


def one_scene_file(alg, parameters, context) -> str:
    """SCENE's file when SCENES is not given; QgsProcessingException naming both when neither is."""
    path = alg.parameterAsFile(parameters, SCENE, context)
    if not path:
        raise QgsProcessingException(f"give {SCENE} (one scene) or {SCENES} (a block of scenes): neither is given")
    return path


def scene_files(alg, parameters, context) -> list[str]:
    """The files of SCENES ([] when not given: QGIS 3.22 reads an empty list as [''])."""
    return [path for path in alg.parameterAsFileList(parameters, SCENES, context) if path]


def block_given(alg, parameters, context) -> bool:
    """Whether SCENES is given (a block of scenes); QgsProcessingException naming both parameters,
    and what the algorithm does with each (its SCENE_OR_SCENES), when SCENE is given too."""
    if not scene_files(alg, parameters, context):
        return False
    if alg.parameterAsFile(parameters, SCENE, context):
        one, block = alg.SCENE_OR_SCENES
        raise QgsProcessingException(f"{SCENE} and {SCENES} are both given: give {SCENE} to {one}, or {SCENES} to "
                                     f"{block}, not both")
    return True


def image_camera(name: str, scene, path: str, size: tuple[int, int]) -> int:
    """The camera of scene ``name`` whose size (cols, rows) is the image's; QgsProcessingException
    (INPUTS) when none is, or when several are (a multi-camera product: which camera the image
    is cannot be told)."""
    fits = [k for k, c in enumerate(scene.cameras) if (int(c.cols), int(c.rows)) == size]
    cameras = ", ".join(f"{c.name} {int(c.cols)} x {int(c.rows)}{size_note(c)}" for c in scene.cameras)
    if not fits:
        raise QgsProcessingException(f"{INPUTS}: {path} is {size[0]} x {size[1]} px, but no camera of scene {name} "
                                     f"has that size ({cameras}): give one raw image per scene, in the order of "
                                     f"{SCENES}")
    if len(fits) > 1:
        raise QgsProcessingException(f"{INPUTS}: {path} has the size of {len(fits)} cameras of scene {name} "
                                     f"({cameras}), so which camera it is cannot be told: give single-camera "
                                     f"products in {SCENES} (one scene file per image), or match the cameras of "
                                     f"one scene with {SCENE}")
    return fits[0]


def block_views(alg, parameters, context, feedback) -> list[View]:
    """The block's views: SCENES (two or more, named by :func:`ui.inputs.block_scene_names`) with
    INPUTS, one raw image per scene in the same order, each given to the camera of its size."""
    paths = scene_files(alg, parameters, context)
    if len(paths) < 2:
        raise QgsProcessingException(f"{SCENES}: {len(paths)} scene given; tie points between scenes need two or "
                                     f"more (the cameras of one scene: {SCENE})")
    names = block_scene_names(paths)
    scenes = [load_scene_for(SCENES, path, feedback) for path in paths]
    images = raster_files(alg, parameters, INPUTS, context)
    if len(images) != len(paths):
        raise QgsProcessingException(f"{INPUTS}: {len(images)} raw image(s) given for the {len(paths)} scenes of "
                                     f"{SCENES} ({', '.join(names)}): give one image per scene, in that order")
    views = []
    for name, scene, path, image in zip(names, scenes, paths, images):
        if not image:
            raise QgsProcessingException(f"{INPUTS}: the image of scene {name} is not a file (a memory or service "
                                         "layer); save it as GeoTIFF first")
        with processing_errors(f"{INPUTS}: "):
            camera = image_camera(name, scene, image, check_input_raster(image))
            check_images(scene, {camera: image})
        feedback.pushInfo(f"scene {name} ({path}): camera {scene.cameras[camera].name}, image {image}")
        views.append(View(name, scene, camera, Path(image)))
    return views


def match_block(alg, parameters, context, feedback):
    """Tie points between the first image of the block and every other (a TieTable whose scene
    column names each observation's scene), reported per scene pair."""
    views = block_views(alg, parameters, context, feedback)
    surface = dem_from_parameters(alg, parameters, context, views[0].scene, feedback)
    settings = matching_settings(alg, parameters, context)
    progress, is_cancelled = feedback_callbacks(feedback)
    with processing_errors("", CORE_PARAMETERS), core_log_to(feedback, measure.__name__):
        table, rejected = match_block_tiepoints(views, surface, settings, 0,
                                                lambda f, m=None: progress(0.9 * f, m), is_cancelled)
    check_cancelled(feedback)
    report_block(views, table, rejected, feedback)
    feedback.pushInfo("block of scenes: the checks against one scene (cameras, image bounds, onboard forward "
                      "intersection, likely mismatches) do not apply and were skipped; the layer holds no "
                      "a-priori intersection (rays and residuals empty)")
    return table


def report_block(views: list[View], table, rejected: dict, feedback) -> None:
    """Per scene matched against the first: grid points matched, rejections by reason; then the tie
    points per pair of scenes (a point matched in several scenes ties each pair of them)."""
    base = views[0]
    for view in views[1:]:
        counts = rejected[view.label]
        matched = int(np.sum((table.scene == view.scene_name) & (table.camera == view.camera_name)))
        total = matched + sum(counts.values())
        reasons = ", ".join(f"{v} {k}" for k, v in counts.items() if v) or "none"
        feedback.pushInfo(f"{base.label}-{view.label}: matched {matched} of {total} grid points; rejected: {reasons}")
    pairs = tiepoints.summary(table, by_scene=True)["pairs"]
    feedback.pushInfo("tie points per scene pair: " + ", ".join(f"{k} {v}" for k, v in pairs.items()))
