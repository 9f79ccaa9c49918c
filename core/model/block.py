"""A block of independent scenes (a stereo pair, tri-stereo, multi-date, neighbouring orbits) as one
composite :class:`SceneModel`, and back.

The composite's cameras are every scene's cameras, renamed ``<scene>/<camera>`` (their named
chips likewise), in the order of the scenes. Each camera looks through its own scene's platform
(ephemeris, attitude and any corrections, :attr:`core.model.trajectory.Platform.camera_platforms`),
with its times counted from its own scene's epoch: the composite has no common time axis, and
:meth:`SceneModel.time_span` of it is meaningful only for the cameras of one scene. The
composite's own ``platform`` (the first scene's ephemeris and attitude, no correction) is a
placeholder no camera sees; the composite is never written (:func:`split_block` gives the
scenes to write).

Ground <-> image, tie-point intersection and the whole bundle adjustment work on the composite as
on any scene (:mod:`core.adjust.block`); the adjustment gives each scene's cameras one trajectory
correction of its own, on a time basis over its own scene's lines.
"""
from __future__ import annotations

from dataclasses import replace

from ..errors import InputError
from .kinds import BLOCK_KEY
from .sensor import SceneModel
from .trajectory import Platform

SEPARATOR = "/"


def block_camera(scene: str, camera: str) -> str:
    """The composite's name of camera ``camera`` of block scene ``scene``."""
    return f"{scene}{SEPARATOR}{camera}"


def is_block(scene) -> bool:
    """Whether ``scene`` (any kind, :mod:`core.model.kinds`) is a block: a composite made by
    :func:`compose_block` or a block with RPC images."""
    return bool(scene.block_members())


def check_scene_names(scenes: dict) -> None:
    """InputError unless the block ``scenes`` (name -> scene) has at least one scene, every name is
    non-empty and free of '/', and no scene object is listed twice."""
    if not scenes:
        raise InputError("a block needs at least one scene", parameter="scenes")
    seen: dict[int, str] = {}
    for name, scene in scenes.items():
        if not isinstance(name, str) or not name.strip() or SEPARATOR in name:
            raise InputError(f"block scene name {name!r}: names must be non-empty and contain no "
                             f"{SEPARATOR!r}", parameter="scenes")
        if id(scene) in seen:
            raise InputError(f"scene {name!r} is the same scene as {seen[id(scene)]!r}: a scene is listed twice in "
                             "the block", parameter="scenes")
        seen[id(scene)] = name


def compose_block(scenes: dict[str, SceneModel]) -> SceneModel:
    """The composite scene of the block ``scenes`` (name -> rigorous scene, at least one). Scene
    names must be non-empty and free of '/'; a scene object may appear once; the scenes must agree
    on the aberration and refraction corrections. InputError naming what is wrong."""
    check_scene_names(scenes)
    for name, scene in scenes.items():
        if is_block(scene) or scene.platform.camera_platforms:
            raise InputError(f"scene {name!r} is itself a block: give its scenes instead", parameter="scenes")
    first = next(iter(scenes.values()))
    for name, scene in scenes.items():
        if (scene.aberration, scene.refraction) != (first.aberration, first.refraction):
            raise InputError(f"scene {name!r} has aberration={scene.aberration}, refraction={scene.refraction} but "
                             f"{next(iter(scenes))!r} has {first.aberration}, {first.refraction}: the scenes of a "
                             "block must use the same corrections", parameter="scenes")
    cameras, platforms, entries = [], {}, {}
    for name, scene in scenes.items():
        p = scene.platform
        # a platform object of its own per scene: it tells the adjustment which cameras share a trajectory
        own = Platform(p.ephemeris, p.attitude, p.correction, p.cache_step,
                       {block_camera(name, k): v for k, v in p.camera_corrections.items()})
        for cam in scene.cameras:
            cameras.append(_renamed(cam, lambda n, scene=name: block_camera(scene, n)))
            platforms[cameras[-1].name] = own
        entries[name] = {"epoch": scene.epoch, "cameras": [c.name for c in scene.cameras], "info": dict(scene.info)}
    ranges = [s.height_range for s in scenes.values()]
    info = {BLOCK_KEY: entries, "height_range": [min(r[0] for r in ranges), max(r[1] for r in ranges)],
            "sensor": "block of " + ", ".join(scenes)}
    platform = Platform(first.platform.ephemeris, first.platform.attitude, None, first.platform.cache_step,
                        camera_platforms=platforms)
    return SceneModel(first.epoch, platform, cameras, first.aberration, first.refraction, info)


def split_block(composite: SceneModel) -> dict[str, SceneModel]:
    """The scenes of a composite (name -> scene, in block order), each with its own epoch, platform
    (with the corrections the composite's cameras of that scene see), cameras under their own
    names, and its own info plus what the composite's info gained beyond the block (e.g. an
    adjustment's record)."""
    entries = composite.info[BLOCK_KEY]
    extra = {k: v for k, v in composite.info.items() if k not in (BLOCK_KEY, "height_range", "sensor")}
    names = [c.name for c in composite.cameras]
    out = {}
    for name, entry in entries.items():
        index = [names.index(block_camera(name, cam)) for cam in entry["cameras"]]
        p = composite.platform.trajectory_of(names[index[0]])
        own = {cam: p.camera_corrections[block_camera(name, cam)] for cam in entry["cameras"]
               if block_camera(name, cam) in p.camera_corrections}
        platform = Platform(p.ephemeris, p.attitude, p.correction, p.cache_step, own)
        cameras = [_renamed(composite.cameras[i], lambda n, cut=len(name) + len(SEPARATOR): n[cut:]) for i in index]
        out[name] = SceneModel(entry["epoch"], platform, cameras, composite.aberration, composite.refraction,
                               {**entry["info"], **extra})
    return out


def _renamed(camera, rename):
    """``camera`` with its name and its chips' names (where given) passed through ``rename``: the
    composite's names carry the scene (parameters are named after cameras and chips)."""
    chips = [replace(ch, name=rename(ch.name)) if ch.name else ch for ch in camera.chips]
    return replace(camera, name=rename(camera.name), chips=chips)


def chip_label(camera, k: int) -> str:
    """``<camera>/<chip>`` naming chip ``k`` of ``camera`` in reports (its number from 1 when the
    chip has no name); in a composite the chip's own copy of the scene prefix is left out
    (``A/NAD/NAD-1``, not ``A/NAD/A/NAD-1``)."""
    chip = camera.chips[k].name
    if not chip:
        return f"{camera.name}/{k + 1}"
    scene = camera.name.rpartition(SEPARATOR)[0]
    prefix = f"{scene}{SEPARATOR}"
    return f"{camera.name}/{chip[len(prefix):] if scene and chip.startswith(prefix) else chip}"


def scene_cameras(composite: SceneModel, scene: str) -> list[int]:
    """Indices of the composite's cameras of block scene ``scene``."""
    prefix = f"{scene}{SEPARATOR}"
    return [c for c, cam in enumerate(composite.cameras) if cam.name.startswith(prefix)]

