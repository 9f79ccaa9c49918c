"""The block simulator: several independent scenes over one ground (tri-stereo from one pass, another
sensor, another date delivered as an RPC product), checked against the truth it records: the true
models reproduce every measurement, the onboard models miss by the drawn errors, tie points of one
id are one ground point in every scene, rendered images of one ground look alike, the RPC product
reproduces its onboard model, and bad input is refused naming the field."""
import csv
import json
import math
import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import map_coordinates

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import Cancelled, InputError
from pushbroom_adjust.core.files import OutputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.simulation.block import BlockMember, simulate_block
from pushbroom_adjust.simulation.presets import PRESETS, cut_preset
from osgeo import gdal

TLC = cut_preset(PRESETS["th1_tlc"], 500, 500)           # TH-1 three-line camera, 500 x 500 px of 5 m
ONE = replace(TLC, name="th1_nad_500", cameras=TLC.cameras[:1])   # its nadir camera alone
MEMBERS = [BlockMember("fwd", ONE, view=(18.0, 0.0)),
           BlockMember("nad", TLC),                              # another sensor: three cameras
           BlockMember("bwd", ONE, view=(-18.0, 0.0)),
           BlockMember("date2", ONE, view=(0.0, 8.0), date="2011-03-02", rpc=True)]
NOISE = 0.3


def _read(path: Path) -> dict:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


def _f(table: dict, *names) -> list[np.ndarray]:
    return [table[n].astype(float) for n in names]


def _load(result) -> dict:
    return {"result": result, "dem": Dem(result.dem, datum="geoid"), "gcps": _read(result.gcps),
            "ties": _read(result.tie_points), "manifest": json.loads(result.manifest.read_text()),
            "true": {n: load_scene(f["true_scene"]) for n, f in result.members.items()},
            "onboard": {n: load_scene(f["onboard_scene"]) for n, f in result.members.items()}}


@pytest.fixture(scope="module")
def block(tmp_path_factory) -> dict:
    """The four-member block, not rendered (about 1.5 s)."""
    return _load(simulate_block(MEMBERS, tmp_path_factory.mktemp("block"), seed=4, n_gcps=60, n_tie_points=80,
                                image_noise=NOISE))


@pytest.fixture(scope="module")
def rendered(tmp_path_factory) -> dict:
    """A rendered tri-stereo of one-camera members plus the other date (about 3 s)."""
    members = [MEMBERS[0], replace(MEMBERS[1], preset=ONE), MEMBERS[2], MEMBERS[3]]
    return _load(simulate_block(members, tmp_path_factory.mktemp("rendered"), seed=9, n_gcps=10, n_tie_points=120,
                                image_noise=0.0, render=True))


def _project(scene, table: dict, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(col, row) of rows' true ground points in ``scene``, each in its row's camera."""
    ground = geodetic_to_ecef(*_f({k: v[rows] for k, v in table.items()}, "lon_true", "lat_true", "h_true"))
    col, row = np.full(rows.size, np.nan), np.full(rows.size, np.nan)
    for k, cam in enumerate(scene.cameras):
        m = table["camera"][rows] == cam.name
        col[m], row[m] = scene.ground_to_image(ground[m], k)
    return col, row


# --- geometry: one ground, each member its own errors --------------------------------------------------
def test_members_image_the_common_centre_in_pass_order(block):
    centre = block["manifest"]["centre"]
    for name, scene in block["true"].items():
        cam = scene.cameras[0]
        g = scene.image_to_ground_dem(np.array([cam.cols / 2]), np.array([cam.rows / 2]), block["dem"])
        lon, lat, _ = ecef_to_geodetic(g)
        east = (lon[0] - centre["lon"]) * 111320 * math.cos(math.radians(centre["lat"]))
        north = (lat[0] - centre["lat"]) * 110540
        # measured 1.7-8 m: the platform's wobble and the terrain beside the aimed height
        assert math.hypot(east, north) < 40.0, name
    epochs = {m["name"]: m["epoch"] for m in block["manifest"]["members"]}
    assert epochs["fwd"] < epochs["nad"] < epochs["bwd"]       # one pass: forward view first, 22.7 s apart
    assert epochs["date2"].startswith("2011-03-02T")


def test_true_models_reproduce_gcps_and_onboard_models_miss_by_the_drawn_errors(block):
    g, worst, misses = block["gcps"], 0.0, {}
    assert set(g["scene"]) == {"fwd", "nad", "bwd", "date2"}
    assert set(g["role"]) == {"control", "check"}
    residual = []
    for name, scene in block["true"].items():
        rows = np.nonzero(g["scene"] == name)[0]
        col, row = _project(scene, g, rows)
        c_true, r_true, c, r = _f({k: v[rows] for k, v in g.items()}, "col_true", "row_true", "col", "row")
        worst = max(worst, float(np.max(np.hypot(col - c_true, row - r_true))))
        residual.append(np.concatenate([c - col, r - row]))
        oc, orow = _project(block["onboard"][name], g, rows)
        misses[name] = float(np.median(np.hypot(oc - col, orow - row)))
    assert worst < 1e-6                                          # measured ~1e-8 px
    rms = float(np.sqrt(np.mean(np.concatenate(residual) ** 2)))
    assert 0.8 * NOISE < rms < 1.2 * NOISE                        # measured 0.301 px
    # one ground point, one id in every scene: the same truth on each of its rows
    for column in ("lon_true", "lat_true", "h_true", "lon", "lat", "h", "role"):
        per_id = {}
        for i, v in zip(g["id"], g[column]):
            assert per_id.setdefault(i, v) == v, column
    assert sum(len(set(g["scene"][g["id"] == i])) > 1 for i in set(g["id"])) > 20   # shared: 25 of 60
    # Onboard: the attitude bias of each member seen from its slant range, ~10 px (measured 8.4-18.9 px
    # against 8.5-11.1 predicted; the three-line member adds its cameras' installation errors)
    for m in block["manifest"]["members"]:
        bias = np.asarray(m["truth"]["trajectory"]["attitude_bias"])
        slant = TLC.altitude / (math.cos(math.radians(m["view_deg"]["pitch"])) * math.cos(math.radians(m["view_deg"]["roll"])))
        predicted = math.hypot(bias[0], bias[1]) * slant / 5.0
        assert 0.5 * predicted < misses[m["name"]] < 1.6 * predicted + 3.0, (m["name"], misses, predicted)
        assert misses[m["name"]] > 5.0
    drawn = [tuple(m["truth"]["trajectory"]["attitude_bias"]) for m in block["manifest"]["members"]]
    assert len(set(drawn)) == len(drawn)                           # each member its own draw


def test_tie_points_of_one_id_are_one_ground_point_in_every_scene(block):
    t, dem = block["ties"], block["dem"]
    ids, first = np.unique(t["id"], return_index=True)
    assert ids.size == 80
    assert all(len(set(t["scene"][t["id"] == i])) >= 2 for i in ids)
    # the ground each id's first observation sees (its scene's true model on the DEM) ...
    ground = np.empty((ids.size, 3))
    for name, scene in block["true"].items():
        for k, cam in enumerate(scene.cameras):
            m = (t["scene"][first] == name) & (t["camera"][first] == cam.name)
            col, row = _f({n: t[n][first[m]] for n in ("col_true", "row_true")}, "col_true", "row_true")
            ground[m] = scene.image_to_ground_dem(col, row, dem, k)
    where = np.searchsorted(ids, t["id"])
    # ... is where every other scene and camera measured it
    worst = 0.0
    for name, scene in block["true"].items():
        for k, cam in enumerate(scene.cameras):
            m = (t["scene"] == name) & (t["camera"] == cam.name)
            col, row = scene.ground_to_image(ground[where[m]], k)
            worst = max(worst, float(np.max(np.hypot(col - t["col_true"][m].astype(float),
                                                       row - t["row_true"][m].astype(float)))))
    assert worst < 2e-3                                                 # measured 1.1e-5 px (DEM intersection)
    noise = np.concatenate([t["col"].astype(float) - t["col_true"].astype(float),
                            t["row"].astype(float) - t["row_true"].astype(float)])
    assert 0.8 * NOISE < np.std(noise) < 1.2 * NOISE


def test_an_orbit_offset_moves_the_strip_across_track(tmp_path):
    """A neighbour strip 1.5 km to the right of the track: its image centre moves 1.5 km across the
    track and not along it; the 1 km of shared ground carries the tie points."""
    members = [BlockMember("left", ONE), BlockMember("right", ONE, orbit_offset_km=1.5)]
    sim = _load(simulate_block(members, tmp_path / "b", seed=2, n_gcps=20, n_tie_points=20))
    centres = []
    for name in ("left", "right"):
        scene = sim["true"][name]
        cam = scene.cameras[0]
        centres.append(scene.image_to_ground_dem(np.array([cam.cols / 2, cam.cols / 2]),
                                                 np.array([cam.rows / 2, cam.rows / 2 + 100]), sim["dem"]))
    along = centres[0][1] - centres[0][0]                   # 100 rows along the track
    step = centres[1][0] - centres[0][0]
    along_m = float(step @ along / np.linalg.norm(along))
    across_m = float(np.linalg.norm(step - along_m * along / np.linalg.norm(along)))
    assert abs(across_m - 1500.0) < 25.0 and abs(along_m) < 25.0   # measured 1501.5 m and -7.1 m
    # right of the (descending, south-going) track is west: the right strip's columns see it
    col, _ = sim["true"]["left"].ground_to_image(centres[1][:1])
    assert abs(col[0] - (250.0 - 300.0)) < 10.0                # 1.5 km = 300 px west of the centre: measured -51.0
    assert set(sim["ties"]["scene"]) == {"left", "right"}


# --- rendering: one ground texture in every image --------------------------------------------------------
def _chips(image: Path, col: np.ndarray, row: np.ndarray, half: int = 10) -> np.ndarray:
    """(n, 2 half + 1, 2 half + 1) chips of an image centred on (col, row) (GDAL, pixel centres at +0.5)."""
    a = gdal.Open(str(image)).ReadAsArray().astype(float)
    d = np.arange(-half, half + 1)
    rr = row[:, None, None] - 0.5 + d[None, :, None]
    cc = col[:, None, None] - 0.5 + d[None, None, :]
    return map_coordinates(a, [rr + 0 * cc, cc + 0 * rr], order=1)


def _ncc(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a = a - a.mean(axis=(1, 2), keepdims=True)
    b = b - b.mean(axis=(1, 2), keepdims=True)
    return (a * b).sum(axis=(1, 2)) / np.sqrt((a * a).sum(axis=(1, 2)) * (b * b).sum(axis=(1, 2)))


def _pair(sim: dict, a: str, b: str) -> tuple:
    """True positions in members a and b of the tie points both see, 15 px from the borders."""
    t = sim["ties"]
    pos = {}
    for name in (a, b):
        m = t["scene"] == name
        pos[name] = dict(zip(t["id"][m], zip(t["col_true"][m].astype(float), t["row_true"][m].astype(float))))
    both = sorted(set(pos[a]) & set(pos[b]))
    pa, pb = np.array([pos[a][i] for i in both]), np.array([pos[b][i] for i in both])
    ok = np.all((pa > 15) & (pa < 485) & (pb > 15) & (pb < 485), axis=1)
    return pa[ok], pb[ok]


def test_rendered_members_show_one_ground(rendered):
    images = {n: next(iter(f["images"].values())) for n, f in rendered["result"].members.items()}
    assert images["fwd"].name == "image_NAD.tif" and images["date2"].name == "date2.tif"
    pa, pb = _pair(rendered, "fwd", "bwd")
    assert len(pa) > 40
    ncc = _ncc(_chips(images["fwd"], *pa.T), _chips(images["bwd"], *pb.T))
    shifted = _ncc(_chips(images["fwd"], *pa.T), _chips(images["bwd"], pb[:, 0] + 8, pb[:, 1]))
    assert np.median(ncc) > 0.95 and ncc.min() > 0.8             # measured median 0.996, min 0.974
    assert np.median(shifted) < 0.5                              # 8 px off: measured 0.30
    # another date: other gain, gamma and noise, and patches of changed land cover
    pa, pc = _pair(rendered, "nad", "date2")
    ncc = _ncc(_chips(images["nad"], *pa.T), _chips(images["date2"], *pc.T))
    assert np.median(ncc) > 0.9                                  # measured 0.997; a changed patch: min -0.34
    look = {m["name"]: m["radiometry"] for m in rendered["manifest"]["members"]}
    assert look["fwd"] == look["nad"] == look["bwd"] and look["fwd"]["gain"] == 1.0
    assert look["date2"]["gain"] != 1.0 and look["date2"]["noise"] > 0
    assert rendered["result"].reference.is_file()


def test_rpc_member_reproduces_its_onboard_scene(rendered):
    files = rendered["result"].members["date2"]
    rpc_path = files["rpc"]["NAD"]
    assert rpc_path.name == "date2_RPC.TXT" and rpc_path.parent.name == "date2"
    rpc = load_scene(rpc_path)
    assert rpc.info["image"] == str(files["images"]["NAD"]) and not rpc.info["warnings"]  # GDAL pairs them
    onboard, dem = rendered["onboard"]["date2"], rendered["dem"]
    cam = onboard.cameras[0]
    c, r = (v.ravel() for v in np.meshgrid(np.linspace(0.5, cam.cols - 0.5, 25), np.linspace(0.5, cam.rows - 0.5, 25)))
    ground = onboard.image_to_ground_dem(c, r, dem)
    col, row = rpc.ground_to_image(ground)
    error = float(np.max(np.hypot(col - c, row - r)))
    assert error < 0.05                                          # measured 6e-8 px
    fit = {m["name"]: m["rpc_fit_px"] for m in rendered["manifest"]["members"]}
    assert fit["date2"]["NAD"]["max_px"] < 0.05 and fit["fwd"] is None


# --- files and bad input -------------------------------------------------------------------------------
def test_a_block_rewrites_its_own_files_and_refuses_foreign_ones(tmp_path):
    members = [MEMBERS[0], replace(MEMBERS[2], name="bwd")]
    simulate_block(members, tmp_path / "b", seed=1, n_gcps=5, n_tie_points=5)
    simulate_block(members, tmp_path / "b", seed=2, n_gcps=5, n_tie_points=5)   # its own files: replaced
    edited = tmp_path / "b" / "fwd" / "true_scene.json"                         # a user's edit, after the block
    edited.write_text("{}")
    later = (tmp_path / "b" / "block.json").stat().st_mtime_ns + 10 ** 9
    os.utime(edited, ns=(later, later))
    with pytest.raises(OutputError, match="fwd/true_scene.json"):
        simulate_block(members, tmp_path / "b", seed=3, n_gcps=5, n_tie_points=5)


def test_cancel_leaves_nothing(tmp_path):
    calls = []

    def cancel() -> bool:
        calls.append(1)
        return len(calls) > 3

    with pytest.raises(Cancelled):
        simulate_block(MEMBERS[:3], tmp_path / "x" / "block", seed=1, n_gcps=5, n_tie_points=5, render=True,
                       is_cancelled=cancel)
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("members, field, message", [
    ([], "members", "at least one member"),
    ([BlockMember("a", ONE, along_track_km=5000.0)], "members[0].along_track_km", "offset"),
    ([BlockMember("a", ONE), BlockMember("A", ONE)], "members[1].name", r"already the name of members\[0\]"),
    ([BlockMember("../up", ONE)], "members[0].name", "not safe as a folder name"),
    ([BlockMember("dem.tif", ONE)], "members[0].name", "not safe"),
    ([BlockMember("", ONE)], "members[0].name", "not safe"),
    ([BlockMember("a", "spot9")], "members[0].preset", "unknown preset"),
    ([BlockMember("a", ONE, view=(60.0, 0.0))], "members[0].view", "pitch must be a number between -45 and 45"),
    ([BlockMember("a", ONE, view=(0.0, float("nan")))], "members[0].view", "roll"),
    ([BlockMember("a", ONE, view=5.0)], "members[0].view", r"\(pitch, roll\)"),
    ([BlockMember("a", ONE, orbit_offset_km="far")], "members[0].orbit_offset_km", "offset"),
    ([BlockMember("a", ONE, date="2011-02-30")], "members[0].date", "not a calendar date"),
    ([BlockMember("a", ONE, errors={"attitude_bias": -1.0})], "members[0].errors", ">= 0"),
    ([BlockMember("a", ONE, errors={"wobble": 1.0})], "members[0].errors", "unknown error setting"),
    ([BlockMember("a", ONE, rpc="yes")], "members[0].rpc", "True or False"),
    ([BlockMember("a", ONE), BlockMember("b", ONE, orbit_offset_km=30.0)], "members",
     "share no common ground: a \\| b"),
])
def test_bad_members_are_refused_naming_the_field(tmp_path, members, field, message):
    with pytest.raises(InputError, match=message) as info:
        simulate_block(members, tmp_path / "out", n_gcps=5, n_tie_points=5)
    assert info.value.parameter == field
    assert field.split(".")[0] in str(info.value) or field == "members"
    assert not (tmp_path / "out").exists()


def test_tie_points_need_two_members(tmp_path):
    with pytest.raises(InputError, match="at least two members") as info:
        simulate_block([BlockMember("a", ONE)], tmp_path / "out", n_tie_points=5)
    assert info.value.parameter == "n_tie_points"
    simulate_block([BlockMember("a", ONE)], tmp_path / "out", n_gcps=5, n_tie_points=0)
    assert (tmp_path / "out" / "a" / "true_scene.json").is_file()
