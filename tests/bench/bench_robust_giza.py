"""Whether the robust loop converges on real tie sets (issue 28): the Pleiades pair over Giza
(tests/data/pleiades_gizeh) matched by core.measure.tiematching on flat surfaces at 0 to 300 m (every
20 m), on grids of 16, 20, 25 and 30 px with windows of 11, 15 and 21 px, a 100 m search, correlation
>= 0.5 and peak ratio <= 0.95 (loose: the sets hold wrong matches), each adjusted as a ties-only block
of the two vendor RPCs (drift, RPC_SIGMA 10 px). Prints per set the robust passes, whether the loop
stopped at its limit, the flags and the observations held flagged, then a summary (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_robust_giza.py [--unheld]

--unheld: observations are never held flagged (the rule before issue 28), to compare.
Some sets do not solve at all (the first pass, with every wrong match at full weight, does not
converge in 30 iterations; or a match lies outside its image): counted and left out.
"""
from __future__ import annotations

import argparse
import itertools
import logging
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.support import plugin_package  # noqa: F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.adjust import AdjustmentSettings, estimation
from pushbroom_adjust.core.adjust.block import adjust_block
from pushbroom_adjust.core.dem import ConstantHeight
from pushbroom_adjust.core.errors import PushbroomError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.measure.matching import MatchSettings
from pushbroom_adjust.core.measure.tiematching import View, match_block_tiepoints
from tests.support.paths import TEST_DATA

NAMES = ("img1", "img2")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--unheld", action="store_true", help="never hold an observation flagged (the old rule)")
    args = parser.parse_args()
    logging.disable(logging.WARNING)
    if args.unheld:
        estimation.REFLAGGED = 10 ** 9
    folder = TEST_DATA / "pleiades_gizeh"
    scenes = {n: load_scene(folder / f"{n}.tif") for n in NAMES}
    views = [View(n, scenes[n], 0, folder / f"{n}.tif") for n in NAMES]
    passes, limits, unsolved = [], 0, 0
    for height, spacing, window in itertools.product(range(0, 320, 20), (16, 20, 25, 30), (11, 15, 21)):
        label = f"{height:3d} m, {spacing} px grid, {window} px window"
        try:
            ties, _ = match_block_tiepoints(views, ConstantHeight(height), MatchSettings(
                spacing=spacing, window=window, search=100.0, min_correlation=0.5, max_peak_ratio=0.95))
            robust = adjust_block(scenes, None, ties, AdjustmentSettings(rpc_correction="drift", rpc_sigma=10.0)
                                  ).adjustment.report["robust"]
        except PushbroomError as exc:
            unsolved += 1
            print(f"{label}: not solved ({str(exc)[:80]})", flush=True)
            continue
        passes.append(len(robust["passes"]))
        limits += robust["stopped_at_limit"]
        print(f"{label}: {len(ties) // 2} ties, {passes[-1]} passes{' (limit)' * robust['stopped_at_limit']}, "
              f"{robust['flagged']} flagged, {robust['held_flagged']} held; down-weighted per pass "
              f"{[p['down_weighted'] for p in robust['passes']]}", flush=True)
    n = np.array(passes)
    print(f"{n.size} sets solved ({unsolved} not): {limits} stopped at the pass limit; passes mean {n.mean():.2f}, "
          f"max {n.max()}, {(n >= 6).sum()} with 6 or more")


if __name__ == "__main__":
    main()
