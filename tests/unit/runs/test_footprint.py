"""core.runs.footprint: the use case behind pushbroom:footprint, on a cut of a simulated CBERS-02B scene:
the outline's area is the image's pixel count times the ground area of a pixel at its centre."""

import numpy as np
import pytest

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import Cancelled, InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.runs import footprint as use_case
from pushbroom_adjust.core.runs.base import Terrain
from tests.support.ortho_compare import saved_cut


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    return saved_cut(tmp_path_factory.mktemp("runs_footprint"), seed=3, rows=400)


def test_the_outline_covers_the_image_s_ground(cut):
    scene_path, _, dem = cut
    result = use_case.run(use_case.FootprintRequest(scene_path, Terrain(dem), samples=64))
    (fp,) = result.figures["footprints"]
    scene = load_scene(scene_path)
    cam = scene.cameras[0]
    c, r = cam.cols / 2, cam.rows / 2
    p = scene.image_to_ground_dem(np.array([c, c + 1, c]), np.array([r, r, r + 1]), Dem(dem))
    pixel_m2 = np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
    assert fp.area_km2 == pytest.approx(cam.cols * cam.rows * pixel_m2 / 1e6, rel=0.02)
    assert (fp.camera, fp.cols, fp.rows) == (cam.name, cam.cols, cam.rows) and fp.lon.size >= 4 * 64
    assert result.files == {} and result.lines == []


def test_refusals_and_cancelling(cut, tmp_path):
    scene_path, _, _ = cut
    with pytest.raises(InputError, match="no such file") as refused:
        use_case.run(use_case.FootprintRequest(str(tmp_path / "none.json")))
    assert refused.value.parameter == "scene"
    with pytest.raises(Cancelled):
        use_case.run(use_case.FootprintRequest(scene_path, Terrain(height=100.0)), is_cancelled=lambda: True)
