"""pushbroom:simulatescene and pushbroom:simulateblock as use cases (the shape of :mod:`core.runs`: a
request in, a :class:`core.runs.base.RunResult` out): a scene, or a block of scenes, simulated from a
preset sensor into a folder, with known truth."""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Callable

from ..core.errors import InputError
from ..core.log import LogLine
from ..core.runs.base import RunResult, concerning
from .block import simulate_block
from .layouts import layout_members
from .measurements import GcpSettings
from .presets import PRESETS, cut_preset
from .region import RegionLayout, region_members
from .roads import LINES_FILE, POINTS_FILE, RoadSettings
from .rpcregion import RegionSettings, simulate_region
from .simulator import check_folder, output_names, simulate

# The inputs errors name (InputError.parameter).
IMAGE_SIZE, FOLDER = "image_size", "folder"
N_TIE_POINTS, RENDER = "n_tie_points", "render"
# The files of the results (the provider's output names).
OUTPUT_FOLDER, ONBOARD_SCENE, TRUE_SCENE, GCPS, DEM = "OUTPUT_FOLDER", "ONBOARD_SCENE", "TRUE_SCENE", "GCPS", "DEM"
TIE_POINTS, LINES, MANIFEST, IMAGE, IMAGES = "TIE_POINTS", "LINES", "MANIFEST", "IMAGE", "IMAGES"
REFERENCE, SCENES, TRUE_SCENES = "REFERENCE", "SCENES", "TRUE_SCENES"


@dataclass(frozen=True)
class SimulateSceneRequest:
    """A strip of ``n_scenes`` scenes of preset ``preset`` (a name of PRESETS; with ``image_size``
    > 0 its cameras cut to that many detectors and lines) simulated into ``folder`` from ``seed``:
    ``errors`` {ErrorSettings field: value, SI units} override the preset's, ``gcps`` and ``roads``
    say what is measured; ``render``: the raw images and the reference orthoimage too."""
    folder: str
    preset: str
    seed: int = 0
    n_scenes: int = 1
    render: bool = False
    errors: dict = field(default_factory=dict)
    gcps: GcpSettings = field(default_factory=GcpSettings)
    roads: RoadSettings = field(default_factory=RoadSettings)
    image_size: int = 0


@dataclass(frozen=True)
class SimulateBlockRequest:
    """A block of layout ``layout`` (simulation.layouts) of preset ``preset`` (cut to ``image_size``
    when > 0) simulated into ``folder``, with the arguments of :func:`simulation.block.simulate_block`.
    The region layouts (simulation.layouts.REGION_LAYOUTS) take ``region`` (:class:`simulation.region.RegionLayout`);
    'rpc_region' (:func:`simulation.rpcregion.simulate_region`, no images) also
    ``ties_per_product`` instead of n_tie_points, and n_gcps (0: 4 per product)."""
    folder: str
    preset: str
    layout: str
    seed: int = 0
    n_gcps: int = 60
    n_tie_points: int = 200
    image_noise: float = 0.3
    render: bool = False
    check_fraction: float = 0.25
    image_size: int = 0
    region: RegionLayout = field(default_factory=RegionLayout)
    ties_per_product: int = 2000


def _preset(name: str, size: int):
    """The preset of ``name``, its cameras cut to ``size`` when > 0 (errors concern IMAGE_SIZE)."""
    if not size:
        return PRESETS[name]
    with concerning(IMAGE_SIZE):
        return cut_preset(PRESETS[name], size, size)


def run_scene(request: SimulateSceneRequest, progress: Callable[[float, str | None], None] | None = None,
              is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Simulate a scene as ``request`` says, the folder checked first (a user's files there are
    kept); files {OUTPUT_FOLDER, ONBOARD_SCENE, TRUE_SCENE, GCPS, DEM, TIE_POINTS, LINES, MANIFEST,
    IMAGE, IMAGES, REFERENCE} (None for files not written)."""
    spec = _preset(request.preset, request.image_size)
    with concerning(FOLDER):
        check_folder(request.folder, output_names(spec, request.gcps, request.render)
                     + ([LINES_FILE, POINTS_FILE] if request.roads.n_lines else []))
    result = simulate(spec if request.image_size else request.preset, request.folder, seed=request.seed,
                      n_scenes=request.n_scenes, render=request.render, errors=request.errors,
                      gcp_settings=request.gcps, road_settings=request.roads, progress=progress,
                      is_cancelled=is_cancelled)
    written = (result.onboard_scene, result.true_scene, result.gcps, result.dem, result.tie_points, result.lines,
               *result.images.values())
    line = LogLine(f"simulated {spec.name if request.image_size else request.preset} into {request.folder}: "
                   + ", ".join(p.name for p in written if p is not None))
    images = [str(path) for path in result.images.values()]
    files = {OUTPUT_FOLDER: request.folder, ONBOARD_SCENE: str(result.onboard_scene),
             TRUE_SCENE: str(result.true_scene), GCPS: str(result.gcps), DEM: str(result.dem),
             TIE_POINTS: _optional(result.tie_points), LINES: _optional(result.lines),
             MANIFEST: str(result.manifest), IMAGE: images[0] if images else None, IMAGES: images,
             REFERENCE: _optional(result.reference)}
    return RunResult(files, {}, [line])


def run_block(request: SimulateBlockRequest, progress: Callable[[float, str | None], None] | None = None,
              is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Simulate a block as ``request`` says; files {OUTPUT_FOLDER, SCENES (each scene's product: its
    onboard scene JSON, or an RPC product's RPC file), TRUE_SCENES, IMAGES, GCPS, TIE_POINTS, DEM,
    REFERENCE, MANIFEST}, a line per scene."""
    if request.layout == "rpc_region":
        return run_rpc_region(request, progress, is_cancelled)
    spec = _preset(request.preset, request.image_size)
    members = (region_members(request.region, spec) if request.layout == "region"
               else layout_members(request.layout, spec))
    result = simulate_block(members, request.folder, seed=request.seed, n_gcps=request.n_gcps,
                            n_tie_points=request.n_tie_points, image_noise=request.image_noise,
                            render=request.render, check_fraction=request.check_fraction, progress=progress,
                            is_cancelled=is_cancelled)
    scenes, images, lines = [], [], []
    for name, files in result.members.items():
        product = next(iter(files["rpc"].values())) if files.get("rpc") else files["onboard_scene"]
        scenes.append(str(product))
        images += [str(p) for p in files["images"].values()]
        lines.append(LogLine(f"scene {name}: {product}" + (f", image {', '.join(map(str, files['images'].values()))}"
                                                            if files["images"] else "")))
    return RunResult({OUTPUT_FOLDER: request.folder, SCENES: scenes,
                      TRUE_SCENES: [str(f["true_scene"]) for f in result.members.values()], IMAGES: images,
                      GCPS: str(result.gcps), TIE_POINTS: _optional(result.tie_points), DEM: str(result.dem),
                      REFERENCE: _optional(result.reference), MANIFEST: str(result.manifest)}, {}, lines)


def run_rpc_region(request: SimulateBlockRequest, progress=None, is_cancelled=None) -> RunResult:
    """The 'rpc_region' layout: RPC products without images (:func:`simulation.rpcregion.simulate_region`);
    the files of :func:`run_block` (SCENES the RPC files, TRUE_SCENES the true RPC scene JSONs, no
    IMAGES nor REFERENCE), one line for the region."""
    if request.render:
        raise InputError("the layout rpc_region has no images (its tie observations are simulated directly); "
                         "for a rendered region choose the layout region", parameter=RENDER)
    if request.n_tie_points:
        raise InputError("the layout rpc_region takes TIES_PER_PRODUCT (tie observations per product), not a "
                         "number of tie points: leave N_TIE_POINTS at 0", parameter=N_TIE_POINTS)
    settings = RegionSettings(ties_per_product=request.ties_per_product, n_gcps=request.n_gcps or None,
                              check_fraction=request.check_fraction, image_noise=request.image_noise)
    spec = _preset(request.preset, request.image_size)
    result = simulate_region(request.region, request.folder, spec, request.seed, settings, progress, is_cancelled)
    counts = json.loads(result.manifest.read_text())["points"]
    line = LogLine(f"region of {len(result.products)} RPC products ({request.region.strips} strips x "
                   f"{request.region.products_per_strip}) in {request.folder}: {counts['tie_points']} tie points, "
                   f"{counts['tie_observations']} tie observations, {counts['check_points']} check and "
                   f"{counts['control_points']} control points")
    return RunResult({OUTPUT_FOLDER: request.folder, SCENES: [str(p) for p in result.products.values()],
                      TRUE_SCENES: [str(p) for p in result.truth.values()], IMAGES: [], GCPS: str(result.gcps),
                      TIE_POINTS: str(result.tie_points), DEM: str(result.dem), REFERENCE: None,
                      MANIFEST: str(result.manifest)}, {}, [line])


def _optional(path) -> str | None:
    return str(path) if path else None
