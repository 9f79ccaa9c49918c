"""A region as input: the entries of SCENES expanded into product files, and the raw image of each
product found beside it.

An entry of SCENES is a product file (any the plugin reads, :func:`core.formats.load_scene`), a
folder (every product in it and in its subfolders: :func:`products_in_folder`) or a list file
(a text file of products, one per line, relative paths relative to the list's folder:
:func:`listed_products`)."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

from ..errors import InputError, PushbroomError
from ..formats import load_scene
from ..formats.rpcfiles import IMAGE_SUFFIXES, image_stem, is_rpc_text
from ..log import LogLine

# The input a block's errors and log lines name (InputError.parameter, LogLine.parameter).
SCENES = "scenes"

LIST_SUFFIXES = (".txt", ".lst", ".list")          # list files (an _RPC.TXT is a product, not a list)
ONBOARD_SCENE = "onboard_scene.json"                # a simulated member's folder: the scene to adjust
NOT_PRODUCTS = ("true_scene.json", "adjusted_scene.json")  # beside it: its truth, an adjustment's result
LOOKED_FOR = ("scene JSON, DIMAP DIM_*.XML or RPC_*.XML, Maxar XML, _RPC.TXT, .RPB, or an image with RPC metadata "
              f"({', '.join(IMAGE_SUFFIXES)})")
SKIPPED_NAMED = 5                                   # skipped files named in the log, the rest counted


def expand_scenes(entries: Sequence[str]) -> tuple[tuple[str, ...], list[LogLine]]:
    """(the product files of SCENES ``entries``, in their order, each folder's in name order; log
    lines on each folder and list read). InputError (SCENES) for an entry that does not exist, a
    folder with no product, a list line that names no file."""
    files, lines = [], []
    for entry in map(Path, entries):
        if entry.is_dir():
            found, skipped = products_in_folder(entry)
            files += found
            lines.append(LogLine(f"SCENES folder {entry}: {len(found)} product(s){skipped_note(skipped)}"))
        elif is_list_file(entry):
            listed = listed_products(entry)
            files += listed
            lines.append(LogLine(f"SCENES list {entry}: {len(listed)} product(s)"))
        elif entry.is_file():
            files.append(str(entry))
        else:
            raise InputError(f"{entry}: no such file or folder", parameter=SCENES)
    return tuple(files), lines


def is_list_file(path: Path) -> bool:
    """Whether ``path`` is a list of products: a text file named .txt/.lst/.list that is not an RPC text."""
    if not path.is_file() or path.suffix.lower() not in LIST_SUFFIXES:
        return False
    with path.open("rb") as f:
        head = f.read(64).lstrip()
    return not is_rpc_text(path, head)


def listed_products(path: Path, parameter: str = SCENES, what: str = "product") -> list[str]:
    """The ``what`` files (products; raw images for the images) a list file names, one per line
    (blank lines and lines starting with '#' left out; a relative path is relative to the list's
    folder). InputError (``parameter``) naming the file and line for a line that names no file, or
    a list that is not text or names none."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (UnicodeDecodeError, OSError) as exc:
        raise InputError(f"{path}: not a readable text list of {what}s ({exc})", parameter=parameter) from None
    files = []
    for number, line in enumerate(text.splitlines(), start=1):
        entry = line.strip()
        if not entry or entry.startswith("#"):
            continue
        file = path.parent / Path(entry).expanduser()
        if not file.is_file():
            wrong = f"a folder (list {what} files)" if file.is_dir() else "no such file"
            raise InputError(f"{path}, line {number}: {entry!r} is {wrong}; each line names one {what} file, "
                             "relative to the list's folder or absolute", parameter=parameter)
        files.append(str(file))
    if not files:
        raise InputError(f"{path}: the list names no {what} (one {what} file per line)", parameter=parameter)
    return files


def products_in_folder(folder: Path) -> tuple[list[str], list[Path]]:
    """(the products in ``folder`` and its subfolders, folder by folder in name order; the files
    looked at and skipped as no product the plugin reads). In one folder a product is read once:
    an image is left out when its _RPC.TXT / .RPB is there, an RPC_<id>.XML when its DIM_<id>.XML
    is, a simulated member's true and adjusted scenes beside its onboard_scene.json, and that too
    beside the RPC file of the folder's name (a simulated RPC product, named as the folder).
    InputError naming the folder and what was looked for when it holds none."""
    found, skipped = [], []
    for here, subfolders, names in os.walk(folder):
        subfolders.sort()
        for path in candidates(Path(here), sorted(names)):
            try:
                load_scene(path)
            except (PushbroomError, OSError, ValueError):
                skipped.append(path)
                continue
            found.append(str(path))
    if not found:
        raise InputError(f"{folder}: no product found in the folder or its subfolders (looked for {LOOKED_FOR}"
                         f"{'; ' + skipped_note(skipped).lstrip('; ') if skipped else ''})", parameter=SCENES)
    return found, skipped


def candidates(folder: Path, names: list[str]) -> list[Path]:
    """The files of one folder that may be products, one per product (see :func:`products_in_folder`)."""
    upper = {n.upper() for n in names}
    rpc_stems = {image_stem(n).upper() for n in names if n.upper().endswith(("_RPC.TXT", ".RPB"))}
    if ONBOARD_SCENE in names:
        names = [n for n in names if n not in NOT_PRODUCTS]
    if folder.name.upper() in rpc_stems:     # a simulated RPC member: its RPC file is the product delivered
        names = [n for n in names if n != ONBOARD_SCENE]
    out = []
    for name in names:
        up, suffix = name.upper(), Path(name).suffix.lower()
        if suffix in IMAGE_SUFFIXES:
            if Path(name).stem.upper() not in rpc_stems:
                out.append(folder / name)
        elif up.startswith("RPC_") and up.endswith(".XML"):
            if "DIM_" + up[4:] not in upper:
                out.append(folder / name)
        elif suffix in (".json", ".xml", ".rpb") or up.endswith("_RPC.TXT"):
            out.append(folder / name)
    return out


def skipped_note(skipped: list[Path]) -> str:
    """'; skipped ...' naming the first SKIPPED_NAMED files that are no product, counting the rest."""
    if not skipped:
        return ""
    named = ", ".join(p.name for p in skipped[:SKIPPED_NAMED])
    more = f" and {len(skipped) - SKIPPED_NAMED} more" if len(skipped) > SKIPPED_NAMED else ""
    return f"; {len(skipped)} file(s) skipped, not a product the plugin reads: {named}{more}"


def block_images(given: Sequence[str], block) -> tuple[str, ...]:
    """The raw image of each scene of ``block`` (a core.runs.scenes.Block), in its order, as the
    images input gives them: one file per scene as given; nothing: each found beside its product
    (:func:`image_beside`); one folder: each found there by its name (:func:`image_beside`); one
    list file: one image per line (:func:`listed_products`)."""
    if len(given) == 1 and Path(given[0]).is_dir():
        return tuple(image_beside(n, block.scenes[n], block.files[n], Path(given[0])) for n in block.files)
    if len(given) == 1 and is_list_file(Path(given[0])):
        return tuple(listed_products(Path(given[0]), "images", "raw image"))
    if not given:
        return tuple(image_beside(n, block.scenes[n], block.files[n]) for n in block.files)
    return tuple(given)


def image_beside(name: str, scene, scene_file: str, folder: Path | None = None) -> str:
    """The raw image of the product ``name`` (``scene`` read from ``scene_file``) found beside it
    (or in ``folder``): the image its reader found (an RPC product's; not with ``folder``), else the
    one raster in the folder named <name>.*, <name>_<camera>.* or image_<camera>.* (the
    simulator's) for one of its cameras. InputError (images) naming the product and what was looked
    for when there is none, or several."""
    known = (getattr(scene, "info", None) or {}).get("image")
    if known and folder is None:
        return str(known)
    folder = folder or Path(scene_file).parent
    stems = {name.upper()} | {s.upper() for c in scene.cameras for s in (f"{name}_{c.name}", f"image_{c.name}")}
    found = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.stem.upper() in stems)
    if len(found) != 1:
        cameras = "|".join(c.name for c in scene.cameras)
        looked = f"{name}, {name}_<{cameras}>, image_<{cameras}> with {', '.join(IMAGE_SUFFIXES)} in {folder}"
        what = "no raw image" if not found else f"{len(found)} raw images ({', '.join(p.name for p in found)})"
        raise InputError(f"{what} found for scene {name} (looked for {looked}); give INPUTS, one image per "
                         "scene in the order of SCENES, or a folder or list file of them", parameter="images")
    return str(found[0])

