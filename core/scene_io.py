"""Scene JSON (the project's own scene file) and the reader dispatcher.

Scene JSON, version 2 — one object (version 1 files, without corrections, are read too):
    format      "pushbroom-scene"
    version     2
    epoch       UTC ISO-8601 string; every time in the file is seconds from it
    platform    {"ephemeris": {times, positions, velocities?, order},
                 "attitude": {"kind": "quaternion_samples", times, quaternions (w,x,y,z), order}
                          or {"kind": "quaternion_polynomial", offset, scale, coefficients},
                 "correction" (optional, written by an adjustment): {"position": {basis, coefficients},
                     "attitude": {basis, coefficients}} — see core.trajectory.TrajectoryCorrection}
    cameras     list of {name, cols, rows, timing {t0, period} or {lines, times},
                 chips [...], focal_length, principal_point, distortion, installation}
    corrections {"aberration": bool, "refraction": bool}
    info        free metadata: sensor, source, height_range, ...
Readers for vendor formats return the same SceneModel, so every algorithm accepts any of them.
"""
from __future__ import annotations

import json
from pathlib import Path

from .camera import Camera
from .errors import InputError, MetadataError
from .files import OutputSet, write_text
from .sensor import SceneModel
from .trajectory import Platform

FORMAT = "pushbroom-scene"
VERSION = 2


def scene_to_dict(scene: SceneModel) -> dict:
    return {"format": FORMAT, "version": VERSION, "epoch": scene.epoch,
            "platform": scene.platform.to_dict(), "cameras": [c.to_dict() for c in scene.cameras],
            "corrections": {"aberration": scene.aberration, "refraction": scene.refraction},
            "info": scene.info}


def scene_from_dict(d: dict, source: str = "scene JSON") -> SceneModel:
    if d.get("format") != FORMAT:
        raise MetadataError(f"{source}: not a Pushbroom Adjust scene (field 'format' must be {FORMAT!r})")
    if int(d.get("version", 0)) > VERSION:
        raise MetadataError(f"{source}: scene version {d.get('version')} is newer than this plugin reads ({VERSION})")
    try:
        corrections = d.get("corrections", {})
        return SceneModel(epoch=str(d["epoch"]), platform=Platform.from_dict(d["platform"]),
                          cameras=[Camera.from_dict(c) for c in d["cameras"]],
                          aberration=bool(corrections.get("aberration", False)),
                          refraction=bool(corrections.get("refraction", False)), info=dict(d.get("info", {})))
    except KeyError as exc:
        raise MetadataError(f"{source}: required field {exc.args[0]!r} is missing") from None
    except (TypeError, ValueError, InputError) as exc:
        raise MetadataError(f"{source}: malformed value ({exc})") from None


def save_scene(scene: SceneModel, path: str | Path, files: OutputSet | None = None) -> None:
    """Write a scene JSON completely or not at all (:func:`core.files.write_text`; with
    ``files``, as part of that set)."""
    write_text(path, json.dumps(scene_to_dict(scene), indent=1), files)


def load_scene(path: str | Path) -> SceneModel:
    """Read any supported scene: scene JSON, Pleiades/SPOT DIMAP v2, Maxar/DigitalGlobe XML."""
    path = Path(path)
    if not path.is_file():
        raise MetadataError(f"{path}: no such file")
    with path.open("rb") as f:
        head = f.read(4096).lstrip()
    if head.startswith(b"{"):
        try:
            d = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            raise MetadataError(f"{path}: invalid JSON ({exc})") from None
        scene = scene_from_dict(d, str(path))
    elif head.startswith(b"<"):
        from .readers import read_xml_scene
        scene = read_xml_scene(path)
    else:
        raise MetadataError(f"{path}: neither scene JSON nor XML metadata (DIMAP v2 or Maxar)")
    scene.info.setdefault("source", str(path))
    return scene
