"""Scene simulator: a pushbroom acquisition with known truth, deterministic by seed.

A circular sun-synchronous orbit passes (descending) over a synthetic terrain; a preset
camera set images it. Two scene models are written:

- the **true** scene: the geometry that made the measurements;
- the **onboard** scene: what the satellite's own ephemeris, attitude and laboratory
  calibration deliver, i.e. the truth with the simulated errors. Error conventions (the
  adjustment estimates their negatives):
    onboard position(t) = true position(t) + b + d (t - t_c) + q (t - t_c)^2   (ECEF axes, m)
    onboard attitude(t) = true attitude(t) @ R(a(t)),  a(t) = a0 + a1 (t - t_c) + a2 (t - t_c)^2,
                          R = rotation_from_angles(roll, pitch, yaw) in the body frame (rad)
    onboard camera      = the nominal (laboratory) design; the true camera has per-chip
                          shifts (dx, dy), rotations dtheta, the 10 camera terms of Zhang et
                          al. 2015 eq. 7 (principal point, focal length, radial k1 k2,
                          decentring p1 p2, affinity b1 b2 b3) and, for multi-camera sets,
                          installation errors.
  t_c is the strip's mid time. Every drawn value is in ``simulation.json``.

Outputs in the folder: ``onboard_scene.json``, ``true_scene.json``, ``gcps.csv`` (ground
control and check points), ``tie_points.csv`` (multi-camera presets), ``dem.tif`` (EGM96
geoid heights), ``simulation.json`` (settings and truth), and with ``render=True`` one raw
image per camera ``image_<CAMERA>.tif`` (see :mod:`simulation.render`) and the reference orthoimage
``reference.tif`` of the same ground (see :mod:`simulation.reference`). With roads (``n_lines``),
``lines.gpkg`` (road map and image lines) and ``line_points.csv`` (see :mod:`simulation.roads`).

Frames: ECEF metres, times in seconds from the epoch, image coordinates GDAL (col, row).
The focal-plane chips run from right to left across track (nominal theta = pi), so that a
descending pass gives images with north up and east to the right, as delivered products.

This module runs a simulation; its parts: :mod:`simulation.presets` (sensors, orbits, error
magnitudes), :mod:`simulation.geometry` (orbit, attitude, cameras, the two scene models),
:mod:`simulation.terrain` (the DEM), :mod:`simulation.measurements` (GCPs, tie points, CSV),
:mod:`simulation.roads`, :mod:`simulation.render` and :mod:`simulation.reference`.
"""
from __future__ import annotations

import json
import logging
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..core.dem import Dem
from ..core.errors import Cancelled, InputError
from ..core.files import OutputError, atomic_outputs, check_folder_destination, new_folder, write_text
from ..core.formats.scene_json import save_scene
from .geometry import EPOCH, build_scenes, scene_bounds
from .measurements import GCP_COLUMNS, TIE_COLUMNS, GcpSettings, gcp_columns, tie_columns, write_csv
from .presets import PRESETS, ErrorSettings, Preset, resolve_errors
from .reference import REFERENCE_NAME, write_reference
from .render import render_image
from .roads import LINES_FILE, POINTS_FILE, RoadSettings, simulate_roads
from .terrain import set_height_range, write_dem
from .texture import texture_frame

log = logging.getLogger(__name__)

MANIFEST = "simulation.json"       # the settings and truth of a simulation, in its folder


@dataclass
class SimulationResult:
    """Paths of the files written by :func:`simulate`."""
    folder: Path
    onboard_scene: Path
    true_scene: Path
    gcps: Path
    dem: Path
    manifest: Path
    tie_points: Path | None = None
    images: dict = field(default_factory=dict)
    lines: Path | None = None
    reference: Path | None = None


def simulate(preset: "str | Preset", folder, seed: int = 0, n_scenes: int = 1, n_gcps: int = 200,
             image_noise: float = 0.3, render: bool = False, errors: ErrorSettings | dict | None = None,
             gcp_settings: GcpSettings | None = None, progress: Callable[[float, str | None], None] | None = None,
             is_cancelled: Callable[[], bool] | None = None, n_lines: int = 0,
             road_settings: RoadSettings | None = None) -> SimulationResult:
    """Simulate a strip of ``n_scenes`` scenes of ``preset`` (a name of PRESETS, or a Preset of
    one's own, e.g. a small scene for tests) into ``folder`` (created).

    errors: the preset's :class:`ErrorSettings` (None), or another one, or a dict overriding
    some of its fields. gcp_settings: measurement settings; n_gcps and image_noise set its
    fields when it is None. progress(fraction, message) and is_cancelled() report and stop
    long work; on cancel or error nothing is written (every file is renamed into place at the
    end, :class:`core.files.OutputSet`). Files of the same names already in ``folder`` are
    replaced only when an earlier simulation wrote them (:func:`check_folder`).
    n_lines / road_settings: simulated roads, control lines with their truth (:mod:`simulation.roads`);
    n_lines sets the number of roads when road_settings is None.
    """
    if not isinstance(preset, Preset) and preset not in PRESETS:
        raise InputError(f"unknown preset {preset!r} (choose one of {', '.join(PRESETS)})")
    if not 1 <= int(n_scenes) <= 200:
        raise InputError(f"n_scenes must be between 1 and 200 (got {n_scenes})")
    spec = preset if isinstance(preset, Preset) else PRESETS[preset]
    errors = resolve_errors(spec, errors)
    settings = gcp_settings or GcpSettings(n_gcps=int(n_gcps), image_noise=float(image_noise))
    settings.validate()
    if settings.n_tie_points and len(spec.cameras) < 2:
        raise InputError(f"tie points need a preset with several cameras ({preset} has one)")
    report = progress or (lambda fraction, message=None: None)
    cancelled = is_cancelled or (lambda: False)
    roads = road_settings or RoadSettings(n_lines=int(n_lines))
    roads.validate()
    folder = Path(folder)
    check_folder(folder, output_names(spec, settings, render) + ([LINES_FILE, POINTS_FILE] if roads.n_lines else []))
    with new_folder(folder):
        return _simulate(spec, folder, seed, int(n_scenes), render, errors, settings, report, cancelled, roads)


def _simulate(spec: Preset, folder: Path, seed: int, n_scenes: int, render: bool, errors: ErrorSettings,
              settings: GcpSettings, report, cancelled, roads: RoadSettings) -> SimulationResult:
    """:func:`simulate` once its arguments are checked and ``folder`` exists."""
    preset = spec.name
    rng = np.random.default_rng(seed)

    def step(fraction: float, message: str) -> None:
        if cancelled():
            raise Cancelled("simulation cancelled by the user")
        report(fraction, message)
        log.info(message)

    with atomic_outputs() as files:
        step(0.0, f"building the {preset} strip of {n_scenes} scene(s)")
        geo = build_scenes(spec, int(n_scenes), errors, rng)
        step(0.1, "writing the terrain")
        dem_tmp = files.path(folder / "dem.tif")
        bounds = scene_bounds(geo.true, tuple(geo.true.height_range))
        write_dem(dem_tmp, bounds, spec.centre, spec.relief, seed)
        dem = Dem(dem_tmp, datum="geoid")
        set_height_range((geo.true, geo.onboard), dem)
        step(0.3, f"measuring {settings.n_gcps} ground control points")
        gcp_data = gcp_columns(geo.true, dem, settings, int(n_scenes), rng)
        gcp_tmp = files.path(folder / "gcps.csv")
        write_csv(gcp_tmp, GCP_COLUMNS, gcp_data)
        tie_tmp = None
        if settings.n_tie_points:
            step(0.5, f"measuring {settings.n_tie_points} tie points")
            tie = tie_columns(geo.true, dem, settings, int(n_scenes), rng)
            tie_tmp = files.path(folder / "tie_points.csv")
            write_csv(tie_tmp, TIE_COLUMNS, tie)
        road_truth = None
        if roads.n_lines:
            step(0.55, f"drawing {roads.n_lines} roads (control lines)")
            road_truth = simulate_roads(geo.true, dem, roads, seed, folder, files)
        step(0.6, "writing the scene models")
        save_scene(geo.true, folder / "true_scene.json", files)
        save_scene(geo.onboard, folder / "onboard_scene.json", files)
        images, frame = {}, None
        if render:
            frame = texture_frame(geo.true, dem, seed)
            frame["roads"] = road_truth
            for k, cam in enumerate(geo.true.cameras):
                path = files.path(folder / f"image_{cam.name}.tif")
                base = 0.65 + 0.35 * k / len(geo.true.cameras)
                step(base, f"rendering the {cam.name} image ({cam.cols} x {cam.rows})")
                frame.setdefault("interpolation_error_px", {})[cam.name] = render_image(
                    geo.true, k, dem, path, frame,
                    progress=lambda f, b=base: report(b + f * 0.35 / len(geo.true.cameras), None),
                    is_cancelled=cancelled)
                images[cam.name] = folder / f"image_{cam.name}.tif"
            step(0.99, "writing the reference orthoimage")
            frame["reference"] = write_reference(geo.true, dem, frame, files.path(folder / REFERENCE_NAME), seed,
                                                 is_cancelled=cancelled)
        manifest = {"preset": preset, "seed": seed, "n_scenes": int(n_scenes), "epoch": EPOCH,
                    "errors": asdict(errors), "measurements": asdict(settings), "truth": geo.truth,
                    "texture": frame, "roads": road_truth,
                    "conventions": __doc__.split("\n\n")[1].strip(),
                    "files": {"true_scene": "true_scene.json", "onboard_scene": "onboard_scene.json",
                              "gcps": "gcps.csv", "dem": "dem.tif (EGM96 geoid heights)",
                              "tie_points": "tie_points.csv" if tie_tmp else None,
                              "lines": LINES_FILE if road_truth else None,
                              "line_points": POINTS_FILE if road_truth else None,
                              "images": {k: v.name for k, v in images.items()},
                              "reference": frame["reference"]["file"] if render else None}}
        write_text(folder / MANIFEST, json.dumps(manifest, indent=1), files)
    report(1.0, "simulation written")
    return SimulationResult(folder, folder / "onboard_scene.json", folder / "true_scene.json", folder / "gcps.csv",
                            folder / "dem.tif", folder / MANIFEST,
                            folder / "tie_points.csv" if settings.n_tie_points else None, images,
                            folder / LINES_FILE if road_truth else None,
                            folder / "reference.tif" if render else None)


def output_names(spec: Preset, settings: GcpSettings, render: bool) -> list[str]:
    """Names of the files :func:`simulate` writes into its folder with these settings."""
    names = ["dem.tif", "gcps.csv", "true_scene.json", "onboard_scene.json", MANIFEST]
    if settings.n_tie_points:
        names.append("tie_points.csv")
    return names + ([f"image_{cam.name}.tif" for cam in spec.cameras] + ["reference.tif"] if render else [])


def check_folder(folder, names, manifest: str = MANIFEST,
                 listed: Callable[[Path], set[str]] | None = None) -> None:
    """OutputError unless ``folder`` (existing or not) can take the files ``names`` (paths
    relative to it): each one it already holds must be a file an earlier simulation wrote there
    (listed in its manifest, ``manifest``: simulation.json, read by ``listed(folder)``, default
    :func:`simulate`'s reader) and not modified since; anything else is a user's file, never
    replaced."""
    folder = Path(folder)
    check_folder_destination(folder)
    present = [n for n in names if (folder / n).exists() or (folder / n).is_symlink()]
    if not present:
        return
    ours = (listed or _simulated_files)(folder)
    manifest_time = (folder / manifest).stat().st_mtime_ns if ours else 0
    foreign = [n for n in present if n not in ours or not (folder / n).is_file()
               or (folder / n).stat().st_mtime_ns > manifest_time]
    if foreign:
        raise OutputError(f"{folder} holds {', '.join(foreign)}, which no earlier simulation there wrote (or which "
                          "were changed since): they are not replaced; choose an empty folder or move them")


def _simulated_files(folder: Path) -> set[str]:
    """Names of the files an earlier simulation wrote into ``folder`` (its manifest included),
    from its simulation.json; empty when there is none or it is not a simulator's manifest."""
    try:
        manifest = json.loads((folder / MANIFEST).read_text())
        listed = manifest["files"]
        names = [listed[k] for k in ("true_scene", "onboard_scene", "gcps", "dem", "tie_points")]
        names += list(listed["images"].values()) + [listed.get("reference")]
        names += [listed.get("lines"), listed.get("line_points")]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return set()
    return {MANIFEST, *(n.split(" ")[0] for n in names if isinstance(n, str))}
