"""Real data: the Pleiades 1B scene with a known attitude bias and drift added to its
attitude, GCPs from the vendor's own direct RFM at DEM heights with 0.3 px noise. The
adjustment must recover the bias and drift (with opposite sign: it corrects them) within
their sigmas, and bring the check points to the noise."""
import numpy as np
import pytest

from core.adjust import AdjustmentSettings, adjust
from core.dem import Dem
from core.gcps import GcpTable
from core.readers.dimap import read_dimap_rfm
from core.rotations import matrix_to_quat, rotation_from_angles
from core.scene_io import load_scene
from core.sensor import SceneModel
from core.trajectory import Platform, QuaternionSamples

DIMAP = "pleiades/PHRDIMAP_P1BP--2018122638935449CP.XML"
MNT = "pleiades/MNT_P1BP--2018122638935449CP.tif"
BIAS = np.array([20e-6, -15e-6, 30e-6])   # rad: roll, pitch, yaw (14, 10, 21 m on the ground)
DRIFT = np.array([2e-6, -1.5e-6, 1e-6])   # rad/s over the ~2.8 s acquisition


@pytest.fixture(scope="module")
def truth(shared_data):
    return load_scene(shared_data / DIMAP)


def perturbed(scene: SceneModel, bias, drift) -> SceneModel:
    """The scene with its attitude turned by R(bias + drift (t - t_mid)) in the body frame,
    sampled every 20 ms (8-point Lagrange: exact to ~1e-12 rad)."""
    t_min, t_max = scene.time_span()
    t_mid = 0.5 * (t_min + t_max)
    t = np.arange(t_min - 1.0, t_max + 1.0, 0.02)
    angles = bias + drift * (t - t_mid)[:, None]
    rot = scene.platform.attitude.rotation(t) @ rotation_from_angles(*angles.T)
    platform = Platform(scene.platform.ephemeris, QuaternionSamples(t, matrix_to_quat(rot), order=8))
    return SceneModel(scene.epoch, platform, scene.cameras, scene.aberration, scene.refraction, dict(scene.info))


def vendor_gcps(scene, shared_data, noise_px: float, seed: int) -> GcpTable:
    """A 14 x 14 grid of image points located on the DEM by the vendor direct RFM; every
    other point a check point; measured image positions with noise."""
    _, direct = read_dimap_rfm(shared_data / DIMAP)
    dem = Dem(shared_data / MNT, datum="geoid")
    cam = scene.cameras[0]
    c, r = (a.ravel() for a in np.meshgrid(np.linspace(600, cam.cols - 600, 14), np.linspace(600, cam.rows - 600, 14)))
    h = np.full(c.shape, np.mean(dem.height_range))
    for _ in range(4):  # the RFM's ground point at the DEM height under it
        lon, lat = direct.image_to_ground(c, r, h)
        h = dem.height(lon, lat)
    rng = np.random.default_rng(seed)
    n = c.size
    return GcpTable(np.char.add("P", np.arange(n).astype(str)), np.where(np.arange(n) % 2, "check", "control"),
                    np.full(n, cam.name), c + rng.normal(0, noise_px, n), r + rng.normal(0, noise_px, n), lon, lat, h,
                    noise_px, 0.05, 0.05)


SETTINGS = AdjustmentSettings(position_model="polynomial", position_order=0, position_sigma=1.0,
                              attitude_model="polynomial", attitude_order=1, robust="none")


def _estimates(report: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    p = {q["name"]: q for q in report["parameters"]}
    pick = lambda term, key: np.array([p[f"attitude.{a}.{term}"][key] for a in ("roll", "pitch", "yaw")])  # noqa: E731
    return pick("bias", "value"), pick("bias", "sigma"), pick("drift", "value"), pick("drift", "sigma")


def test_attitude_bias_and_drift_are_recovered(truth, shared_data):
    onboard = perturbed(truth, BIAS, DRIFT)
    out = adjust(onboard, vendor_gcps(truth, shared_data, 0.3, seed=1), SETTINGS)
    rep = out.report
    bias, bias_sigma, drift, drift_sigma = _estimates(rep)
    half_span = 0.5 * np.subtract(*truth.time_span()[::-1])
    # the correction undoes the error: estimated = -applied (drift per unit of normalised time)
    assert np.all(np.abs(bias + BIAS) < 2 * bias_sigma), (bias, bias_sigma)
    assert np.all(np.abs(drift + DRIFT * half_span) < 3 * drift_sigma), (drift, drift_sigma)
    assert rep["sigma0"] == pytest.approx(1.0, abs=0.15)
    before, after = rep["check_points_before"], rep["check_points"]
    assert before["ground"]["rmse"] > 10.0  # tens of metres from the attitude error
    assert after["image"]["rmse"] < 0.3 * np.sqrt(2) * 1.25  # the 0.3 px noise, both axes
    assert after["ground"]["rmse"] < 0.5


def test_over_noise_draws_the_bias_is_unbiased_with_true_sigmas(truth, shared_data):
    """12 noise draws: errors over reported sigma (z). Measured: roll and pitch |z| <= 0.13 (their
    sigmas include the 1 m orbit uncertainty they trade with); yaw z mean 0.23, std 1.02 —
    within its sigma in 8 of 12 draws, as a 1-sigma bound should be about 68 % of the time."""
    onboard = perturbed(truth, BIAS, DRIFT)
    z = []
    for seed in range(1, 13):
        bias, sigma, _, _ = _estimates(adjust(onboard, vendor_gcps(truth, shared_data, 0.3, seed), SETTINGS).report)
        z.append((bias + BIAS) / sigma)
    z = np.array(z)
    assert np.all(np.abs(z) < 3)
    assert np.all(np.abs(z[:, :2]) < 1)
    assert abs(z[:, 2].mean()) < 0.7 and 0.6 < z[:, 2].std() < 1.4


def test_without_error_the_perturbed_scene_is_the_truth(truth, shared_data):
    same = perturbed(truth, np.zeros(3), np.zeros(3))
    cam = truth.cameras[0]
    c, r = np.array([10.0, cam.cols / 2, cam.cols - 10]), np.array([10.0, cam.rows / 2, cam.rows - 10])
    ground = truth.image_to_ground(c, r, 500.0)
    col, row = same.ground_to_image(ground)
    assert np.max(np.hypot(col - c, row - r)) < 1e-4
