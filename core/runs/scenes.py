"""The scenes a use case works on: one scene file (SCENE), or the files of a block of scenes (SCENES),
each named as its observations name it (:func:`block_scene_names`), read once with their log lines."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..errors import InputError
from ..formats.rpcfiles import image_name
from .base import SCENE, scene_from
from .region import SCENES, expand_scenes

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
    """(the block of SCENES ``paths`` (product files, folders or list files:
    :func:`core.runs.region.expand_scenes`), each named by :func:`block_scene_names`, log lines):
    :func:`read_block`."""
    files, lines = expand_scenes(paths)
    block, more = read_block(dict(zip(block_scene_names(files), files)))
    return block, lines + more


def read_block(files: dict) -> tuple[Block, list]:
    """(the block of scene files {name: file} ``files``, log lines): every file read as
    :func:`core.runs.base.scene_from` reads one, its errors and lines concerning SCENES."""
    scenes, lines = {}, []
    for name, path in files.items():
        scenes[name], more = scene_from(path, SCENES)
        lines += more
    return Block(dict(files), scenes), lines


def read_scene(path: str, parameter: str = SCENE) -> tuple:
    """(scene, log lines) of the scene file ``path`` an input ``parameter`` gives (SCENE, or SCENES for
    a member of a block): :func:`core.runs.base.scene_from`."""
    return scene_from(path, parameter)
