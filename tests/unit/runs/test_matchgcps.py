"""core.runs.matchgcps: GCPs matched between a rendered raw image and its reference orthoimage lie
on the true scene's rays (a-priori residuals well under a pixel), through the onboard scene they
show its known errors; the matching's sentences are returned."""
import numpy as np
import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.observations import gcps
from pushbroom_adjust.core.runs import matchgcps as use_case
from pushbroom_adjust.core.runs.base import Terrain

MATCHING = {"spacing": 40.0, "search": 300.0}


def _run(th1, scene: str, out):
    return use_case.run(use_case.MatchGcpsRequest(str(out), th1[scene], th1["IMAGE"], th1["REFERENCE"],
                                                  Terrain(th1["DEM"], "geoid"), "NAD", MATCHING, 0.2))


def test_matched_gcps_lie_on_the_true_scene_s_rays(th1, tmp_path):
    result = _run(th1, "TRUE_SCENE", tmp_path / "m.gpkg")
    table = gcps.read_gpkg(str(tmp_path / "m.gpkg"))
    f = result.figures
    assert result.files == {"OUTPUT": str(tmp_path / "m.gpkg")}
    assert f["points"] == f["matched"] == len(table) >= 20 and f["grid_points"] >= f["matched"]
    assert f["check"] == round(0.2 * f["points"]) and f["median_px"] < 0.3
    assert [line.text.split(" ")[0] for line in result.lines[-4:]] == ["matched", "rejected:", "onboard", "quality"]
    onboard = _run(th1, "ONBOARD_SCENE", tmp_path / "o.gpkg").figures
    assert onboard["median_px"] > 1.0 and abs(onboard["matched"] - f["matched"]) <= 0.2 * f["matched"]
    assert np.all(table.camera == "NAD")


def test_a_missing_raster_is_named(th1, tmp_path):
    with pytest.raises(InputError, match="no raster given") as refused:
        use_case.run(use_case.MatchGcpsRequest(str(tmp_path / "m.gpkg"), th1["TRUE_SCENE"], th1["IMAGE"], ""))
    assert refused.value.parameter == use_case.REFERENCE
    with pytest.raises(InputError, match="out of range"):
        use_case.run(use_case.MatchGcpsRequest(str(tmp_path / "m.gpkg"), th1["TRUE_SCENE"], th1["IMAGE"],
                                               th1["REFERENCE"], matching={"window": 8}))
