"""pushbroom:simulatescene and pushbroom:simulateblock as use cases (the shape of :mod:`core.runs`: a
request in, a :class:`core.runs.base.RunResult` out): a scene, or a block of scenes, simulated from a
preset sensor into a folder, with known truth."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from ..core.log import LogLine
from ..core.runs.base import RunResult, concerning
from .block import simulate_block
from .layouts import layout_members
from .measurements import GcpSettings
from .presets import PRESETS, cut_preset
from .roads import LINES_FILE, POINTS_FILE, RoadSettings
from .simulator import check_folder, output_names, simulate

# The inputs errors name (InputError.parameter).
IMAGE_SIZE, FOLDER = "image_size", "folder"
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
    when > 0) simulated into ``folder``, with the arguments of :func:`simulation.block.simulate_block`."""
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
    members = layout_members(request.layout, _preset(request.preset, request.image_size))
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


def _optional(path) -> str | None:
    return str(path) if path else None
