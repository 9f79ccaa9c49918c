"""pushbroom:matchtiepoints as a use case: tie points matched between the cameras of a three-line
scene (or strip), or between the raw images of the scenes of a block, in a common ground geometry
(:mod:`core.measure.tiematching`), written as the tie-point layer the adjustment reads.

A block's scenes are independent sensor models, so the checks and the forward intersection of
:func:`core.observations.tiepoints.check_against_scene` (made against one scene) do not apply to a
block: its layer is written without a-priori intersection, its observations naming their scene."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from .. import measure
from ..errors import InputError
from ..log import LogLine
from ..measure.tiematching import View, match_block_tiepoints, match_tiepoints
from ..model.rpcscene import size_note
from ..observations import tiepoints
from ..products.ortho import check_images
from ..rasters import check_input_raster
from .base import IMAGES, FilesInUse, RunResult, Terrain, camera_images, concerning, logged, scene_from, surface_from
from .layers import OUTPUT, check_cancelled, check_gpkg, write_ties
from .matchgcps import match_settings
from .scenes import SCENES, block_from

BLOCK_SKIPS = ("block of scenes: the checks against one scene (cameras, image bounds, onboard forward intersection, "
               "likely mismatches) do not apply and were skipped; the layer holds no a-priori intersection (rays "
               "and residuals empty)")


@dataclass(frozen=True)
class MatchTiesRequest:
    """Tie points between the cameras of the scene file ``scene`` or, with ``scenes``, between the
    images of the block's scenes; ``images``: one raw image per camera of the scene, in its camera
    order, or per scene of the block, in its order. Heights from the terrain, matching settings
    ``matching`` ({:class:`core.measure.matching.MatchSettings` field: value}); written to ``output``."""
    output: str
    images: tuple[str, ...]
    scene: str = ""
    scenes: tuple[str, ...] = ()
    terrain: Terrain = Terrain()
    matching: dict = field(default_factory=dict)
    files: FilesInUse = field(default_factory=FilesInUse)


def run(request: MatchTiesRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Match as ``request`` says: files {OUTPUT}, figures the table's summary
    (:func:`core.observations.tiepoints.summary`)."""
    report = progress or (lambda fraction, message=None: None)
    check_gpkg(request.output, "tie-point layers", request.files)
    if request.scenes:
        table, lines = _match_block(request, report, is_cancelled)
    else:
        table, lines = _match_scene(request, report, is_cancelled)
    lines += write_ties(table, request.output, by_scene=bool(request.scenes))
    report(1.0)
    return RunResult({OUTPUT: request.output}, tiepoints.summary(table, bool(request.scenes)), lines)


def _match_scene(request: MatchTiesRequest, report, is_cancelled) -> tuple:
    """(table, lines) of the tie points between the cameras of one scene, checked and intersected."""
    scene, lines = scene_from(request.scene)
    if len(scene.cameras) < 2:
        raise InputError(f"{request.scene} has one camera ({scene.cameras[0].name}); tie points are matched between "
                         "the cameras of a scene with two or more (a three-line camera such as TH-1 or ZY-3)",
                         parameter="scene")
    images = camera_images(scene, request.images)
    with concerning(IMAGES):
        check_images(scene, images)
    lines += [LogLine(f"camera {scene.cameras[k].name}: {image}") for k, image in images.items()]
    surface, more = surface_from(request.terrain, scene)
    lines += more
    settings = match_settings(request.matching)
    with logged(measure.__name__, lines):
        table, rejected = match_tiepoints(scene, images, surface, settings, 0,
                                          lambda f, m=None: report(0.85 * f, m), is_cancelled)
    check_cancelled(is_cancelled)
    base = scene.cameras[0].name
    for name, counts in rejected.items():
        lines.append(_pair_line(base, name, int((table.camera == name).sum()), counts))
    pairs = tiepoints.summary(table)["pairs"]
    lines.append(LogLine("tie points per camera pair: " + ", ".join(f"{k} {v}" for k, v in pairs.items())))
    report(0.85, f"checking and intersecting {len(table)} observations")
    with logged(tiepoints.__name__, lines):
        table = tiepoints.check_against_scene(table, scene, request.scene, "matched tie points")
    check_cancelled(is_cancelled)
    return table, lines


def _pair_line(base: str, other: str, matched: int, rejected: dict) -> LogLine:
    """Grid points of ``other`` matched against ``base``, rejections by reason."""
    reasons = ", ".join(f"{v} {k}" for k, v in rejected.items() if v) or "none"
    return LogLine(f"{base}-{other}: matched {matched} of {matched + sum(rejected.values())} grid points; rejected: "
                   f"{reasons}")


def _match_block(request: MatchTiesRequest, report, is_cancelled) -> tuple:
    """(table, lines) of the tie points between the first image of the block and every other (its
    scene column naming each observation's scene), reported per scene pair."""
    views, lines = block_views(request.scenes, request.images)
    surface, more = surface_from(request.terrain, views[0].scene)
    lines += more
    settings = match_settings(request.matching)
    with logged(measure.__name__, lines):
        table, rejected = match_block_tiepoints(views, surface, settings, 0,
                                                lambda f, m=None: report(0.9 * f, m), is_cancelled)
    check_cancelled(is_cancelled)
    for view in views[1:]:
        matched = int(np.sum((table.scene == view.scene_name) & (table.camera == view.camera_name)))
        lines.append(_pair_line(views[0].label, view.label, matched, rejected[view.label]))
    pairs = tiepoints.summary(table, by_scene=True)["pairs"]
    lines += [LogLine("tie points per scene pair: " + ", ".join(f"{k} {v}" for k, v in pairs.items())),
              LogLine(BLOCK_SKIPS)]
    return table, lines


def block_views(paths: tuple[str, ...], images: tuple[str, ...]) -> tuple[list[View], list]:
    """(views, log lines) of a block: the scene files ``paths`` (two or more) with ``images``, one raw
    image per scene in the same order, each given to the camera of its size (:func:`image_camera`)."""
    if len(paths) < 2:
        raise InputError(f"{len(paths)} scene given; tie points between scenes need two or more (the cameras of one "
                         "scene: SCENE)", parameter=SCENES)
    block, lines = block_from(paths)
    names = list(block.files)
    if len(images) != len(paths):
        raise InputError(f"{len(images)} raw image(s) given for the {len(paths)} scenes of SCENES "
                         f"({', '.join(names)}): give one image per scene, in that order", parameter=IMAGES)
    views = []
    for name, image in zip(names, images):
        if not image:
            raise InputError(f"the image of scene {name} is not a file (a memory or service layer); save it as "
                             "GeoTIFF first", parameter=IMAGES)
        scene = block.scenes[name]
        with concerning(IMAGES):
            camera = image_camera(name, scene, image, check_input_raster(image))
            check_images(scene, {camera: image})
        lines.append(LogLine(f"scene {name} ({block.files[name]}): camera {scene.cameras[camera].name}, image {image}"))
        views.append(View(name, scene, camera, Path(image)))
    return views, lines


def image_camera(name: str, scene, path: str, size: tuple[int, int]) -> int:
    """The camera of scene ``name`` whose size (cols, rows) is the image's; InputError (IMAGES) when
    none is, or when several are (a multi-camera product: which camera the image is cannot be told)."""
    fits = [k for k, c in enumerate(scene.cameras) if (int(c.cols), int(c.rows)) == size]
    cameras = ", ".join(f"{c.name} {int(c.cols)} x {int(c.rows)}{size_note(c)}" for c in scene.cameras)
    if not fits:
        raise InputError(f"{path} is {size[0]} x {size[1]} px, but no camera of scene {name} has that size "
                         f"({cameras}): give one raw image per scene, in the order of SCENES", parameter=IMAGES)
    if len(fits) > 1:
        raise InputError(f"{path} has the size of {len(fits)} cameras of scene {name} ({cameras}), so which camera "
                         "it is cannot be told: give single-camera products in SCENES (one scene file per image), "
                         "or match the cameras of one scene with SCENE", parameter=IMAGES)
    return fits[0]
