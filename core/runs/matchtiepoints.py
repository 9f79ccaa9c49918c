"""pushbroom:matchtiepoints as a use case: tie points matched between the cameras of a three-line
scene (or strip), or between the raw images of the scenes of a block, in a common ground geometry
(:mod:`core.measure.tiematching`), written as the tie-point layer the adjustment reads. A block is
matched on its overlap graph (:mod:`core.measure.pairmatching`): every pair of images whose
footprints overlap, the pairs' ties chained into multi-image points.

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
from ..measure.pairmatching import MIN_PAIR_TIES, PairReport, match_overlap_graph, overlap_pairs, weak_pairs
from ..measure.tiematching import View, match_tiepoints, refuse_shared_images
from ..model.rpcscene import size_note
from ..observations import tiepoints
from ..observations.tiechains import ChainResult
from ..products.overlaps import disconnection, tied_graph
from ..products.ortho import check_images
from ..rasters import check_input_raster
from .base import IMAGES, FilesInUse, RunResult, Terrain, camera_images, concerning, logged, scene_from, surface_from
from .layers import OUTPUT, check_cancelled, check_gpkg, write_ties
from .matchgcps import match_settings
from .region import block_images
from .scenes import SCENES, block_from

BLOCK_SKIPS = ("block of scenes: the checks against one scene (cameras, image bounds, onboard forward intersection, "
               "likely mismatches) do not apply and were skipped; the layer holds no a-priori intersection (rays "
               "and residuals empty)")


@dataclass(frozen=True)
class MatchTiesRequest:
    """Tie points between the cameras of the scene file ``scene`` or, with ``scenes`` (product
    files, folders or list files), between the images of the block's scenes on its overlap graph;
    ``images``: one raw image per camera of the scene, in its camera order, or per scene of the
    block, in its order (none: found beside each product). Heights from the terrain, matching
    settings ``matching`` ({:class:`core.measure.matching.MatchSettings` field: value}); written to
    ``output``. A block's pairs run on the Dask scheduler at ``scheduler`` (an address), else on
    ``processes`` local processes (0: one per core; 1: one after the other in this process)."""
    output: str
    images: tuple[str, ...]
    scene: str = ""
    scenes: tuple[str, ...] = ()
    terrain: Terrain = Terrain()
    matching: dict = field(default_factory=dict)
    files: FilesInUse = field(default_factory=FilesInUse)
    scheduler: str = ""
    processes: int = 0


def run(request: MatchTiesRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Match as ``request`` says: files {OUTPUT}, figures the table's summary
    (:func:`core.observations.tiepoints.summary`)."""
    report = progress or (lambda fraction, message=None: None)
    check_gpkg(request.output, "tie-point layers", request.files)
    figures = {}
    if request.scenes:
        table, lines, figures = _match_block(request, report, is_cancelled)
    else:
        table, lines = _match_scene(request, report, is_cancelled)
    lines += write_ties(table, request.output, by_scene=bool(request.scenes))
    report(1.0)
    return RunResult({OUTPUT: request.output}, {**tiepoints.summary(table, bool(request.scenes)), **figures}, lines)


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
    """(table, lines, figures) of the tie points of a block on its overlap graph
    (:mod:`core.measure.pairmatching`): every overlapping pair of images matched, the ties chained
    into multi-image points (the scene column naming each observation's scene), reported per pair.
    InputError naming the products the footprints or the ties leave apart from the others."""
    views, lines, files = block_views(request.scenes, request.images)
    surface, more = surface_from(request.terrain, views[0].scene)
    lines += more
    settings = match_settings(request.matching)
    with logged(measure.__name__, lines):
        graph = overlap_pairs(views, surface)
        report(0.05, f"{len(graph.pairs)} overlapping pairs of {len(views)} images")
        chained, reports = match_overlap_graph(views, graph, surface, settings, scheduler=request.scheduler,
                                               processes=request.processes, scene_files=files,
                                               progress=lambda f, m=None: report(0.05 + 0.85 * f, m),
                                               is_cancelled=is_cancelled)
    check_cancelled(is_cancelled)
    lines += [_graph_pair_line(r) for r in reports]
    apart = disconnection(tied_graph(graph, np.array([r.chained > 0 for r in reports], bool)))
    if apart:
        raise InputError(f"the tie points do not connect the block: {apart}; no tie of their pairs was kept "
                         f"({'; '.join(f'{r.first}-{r.second}: {r.why}' for r in reports if not r.chained)}). "
                         "A product the ties leave apart would be adjusted on its own: leave it out, or match "
                         "with other settings (quality threshold, window, search range)", parameter=SCENES)
    table = chained.table
    pairs = tiepoints.summary(table, by_scene=True)["pairs"]
    lines += [LogLine("tie points per scene pair: " + ", ".join(f"{k} {v}" for k, v in pairs.items())),
              LogLine(BLOCK_SKIPS)]
    return table, lines, pair_figures(reports, chained)


def _graph_pair_line(r: PairReport) -> LogLine:
    """One pair of the overlap graph: its overlap, grid points matched, rejections by reason, ties
    refused in inconsistent chains; or why it could not be matched (a warning)."""
    if r.failure:
        return LogLine(f"{r.first}-{r.second}: not matched ({r.failure}); overlap {r.overlap_km2:.2f} km2", True,
                       SCENES)
    chains = f"; {r.refused_in_chains} refused in inconsistent chains" if r.refused_in_chains else ""
    line = _pair_line(r.first, r.second, r.matched, r.rejected)
    return LogLine(f"{line.text}{chains}; overlap {r.overlap_km2:.2f} km2")


def pair_figures(reports: list[PairReport], chained: ChainResult) -> dict:
    """The run's figures on the overlap graph: per pair (overlap km², grid points, matched,
    rejected by reason, refused in chains, chained, failure), the pairs with fewer than
    MIN_PAIR_TIES chained ties, the chains refused and the points by number of images."""
    return {"overlap_pairs": [{"pair": f"{r.first}-{r.second}", "overlap_km2": round(r.overlap_km2, 3),
                               "grid_points": r.grid_points, "matched": r.matched, "rejected": dict(r.rejected),
                               "refused_in_chains": r.refused_in_chains, "chained": r.chained,
                               "failure": r.failure} for r in reports],
            "weak_pairs": [f"{r.first}-{r.second}" for r in weak_pairs(reports, MIN_PAIR_TIES)],
            "min_pair_ties": MIN_PAIR_TIES, "inconsistent_chains": chained.inconsistent_chains,
            "points_by_rays": dict(chained.points_by_rays)}


def block_views(paths: tuple[str, ...], images: tuple[str, ...]) -> tuple[list[View], list, dict]:
    """(views, log lines, {scene name: its file}) of a block: the SCENES ``paths`` (product files,
    folders or list files: :func:`core.runs.region.expand_scenes`; two or more products) with
    ``images``, one raw image per scene in the same order, each given to the camera of its size
    (:func:`image_camera`); no ``images``, a folder or a list file of them:
    :func:`core.runs.region.block_images`."""
    block, lines = block_from(paths)
    names = list(block.files)
    if len(names) < 2:
        raise InputError(f"{len(names)} scene given; tie points between scenes need two or more (the cameras of one "
                         "scene: SCENE)", parameter=SCENES)
    images = block_images(images, block)
    if len(images) != len(names):
        raise InputError(f"{len(images)} raw image(s) given for the {len(names)} scenes of SCENES "
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
    refuse_shared_images(views)
    return views, lines, dict(block.files)


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
