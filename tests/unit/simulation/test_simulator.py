"""The scene simulator: presets as the seeds describe them, truth reproduced exactly, the
onboard model off by the recorded errors, measurement statistics, rendering, bad input."""
import csv
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import Cancelled, InputError
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.simulation.texture import texture_at, texture_frame, to_digital_numbers
from pushbroom_adjust.simulation.render import render_image
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation.presets import CAMERA_ERRORS, PRESETS, ErrorSettings, camera_term
from pushbroom_adjust.simulation.geometry import nominal_camera, perturbed_camera
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate
from tests.support.seams import round_trip_errors


def _read(path: Path) -> dict:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


def _floats(table, *names):
    return [table[n].astype(float) for n in names]


_SIMULATIONS: dict = {}


def _simulation(preset: str, tmp_path_factory) -> dict:
    """One noise-free simulation per preset for the whole module."""
    if preset not in _SIMULATIONS:
        result = simulate(preset, tmp_path_factory.mktemp(preset), seed=5, n_gcps=400, image_noise=0.0)
        _SIMULATIONS[preset] = {
            "preset": preset, "result": result, "true": load_scene(result.true_scene),
            "onboard": load_scene(result.onboard_scene), "dem": Dem(result.dem, datum="geoid"),
            "gcps": _read(result.gcps), "manifest": json.loads(result.manifest.read_text())}
    return _SIMULATIONS[preset]


@pytest.fixture(scope="module", params=list(PRESETS))
def sim(request, tmp_path_factory):
    return _simulation(request.param, tmp_path_factory)


def _gsd(scene, camera: int, dem) -> tuple[float, float]:
    """(across, along) ground distance (m) between neighbouring pixels at the image centre."""
    cam = scene.cameras[camera]
    c, r = cam.cols / 2 + 100.25, cam.rows / 2
    g = scene.image_to_ground_dem(np.array([c, c + 1, c]), np.array([r, r, r + 1]), dem, camera)
    return float(np.linalg.norm(g[1] - g[0])), float(np.linalg.norm(g[2] - g[0]))


# --- presets ------------------------------------------------------------------------------------------
def test_cbers_hrc_layout_matches_seed_000(tmp_path_factory):
    sim = _simulation("cbers02b_hrc", tmp_path_factory)
    cam = sim["onboard"].cameras[0]
    assert (cam.cols, len(cam.chips)) == (12246, 3)
    assert [c.n_pixels for c in cam.chips] == [4096] * 3
    assert [c.col_offset for c in cam.chips] == [0.0, 4075.0, 8150.0]  # 21 px overlaps
    assert cam.focal_length == 3.3 and cam.chips[0].pitch == 10e-6
    # the middle chip is displaced along track; its rows are delayed to align the image
    assert cam.chips[1].x0 > 0 and cam.chips[0].x0 == cam.chips[2].x0 == 0
    assert cam.chips[1].time_offset < 0 == cam.chips[0].time_offset
    across, along = _gsd(sim["true"], 0, sim["dem"])
    assert 2.30 < across < 2.45 and 2.30 < along < 2.45  # 2.36 m nadir GSD


@pytest.mark.parametrize("preset, gsd", [("th1_tlc", {"NAD": 5.0, "FWD": 5.0 / math.cos(math.radians(25)) ** 2}),
                                         ("zy3_tlc", {"NAD": 2.1, "FWD": 3.5, "BWD": 3.5})])
def test_three_line_cameras_look_forward_nadir_backward(tmp_path_factory, preset, gsd):
    sim = _simulation(preset, tmp_path_factory)
    scene, dem = sim["true"], sim["dem"]
    assert [c.name for c in scene.cameras] == ["NAD", "FWD", "BWD"]
    for name, expected in gsd.items():
        k = scene.camera_index(name)
        across, along = _gsd(scene, k, dem)
        assert along == pytest.approx(expected, rel=0.08), name
    # the same ground point is seen first by the forward, last by the backward camera
    g = scene.image_to_ground_dem(np.array([scene.cameras[0].cols / 2]), np.array([scene.cameras[0].rows / 2]), dem)
    times = {c.name: c.timing.time(scene.ground_to_image(g, k)[1])[0] for k, c in enumerate(scene.cameras)}
    assert times["FWD"] < times["NAD"] < times["BWD"]
    lead = times["NAD"] - times["FWD"]
    tilt = 25.0 if preset == "th1_tlc" else 22.0
    assert lead == pytest.approx(PRESETS[preset].altitude * math.tan(math.radians(tilt)) / 7000.0, rel=0.1)


# --- truth and onboard errors --------------------------------------------------------------------------
def test_true_scene_reproduces_noise_free_gcps(sim):
    g = sim["gcps"]
    scene = sim["true"]
    ground = geodetic_to_ecef(*_floats(g, "lon_true", "lat_true", "h_true"))
    worst = 0.0
    for k, cam in enumerate(scene.cameras):
        m = g["camera"] == cam.name
        col, row = scene.ground_to_image(ground[m], k)
        c0, r0 = _floats({n: g[n][m] for n in ("col_true", "row_true")}, "col_true", "row_true")
        worst = max(worst, np.max(np.hypot(col - c0, row - r0)))
        # noise 0: measured = true
        assert np.array_equal(g["col"][m].astype(float), c0)
    assert worst < 1e-6  # measured 2e-8 px
    # ground points lie on the DEM
    lon, lat, h = _floats(g, "lon_true", "lat_true", "h_true")
    assert np.max(np.abs(h - sim["dem"].height(lon, lat))) < 1e-3


def test_onboard_model_is_off_by_the_simulated_errors(sim):
    g = sim["gcps"]
    m = g["camera"] == sim["true"].cameras[0].name
    col, row, lon, lat, h = _floats({k: v[m] for k, v in g.items()}, "col_true", "row_true", "lon_true", "lat_true",
                                    "h_true")
    seen = sim["onboard"].image_to_ground(col, row, h)
    error_m = np.linalg.norm(seen - geodetic_to_ecef(lon, lat, h), axis=1)
    low, high = {"cbers02b_hrc": (150.0, 1500.0)}.get(sim["preset"], (20.0, 300.0))
    assert low < np.median(error_m) < high


def test_manifest_records_the_differences_between_the_models(sim):
    true, onboard, truth = sim["true"], sim["onboard"], sim["manifest"]["truth"]
    for cam_t, cam_o, rec in zip(true.cameras, onboard.cameras, truth["interior"]):
        assert rec["camera"] == cam_t.name
        assert cam_t.focal_length - cam_o.focal_length == pytest.approx(rec["camera_terms"]["f"], abs=1e-15)
        for chip_t, chip_o, c in zip(cam_t.chips, cam_o.chips, rec["chips"]):
            assert (chip_t.x0 - chip_o.x0) / chip_o.pitch == pytest.approx(c["dx_px"], abs=1e-9)
            assert (chip_t.y0 - chip_o.y0) / chip_o.pitch == pytest.approx(c["dy_px"], abs=1e-9)
            assert chip_t.theta - chip_o.theta == pytest.approx(c["dtheta_rad"], abs=1e-15)
    errors = sim["manifest"]["errors"]
    # the middle chip is the reference; the others are off by 1/3..1 of the magnitude
    for c in truth["interior"][0]["chips"]:
        if c["dx_px"] or c["dy_px"]:
            assert errors["ccd_shift"] / 3 <= abs(c["dx_px"]) <= errors["ccd_shift"]
    # the onboard ephemeris is the true one plus the recorded bias and drift (t = 0 mid-strip)
    t = np.array([0.0, 10.0])
    bias, drift, quad = (np.array(truth["trajectory"][k]) for k in
                         ("position_bias", "position_drift", "position_quadratic"))
    diff = onboard.platform.ephemeris.position(t) - true.platform.ephemeris.position(t)
    assert np.allclose(diff, bias + drift * t[:, None] + quad * t[:, None] ** 2, atol=1e-6)


@pytest.mark.parametrize("preset", ["th1_tlc", "zy3_tlc"])
@pytest.mark.parametrize("field", list(CAMERA_ERRORS))
def test_each_camera_term_moves_the_array_end_by_its_px(preset, field):
    """One term at a time: the true camera's image point at the end of the detector line (for
    b1, which a line through the principal point does not see: half the array's length along
    track) lies the drawn px from the nominal camera's, and the drawn px is 1/3..1 of the magnitude."""
    spec = PRESETS[preset].cameras[1]
    nominal = nominal_camera(spec, 1000, 0.0, 1e-3)
    pitch, half = nominal.chips[0].pitch, 0.5 * nominal.cols * nominal.chips[0].pitch
    for seed in range(5):
        true, truth = perturbed_camera(nominal, ErrorSettings(**{field: 3.0}), reference=True,
                                       rng=np.random.default_rng(seed))
        term = CAMERA_ERRORS[field]
        px = truth["camera_terms_px"][term]
        assert 1.0 <= abs(px) <= 3.0
        assert [t for t, v in truth["camera_terms_px"].items() if v] == [term]
        if term == "b1":
            point = (half, 0.0)  # focal-plane x, y (m)
            moved = np.subtract(true._focal_plane_to_normalised(*point), nominal._focal_plane_to_normalised(*point))
        else:  # column 0 is the array end: y = +half on the nominal focal plane
            moved = np.subtract(true.image_plane(0.0), nominal.image_plane(0.0))[:, 0]
        shift = np.hypot(*moved) * nominal.focal_length / pitch
        assert shift == pytest.approx(abs(px), rel=1e-3), (field, seed)  # focal: first order in df/f
        assert truth["camera_terms"][term] == pytest.approx(camera_term(term, px, pitch, half, spec.focal_length),
                                                            rel=1e-12)


def test_preset_camera_terms_round_trip_through_simulation_json(sim):
    """The true scene's cameras carry exactly the SI terms simulation.json records, and those are
    the recorded px converted at each camera's array end."""
    true, onboard = sim["true"], sim["onboard"]
    errors = sim["manifest"]["errors"]
    for cam_t, cam_o, rec in zip(true.cameras, onboard.cameras, sim["manifest"]["truth"]["interior"]):
        si, px = rec["camera_terms"], rec["camera_terms_px"]
        assert cam_o.distortion == {}
        assert cam_t.distortion == {t: v for t, v in si.items() if t != "f" and v}
        assert cam_t.focal_length - cam_o.focal_length == pytest.approx(si["f"], abs=1e-15)
        pitch = cam_o.chips[0].pitch
        for name, term in CAMERA_ERRORS.items():
            assert si[term] == pytest.approx(camera_term(term, px[term], pitch, 0.5 * cam_o.cols * pitch,
                                                         cam_o.focal_length), rel=1e-12, abs=0)
            assert errors[name] / 3 - 1e-12 <= abs(px[term]) <= errors[name] + 1e-12 or px[term] == errors[name] == 0
        assert rec["camera_terms_units"]["k2"] == "1/m4"


def test_three_line_presets_draw_the_seed_dominant_terms():
    """TH-1 (Zhang et al. 2015): principal point and decentring the largest, focal length next,
    b1 and b2 off (their estimates are ~1e-14); ZY-3 (Zhang et al. 2024): calibrated lines of
    sight, sub-pixel interior terms; both keep the trajectory errors of the earlier presets."""
    th1, zy3 = PRESETS["th1_tlc"].errors, PRESETS["zy3_tlc"].errors
    assert min(th1.principal_point_x, th1.principal_point_y, th1.decentring_p1) > max(th1.focal, th1.radial_k1,
                                                                                      th1.affinity_b3) > 0
    assert th1.affinity_b1 == th1.affinity_b2 == 0
    assert max(getattr(zy3, name) for name in CAMERA_ERRORS) < 0.5
    for e in (th1, zy3):
        assert (e.position_bias, e.position_drift, e.attitude_bias, e.attitude_drift, e.attitude_quadratic,
                e.installation) == (10.0, 0.02, 1e-4, 5e-7, 1e-9, 20 * math.pi / 648000)


def test_error_names_of_earlier_versions(tmp_path):
    """'distortion' is radial_k1 under its old name; 'focal_error' was in metres and is refused
    unless 0 (off), which the earlier tests and scripts use."""
    a = simulate("th1_tlc", tmp_path / "a", seed=3, n_gcps=5, errors={"distortion": 2.0, "focal_error": 0.0})
    errors = json.loads(a.manifest.read_text())["errors"]
    assert errors["radial_k1"] == 2.0 and errors["focal"] == 0.0
    with pytest.raises(InputError, match=r"focal_error \(now focal \(px at the array end\)\) replaced"):
        simulate("th1_tlc", tmp_path / "b", seed=3, n_gcps=5, errors={"focal_error": 20e-6})
    assert not (tmp_path / "b").exists()


def test_round_trip_over_the_whole_image(sim):
    rng = np.random.default_rng(1)
    for scene in (sim["true"], sim["onboard"]):
        for k, cam in enumerate(scene.cameras):
            col = np.r_[rng.uniform(0, cam.cols, 3000), 0.0, cam.cols, 0.0, cam.cols]
            row = np.r_[rng.uniform(0, cam.rows, 3000), 0.0, 0.0, cam.rows, cam.rows]
            ground = scene.image_to_ground_dem(col, row, sim["dem"], k)
            c2, r2 = scene.ground_to_image(ground, k)
            err, _ = round_trip_errors(scene, sim["dem"], col, row, c2, r2, k)
            assert np.max(err) < 1e-4, (scene.info["model"], cam.name)


# --- measurements ----------------------------------------------------------------------------------
def test_noise_gross_errors_ground_noise_and_check_points(tmp_path):
    settings = GcpSettings(n_gcps=4000, check_fraction=0.5, image_noise=0.7, ground_noise_xy=3.0,
                           ground_noise_z=10.0, gross_fraction=0.1, gross_min=5.0, gross_max=100.0)
    result = simulate("cbers02b_hrc", tmp_path, seed=2, gcp_settings=settings)
    g = _read(result.gcps)
    col, row, c0, r0 = _floats(g, "col", "row", "col_true", "row_true")
    gross = g["gross"].astype(int) == 1
    good = ~gross
    assert np.std(col[good] - c0[good]) == pytest.approx(0.7, rel=0.06)
    assert np.std(row[good] - r0[good]) == pytest.approx(0.7, rel=0.06)
    assert gross.sum() == 400
    size = np.hypot(col - c0, row - r0)[gross]
    assert size.min() > 5.0 - 4 * 0.7 and size.max() < 100.0 + 4 * 0.7
    assert np.sum(g["role"] == "check") == 2000
    lon, lat, h, lon0, lat0, h0 = _floats(g, "lon", "lat", "h", "lon_true", "lat_true", "h_true")
    d = geodetic_to_ecef(lon, lat, h0) - geodetic_to_ecef(lon0, lat0, h0)
    assert np.sqrt(np.mean(np.sum(d * d, axis=1)) / 2) == pytest.approx(3.0, rel=0.06)
    assert np.std(h - h0) == pytest.approx(10.0, rel=0.06)
    assert set(np.unique(g["sigma_px"])) == {"0.7"}


def test_tie_points_are_seen_by_several_cameras(tmp_path):
    result = simulate("th1_tlc", tmp_path, seed=4, gcp_settings=GcpSettings(n_gcps=10, n_tie_points=300))
    t = _read(result.tie_points)
    ids, counts = np.unique(t["id"], return_counts=True)
    assert ids.size > 250 and counts.min() >= 2 and set(t["camera"]) == {"NAD", "FWD", "BWD"}
    scene = load_scene(result.true_scene)
    ground = geodetic_to_ecef(*_floats(t, "lon_true", "lat_true", "h_true"))
    for k, cam in enumerate(scene.cameras):
        m = t["camera"] == cam.name
        col, row = scene.ground_to_image(ground[m], k)
        assert np.max(np.abs(col - t["col_true"][m].astype(float))) < 1e-6
    # every camera that sees a point measures it: none is missing inside an image
    for k, cam in enumerate(scene.cameras):
        col, row = scene.ground_to_image(ground, k)
        inside = (col >= 0) & (col <= cam.cols) & (row >= 0) & (row <= cam.rows)
        assert set(t["id"][inside]) == set(t["id"][t["camera"] == cam.name]), cam.name
    assert set(t["scene"]) == {"1"}


def test_tie_points_have_gross_errors_and_tie_neighbouring_scenes(tmp_path):
    settings = GcpSettings(n_gcps=10, n_tie_points=1500, image_noise=0.5, gross_fraction=0.05)
    result = simulate("th1_tlc", tmp_path, seed=4, n_scenes=2, gcp_settings=settings)
    t = _read(result.tie_points)
    col, row, c0, r0 = _floats(t, "col", "row", "col_true", "row_true")
    gross = t["gross"].astype(int) == 1
    assert gross.sum() == round(0.05 * t["id"].size)
    assert np.min(np.hypot(col - c0, row - r0)[gross]) > 5.0 - 4 * 0.5
    assert np.std((col - c0)[~gross]) == pytest.approx(0.5, rel=0.08)
    # the scene of each observation is the one its (true) row falls in, in its own camera
    scene = load_scene(result.true_scene)
    rows = np.array([scene.cameras[scene.camera_index(c)].rows for c in t["camera"]])
    assert np.array_equal(t["scene"].astype(int), np.where(r0 < rows / 2, 1, 2))
    # points near the scene boundary are seen in scene 1 by one camera and scene 2 by another
    spans = {i: set(t["scene"][t["id"] == i]) for i in np.unique(t["id"])}
    assert sum(len(s) == 2 for s in spans.values()) >= 10  # measured 33


def _numbers(obj) -> np.ndarray:
    """Every number in a parsed JSON document, in order."""
    if isinstance(obj, dict):
        return np.concatenate([_numbers(v) for v in obj.values()] or [np.zeros(0)])
    if isinstance(obj, list):
        return np.concatenate([_numbers(v) for v in obj] or [np.zeros(0)])
    return np.array([float(obj)]) if isinstance(obj, (int, float)) else np.zeros(0)


def test_same_seed_same_simulation_other_seed_other_errors(tmp_path):
    """Same seed: the same numbers, to the last bit or so (numpy's vector kernels may round the
    last bit differently with memory alignment), the same CSV text and DEM."""
    a = simulate("cbers02b_hrc", tmp_path / "a", seed=9, n_gcps=30)
    b = simulate("cbers02b_hrc", tmp_path / "b", seed=9, n_gcps=30)
    c = simulate("cbers02b_hrc", tmp_path / "c", seed=10, n_gcps=30)
    for name in ("true_scene.json", "onboard_scene.json", "simulation.json"):
        x, y = (_numbers(json.loads((tmp_path / d / name).read_text())) for d in "ab")
        assert x.size == y.size and np.allclose(x, y, rtol=1e-14, atol=0), name
    ga, gb = _read(a.gcps), _read(b.gcps)
    assert all(np.array_equal(ga[k], gb[k]) for k in ("id", "camera", "role", "gross"))
    for k in ("col", "row", "lon", "lat", "h", "col_true", "row_true"):
        assert np.allclose(ga[k].astype(float), gb[k].astype(float), rtol=1e-13, atol=0), k
    assert a.dem.read_bytes() == b.dem.read_bytes()
    assert a.gcps.read_text() != c.gcps.read_text()
    assert json.loads(a.manifest.read_text())["truth"] != json.loads(c.manifest.read_text())["truth"]


def test_strip_of_scenes_is_one_continuous_image(tmp_path):
    result = simulate("cbers02b_hrc", tmp_path, seed=1, n_scenes=4, n_gcps=200)
    scene = load_scene(result.onboard_scene)
    assert scene.cameras[0].rows == 4 * 12246 and scene.info["n_scenes"] == 4
    g = _read(result.gcps)
    assert set(g["scene"]) == {"1", "2", "3", "4"}
    row = g["row_true"].astype(float)
    assert np.all((row >= (g["scene"].astype(int) - 1) * 12246 - 1) & (row <= g["scene"].astype(int) * 12246 + 1))


def test_error_overrides(tmp_path):
    result = simulate("cbers02b_hrc", tmp_path, seed=1, n_gcps=50,
                      errors={"position_bias": 0.0, "position_drift": 0.0, "attitude_bias": 0.0,
                              "attitude_drift": 0.0, "attitude_quadratic": 0.0, "ccd_shift": 0.0,
                              "ccd_rotation": 0.0})
    g = _read(result.gcps)
    onboard = load_scene(result.onboard_scene)
    col, row = onboard.ground_to_image(geodetic_to_ecef(*_floats(g, "lon_true", "lat_true", "h_true")))
    assert np.max(np.hypot(col - g["col_true"].astype(float), row - g["row_true"].astype(float))) < 1e-6


# --- rendering -------------------------------------------------------------------------------------------
def test_rendered_pixels_show_the_texture_where_their_rays_meet_the_dem(sim, tmp_path):
    if sim["preset"] == "cbers02b_hrc":
        cams = [0]
    else:
        cams = [1]  # a tilted camera: relief displacement matters
    scene, dem = sim["true"], sim["dem"]
    frame = texture_frame(scene, dem, 5)
    for k in cams:
        # a 600-row cut of the camera keeps the test fast; geometry is unchanged
        small = replace(scene, cameras=[replace(scene.cameras[k], rows=600)], _guess={})
        path = tmp_path / "img.tif"
        error = render_image(small, 0, dem, path, frame)
        # ground interpolation error in px: measured 2e-4 at nadir, 0.007-0.011 at 22-25 deg
        assert error < (1e-3 if sim["preset"] == "cbers02b_hrc" else 0.02)
        from osgeo import gdal
        img = gdal.Open(str(path)).ReadAsArray()
        assert img.shape == (600, small.cameras[0].cols) and img.dtype == np.uint8
        rng = np.random.default_rng(3)
        i, j = rng.integers(0, 600, 3000), rng.integers(0, img.shape[1], 3000)
        lon, lat, _ = ecef_to_geodetic(small.image_to_ground_dem(j + 0.5, i + 0.5, dem))
        expected = to_digital_numbers(texture_at(lon, lat, tuple(frame["centre"]), frame["gsd_m"], 5))
        assert np.max(np.abs(img[i, j].astype(int) - expected.astype(int))) <= 1


def test_render_through_simulate_is_cancellable_and_leaves_no_partial_files(tmp_path):
    calls = []

    def cancel_when_rendering():
        calls.append(1)
        return len(calls) > 6  # past the model-writing steps, inside rendering

    with pytest.raises(Cancelled):
        simulate("th1_tlc", tmp_path, seed=1, n_gcps=20, render=True, is_cancelled=cancel_when_rendering)
    assert list(tmp_path.iterdir()) == []


# --- bad input ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, message", [
    ({"preset": "spot5"}, "unknown preset 'spot5'"),
    ({"n_scenes": 0}, "n_scenes must be between 1 and 200"),
    ({"errors": {"roll_bias": 1.0}}, r"unknown error setting\(s\) \['roll_bias'\]"),
    ({"errors": {"ccd_shift": -1.0}}, "error magnitudes must be finite and >= 0"),
    ({"errors": {"ccd_shift": float("nan")}}, "error magnitudes must be finite and >= 0"),
    ({"gcp_settings": GcpSettings(check_fraction=1.5)}, "check_fraction must be between 0 and 1"),
    ({"gcp_settings": GcpSettings(gross_min=10, gross_max=5)}, r"gross_max \(5\) must not be below gross_min"),
    ({"gcp_settings": GcpSettings(n_tie_points=10)}, "tie points need a preset with several cameras"),
])
def test_bad_settings_are_named_and_nothing_is_written(tmp_path, kwargs, message):
    args = {"preset": "cbers02b_hrc", "folder": tmp_path / "out", "n_gcps": 5, **kwargs}
    with pytest.raises(InputError, match=message):
        simulate(**args)
    assert not (tmp_path / "out").exists() or list((tmp_path / "out").iterdir()) == []
