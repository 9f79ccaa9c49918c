"""core.runs.importtiepoints: the simulator's noise-free tie points intersect through the true scene
with no residual, through the onboard scene (whose cameras are misaligned) with some; every point is
seen in two or more cameras of the three-line scene but those the cut left in one camera."""
import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.observations import tiepoints
from pushbroom_adjust.core.runs import importtiepoints as use_case
from tests.unit.runs.conftest import N_TIE_POINTS


def test_noise_free_tie_points_intersect_exactly_through_the_true_scene(th1, tmp_path):
    out = str(tmp_path / "ties.gpkg")
    result = use_case.run(use_case.ImportTiesRequest(out, th1["TRUE_SCENE"], th1["TIE_POINTS"],
                                                     tiepoints.CsvMapping()))
    s = result.figures
    assert result.files == {"OUTPUT": out}
    assert 0 < s["points"] - s["single"] <= N_TIE_POINTS and s["suspect"] == 0  # the single ones: cut off the others
    assert s["rms_px"] < 1e-3
    assert set(s["cameras"]) == {"NAD", "FWD", "BWD"}
    assert len(tiepoints.read_gpkg(out)) == s["observations"]
    assert result.lines[-1].text.startswith(f"a-priori intersection residuals (onboard model, {s['points'] - s['single']} intersected ")
    onboard = use_case.run(use_case.ImportTiesRequest(str(tmp_path / "onboard.gpkg"), th1["ONBOARD_SCENE"],
                                                      th1["TIE_POINTS"], tiepoints.CsvMapping()))
    assert onboard.figures["rms_px"] > 10 * s["rms_px"]


def test_a_missing_column_is_named(th1, tmp_path):
    with pytest.raises(InputError, match="sigma_of_mine"):
        use_case.run(use_case.ImportTiesRequest(str(tmp_path / "t.gpkg"), th1["TRUE_SCENE"], th1["TIE_POINTS"],
                                                tiepoints.CsvMapping(sigma_px="sigma_of_mine")))
    assert not (tmp_path / "t.gpkg").exists()
