"""core.runs.importlines: the simulator's roads (ground lines with their true heights, image lines
clicked on them) are on the true scene's rays, and off the onboard scene's by its known errors."""
import pytest
from osgeo import ogr

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.runs import importlines as use_case
from pushbroom_adjust.core.runs.layers import PointHeights
from tests.unit.runs.conftest import N_LINES


def _run(th1, scene: str, out):
    return use_case.run(use_case.ImportLinesRequest(
        str(out), th1[scene], (th1["LINES"], "ground_lines"), (th1["LINES"], "image_lines"), "EPSG:4979",
        heights=PointHeights("z", "ellipsoid")))


def test_roads_lie_on_the_true_scene_s_rays(th1, tmp_path):
    true, onboard = _run(th1, "TRUE_SCENE", tmp_path / "t.gpkg"), _run(th1, "ONBOARD_SCENE", tmp_path / "o.gpkg")
    assert true.files == {"OUTPUT": str(tmp_path / "t.gpkg")}
    rms_true, rms_onboard = (r.figures["rms_across_m"] for r in (true, onboard))
    assert len(rms_true) == N_LINES - len(true.figures["outside"])
    assert max(rms_true.values()) < 3.0 < min(rms_onboard.values())
    ds = ogr.Open(str(tmp_path / "t.gpkg"))  # held: its layer dies with it
    assert ds.GetLayer("ground_lines").GetFeatureCount() == N_LINES
    assert true.lines[0].text.startswith(f"{N_LINES} ground line part(s)")


def test_the_same_layer_twice_is_refused(th1, tmp_path):
    with pytest.raises(InputError, match="the same layer as INPUT") as refused:
        use_case.run(use_case.ImportLinesRequest(str(tmp_path / "x.gpkg"), th1["TRUE_SCENE"],
                                                 (th1["LINES"], "image_lines"), (th1["LINES"], "image_lines")))
    assert refused.value.parameter == use_case.IMAGE_LINES
    with pytest.raises(InputError) as refused:
        use_case.run(use_case.ImportLinesRequest(str(tmp_path / "x.gpkg"), th1["TRUE_SCENE"],
                                                 (th1["LINES"], "no_such_layer"), (th1["LINES"], "image_lines"),
                                                 "EPSG:4979", heights=PointHeights("z", "ellipsoid")))
    assert refused.value.parameter == use_case.GROUND_LINES
