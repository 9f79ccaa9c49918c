"""Words for people (issue 28): a figure with nothing to count says so ('no control points'), never
'nan'; a check point the model does not image is counted and left out, named; refusals name the
Processing parameter (RPC_SIGMA, ALPHA, ...), never a settings field."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pushbroom_adjust.core.adjust import AdjustmentSettings
from pushbroom_adjust.core.adjust.settings import PARAMETERS
from pushbroom_adjust.core.adjust.checkpoints import accuracy, summary_lines
from pushbroom_adjust.core.adjust.report import (control_line_lines, control_residual_sentence, ground_taken_sentence,
                                                 sigma0_sentence)
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.model.rpcscene import RpcCamera, RpcScene
from pushbroom_adjust.core.observations.gcps import GcpTable
from tests.support.rpcdata import worldview2_rpc


def no_nan(text: str) -> bool:
    return not any(word.strip(".,;:()") == "nan" for word in text.lower().split())


def test_control_residuals_with_nothing_to_count():
    none = {"count": 0}
    assert control_residual_sentence({"observations": {"control_points": 0}, "control_residuals": none}) == \
        "control residuals: no control points"
    assert control_residual_sentence({"observations": {"control_points": 5}, "control_residuals": none}) == \
        "control residuals: none left of the 5 control points (all flagged)"
    some = {"count": 4, "rmse_col": 0.1, "rmse_row": 0.2}
    assert control_residual_sentence({"observations": {"control_points": 2}, "control_residuals": some}) == \
        "control residuals RMSE col 0.100 px, row 0.200 px"
    ground = {"at_stated_ground": none, "shift_rmse_horizontal_m": 0.1, "shift_rmse_vertical_m": 0.2, "ground_share": 0.5}
    assert ground_taken_sentence(ground).endswith("residuals at the stated ground coordinates none (no control point "
                                                  "is imaged at its stated ground)")


def test_sigma0_and_lines_with_nothing_to_count():
    assert sigma0_sentence({"sigma0": float("nan")}) == \
        "sigma0 not estimated (no redundancy left among the observations kept)"
    lines = {"lines": 3, "points": 12, "across_rmse_m": None, "across_rmse_before_m": None, "flagged_points": 12,
             "flagged_lines": 0, "flagged_line_ids": [], "directions": {"determined": True}}
    text = control_line_lines(lines)[0].text
    assert "across-line RMSE no line point left (all flagged)" in text and no_nan(text)


@pytest.fixture(scope="module")
def rpc_scene(shared_data) -> RpcScene:
    rpc = worldview2_rpc(shared_data)
    return RpcScene(rpc, RpcCamera("WV2", 35180, 24000))


def test_a_check_point_the_model_does_not_image_is_counted_and_left_out(rpc_scene):
    """A check point with a wrong coordinate, far outside the RPC's ground domain: the RPC images
    nothing there (NaN), which the figures leave out and name, never a 'nan' in the log."""
    rng = np.random.default_rng(2)
    col, row = rng.uniform(1000, 20000, 6), rng.uniform(1000, 20000, 6)
    lon, lat, h = ecef_to_geodetic(rpc_scene.image_to_ground(col, row, 600.0))
    lon[0] += 30.0                                                      # 30 degrees off: a typo
    table = GcpTable(np.array([f"c{i}" for i in range(6)]), np.full(6, "check"), np.full(6, "WV2"), col, row,
                     lon, lat, h, np.full(6, 0.5), np.full(6, 1.0), np.full(6, 1.0))
    figures = accuracy(rpc_scene, table, np.arange(6), 0.001)
    assert figures["not_imaged"] == 1 and figures["not_imaged_ids"] == ["c0"]
    assert math.isfinite(figures["image"]["rmse"]) and figures["image"]["rmse"] < 1e-3
    figures["intersection"] = {}
    lines = summary_lines(figures, figures)
    assert any(line.startswith("1 check observation(s) left out after: the model does not image their ground") and
               line.endswith(": c0") for line in lines), lines
    assert all(no_nan(line) for line in lines), lines


@pytest.mark.parametrize("change, parameter", [
    ({"ground": "loose"}, "GROUND"), ({"robust": "maybe"}, "ROBUST"), ({"alpha": 0.7}, "ALPHA"),
    ({"camera_trajectory": "each"}, "CAMERA_TRAJECTORY"), ({"on_singular": "ignore"}, "ON_SINGULAR"),
    ({"rpc_correction": "quadratic"}, "RPC_CORRECTION"), ({"interior_selection": "all"}, "INTERIOR_SELECTION"),
    ({"rpc_sigma": -1.0}, "RPC_SIGMA"), ({"position_sigma": 1e9}, "POSITION_SIGMA"),
    ({"attitude_sigma": 1.0}, "ATTITUDE_SIGMA"), ({"scene_sigmas": {"S1": {"rpc_sigma": 0.0}}}, "SCENE_SIGMAS"),
])
def test_settings_refusals_name_the_parameter(change, parameter):
    with pytest.raises(InputError) as err:
        AdjustmentSettings(**change).validate()
    text = str(err.value)
    assert text.startswith(parameter) and "settings." not in text, text
    assert not [field for field in PARAMETERS if "_" in field and field in text], text  # no field names
