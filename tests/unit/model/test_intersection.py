"""Forward intersection against simulated truth (TH-1 three-line camera)."""
import csv

import numpy as np
import pytest

from pushbroom_adjust.core.geodesy import geodetic_to_ecef
from pushbroom_adjust.core.model.intersection import intersect
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.simulator import simulate


@pytest.fixture(scope="module")
def th1(tmp_path_factory):
    folder = tmp_path_factory.mktemp("th1")
    res = simulate("th1_tlc", folder, seed=3, n_gcps=10,
                   gcp_settings=GcpSettings(n_gcps=10, image_noise=0.0, n_tie_points=60))
    with open(res.tie_points) as f:
        rows = list(csv.DictReader(f))
    true = load_scene(res.true_scene)
    names = [c.name for c in true.cameras]
    ids, point = np.unique([r["id"] for r in rows], return_inverse=True)
    data = {k: np.array([float(r[k]) for r in rows]) for k in ("col_true", "row_true", "lon_true", "lat_true", "h_true")}
    camera = np.array([names.index(r["camera"]) for r in rows])
    return true, load_scene(res.onboard_scene), camera, point, data


def test_true_model_recovers_the_true_points(th1):
    true, _, camera, point, d = th1
    out = intersect(true, camera, d["col_true"], d["row_true"], point)
    truth = geodetic_to_ecef(d["lon_true"], d["lat_true"], d["h_true"])
    error = np.linalg.norm(out.ground[point] - truth, axis=1)
    assert out.converged
    assert np.all(out.rays >= 2)
    assert error.max() < 0.01                      # m
    assert np.abs(out.residuals).max() < 1e-3      # px
    # TH-1 at +-25 deg, 5 m GSD: a few metres per px of image noise
    assert np.all((out.condition > 1.0) & (out.condition < 20.0))


def test_single_rays_are_not_intersected(th1):
    true, _, camera, point, d = th1
    three = np.nonzero(np.bincount(point) == 3)[0][:6]
    obs = [np.nonzero(point == p)[0] for p in three]
    drop = np.concatenate([o[:1] for o in obs[:3]] + [o[:2] for o in obs[3:]])
    keep = ~np.isin(np.arange(point.size), drop)
    out = intersect(true, camera[keep], d["col_true"][keep], d["row_true"][keep], point[keep], int(point.max()) + 1)
    assert np.all(out.rays[three] == [2, 2, 2, 1, 1, 1])
    assert np.isfinite(out.ground[three[:3]]).all()
    assert np.isnan(out.ground[three[3:]]).all()
    assert np.isnan(out.residuals[np.isin(point[keep], three[3:])]).all()


def test_onboard_model_is_off_by_its_trajectory_error(th1):
    true, onboard, camera, point, d = th1
    truth = geodetic_to_ecef(d["lon_true"], d["lat_true"], d["h_true"])
    out = intersect(onboard, camera, d["col_true"], d["row_true"], point)
    error = np.linalg.norm(out.ground[point] - truth, axis=1)
    assert 1.0 < np.median(error) < 500.0


def test_single_rays_only_give_no_point_and_no_error(tmp_path):
    """Every point seen once (e.g. a tie layer of one camera): nothing to intersect, NaN, no error."""
    scene = load_scene(simulate("th1_tlc", tmp_path, seed=1, n_gcps=3).onboard_scene)
    found = intersect(scene, [0, 1, 2], [100.0, 200.0, 300.0], [50.0, 60.0, 70.0], [0, 1, 2], 3)
    assert found.rays.tolist() == [1, 1, 1] and np.isnan(found.ground).all() and found.iterations == 0
