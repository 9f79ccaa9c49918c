"""The scenes a use case works on: one scene file (SCENE), or the files of a block of scenes (SCENES),
each named as its observations name it (:func:`block_scene_names`), read once with their log lines."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..errors import InputError
from ..formats.rpcfiles import image_name
from .base import SCENE, scene_from

# The input a block's errors and log lines name (InputError.parameter, LogLine.parameter).
SCENES = "scenes"

# Scene JSON files a block's folder layout names by their folder (simulation's block, bundle adjustment)
FOLDER_NAMED_SCENES = ("onboard_scene.json", "true_scene.json", "adjusted_scene.json")


def block_scene_names(paths: Sequence) -> list[str]:
    """The name of each scene file of a block: its file's stem (less the suffix of an RPC sidecar,
    <name>_RPC.TXT: the image's name; a file named _RPC.TXT alone takes its folder's name:
    :func:`core.formats.rpcfiles.image_name`), or its folder's name for the scene JSON files of
    FOLDER_NAMED_SCENES (the layout the simulation of a block writes). InputError (SCENES) naming
    both files when two scenes get one name (or one file is listed twice)."""
    names, first = [], {}
    for path in map(Path, paths):
        name = path.parent.name if path.name.lower() in FOLDER_NAMED_SCENES else image_name(path)
        if name in first:
            other = first[name]
            if other.resolve() == path.resolve():
                raise InputError(f"{path} is listed twice; give each scene once", parameter=SCENES)
            raise InputError(f"{other} and {path} are both named {name!r} (a scene's name is its file's stem, or its "
                             f"folder's for {' / '.join(FOLDER_NAMED_SCENES)}); rename one so that observations can "
                             "name their scene", parameter=SCENES)
        first[name] = path
        names.append(name)
    return names


@dataclass(frozen=True)
class Block:
    """The scenes of a block, by name (:func:`block_scene_names`): ``files`` {name: scene file},
    ``scenes`` {name: the scene read from it}, in the order given."""
    files: dict
    scenes: dict


def block_from(paths: Sequence[str]) -> tuple[Block, list]:
    """(the block of scene files ``paths``, log lines): every file read as :func:`core.runs.base.scene_from`
    reads one, its errors and lines concerning SCENES."""
    files = dict(zip(block_scene_names(paths), map(str, paths)))
    scenes, lines = {}, []
    for name, path in files.items():
        scenes[name], more = member_scene(path)
        lines += more
    return Block(files, scenes), lines


def member_scene(path: str) -> tuple:
    """(scene, log lines) of one scene file of a block: :func:`core.runs.base.scene_from`, whose errors
    and lines about SCENE concern SCENES instead."""
    try:
        scene, lines = scene_from(path)
    except InputError as exc:
        if exc.parameter != SCENE:
            raise
        raise InputError(str(exc), parameter=SCENES) from None
    return scene, [line._replace(parameter=SCENES) if line.parameter == SCENE else line for line in lines]


def read_scene(path: str, parameter: str = SCENE) -> tuple:
    """(scene, log lines) of the scene file ``path`` an input ``parameter`` gives: SCENE
    (:func:`core.runs.base.scene_from`) or SCENES (:func:`member_scene`)."""
    return member_scene(path) if parameter == SCENES else scene_from(path)
