"""pushbroom:footprint as a use case: the ground outline of each camera's image on the terrain, or
of every product of a block (SCENES: files, folders, list files), so that a region is seen on the
map before any matching or adjustment."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..errors import Cancelled, InputError
from ..log import LogLine
from ..products.footprint import footprints
from ..products.overlaps import GEOD, Outline, disconnection, overlap_graph, product_outline
from .base import DEM, FilesInUse, RunResult, Terrain, concerning, scene_from, surface_from
from .scenes import SCENES, block_from


@dataclass(frozen=True)
class FootprintRequest:
    """The outlines of every camera of the scene file ``scene`` or, with ``scenes`` (product files,
    folders or list files), of every product of the block, on ``terrain``, each image edge divided
    into ``samples`` intervals; ``files``: the files around the run (the outputs are checked first)."""
    scene: str = ""
    terrain: Terrain = Terrain()
    samples: int = 256
    files: FilesInUse = field(default_factory=FilesInUse)
    scenes: tuple[str, ...] = ()


@dataclass(frozen=True)
class ProductFootprint:
    """One product of a block on the ground: its name, file, cameras' names, outline (lon, lat deg
    WGS84 (m,), the union of its cameras' footprints), geodesic area (km²) and the names of the
    products its outline overlaps."""
    name: str
    file: str
    cameras: tuple[str, ...]
    lon: np.ndarray
    lat: np.ndarray
    area_km2: float
    overlaps: tuple[str, ...]


def run(request: FootprintRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Figures {'footprints': [core.products.footprint.Footprint per camera, in camera order]} for a
    scene, or {'products': [ProductFootprint per product, in SCENES order], 'pairs': number of
    overlapping pairs} for a block; a warning line (about the DEM) for each outline the terrain
    leaves partly without heights, and for a block that the overlaps do not connect (naming the
    products of other ground and the groups). No files: the caller writes the outlines."""
    request.files.check({})
    report = progress or (lambda fraction, message=None: None)
    cancelled = is_cancelled or (lambda: False)
    if request.scenes:
        return _block(request, report, cancelled)
    scene, lines = scene_from(request.scene)
    surface, more = surface_from(request.terrain, scene)
    lines += more
    outlines = []
    for k, camera in enumerate(scene.cameras):
        _check(cancelled)
        report(k / len(scene.cameras), f"camera {camera.name}")
        (outline,) = footprints(scene, surface, cameras=[k], samples_per_edge=request.samples)
        lines += [LogLine(outline.note, True, DEM)] if outline.note else []
        outlines.append(outline)
    return RunResult({}, {"footprints": outlines}, lines)


def _check(cancelled: Callable[[], bool]) -> None:
    if cancelled():
        raise Cancelled("cancelled by the user")


def _block(request: FootprintRequest, report, cancelled) -> RunResult:
    """The footprint of every product of the block ``request.scenes`` (see :func:`run`)."""
    block, lines = block_from(request.scenes)
    names = list(block.files)
    surface, more = surface_from(request.terrain, block.scenes[names[0]])
    lines += more
    outlines = []
    for n, name in enumerate(names):
        _check(cancelled)
        report(0.9 * n / len(names), f"product {name}")
        scene = block.scenes[name]
        try:
            cameras = footprints(scene, surface, samples_per_edge=request.samples)
        except InputError as exc:
            raise InputError(f"{name}: {exc}", parameter="dem") from None
        lines += [LogLine(f"{name}: {c.note}", True, DEM) for c in cameras if c.note]
        with concerning(SCENES):
            outlines.append(product_outline(name, [c.lon for c in cameras], [c.lat for c in cameras]))
    graph = overlap_graph(outlines)
    partners = {name: [] for name in names}
    for a, b in graph.pair_names():
        partners[a].append(b)
        partners[b].append(a)
    products = [ProductFootprint(o.name, block.files[o.name], tuple(c.name for c in block.scenes[o.name].cameras),
                                 o.lon, o.lat, _area_km2(o), tuple(partners[o.name])) for o in outlines]
    lines.append(LogLine(f"{len(names)} products, {len(graph.pairs)} overlapping pairs"))
    apart = disconnection(graph) if len(names) > 1 else ""
    if apart:
        lines.append(LogLine(f"the block is not connected by overlaps: {apart}; matching and adjusting it as one "
                             "block will be refused", True, SCENES))
    return RunResult({}, {"products": products, "pairs": len(graph.pairs)}, lines)


def _area_km2(outline: Outline) -> float:
    """Geodesic area (km²) of an outline's ring."""
    area, _ = GEOD.polygon_area_perimeter(outline.lon, outline.lat)
    return abs(area) / 1e6
