"""Scene JSON (the project's own scene file) and the reader dispatcher.

Scene JSON, version 2 — one object (version 1 files, without corrections, are read too):
    format      "pushbroom-scene"
    version     2
    epoch       UTC ISO-8601 string; every time in the file is seconds from it
    platform    {"ephemeris": {times, positions, velocities?, order},
                 "attitude": {"kind": "quaternion_samples", times, quaternions (w,x,y,z), order}
                          or {"kind": "quaternion_polynomial", offset, scale, coefficients},
                 "correction" (optional, written by an adjustment): {"position": {basis, coefficients},
                     "attitude": {basis, coefficients}} — see core.trajectory.TrajectoryCorrection,
                 "camera_corrections" (optional, written by an adjustment with one trajectory
                     correction per camera): {camera name: correction as above}, used by that
                     camera instead of "correction"}
    cameras     list of {name, cols, rows, timing {t0, period} or {lines, times},
                 chips [...], focal_length, principal_point, distortion, installation}
    corrections {"aberration": bool, "refraction": bool}
    info        free metadata: sensor, source, height_range, ...
Readers for vendor formats return the same SceneModel, so every algorithm accepts any of them.
"""
from __future__ import annotations

import json
from pathlib import Path

from ..model.camera import Camera
from ..errors import MetadataError, PushbroomError
from ..files import OutputSet, write_text
from ..model.sensor import SceneModel
from ..model.trajectory import Platform
from ..validation import check_scene_dict, check_scene_model

FORMAT = "pushbroom-scene"
VERSION = 2
UTF8_BOM = b"\xef\xbb\xbf"  # written by some editors (Notepad); JSON and XML both allow it


def scene_to_dict(scene: SceneModel) -> dict:
    return {"format": FORMAT, "version": VERSION, "epoch": scene.epoch,
            "platform": scene.platform.to_dict(), "cameras": [c.to_dict() for c in scene.cameras],
            "corrections": {"aberration": scene.aberration, "refraction": scene.refraction},
            "info": scene.info}


def scene_from_dict(d: dict, source: str = "scene JSON") -> SceneModel:
    """The SceneModel of a scene-JSON object, checked against the schema
    (:func:`core.validation.check_scene_dict`); MetadataError naming ``source`` and the key path.
    An object with ``"model": "rpc"`` is an RPC scene (:class:`core.rpcscene.RpcScene`)."""
    if isinstance(d, dict) and d.get("format") == FORMAT and d.get("model") == "rpc":
        from ..model.rpcscene import RpcScene
        return RpcScene.from_dict(d, source)
    d = check_scene_dict(d, source, FORMAT, VERSION)
    try:
        corrections = d.get("corrections", {})
        return SceneModel(epoch=str(d["epoch"]), platform=Platform.from_dict(d["platform"]),
                          cameras=[Camera.from_dict(c) for c in d["cameras"]],
                          aberration=bool(corrections.get("aberration", False)),
                          refraction=bool(corrections.get("refraction", False)), info=dict(d.get("info", {})))
    except KeyError as exc:
        raise MetadataError(f"{source}: required field {exc.args[0]!r} is missing") from None
    except (TypeError, ValueError, PushbroomError) as exc:
        raise MetadataError(f"{source}: malformed value ({exc})") from None


def validate_scene(scene: SceneModel, source: str) -> SceneModel:
    """Check a scene read from any format by the scene-JSON schema and the model's own checks
    (:mod:`core.validation`): vendor metadata meets the same rules as scene JSON."""
    check_scene_dict(scene_to_dict(scene), source, FORMAT, VERSION)
    check_scene_model(scene, source)
    return scene


def save_scene(scene: SceneModel, path: str | Path, files: OutputSet | None = None) -> None:
    """Write a scene JSON completely or not at all (:func:`core.files.write_text`; with
    ``files``, as part of that set)."""
    d = scene.to_dict() if hasattr(scene, "to_dict") else scene_to_dict(scene)
    write_text(path, json.dumps(d, indent=1), files)


def load_scene(path: str | Path) -> SceneModel:
    """Read any supported scene: scene JSON, Pleiades/SPOT DIMAP v2, Maxar/DigitalGlobe XML, and
    RPC sources (:mod:`core.rpcscene`): an RPC scene JSON, ``_RPC.TXT``, ``.RPB``, DIMAP
    ``RPC_*.XML``, or an image with RPC metadata GDAL reads."""
    from ..model import rpcscene
    path = Path(path)
    if not path.is_file():
        raise MetadataError(f"{path}: no such file")
    with path.open("rb") as f:
        head = f.read(4096).removeprefix(UTF8_BOM).lstrip()
    if head.startswith((b"{", b"[")):
        try:
            d = json.loads(path.read_text(encoding="utf-8-sig"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise MetadataError(f"{path}: invalid JSON ({exc})") from None
        scene = scene_from_dict(d, str(path))
        if isinstance(scene, SceneModel):
            check_scene_model(scene, str(path))
    elif head.startswith(b"<") and path.name.upper().startswith("RPC_"):
        from .vendor_xml import parse_xml
        scene = rpcscene.read_dimap_rpc(path, parse_xml(path))
    elif head.startswith(b"<"):
        from .vendor_xml import read_xml_scene
        scene = validate_scene(read_xml_scene(path), str(path))
    elif rpcscene.is_rpc_text(path, head):
        scene = rpcscene.read_rpc_text(path)
    else:
        scene = rpcscene.read_rpc_image(path)
        if scene is None:
            raise MetadataError(f"{path}: neither scene JSON nor XML metadata (DIMAP v2 or Maxar), nor an RPC file "
                                "(_RPC.TXT, .RPB) or an image with RPC metadata")
    scene.info.setdefault("source", str(path))
    return scene
