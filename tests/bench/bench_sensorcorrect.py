"""Time and peak memory of the sensor correction (core.products.sensorcorrect) of one full CBERS-02B HRC
scene: 12246 x 12246 px, three staggered, misaligned CCDs (the true camera). Prints figures (no
assertions); the machine may be shared, so the load average is printed before and after.

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_sensorcorrect.py
      [--repeats 2] [--out DIR] [--keep]

The scene (seed 0) is simulated and its raw image rendered from the known texture with the true
model over the simulated DEM (ellipsoidal heights); each sensor correction (bilinear, with that
DEM) then runs in a separate process, timed by wall clock and CPU time (user + system: its CPU
time over the number of cores is what it needs at least on an idle machine) with its peak
resident memory. The figures of the last run (densification error, the RPC's independent check)
are printed too. With --out DIR --keep, a later run with the same --out reuses the rendered scene.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.dem import Dem  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.core.products.sensorcorrect import sensor_correct  # noqa: E402
from tests.support.ortho_bench import prepare_cbers  # noqa: E402

log = logging.getLogger("bench_sensorcorrect")
# Runs a command and prints its CPU seconds (user + system) and peak resident memory (kB) last.
MEASURE = ("import resource, subprocess, sys\n"
           "rc = subprocess.run(sys.argv[1:]).returncode\n"
           "use = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
           "print(use.ru_utime + use.ru_stime, use.ru_maxrss)\n"
           "sys.exit(rc)\n")


def prepare(work: Path) -> dict:
    """The scene of bench_ortho_vs_gdalwarp (seed 0, raw image rendered with the true model over
    the ellipsoidal DEM), with its true camera: the staggered, misaligned CCDs."""
    setup = prepare_cbers(work)
    return {"scene": str(Path(setup["scene"]).with_name("true_scene.json")), "raw": setup["raw"], "dem": setup["dem"]}


def run_once(setup: dict, output: Path) -> dict:
    """The sensor correction itself (in the measured process): its figures as JSON on stdout."""
    figures = sensor_correct(load_scene(setup["scene"]), 0, setup["raw"], Dem(setup["dem"], datum="ellipsoid"),
                             output, output.with_name(output.stem + "_scene.json"))
    print(json.dumps(figures))
    return figures


def measured(setup: dict, output: Path) -> tuple[float, float, float, dict]:
    """(wall seconds, CPU seconds, peak resident memory GB, figures) of one run in its own process."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", MEASURE, sys.executable, __file__, "--run", json.dumps(setup),
                           str(output)], capture_output=True, text=True, env=env)
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(done.stderr[-2000:])
    lines = done.stdout.strip().splitlines()
    cpu, rss = lines[-1].split()
    return seconds, float(cpu), int(rss) / 1024 ** 2, json.loads(lines[-2])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--out", type=Path, default=None, help="work folder (default: a temporary one)")
    parser.add_argument("--keep", action="store_true", help="keep the work folder")
    parser.add_argument("--run", nargs=2, help=argparse.SUPPRESS)  # internal: one measured run
    args = parser.parse_args()
    if args.run:
        run_once(json.loads(args.run[0]), Path(args.run[1]))
        return
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    work = args.out or Path(tempfile.mkdtemp(prefix="bench_sensorcorrect_"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        cached = work / "setup.json"
        setup = json.loads(cached.read_text()) if cached.is_file() else prepare(work)
        cached.write_text(json.dumps(setup))
        print(f"cores: {os.cpu_count()}; load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
        for k in range(args.repeats):
            seconds, cpu, gb, figures = measured(setup, work / f"corrected{k}.tif")
            # CPU seconds / cores: the wall time the run needs at least on this many idle cores
            print(f"run {k + 1}: {seconds:.1f} s wall (in-process {figures['seconds']:.1f} s), {cpu:.1f} CPU s "
                  f"(/{os.cpu_count()} cores = {cpu / (os.cpu_count() or 1):.1f} s), peak {gb:.2f} GB; "
                  f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
        print(f"image {figures['cols']} x {figures['rows']} px; densification error "
              f"{figures['densification_error_px']:.1e} px; RPC check RMS {figures['rpc_check_rms_px']:.5f} px, "
              f"max {figures['rpc_check_max_px']:.5f} px")
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
