"""What the two measuring docks share, without their widgets: what the heights form means (where
heights come from, and those words for the messages and the table), the files a raw image opened in a
dock reads (which a save must not replace), and what the scene dialog proposes.

Heights are never guessed: 'dem' chosen with no DEM is the constant height, and the words say so.
"""
from __future__ import annotations

from ..errors import PushbroomError
from ..formats import load_scene
from ..measure.sources import ImageSource, raw_image_candidates
from ..observations.tables import Heights

LINE_MARGIN_PX = 20.0  # image px shown around a line zoomed to


def form_heights(source: str, datum: str, value: float, dem: str | None, dem_name: str,
                 z_words: str) -> tuple[Heights, str]:
    """(the heights, where they come from in words) of the form's choices: ``source`` ('z', 'dem',
    'constant'), ``datum`` of the Z values, the DEM and the constant ``value`` (m); ``dem`` the DEM's
    file (None: none chosen) called ``dem_name``; ``z_words``: what heights from 'z' are."""
    constant = f"the constant {value:.1f} m ({datum})"
    if source == "dem" and dem is None:
        return Heights("constant", datum, None, value), constant + ", no DEM chosen"
    words = {"z": z_words, "constant": constant, "dem": f"the DEM {dem_name}"}[source]
    return Heights(source, datum, dem, value), words


def files_read(label: str, opened: str, source: ImageSource) -> dict[str, list[str]]:
    """{what: files} of one raw image opened in a dock, called ``label`` (``opened``: the file the
    user chose, a scene file or a display copy): its scene file, display copies and raw image."""
    displays = [str(source.display)] + [opened] * (opened not in (source.scene_path, str(source.image)))
    return {f"{label} (scene file)": [source.scene_path], f"{label} (display copy)": displays,
            f"{label} (raw image)": [str(source.image)]}


def scene_cameras(path: str) -> tuple[object | None, list[str], str]:
    """(the scene file ``path`` read (None when it cannot be), its cameras' names, what to tell)."""
    try:
        scene = load_scene(path)
    except (PushbroomError, OSError) as exc:
        return None, [], str(exc)
    return scene, [c.name for c in scene.cameras], f"{path}: {len(scene.cameras)} camera(s)"


def proposed_image(scene, path: str, camera: str) -> tuple[str, str]:
    """(the raw image of ``scene``'s ``camera`` found beside its file ``path`` ('' for none), what to
    tell ('' for nothing): :func:`core.measure.sources.raw_image_candidates`)."""
    cam = scene.cameras[scene.camera_index(camera)]
    found = raw_image_candidates(path, cam.cols, cam.rows, cam.name, scene.info.get("image"))
    if found:
        return str(found[0]), ""
    return "", f"No raster of {cam.cols} x {cam.rows} px (camera {cam.name}) beside the scene: choose its raw image"


def frame(pixels: list[tuple[float, float]], margin: float = LINE_MARGIN_PX) -> tuple[float, float, float]:
    """(col, row, half) px: the square centred on ``pixels`` [(col, row)] (a line's vertices) that shows
    them all with ``margin`` px around them."""
    cols, rows = [p[0] for p in pixels], [p[1] for p in pixels]
    half = max(max(cols) - min(cols), max(rows) - min(rows)) / 2 + margin
    return (max(cols) + min(cols)) / 2, (max(rows) + min(rows)) / 2, half
