"""Time bases and trajectory corrections: each family reproduces what it should, corrections
round-trip through scene JSON, and the negated simulated errors restore the true trajectory."""
import json

import numpy as np
import pytest

from pushbroom_adjust.core.errors import InputError, MetadataError
from pushbroom_adjust.core.geodesy import geodetic_to_ecef
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.scene_json import save_scene
from pushbroom_adjust.simulation.simulator import simulate
from pushbroom_adjust.core.model.timebasis import TimeBasis
from pushbroom_adjust.core.model.trajectory import TrajectoryCorrection


@pytest.mark.parametrize("kind", ["lagrange", "spline"])
def test_knot_bases_are_partitions_of_unity_and_reproduce_lines(kind):
    b = TimeBasis.covering(kind, -100.0, 100.0, interval=13.0)
    assert b.knot_times()[0] <= -100.0 and b.knot_times()[-1] >= 100.0
    t = np.linspace(-120.0, 120.0, 999)
    m = b.matrix(t)
    assert m.shape == (999, b.size) and np.allclose(m.sum(axis=1), 1.0, atol=1e-12)
    # a straight line is represented exactly: Lagrange by its knot values, the spline by its
    # Greville abscissae (mid-points of the knot intervals around each function)
    knots = b.start + b.interval * np.arange(-2, b.n_knots + 2)
    nodes = b.knot_times() if kind == "lagrange" else 0.5 * (knots[1:-2] + knots[2:-1])
    assert np.allclose(m @ (3.0 + 0.5 * nodes), 3.0 + 0.5 * t, atol=1e-9)


def test_lagrange_interpolates_its_knots_and_uses_four_of_them():
    b = TimeBasis.covering("lagrange", 0.0, 60.0, interval=10.0)
    m = b.matrix(b.knot_times())
    assert np.allclose(m, np.eye(b.size), atol=1e-12)
    assert np.all(np.count_nonzero(np.abs(b.matrix(np.linspace(1, 59, 50))) > 1e-12, axis=1) <= 4)


def test_spline_is_continuous_in_value_and_slope_at_knots():
    b = TimeBasis.covering("spline", 0.0, 50.0, interval=10.0)
    c = np.random.default_rng(0).normal(size=b.size)
    for k in b.knot_times()[1:-1]:
        h = 1e-6
        left, right = b.matrix([k - h]) @ c, b.matrix([k + h]) @ c
        assert abs(left - right)[0] < 1e-6
        s_left = (b.matrix([k - h]) @ c - b.matrix([k - 2 * h]) @ c) / h
        s_right = (b.matrix([k + 2 * h]) @ c - b.matrix([k + h]) @ c) / h
        assert abs(s_left - s_right)[0] < 1e-3


def test_polynomial_derivative_and_bad_settings():
    b = TimeBasis.covering("polynomial", -10.0, 30.0, order=2)
    t = np.array([-5.0, 7.0])
    tau = (t - 10.0) / 20.0
    assert np.allclose(b.matrix(t), np.stack([np.ones(2), tau, tau * tau], axis=1))
    assert np.allclose(b.derivative(t), np.stack([np.zeros(2), np.full(2, 1 / 20), 2 * tau / 20], axis=1))
    with pytest.raises(InputError, match="polynomial order must be 0, 1 or 2"):
        TimeBasis("polynomial", order=3)
    with pytest.raises(InputError, match="unknown trajectory model 'cubic'"):
        TimeBasis("cubic")
    with pytest.raises(InputError, match="needs a positive knot interval"):
        TimeBasis.covering("lagrange", 0.0, 10.0)


def test_negated_simulated_errors_restore_the_true_scene(tmp_path):
    """Onboard position bias/drift/quadratic and attitude bias/drift undone by a polynomial
    correction: the corrected onboard scene meets the truth (no interior errors simulated)."""
    result = simulate("cbers02b_hrc", tmp_path, seed=3, n_gcps=200, image_noise=0.0,
                      errors={"ccd_shift": 0.0, "ccd_rotation": 0.0})
    truth = json.loads(result.manifest.read_text())["truth"]["trajectory"]
    onboard = load_scene(result.onboard_scene)
    t_min, t_max = onboard.time_span()
    # the simulator's error polynomials are in seconds from t = 0, the strip's middle
    basis = TimeBasis("polynomial", t0=0.0, scale=0.5 * (t_max - t_min), order=2)
    powers = basis.scale ** np.arange(3)[:, None]
    pos = -np.array([truth["position_bias"], truth["position_drift"], truth["position_quadratic"]]) * powers
    att = -np.array([truth["attitude_bias"], truth["attitude_drift"], truth["attitude_quadratic"]]) * powers
    onboard.platform.correction = TrajectoryCorrection(basis, pos, basis, att)
    save_scene(onboard, tmp_path / "corrected.json")
    corrected = load_scene(tmp_path / "corrected.json")
    assert json.loads((tmp_path / "corrected.json").read_text())["version"] == 2
    g = np.genfromtxt(result.gcps, delimiter=",", names=True, dtype=None, encoding=None)
    col, row = corrected.ground_to_image(geodetic_to_ecef(g["lon_true"], g["lat_true"], g["h_true"]))
    # (-a) undoes R(a) to second order: ~ a^2 / 2 = 1e-7 rad, 0.03 px from 778 km
    assert np.max(np.hypot(col - g["col_true"], row - g["row_true"])) < 0.05


def test_malformed_correction_in_scene_json_names_the_file(tmp_path):
    result = simulate("cbers02b_hrc", tmp_path, seed=1, n_gcps=5)
    d = json.loads(result.onboard_scene.read_text())
    basis = {"kind": "polynomial", "t0": 0.0, "scale": 1.0, "order": 5}
    d["platform"]["correction"] = {"position": {"basis": basis, "coefficients": [[0, 0, 0]]},
                                   "attitude": {"basis": basis, "coefficients": [[0, 0, 0]]}}
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    with pytest.raises(MetadataError, match=r"bad.json: malformed value \(polynomial order must be 0, 1 or 2"):
        load_scene(bad)
