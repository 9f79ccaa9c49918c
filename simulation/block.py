"""Blocks of several independent scenes over one ground, with known truth: stereo and tri-stereo
from one pass (the platform pitched forward and back), neighbour orbits (rolled, or offset across
track), other dates (other radiometry, changed land cover) and other sensors (other presets).

Each member is a simulated scene of its own (:func:`simulation.geometry.build_scenes`): its own
orbit, pointing, trajectory and interior errors, drawn from its own random stream
(``default_rng([seed, 1, index])``); the error conventions are :mod:`simulation.simulator`'s, with
t = 0 the middle of the member's imaging span. All members look at one ground centre, the first
member's preset centre on the terrain: its pitch shifts along track, its roll across track, where
its orbit passes (:func:`simulation.geometry.aim_pass_point`); ``orbit_offset_km`` then moves the
whole acquisition across track (its strip and the ground it sees), for side-lapping strips, and
``along_track_km`` along it, for the consecutive products of a strip (:mod:`simulation.region`). They
share one terrain, one ground texture frame (a ground point looks alike in all of them, apart from
each date's radiometry, :mod:`simulation.radiometry`) and one set of ground points
(:mod:`simulation.blockpoints`).

Files in the folder: ``dem.tif`` (EGM96 geoid heights) covering every member; ``gcps.csv``
(control and check points, one row per scene and camera seeing a point, the same id in each, a
``scene`` column with the member's name, truth in col_true/row_true/lon_true/lat_true/h_true);
``tie_points.csv`` (points seen by at least two scenes, same columns as :func:`simulate`'s);
``block.json`` (members, their drawn truth, radiometry, files); per member a folder ``<name>/`` with
``onboard_scene.json`` and ``true_scene.json`` and, rendered, ``image_<CAMERA>.tif``. An RPC member
(``rpc=True``) is delivered as an RPC product: its onboard scene fitted by RPC00B models over the
DEM's heights, ``<name>/<name>_RPC.TXT`` (``<name>_<CAMERA>_RPC.TXT`` for several cameras) with the
fit report beside it (``.json``), and its images named ``<name>.tif`` (``<name>_<CAMERA>.tif``) so
that GDAL and :func:`core.formats.rpcfiles.read_rpc_text` pair image and RPC by name; its scene
JSONs are still written, as truth. ``reference.tif`` (rendered blocks): the reference orthoimage
of the first member's ground (:mod:`simulation.reference`).

Frames: ECEF metres, times in seconds from each member's epoch, image coordinates GDAL (col, row).
"""
from __future__ import annotations

import json
import logging
from contextlib import ExitStack
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..core.dem import Dem, to_ellipsoidal
from ..core.errors import Cancelled, InputError
from ..core.files import atomic_outputs, write_text
from ..core.formats.rpcfiles import write_rpc
from ..core.formats.scene_json import save_scene
from ..core.products.rpcfit import dem_height_range, fit_rpc
from .blockmembers import BlockMember, ResolvedMember, aim_member, check_members, member_files
from .blockpoints import MAX_ROUNDS, POOL, block_bounds, block_gcp_columns, block_tie_columns, place_block_points
from .geometry import build_scenes
from .measurements import GCP_COLUMNS, TIE_COLUMNS, GcpSettings, write_csv
from .memory import refuse_beyond_memory
from .radiometry import Radiometry, draw_radiometry
from .reference import REFERENCE_NAME, write_reference
from .render import TILE_ROWS, render_image
from .simulator import check_folder, new_folder
from .terrain import set_height_range, terrain_heights, write_dem
from .texture import texture_frame, texture_plane

log = logging.getLogger(__name__)

BLOCK_MANIFEST = "block.json"
# Bytes held per image observation of a point (its columns as arrays, then as CSV text), per
# candidate point and scene (the visibility test), per rendered pixel of a tile (a few float64
# planes: ground, texture, radiometry) and per member (its scene models and figures).
OBSERVATION_BYTES, CANDIDATE_BYTES, TILE_PIXEL_BYTES, MEMBER_BYTES = 400, 2, 100, 2e6


@dataclass
class BlockResult:
    """Paths of the files written by :func:`simulate_block`: shared ones, and per member name a
    dict with onboard_scene, true_scene, images ({camera: path}) and rpc ({camera: path})."""
    folder: Path
    manifest: Path
    dem: Path
    gcps: Path
    tie_points: Path | None
    members: dict = field(default_factory=dict)
    reference: Path | None = None


def simulate_block(members: list[BlockMember], folder, seed: int = 0, n_gcps: int = 60, n_tie_points: int = 200,
                   image_noise: float = 0.3, render: bool = False, check_fraction: float = 0.25,
                   gcp_settings: GcpSettings | None = None,
                   progress: Callable[[float, str | None], None] | None = None,
                   is_cancelled: Callable[[], bool] | None = None) -> BlockResult:
    """Simulate a block of ``members`` (one or more :class:`BlockMember`; as many as this machine's
    memory holds, :func:`check_block_memory`) into ``folder`` (created).

    n_gcps: ground points (control and, a share ``check_fraction`` of them, check points) seen by at
    least one member; n_tie_points: ground points seen by at least two; image_noise: standard
    deviation (px) of every image measurement. gcp_settings (:class:`GcpSettings`) replaces these
    four when given (gross errors, ground noise). render: the images and the reference orthoimage.
    progress(fraction, message) and is_cancelled() report and stop long work; on cancel or error
    nothing is written (:class:`core.files.OutputSet`), and folders made for the block are removed.
    Files already in ``folder`` are replaced only when an earlier block simulation wrote them.
    InputError names the member field at fault (``members[i].<field>``).
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed must be a whole number >= 0 (got {seed!r})", parameter="seed")
    resolved = check_members(members)
    settings = gcp_settings or GcpSettings(n_gcps=int(n_gcps), image_noise=float(image_noise),
                                           check_fraction=float(check_fraction), n_tie_points=int(n_tie_points))
    settings.validate()
    if settings.n_tie_points and len(resolved) < 2:
        raise InputError("tie points need at least two members in the block", parameter="n_tie_points")
    check_block_memory(resolved, settings, render)
    folder = Path(folder)
    check_folder(folder, output_names(resolved, settings, render), BLOCK_MANIFEST, block_files)
    report = progress or (lambda fraction, message=None: None)
    cancelled = is_cancelled or (lambda: False)
    with ExitStack() as folders:
        folders.enter_context(new_folder(folder))
        for m in resolved:
            folders.enter_context(new_folder(folder / m.name))
        return _simulate_block(resolved, folder, int(seed), settings, render, report, cancelled)


def block_memory(members: list[ResolvedMember], settings: GcpSettings, render: bool) -> float:
    """Bytes a block simulation holds at its peak, at most: every point observed in every camera of
    every member (an upper bound: a point of a wide block is seen by a few), the candidate points'
    visibility in every member, the members' models and, rendered, the largest image (its tiles
    wait to be written) and the tiles being rendered."""
    cameras = sum(len(m.spec.cameras) for m in members)
    need = (settings.n_gcps + settings.n_tie_points) * cameras * OBSERVATION_BYTES
    need += len(members) * (POOL * MAX_ROUNDS * CANDIDATE_BYTES + MEMBER_BYTES)
    if render:
        sizes = [(c.cols, m.spec.scene_rows) for m in members for c in m.spec.cameras]
        need += max(cols * rows + 2 * TILE_ROWS * cols * TILE_PIXEL_BYTES for cols, rows in sizes)
    return float(need)


def check_block_memory(members: list[ResolvedMember], settings: GcpSettings, render: bool) -> None:
    """InputError (parameter 'members') before any work when :func:`block_memory` exceeds what this
    machine can give (:func:`simulation.memory.refuse_beyond_memory`)."""
    points = settings.n_gcps + settings.n_tie_points
    refuse_beyond_memory(block_memory(members, settings, render), "members",
                         f"a block of {len(members)} members with {points} ground points"
                         + (" rendered" if render else "") + f" (at most {OBSERVATION_BYTES} bytes per point and "
                         "camera" + (", the largest image and its tiles" if render else "") + ")")


def output_names(members: list[ResolvedMember], settings: GcpSettings, render: bool) -> list[str]:
    """Paths (relative to the folder) of the files :func:`simulate_block` writes."""
    names = ["dem.tif", "gcps.csv", BLOCK_MANIFEST] + (["tie_points.csv"] if settings.n_tie_points else [])
    names += [REFERENCE_NAME] if render else []
    for m in members:
        files = member_files(m, render)
        names += [files["true_scene"], files["onboard_scene"], *files["images"].values()]
        names += [p for rpc in files["rpc"].values() for p in (rpc, f"{rpc}.json")]
    return names


def block_files(folder: Path) -> set[str]:
    """Paths (relative to ``folder``) an earlier block simulation wrote there, from its block.json
    (every file named under 'files'); empty when there is none or it is not a block manifest."""
    try:
        listed = json.loads((folder / BLOCK_MANIFEST).read_text())["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return set()
    names, todo = set(), [listed]
    while todo:  # a few nested dicts
        item = todo.pop()
        if isinstance(item, dict):
            todo.extend(item.values())
        elif isinstance(item, str):
            names.add(item.split(" ")[0])
    return names | {BLOCK_MANIFEST} if names else set()


def _simulate_block(members: list[ResolvedMember], folder: Path, seed: int, settings: GcpSettings, render: bool,
                    report, cancelled) -> BlockResult:
    """:func:`simulate_block` once its arguments are checked and the folders exist."""
    def step(fraction: float, message: str) -> None:
        if cancelled():
            raise Cancelled("simulation cancelled by the user")
        report(fraction, message)
        log.info(message)

    first = members[0].spec
    centre = first.centre
    # The common centre's ellipsoidal height, from the terrain the DEM will hold (EGM96 to the
    # ellipsoid), so that the views meet there and not at a height hundreds of metres off.
    geoid_h = float(terrain_heights(np.array([centre[0]]), np.array([centre[1]]), centre, first.relief, seed)[0])
    target_h = float(to_ellipsoidal(centre[0], centre[1], geoid_h, "geoid"))
    with atomic_outputs() as files:
        for i, m in enumerate(members):
            step(0.02 + 0.1 * i / len(members), f"aiming and building member {m.name} ({m.spec.name})")
            aim_member(m, (centre[0], centre[1], target_h))
            m.geo = build_scenes(m.spec, 1, m.errors, np.random.default_rng([seed, 1, i]), m.pointing, m.epoch)
        step(0.12, "writing the terrain")
        scenes = [m.geo.true for m in members]
        dem_tmp = files.path(folder / "dem.tif")
        write_dem(dem_tmp, block_bounds(scenes), centre, first.relief, seed)
        dem = Dem(dem_tmp, datum="geoid")
        set_height_range([s for m in members for s in (m.geo.true, m.geo.onboard)], dem)
        names = [m.name for m in members]
        step(0.2, f"placing {settings.n_gcps} ground control and {settings.n_tie_points} tie points")
        rng = np.random.default_rng([seed, 2])
        gcp_ground, tie_ground = place_block_points(scenes, names, dem, block_bounds(scenes, 0.0), settings.n_gcps,
                                                    settings.n_tie_points, rng)
        write_csv(files.path(folder / "gcps.csv"), GCP_COLUMNS, block_gcp_columns(scenes, names, gcp_ground,
                                                                                  settings, rng))
        if settings.n_tie_points:
            write_csv(files.path(folder / "tie_points.csv"), TIE_COLUMNS,
                      block_tie_columns(scenes, names, tie_ground, settings, rng))
        step(0.3, "writing the scene models")
        listed = {m.name: member_files(m, render) for m in members}
        for m in members:
            save_scene(m.geo.true, folder / listed[m.name]["true_scene"], files)
            save_scene(m.geo.onboard, folder / listed[m.name]["onboard_scene"], files)
        rpc_reports = {}
        for m in (m for m in members if m.rpc):
            step(0.35, f"fitting the RPCs of member {m.name}")
            rpc_reports[m.name] = _write_rpcs(m, dem, folder, listed[m.name]["rpc"], files)
        frame, radiometry = None, {}
        if render:
            frame = texture_frame(members[0].geo.true, dem, seed)
            frame["roads"] = None
            radiometry = _radiometries(members, frame, scenes, seed)
            _render(members, dem, frame, radiometry, folder, listed, files, report, cancelled, step)
            step(0.98, "writing the reference orthoimage")
            frame["reference"] = write_reference(members[0].geo.true, dem, frame,
                                                 files.path(folder / REFERENCE_NAME), seed, is_cancelled=cancelled)
        manifest = _manifest(members, seed, settings, centre, target_h, frame, radiometry, rpc_reports, listed, render,
                             settings.n_tie_points > 0)
        write_text(folder / BLOCK_MANIFEST, json.dumps(manifest, indent=1), files)
    report(1.0, "block simulation written")
    return BlockResult(folder, folder / BLOCK_MANIFEST, folder / "dem.tif", folder / "gcps.csv",
                       folder / "tie_points.csv" if settings.n_tie_points else None,
                       {name: {"true_scene": folder / f["true_scene"], "onboard_scene": folder / f["onboard_scene"],
                               "images": {c: folder / p for c, p in f["images"].items()},
                               "rpc": {c: folder / p for c, p in f["rpc"].items()}} for name, f in listed.items()},
                       folder / REFERENCE_NAME if render else None)


def _write_rpcs(m: ResolvedMember, dem, folder: Path, paths: dict, files) -> dict:
    """Fit and write the RPC00B model of each camera of a member's onboard scene over the DEM's
    heights under it; returns each camera's fit check (rms / max px)."""
    out = {}
    for k, cam in enumerate(m.geo.onboard.cameras):
        rpc, fit = fit_rpc(m.geo.onboard, k, dem_height_range(m.geo.onboard, dem, k))
        write_rpc(rpc, folder / paths[cam.name], fit, files)
        out[cam.name] = {key: fit["check"][key] for key in ("rms_px", "max_px")}
    return out


def _radiometries(members: list[ResolvedMember], frame: dict, scenes, seed: int) -> dict:
    """Radiometry per date label, in order of first appearance: the first date renders as
    :func:`simulate` does (no change, no noise); each later one draws its own
    (:func:`simulation.radiometry.draw_radiometry`) with changed land cover over the block."""
    lon0, lat0, lon1, lat1 = block_bounds(scenes, 0.0)
    x0, y0 = texture_plane(lon0, lat0, tuple(frame["centre"]))
    x1, y1 = texture_plane(lon1, lat1, tuple(frame["centre"]))
    extent = (float(x0), float(y0), float(x1), float(y1))
    out: dict = {}
    for m in members:
        if m.date_key not in out:
            k = len(out)
            out[m.date_key] = (Radiometry() if k == 0 else
                               draw_radiometry(np.random.default_rng([seed, 3, k]), extent, seed=seed * 1000 + k))
    return out


def _render(members, dem, frame, radiometry, folder, listed, files, report, cancelled, step) -> None:
    """Render every camera of every member's true scene with its date's radiometry."""
    jobs = [(m, k, cam) for m in members for k, cam in enumerate(m.geo.true.cameras)]
    for n, (m, k, cam) in enumerate(jobs):
        base = 0.4 + 0.55 * n / len(jobs)
        step(base, f"rendering member {m.name}, camera {cam.name} ({cam.cols} x {cam.rows})")
        look = radiometry[m.date_key]
        m.interpolation_error_px[cam.name] = render_image(
            m.geo.true, k, dem, files.path(folder / listed[m.name]["images"][cam.name]), frame,
            progress=lambda f, b=base: report(b + f * 0.55 / len(jobs), None), is_cancelled=cancelled,
            radiometry=None if look == Radiometry() else look)


def _manifest(members, seed, settings, centre, target_h, frame, radiometry, rpc_reports, listed, render,
              ties) -> dict:
    """block.json: settings, each member's description and drawn truth, the texture, the files."""
    return {
        "kind": "pushbroom block simulation", "seed": seed, "measurements": asdict(settings),
        "centre": {"lon": centre[0], "lat": centre[1], "h_ellipsoid_m": target_h},
        "members": [{"name": m.name, "preset": m.spec.name, "description": m.spec.description,
                     "view_deg": {"pitch": m.view[0], "roll": m.view[1]}, "orbit_offset_km": m.orbit_offset_km,
                     "along_track_km": m.along_track_km,
                     "date": m.date, "rpc": m.rpc, "epoch": m.epoch,
                     "pass_point": list(m.pointing.pass_point), "random_stream": [seed, 1, m.index],
                     "errors": asdict(m.errors), "truth": m.geo.truth,
                     "radiometry": radiometry[m.date_key].as_dict() if render else None,
                     "interpolation_error_px": m.interpolation_error_px or None,
                     "rpc_fit_px": rpc_reports.get(m.name)} for m in members],
        "texture": frame,
        "conventions": __doc__.split("\n\n")[1].strip(),
        "files": {"dem": "dem.tif (EGM96 geoid heights)", "gcps": "gcps.csv",
                  "tie_points": "tie_points.csv" if ties else None,
                  "reference": REFERENCE_NAME if render else None,
                  "members": {name: {"true_scene": f["true_scene"], "onboard_scene": f["onboard_scene"],
                                     "images": f["images"], "rpc": f["rpc"],
                                     "rpc_reports": {c: f"{p}.json" for c, p in f["rpc"].items()}}
                              for name, f in listed.items()}}}

