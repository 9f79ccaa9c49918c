"""The pairs of a block's overlap graph (pushbroom:matchtiepoints with SCENES, issue 31) matched one
after the other in this process, on this machine's threads, and on a local Dask cluster: wall and CPU
time of each, and whether the ties are the same to the bit. Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_pairmatching.py
      [--out DIR] [--threads 0] [--dask-workers 2]

The block: the rendered three strips of tests/unit/measure/test_pairmatching.py (four TH-1 nadir-camera
products, 800 x 800 px of 5 m, strips 3 km apart: 5 overlapping pairs), SPACING 30, SEARCH_RANGE 400.
--out keeps the simulation (and reuses one already there). Each figure depends on what else the
machine runs: quote the load average printed with it.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from distributed import LocalCluster

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.dem import Dem  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.core.measure.pairmatching import overlap_pairs, pair_jobs, run_pair_jobs  # noqa: E402
from pushbroom_adjust.core.measure.tiematching import View  # noqa: E402
from pushbroom_adjust.simulation.block import BLOCK_MANIFEST, simulate_block  # noqa: E402
from tests.unit.measure.test_pairmatching import MEMBERS, SETTINGS  # noqa: E402


def block(folder: Path) -> tuple[list[View], dict, Dem]:
    """The rendered block's views, {name: scene file} and DEM, simulated into ``folder`` when not there."""
    if not (folder / BLOCK_MANIFEST).exists():
        simulate_block(MEMBERS, folder, seed=4, n_gcps=10, n_tie_points=20, render=True)
    members = json.loads((folder / BLOCK_MANIFEST).read_text())["files"]["members"]
    views = [View(name, load_scene(folder / f["onboard_scene"]), 0, folder / next(iter(f["images"].values())))
             for name, f in members.items()]
    return views, {name: folder / f["onboard_scene"] for name, f in members.items()}, Dem(str(folder / "dem.tif"),
                                                                                            "geoid")


def timed(label: str, run) -> list:
    wall, cpu = time.perf_counter(), time.process_time()
    results = run()
    print(f"{label}: {time.perf_counter() - wall:.1f} s wall, {time.process_time() - cpu:.1f} s CPU in this process; "
          f"matched {[r.matched for _, r in results]} (load average {os.getloadavg()[0]:.1f})", flush=True)
    return results


def same(a: list, b: list) -> bool:
    return all(x[1] == y[1] and all(np.array_equal(getattr(x[0], k), getattr(y[0], k))
                                    for k in ("col_a", "row_a", "col_b", "row_b", "sigma_px")) for x, y in zip(a, b))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--threads", type=int, default=0, help="threads for the pairs (0: one per core)")
    parser.add_argument("--dask-workers", type=int, default=2, help="Dask worker processes (0: no Dask run)")
    args = parser.parse_args()
    views, files, dem = block(args.out or Path(tempfile.mkdtemp(prefix="bench_pairs_")))
    graph = overlap_pairs(views, dem)
    jobs = pair_jobs(views, graph, dem, SETTINGS)
    print(f"{len(graph.pairs)} overlapping pairs of {len(views)} images, {os.cpu_count()} cores")
    alone = timed("one after the other (each pair's fine pass on every core)", lambda: run_pair_jobs(jobs, processes=1))
    threads = timed(f"pairs on {args.threads or os.cpu_count()} threads",
                    lambda: run_pair_jobs(jobs, processes=args.threads))
    print("the same ties:", same(alone, threads))
    if args.dask_workers:
        with LocalCluster(n_workers=args.dask_workers, processes=True, threads_per_worker=1, host="127.0.0.1",
                          dashboard_address=None) as cluster:
            light = pair_jobs(views, graph, dem, SETTINGS, files)
            dask = timed(f"on a local Dask cluster of {args.dask_workers} worker processes (scenes as files)",
                         lambda: run_pair_jobs(light, cluster.scheduler_address))
        print("the same ties:", same(alone, dask))


if __name__ == "__main__":
    main()
