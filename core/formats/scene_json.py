"""Scene JSON: the project's own scene file, for rigorous and for RPC scenes.

Scene JSON, version 2 — one object (version 1 files, without corrections, are read too):
    format      "pushbroom-scene"
    version     2
    epoch       UTC ISO-8601 string; every time in the file is seconds from it
    platform    {"ephemeris": {times, positions, velocities?, order},
                 "attitude": {"kind": "quaternion_samples", times, quaternions (w,x,y,z), order}
                          or {"kind": "quaternion_polynomial", offset, scale, coefficients},
                 "correction" (optional, written by an adjustment): {"position": {basis, coefficients},
                     "attitude": {basis, coefficients}} — see core.model.trajectory.TrajectoryCorrection,
                 "camera_corrections" (optional, written by an adjustment with one trajectory
                     correction per camera): {camera name: correction as above}, used by that
                     camera instead of "correction"}
    cameras     list of {name, cols, rows, timing {t0, period} or {lines, times},
                 chips [...], focal_length, principal_point, distortion, installation}
    corrections {"aberration": bool, "refraction": bool}
    info        free metadata: sensor, source, height_range, ...

RPC scene JSON (:class:`core.model.rpcscene.RpcScene`): format and version as above and
    model       "rpc"
    camera      {name, cols, rows}
    rpc         GDAL's RPC metadata keys: LINE_OFF ... HEIGHT_SCALE numbers, *_COEFF lists of 20
    correction  {"col": [a0, a1, a2], "row": [b0, b1, b2]} (see core.model.rpcscene)
    info        free metadata
Readers of vendor formats return the same models (:func:`core.formats.load_scene`), so every
algorithm accepts any of them.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import MetadataError, PushbroomError
from ..files import OutputSet, write_text
from ..model.camera import Camera
from ..model.rpcscene import MODEL, RpcCamera, RpcScene, check_image_domain
from ..model.sensor import SceneModel
from ..model.trajectory import Platform
from .rpcfiles import RPC_COEFFS, RPC_KEYS, rpc_from_metadata, rpc_metadata
from .schema import FORMAT, VERSION, check_rpc_scene_dict, check_scene_dict, check_scene_model


def scene_to_dict(scene: SceneModel) -> dict:
    """The scene-JSON object of a rigorous scene."""
    return {"format": FORMAT, "version": VERSION, "epoch": scene.epoch,
            "platform": scene.platform.to_dict(), "cameras": [c.to_dict() for c in scene.cameras],
            "corrections": {"aberration": scene.aberration, "refraction": scene.refraction},
            "info": scene.info}


def scene_from_dict(d: dict, source: str = "scene JSON") -> SceneModel | RpcScene:
    """The SceneModel of a scene-JSON object, checked against the schema
    (:func:`core.formats.schema.check_scene_dict`); MetadataError naming ``source`` and the key path.
    An object with ``"model": "rpc"`` is an RPC scene (:func:`rpc_scene_from_dict`)."""
    if isinstance(d, dict) and d.get("format") == FORMAT and d.get("model") == MODEL:
        return rpc_scene_from_dict(d, source)
    d = check_scene_dict(d, source)
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


def rpc_scene_to_dict(scene: RpcScene) -> dict:
    """The RPC scene-JSON object of an RPC scene (the RPC with GDAL's origin, 0 at the first pixel's centre)."""
    md = rpc_metadata(scene.rpc)
    rpc = {key: float(md[key]) for key in RPC_KEYS}
    rpc.update({key: [float(v) for v in md[key].split()] for key, _ in RPC_COEFFS})
    return {"format": FORMAT, "version": VERSION, "model": MODEL,
            "camera": {"name": scene.camera.name, "cols": scene.camera.cols, "rows": scene.camera.rows},
            "rpc": rpc, "correction": {"col": scene.correction[0].tolist(), "row": scene.correction[1].tolist()},
            "info": scene.info}


def rpc_scene_from_dict(d: dict, source: str) -> RpcScene:
    """The scene of a scene-JSON object with ``"model": "rpc"``, checked (see
    :func:`core.formats.schema.check_rpc_scene_dict`); MetadataError naming ``source``."""
    d = check_rpc_scene_dict(d, source)
    rpc = rpc_from_metadata(d["rpc"], f"{source}: rpc")
    cam = d["camera"]
    camera = RpcCamera(str(cam["name"]), int(cam["cols"]), int(cam["rows"]))
    correction = np.array([d.get("correction", {}).get("col", [0, 0, 0]),
                           d.get("correction", {}).get("row", [0, 0, 0])], dtype=float)
    scene = RpcScene(rpc, camera, correction, dict(d.get("info", {})))
    check_image_domain(rpc, camera.cols, camera.rows, source)
    return scene


def validate_scene(scene: SceneModel, source: str) -> SceneModel:
    """Check a scene read from any format by the scene-JSON schema and the model's own checks
    (:mod:`core.formats.schema`): vendor metadata meets the same rules as scene JSON."""
    check_scene_dict(scene_to_dict(scene), source)
    check_scene_model(scene, source)
    return scene


def save_scene(scene: SceneModel | RpcScene, path: str | Path, files: OutputSet | None = None) -> None:
    """Write a scene JSON completely or not at all (:func:`core.files.write_text`; with
    ``files``, as part of that set)."""
    d = rpc_scene_to_dict(scene) if isinstance(scene, RpcScene) else scene_to_dict(scene)
    write_text(path, json.dumps(d, indent=1), files)
