"""A tiny hand-made pushbroom scene (one camera of 1000 x 2000 px, a straight orbit), for tests of
scene files and their checks that need no simulation."""
import numpy as np

from pushbroom_adjust.core.model.camera import Camera, Chip, LineTiming
from pushbroom_adjust.core.model.sensor import SceneModel
from pushbroom_adjust.core.model.trajectory import Ephemeris, Platform, QuaternionPolynomial


def tiny_scene() -> SceneModel:
    """Camera PAN (1000 columns, 2000 rows, 1 ms lines, one look-angle chip) on a platform 7000 km
    from the Earth's centre moving 7 km/s along y, looking toward the Earth; aberration on, sensor
    'test', height range 0-100 m."""
    t = np.arange(-20.0, 21.0, 5.0)
    pos = np.stack([7.0e6 + 0 * t, 7000.0 * t, 1000.0 + 0 * t], 1)
    # body z (the view) toward -x ECEF, i.e. toward the Earth from x = 7000 km
    att = QuaternionPolynomial(0.0, 1.0, np.array([[0.5 ** 0.5, 0.0], [0.0, 0.0], [-(0.5 ** 0.5), 0.0], [0.0, 0.0]]))
    chip = Chip(col_offset=0, n_pixels=1000, kind="look_angle", ux_poly=[0.0], uy_poly=[-0.01, 2e-5])
    cam = Camera("PAN", 1000, 2000, LineTiming(-1.0, 1e-3), [chip])
    return SceneModel("2020-01-01T00:00:00Z", Platform(Ephemeris(t, pos), att), [cam], aberration=True,
                      info={"sensor": "test", "height_range": [0.0, 100.0]})
