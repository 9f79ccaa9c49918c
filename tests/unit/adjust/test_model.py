"""core.adjust.model on a simulated CBERS-02B HRC scene (three chips): the exact projection against
the sensor model's own ground -> image, its analytic Jacobian against central differences of the
projection, and the pixel map against differences of r_u. The engine's Problem-level check of the
whole Jacobian is tests/unit/adjust/test_engine.py; these call the module's functions directly."""
import numpy as np
import pytest

from pushbroom_adjust.core.adjust.checks import check_inputs
from pushbroom_adjust.core.adjust.model import (PROJECTION_TOLERANCE, Imaging, Model, build_observations,
                                                pixel_map, project)
from pushbroom_adjust.core.adjust.problem import Problem
from pushbroom_adjust.core.adjust.ties import camera_indices
from pushbroom_adjust.core.model.camera import CAMERA_TERMS
from tests.support.cbers_strip import settings, strip

# corrections away from zero: the installation a few arcseconds, the chips some micrometres, f 20 um
SHIFTED = {"HRC.roll": 2e-5, "HRC.pitch": -1.5e-5, "HRC.yaw": 3e-5, "HRC.f": 2e-5, "HRC-1.dx": 8e-6,
           "HRC-1.dy": -5e-6, "HRC-3.theta": 1e-4}


@pytest.fixture(scope="module")
def scene_and_points(tmp_path_factory):
    """(scene, its parameter set (HRC interior free) shifted by SHIFTED, the GCP table, the
    observations as measured, the ground points (n,3) ECEF)."""
    _, scene, table = strip(tmp_path_factory.mktemp("model"), 1, 80, seed=3)
    s = settings(interior="HRC.*, HRC-1.*, HRC-3.*")
    table = check_inputs(scene, table, s)
    params = Problem(scene, table, s).params
    values = params.values()
    for name, value in SHIFTED.items():
        values[params.index[name]] = value
    params.set_values(values)
    imaging = Imaging(scene, params)
    obs = build_observations(imaging, camera_indices(scene, table.camera), table.col, table.row,
                             np.arange(len(table)), 0.7)
    return scene, params, imaging, obs, table.ecef()


def imaged(params, imaging, obs, x, start_shift=(0.0, 0.0)):
    """(observations imaged where the current model images x, T there, imaged (col, row) (n,2))."""
    start = imaging.at(obs, obs.col + start_shift[0], obs.row + start_shift[1])
    return project(Model(imaging.scene, params), imaging, obs, x, start)


def test_projection_is_the_adjusted_scenes_ground_to_image_from_any_start(scene_and_points):
    """Measured: 3e-10 px from the adjusted scene's own ground -> image, the same from starts 5 px
    apart; r_u at the imaged position ~1e-15 rad (rounding), i.e. < 1e-9 px."""
    scene, params, imaging, obs, x = scene_and_points
    col, row = params.adjusted_scene().ground_to_image(x)
    assert np.abs(col - obs.col).max() > 50.0  # the shifted model images the points far from the measured ones
    model = Model(scene, params)
    results = []
    for shift in ((0.0, 0.0), (3.0, -2.0), (-4.0, 5.0)):
        _, T, pred = imaged(params, imaging, obs, x, shift)
        assert np.isfinite(pred).all()
        assert np.abs(pred[:, 0] - col).max() < 1e-6 and np.abs(pred[:, 1] - row).max() < 1e-6
        r_u = model.residuals_u(imaging.at(obs, pred[:, 0], pred[:, 1]), x)
        assert np.abs(np.einsum("nij,nj->ni", T, r_u)).max() < PROJECTION_TOLERANCE
        results.append(pred)
    assert np.abs(results[1] - results[0]).max() < 1e-8 and np.abs(results[2] - results[0]).max() < 1e-8


def test_a_point_behind_the_camera_is_imaged_nowhere(scene_and_points):
    scene, params, imaging, obs, x = scene_and_points
    behind = x.copy()
    behind[:3] = -x[:3]  # the antipodes: on the far side of the Earth
    _, _, pred = imaged(params, imaging, obs, behind)
    assert np.isnan(pred[:3]).any(axis=1).all() and np.isfinite(pred[3:]).all()


def test_pixel_map_inverts_the_derivative_of_r_u_by_the_image_position(scene_and_points):
    """T = -(d r_u / d(col, row))^-1: T times central differences of r_u (0.5 px steps) gives -I to
    6e-8 (measured)."""
    scene, params, imaging, obs, x = scene_and_points
    model = Model(scene, params)
    _, _, pred = imaged(params, imaging, obs, x)
    at = imaging.at(obs, pred[:, 0], pred[:, 1])
    T = pixel_map(model, imaging, at, x, model.residuals_u(at, x))
    h = 0.5

    def r(dc, dr):
        return model.residuals_u(imaging.at(obs, at.col + dc, at.row + dr), x)

    D = np.stack([(r(h, 0) - r(-h, 0)) / (2 * h), (r(0, h) - r(0, -h)) / (2 * h)], axis=2)  # (n,2,2)
    assert np.abs(T @ D + np.eye(2)).max() < 1e-5


def numeric_derivative(params, imaging, obs, x, name, step):
    """(n,2) px per unit: central differences of the projection by parameter ``name``."""
    values = params.values()
    out = []
    for sign in (1, -1):
        v = values.copy()
        v[params.index[name]] += sign * step
        params.set_values(v)
        out.append(imaged(params, imaging, obs, x)[2])
    params.set_values(values)
    return (out[0] - out[1]) / (2 * step)


@pytest.mark.parametrize("name, block, term, step", [
    ("HRC.roll", "installation", 0, 1e-6), ("HRC.yaw", "installation", 2, 1e-6),
    ("HRC.f", "camera", CAMERA_TERMS.index("f"), 1e-5), ("HRC-1.dx", "chip", 0, 1e-6),
    ("HRC-3.theta", "chip", 2, 1e-5)])
def test_analytic_jacobian_matches_central_differences_of_the_projection(scene_and_points, name, block, term, step):
    """Measured relative differences: roll 7e-10, f 6e-8, HRC-1.dx 4e-6, HRC-3.theta 5e-6."""
    scene, params, imaging, obs, x = scene_and_points
    cur, T, _ = imaged(params, imaging, obs, x)
    jac = Model(scene, params).linearize(cur, x, T)
    analytic = getattr(jac, block)[:, :, term]
    if block == "chip":  # a chip's terms move only the observations on that chip
        chip = int(name.split(".")[0].split("-")[1]) - 1
        analytic = np.where((cur.chip == chip)[:, None], analytic, 0.0)
    numeric = numeric_derivative(params, imaging, obs, x, name, step)
    assert np.abs(numeric).max() > 1e3  # px per unit: a parameter that moves the points
    assert np.abs(analytic - numeric).max() < 1e-4 * np.abs(numeric).max(), name


def test_ground_jacobian_matches_central_differences_of_the_projection(scene_and_points):
    scene, params, imaging, obs, x = scene_and_points
    cur, T, _ = imaged(params, imaging, obs, x)
    jac = Model(scene, params).linearize(cur, x, T)
    for a in range(3):
        dx = np.zeros(3)
        dx[a] = 0.05
        numeric = (imaged(params, imaging, obs, x + dx)[2] - imaged(params, imaging, obs, x - dx)[2]) / 0.1
        assert np.abs(numeric).max() > 0.1  # px per m: ~1 / GSD
        assert np.abs(jac.ground[:, :, a] - numeric).max() < 1e-4 * np.abs(numeric).max()
