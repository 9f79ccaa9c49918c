"""The robust loop converges, and a loop stopped at its limit says so in every report (issue 28).

The tie set: tests/data/pleiades_gizeh/ties_swinging.csv, 234 tie points matched loosely between the two
Pleiades crops over Giza (some wrong matches), adjusted as a ties-only block of the two vendor RPCs
(drift, RPC_SIGMA 10 px). Before observations were held flagged (core.adjust.robust, Convergence), the
selection weights swung between two sets of flags from the third pass on, 14 and 20 observations
down-weighted (weighted squared residuals 197.9 and 225.9, sigma0 0.92 and 0.98), and stopped at the
limit of 12 passes with the flags of whichever pass came last. Now 4 observations (two tie points near
the critical value) are held flagged after their second flagging and the loop converges in 5 passes
(18 flagged, sigma0 0.94). The module runs in about 10 s.
"""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from pushbroom_adjust.core.adjust import AdjustmentSettings, estimation
from pushbroom_adjust.core.adjust.block import adjust_block
from pushbroom_adjust.core.adjust.report import log_lines, write_report_json
from pushbroom_adjust.core.adjust.report_html import block_section, write_report_html
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.observations import tiepoints

NAMES = ("img1", "img2")
SETTINGS = AdjustmentSettings(rpc_correction="drift", rpc_sigma=10.0)
LIMIT = "robust estimation stopped at its limit of 1 passes; the flags may be incomplete"


@pytest.fixture(scope="module")
def scenes(shared_data) -> dict:
    return {n: load_scene(shared_data / "pleiades_gizeh" / f"{n}.tif") for n in NAMES}


@pytest.fixture(scope="module")
def ties(shared_data):
    return tiepoints.read_csv(shared_data / "pleiades_gizeh" / "ties_swinging.csv",
                              tiepoints.CsvMapping(sigma_px="sigma_px"))


def test_without_holding_flags_the_loop_swings_between_two_sets_of_flags(scenes, ties, monkeypatch):
    """The old rule (an observation may be flagged and released any number of times): from the third
    pass on, every other pass has the same flags and cost, and the loop stops at its limit."""
    monkeypatch.setattr(estimation, "REFLAGGED", 10 ** 9)
    rep = adjust_block(scenes, None, ties, SETTINGS).adjustment.report
    passes = rep["robust"]["passes"]
    assert rep["robust"]["stopped_at_limit"] and len(passes) == SETTINGS.max_robust_iterations
    down = [p["down_weighted"] for p in passes[2:]]                 # measured 20, 14, 20, 14, ...
    sigma0 = np.array([p["sigma0"] for p in passes[2:]])
    assert all(a != b for a, b in zip(down, down[1:]))              # every pass changes the flags
    assert np.all(np.abs(sigma0[2:] - sigma0[:-2]) < 0.005)         # and comes back to those of two passes before
    assert np.all(np.abs(np.diff(sigma0)) > 0.03)                   # measured 0.92 and 0.98
    assert rep["robust"]["held_flagged"] == 0


def test_observations_flagged_twice_are_held_and_the_loop_converges(scenes, ties):
    out = adjust_block(scenes, None, ties, SETTINGS)
    rep = out.adjustment.report
    robust = rep["robust"]
    assert not robust["stopped_at_limit"] and len(robust["passes"]) <= 6      # measured 5
    assert 2 <= robust["held_flagged"] <= 8                                    # measured 4
    assert robust["flagged"] >= robust["held_flagged"]                         # held ones count as flagged
    assert int(out.adjustment.tie_points["flagged"].sum()) == robust["flagged"]  # measured 18
    assert 0.85 < rep["sigma0"] < 1.05                                         # measured 0.94
    assert not any("stopped at its limit" in w for w in rep["warnings"] + out.report["warnings"])
    texts = [line.text for line in log_lines(rep, len(ties))]
    assert any(t.startswith(f"{robust['held_flagged']} observations near the critical value were flagged, released "
                            "and flagged again") for t in texts), texts


def test_a_loop_stopped_at_its_limit_is_a_warning_in_the_log_the_json_and_the_html(scenes, ties, tmp_path):
    out = adjust_block(scenes, None, ties, replace(SETTINGS, max_robust_iterations=1))
    rep = out.adjustment.report
    assert rep["robust"]["stopped_at_limit"]
    assert (LIMIT, True) in [(line.text, line.warning) for line in log_lines(rep, len(ties))]
    write_report_json(out.report, tmp_path / "block_report.json")
    write_report_json(rep, tmp_path / "report.json")
    assert LIMIT in json.loads((tmp_path / "block_report.json").read_text())["warnings"]
    assert LIMIT in json.loads((tmp_path / "report.json").read_text())["warnings"]
    write_report_html(rep, out.adjustment.points, tmp_path / "block_report.html", preface=block_section(out.report))
    assert (tmp_path / "block_report.html").read_text().count(LIMIT) == 1     # once, among the warnings on top
