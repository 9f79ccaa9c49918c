"""Hostile-input suite: scene JSON edited by hand. Each case mutates a copy of the simulated
CBERS-02B scene (one key, one value) and runs pushbroom:footprint on it: the run must stop with
a message naming the file and the key path, and leave the folder as it was (no output, the
scene file untouched). A few cases run through qgis_process, and legitimate variants (a BOM, a
quaternion a little off unit length) must give the footprint of the unmodified scene."""
import copy
import json
from pathlib import Path

import numpy as np
import pytest

import processing
from tests.support.hostile import assert_refused, assert_refused_cli

# The example: ephemeris order 0 put the satellite at the Earth's centre (6836 km²).
CBERS_FOOTPRINT_KM2 = (700.0, 900.0)  # 12246 px x 2.36 m squared is ~835 km²


def _set(path: str, value):
    """A mutation setting the value at a key path like 'cameras.0.focal_length'."""
    def mutate(d):
        *parents, last = path.split(".")
        node = d
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        if isinstance(node, list):
            node[int(last)] = value
        else:
            node[last] = value
        return d
    return mutate


def _delete(path: str):
    def mutate(d):
        *parents, last = path.split(".")
        node = d
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        del node[int(last) if isinstance(node, list) else last]
        return d
    return mutate


def _apply(path: str, func):
    """A mutation replacing the value at ``path`` by func(value)."""
    def mutate(d):
        *parents, last = path.split(".")
        node = d
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        key = int(last) if isinstance(node, list) else last
        node[key] = func(node[key])
        return d
    return mutate


def _scaled(factor):
    return lambda a: (np.asarray(a) * factor).tolist()


def _swap_first_two(a):
    return [a[1], a[0]] + a[2:]


def _rotate_180_about_x(m):
    return (np.asarray(m) @ np.diag([1.0, -1.0, -1.0])).tolist()


def _kept_share(share):
    """Keep the first ``share`` of the samples of a trajectory table (times and values)."""
    def mutate(d):
        for key in ("ephemeris", "attitude"):
            table = d["platform"][key]
            n = max(8, int(len(table["times"]) * share))
            for field in ("times", "positions", "velocities", "quaternions"):
                if field in table:
                    table[field] = table[field][:n]
        return d
    return mutate


def _text(text):
    return lambda d: text


def _duplicate_camera(d):
    d["cameras"].append(copy.deepcopy(d["cameras"][0]))
    return d


def _polynomial_attitude(scale):
    """Replace the sampled attitude by a constant quaternion polynomial of norm ``scale``."""
    def mutate(d):
        q = np.asarray(d["platform"]["attitude"]["quaternions"][len(d["platform"]["attitude"]["times"]) // 2])
        d["platform"]["attitude"] = {"kind": "quaternion_polynomial", "offset": 0.0, "scale": 1.0,
                                     "coefficients": (q[:, None] * scale).tolist()}
        return d
    return mutate


# (case id, mutation of the scene dict (or raw text), texts the message must contain)
CASES = [
    # the examples
    ("ephemeris order 0", _set("platform.ephemeris.order", 0), ["platform.ephemeris.order", "between 2"]),
    ("negative focal length", _set("cameras.0.focal_length", -3.3), ["cameras[0].focal_length", "> 0", "-3.3"]),
    ("cols 0", _set("cameras.0.cols", 0), ["cameras[0].cols", "between 1"]),
    ("no cameras", _set("cameras", []), ["cameras", "non-empty"]),
    ("version two", _set("version", "two"), ["version", "whole number", "two"]),
    ("height range not numbers", _set("info.height_range", ["low", "high"]), ["info.height_range", "numbers"]),
    # versions, format, top level
    ("version newer", _set("version", 3), ["version 3 is newer"]),
    ("version 1.5", _set("version", 1.5), ["version", "whole number"]),
    ("version null", _set("version", None), ["version", "whole number"]),
    ("format wrong", _set("format", "pushbroom-scene-v3"), ["not a Pushbroom Adjust scene"]),
    ("top level list", _text("[1, 2, 3]"), ["must be an object"]),
    ("truncated JSON", _text('{"format": "pushbroom-scene", "version": 2, "cameras": ['), ["invalid JSON"]),
    ("empty file", _text(""), ["neither scene JSON nor XML"]),
    ("epoch missing", _delete("epoch"), ["epoch: required field is missing"]),
    ("epoch not a date", _set("epoch", "yesterday"), ["epoch", "ISO 8601", "yesterday"]),
    ("epoch a number", _set("epoch", 1292382000), ["epoch", "text string"]),
    ("platform a string", _set("platform", "LEO"), ["platform", "must be an object"]),
    # ephemeris
    ("ephemeris order 1", _set("platform.ephemeris.order", 1), ["platform.ephemeris.order"]),
    ("ephemeris order beyond samples", _set("platform.ephemeris.order", 500), ["platform.ephemeris.order", "500"]),
    ("ephemeris order text", _set("platform.ephemeris.order", "eight"), ["platform.ephemeris.order", "whole number"]),
    ("ephemeris in km", _apply("platform.ephemeris.positions", _scaled(1e-3)),
     ["platform.ephemeris.positions[0]", "from the Earth's centre"]),
    ("ephemeris at the Earth's centre", _set("platform.ephemeris.positions.5", [0.0, 0.0, 0.0]),
     ["platform.ephemeris.positions[5]", "from the Earth's centre"]),
    ("ephemeris position huge", _set("platform.ephemeris.positions.3", [1e308, 1e308, 0.0]),
     ["platform.ephemeris.positions[3]"]),
    ("ephemeris position NaN", _set("platform.ephemeris.positions.2", [float("nan"), 0.0, 0.0]),
     ["platform.ephemeris.positions[2][0]", "finite"]),
    ("ephemeris position Infinity", _set("platform.ephemeris.positions.2", [float("inf"), 0.0, 0.0]),
     ["platform.ephemeris.positions[2][0]", "finite"]),
    ("ephemeris position text", _set("platform.ephemeris.positions.1", ["x", 0.0, 0.0]),
     ["platform.ephemeris.positions", "only numbers"]),
    ("ephemeris positions 2-D", _apply("platform.ephemeris.positions", lambda a: [p[:2] for p in a]),
     ["platform.ephemeris.positions", "shape"]),
    ("ephemeris times swapped", _apply("platform.ephemeris.times", _swap_first_two),
     ["platform.ephemeris.times[1]", "strictly increasing"]),
    ("ephemeris times repeated", _apply("platform.ephemeris.times", lambda a: [a[0]] + a[:-1]),
     ["platform.ephemeris.times[1]", "strictly increasing"]),
    ("ephemeris one sample", _apply("platform.ephemeris", lambda e: {**e, "times": e["times"][:1],
                                                                    "positions": e["positions"][:1],
                                                                    "velocities": e["velocities"][:1], "order": 1}),
     ["platform.ephemeris.times", "at least 2"]),
    ("ephemeris times a string", _set("platform.ephemeris.times", "0..60"), ["platform.ephemeris.times", "list"]),
    ("ephemeris velocities in km/s", _apply("platform.ephemeris.velocities", _scaled(1e-3)),
     ["platform.ephemeris.velocities[0]", "orbital speed"]),
    ("ephemeris velocities too few", _apply("platform.ephemeris.velocities", lambda a: a[:-1]),
     ["platform.ephemeris.velocities", "shape"]),
    ("ephemeris missing", _delete("platform.ephemeris"), ["platform.ephemeris: required field is missing"]),
    ("trajectory ends before the image", _kept_share(0.3), ["do not cover the image lines"]),
    ("image long after the trajectory", _apply("cameras.0.timing.t0", lambda t: t + 1000.0),
     ["do not cover the image lines"]),
    # attitude
    ("quaternions doubled", _apply("platform.attitude.quaternions", _scaled(2.0)),
     ["platform.attitude.quaternions[0]", "unit quaternion"]),
    ("quaternion zero", _set("platform.attitude.quaternions.7", [0.0, 0.0, 0.0, 0.0]),
     ["platform.attitude.quaternions[7]", "unit quaternion"]),
    ("quaternion three components", _set("platform.attitude.quaternions.7", [1.0, 0.0, 0.0]),
     ["platform.attitude.quaternions", "rows of equal length"]),
    ("attitude times swapped", _apply("platform.attitude.times", _swap_first_two),
     ["platform.attitude.times[1]", "strictly increasing"]),
    ("attitude kind unknown", _set("platform.attitude.kind", "euler_angles"),
     ["platform.attitude.kind", "euler_angles"]),
    ("attitude order 0", _set("platform.attitude.order", 0), ["platform.attitude.order"]),
    ("attitude polynomial of norm 0", _polynomial_attitude(0.0), ["platform.attitude.coefficients", "norm 0"]),
    ("attitude polynomial scale 0", lambda d: _set("platform.attitude.scale", 0)(_polynomial_attitude(1.0)(d)),
     ["platform.attitude.scale", "not be 0"]),
    # cameras
    ("rows negative", _set("cameras.0.rows", -5), ["cameras[0].rows"]),
    ("cols fractional", _set("cameras.0.cols", 12246.5), ["cameras[0].cols", "whole number"]),
    ("cols as text", _set("cameras.0.cols", "12246"),
     ["cameras[0].cols", "whole number"]),
    ("cols beyond any sensor", _set("cameras.0.cols", 10 ** 9), ["cameras[0].cols"]),
    ("camera names repeated", _duplicate_camera, ["cameras[1].name", "unique"]),
    ("camera name empty", _set("cameras.0.name", " "), ["cameras[0].name", "non-empty"]),
    ("cameras missing", _delete("cameras"), ["cameras: required field is missing"]),
    ("focal length 0", _set("cameras.0.focal_length", 0), ["cameras[0].focal_length", "> 0"]),
    ("focal length in mm", _set("cameras.0.focal_length", 3300.0), ["cameras[0].focal_length", "<= 100"]),
    ("focal length in km", _set("cameras.0.focal_length", 0.0033), ["cameras[0].chips[0].pitch", "rad per pixel"]),
    ("line period 0", _set("cameras.0.timing.period", 0.0), ["cameras[0].timing.period", "> 0"]),
    ("line period negative", _set("cameras.0.timing.period", -3.5e-4), ["cameras[0].timing.period", "> 0"]),
    ("line period in ms", _set("cameras.0.timing.period", 0.35 * 1000), ["cameras[0].timing.period", "plausible"]),
    ("timing missing", _delete("cameras.0.timing"), ["cameras[0].timing: required field is missing"]),
    ("timing table decreasing", _set("cameras.0.timing", {"lines": [0, 6000, 12245], "times": [-2.0, 0.1, 0.0]}),
     ["cameras[0].timing.times[2]", "strictly increasing"]),
    ("chips empty", _set("cameras.0.chips", []), ["cameras[0].chips", "non-empty"]),
    ("chip pitch 0", _set("cameras.0.chips.1.pitch", 0.0), ["cameras[0].chips[1].pitch", "> 0"]),
    ("chip pixels 0", _set("cameras.0.chips.2.n_pixels", 0), ["cameras[0].chips[2].n_pixels"]),
    ("chip kind unknown", _set("cameras.0.chips.0.kind", "banana"), ["cameras[0].chips[0].kind", "banana"]),
    ("chips leave a gap", _apply("cameras.0.chips.1.col_offset", lambda c: c + 1000.0),
     ["cameras[0].chips[1].col_offset", "without a detector"]),
    ("chips short of the image", _set("cameras.0.cols", 20000), ["cameras[0].chips", "short of the image"]),
    ("chip time offset huge", _set("cameras.0.chips.1.time_offset", 1e9), ["cameras[0].chips[1].time_offset"]),
    ("installation scaled", _apply("cameras.0.installation", _scaled(2.0)),
     ["cameras[0].installation", "rotation matrix"]),
    ("installation mirrored", _apply("cameras.0.installation", lambda m: (-np.asarray(m)).tolist()),
     ["cameras[0].installation", "determinant"]),
    ("camera looks into space", _apply("cameras.0.installation", _rotate_180_about_x),
     ["cameras[0]", "misses the Earth"]),
    ("principal point one value", _set("cameras.0.principal_point", [0.0]), ["cameras[0].principal_point", "shape"]),
    ("distortion as text", _set("cameras.0.distortion", {"k1": "small"}), ["cameras[0].distortion.k1", "number"]),
    ("distortion unknown term", _set("cameras.0.distortion", {"k9": 0.1}), ["unknown distortion terms"]),
    # corrections and info
    ("correction flag as text", _set("corrections.aberration", "yes"), ["corrections.aberration", "true or false"]),
    ("height range reversed", _set("info.height_range", [1432, 301]), ["info.height_range", "lowest"]),
    ("height range above the orbit", _set("info.height_range", [0, 1e6]), ["info.height_range", "terrain"]),
    ("height range a string", _set("info.height_range", "300..1400"), ["info.height_range", "list"]),
    # not a scene at all: JSON nested 100000 levels deep (a RecursionError once)
    ("nested 100000 levels deep", lambda d: "[" * 50_000 + "{}" + "]" * 50_000, ["nested far more deeply"]),
]


@pytest.fixture(scope="module")
def scene_dict(simulated) -> dict:
    return json.loads(Path(simulated["ONBOARD_SCENE"]).read_text())


def _write(tmp_path, scene_dict, mutation) -> Path:
    changed = mutation(copy.deepcopy(scene_dict))
    path = tmp_path / "scene.json"
    path.write_text(changed if isinstance(changed, str) else json.dumps(changed))
    return path


@pytest.mark.parametrize("case, mutation, texts", CASES, ids=[c[0] for c in CASES])
def test_hand_edited_scene_is_refused_naming_the_key(provider, scene_dict, tmp_path, capfd, case, mutation, texts):
    path = _write(tmp_path, scene_dict, mutation)
    assert_refused("pushbroom:footprint", {"SCENE": str(path), "HEIGHT": 800.0, "OUTPUT": str(tmp_path / "fp.gpkg")},
                   "SCENE", "scene.json", *texts, watch=[tmp_path], capfd=capfd)


CLI_CASES = [CASES[i] for i in (0, 1, 4, -1)]


@pytest.mark.parametrize("case, mutation, texts", CLI_CASES, ids=[c[0] for c in CLI_CASES])
def test_hand_edited_scene_is_refused_on_the_command_line(qgis_process, scene_dict, tmp_path, case, mutation, texts):
    path = _write(tmp_path, scene_dict, mutation)
    assert_refused_cli(qgis_process, "pushbroom:footprint",
                       {"SCENE": path, "HEIGHT": 800, "OUTPUT": tmp_path / "fp.gpkg"}, "scene.json", *texts,
                       watch=[tmp_path])


def _area_km2(scene: Path, tmp_path: Path) -> float:
    out = processing.run("pushbroom:footprint", {"SCENE": str(scene), "HEIGHT": 800.0,
                                                  "OUTPUT": str(tmp_path / f"{scene.stem}.gpkg")})["OUTPUT"]
    from qgis.core import QgsVectorLayer
    return next(QgsVectorLayer(out, "fp", "ogr").getFeatures())["area_km2"]


LEGITIMATE = [
    ("UTF-8 BOM", lambda text: "\ufeff" + text),
    ("quaternions 0.5 % off unit length", lambda text: json.dumps(_apply("platform.attitude.quaternions",
                                                                          _scaled(1.005))(json.loads(text)))),
    ("pretty-printed with CRLF", lambda text: json.dumps(json.loads(text), indent=4).replace("\n", "\r\n")),
]


@pytest.mark.parametrize("case, variant", LEGITIMATE, ids=[c[0] for c in LEGITIMATE])
def test_legitimate_variants_give_the_same_footprint(provider, simulated, tmp_path, case, variant):
    original = Path(simulated["ONBOARD_SCENE"])
    variant_path = tmp_path / "variant.json"
    variant_path.write_bytes(variant(original.read_text()).encode("utf-8"))
    expected = _area_km2(original, tmp_path)
    assert CBERS_FOOTPRINT_KM2[0] < expected < CBERS_FOOTPRINT_KM2[1]
    assert _area_km2(variant_path, tmp_path) == pytest.approx(expected, rel=1e-9)
