"""Regions of RPC products (issue 31, "Done when" 1: scale) adjusted as a user adjusts them: the
simulated region of tests/bench/bench_region.py (the same regions, cached in --out) through
``qgis_process run pushbroom:bundleadjust`` with SCENES a list file (one product per line), TIE_POINTS the
simulator's tie_points.csv, DEM the region's DEM (EGM96 heights: DEM_DATUM=geoid) with TIE_HEIGHT_SIGMA,
RPC_CORRECTION, RPC_SIGMA and OUTPUT_FOLDER (every output a user gets: adjusted scenes, the block report,
the adjusted tie points). No GCPs. Prints figures (no assertions).

Per size: the wall time, CPU time (user + system) and peak resident memory of the qgis_process process
(``/usr/bin/time -v``: QGIS's start, reading the inputs, the adjustment and writing every output); sigma0
and accuracy against the truth at the check points (bench_region.check_errors: neighbours'
misregistration px RMS and absolute error m RMS, also for the vendor RPCs); then the growth exponents of
time and memory between sizes, and the load average (the machine may be shared: compare CPU times).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_region_qgis.py
      [--sizes 100,1000] [--tie-height-sigma 3] [--correction drift] [--rpc-sigma 10] [--out out/bench_region]
      [--ties 2000] [--no-forward-ties] [--drift-m 2]
A region not yet in --out is simulated first (bench_region.simulate; 1,000 products take 1-2 min, not timed).
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from tests.bench.bench_block import read_columns  # noqa: E402
from tests.bench.bench_region import DRIFT_M, SEED, check_errors, exponent, misregistration, simulate  # noqa: E402
from tests.support.paths import PLUGIN, QGIS_PROCESS  # noqa: E402

from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.core.formats.rpcfiles import read_rpc_text  # noqa: E402

ALGORITHM = "pushbroom:bundleadjust"
# /usr/bin/time -v's lines: (figure, pattern of its value)
TIME_FIELDS = {"user_s": r"User time \(seconds\): ([\d.]+)", "system_s": r"System time \(seconds\): ([\d.]+)",
               "wall": r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)",
               "max_rss_kb": r"Maximum resident set size \(kbytes\): (\d+)"}


def qgis_environment(folder: Path) -> dict:
    """The environment qgis_process needs (as tests/qgis/conftest.py's ``qgis_process`` fixture): a plugin
    folder holding only the plugin (a link named PLUGIN to the repository), a throw-away profile, offscreen."""
    plugins = folder / "plugins"
    plugins.mkdir()
    (plugins / PLUGIN).symlink_to(REPO, target_is_directory=True)
    profile = folder / "profile"
    profile.mkdir()
    return dict(os.environ, QGIS_PLUGINPATH=str(plugins), QT_QPA_PLATFORM="offscreen",
                QGIS_CUSTOM_CONFIG_PATH=str(profile), PROJ_DATA="/usr/share/proj")


def product_list(folder: Path, manifest: dict) -> Path:
    """A list file of the region's products (their RPC files, one per line, relative to the list)."""
    path = folder / "products.txt"
    path.write_text("".join(f"{p['rpc']}\n" for p in manifest["products"]))
    return path


def seconds(clock: str) -> float:
    """Seconds of /usr/bin/time's h:mm:ss or m:ss.ss."""
    value = 0.0
    for part in clock.split(":"):
        value = 60.0 * value + float(part)
    return value


def run_qgis(args, folder: Path, env: dict, out: Path) -> dict:
    """Adjust the region in ``folder`` by qgis_process under /usr/bin/time -v; its figures."""
    manifest = json.loads((folder / "region.json").read_text())
    params = {"SCENES": product_list(folder, manifest), "TIE_POINTS": folder / "tie_points.csv",
              "RPC_CORRECTION": args.correction, "RPC_SIGMA": args.rpc_sigma, "OUTPUT_FOLDER": out}
    if args.tie_height_sigma is not None:
        params.update(DEM=folder / "dem.tif", DEM_DATUM="geoid", TIE_HEIGHT_SIGMA=args.tie_height_sigma)
    command = ["/usr/bin/time", "-v", QGIS_PROCESS, "--json", "run", ALGORITHM, "--",
               *(f"{k}={v}" for k, v in params.items())]
    done = subprocess.run(command, env=env, capture_output=True, text=True, stdin=subprocess.DEVNULL)
    if done.returncode:
        raise SystemExit(f"{ALGORITHM} failed (exit {done.returncode}):\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}")
    found = {k: re.search(pattern, done.stderr) for k, pattern in TIME_FIELDS.items()}
    figures = {k: m.group(1) for k, m in found.items() if m}
    report = json.loads((out / "block_report.json").read_text())
    names = [p["name"] for p in manifest["products"]]
    truth = {p["name"]: load_scene(folder / p["true_scene"]) for p in manifest["products"]}
    adjusted = {name: load_scene(out / f"{name}_adjusted.json") for name in names}
    vendor = {p["name"]: read_rpc_text(folder / p["rpc"]) for p in manifest["products"]}
    g = read_columns(folder / "gcps.csv")
    err, err0 = check_errors(adjusted, truth, g), check_errors(vendor, truth, g)
    (mis, pairs), (mis0, _) = misregistration(err), misregistration(err0)
    rms = lambda a: float(np.sqrt(np.nanmean(np.sum(a ** 2, axis=1))))  # noqa: E731
    absolute, absolute0, obs = rms(err["enu"]), rms(err0["enu"]), len(err["id"])
    return {"n": len(names), "wall_s": seconds(figures["wall"]),
            "cpu_s": float(figures["user_s"]) + float(figures["system_s"]),
            "peak_mb": int(figures["max_rss_kb"]) / 1024.0, "sigma0": report["block"]["sigma0"],
            "tie_rmse_before_px": report["block"]["tie_rmse_before_px"], "tie_rmse_px": report["block"]["tie_rmse_px"],
            "misregistration_px": mis, "misregistration_vendor_px": mis0, "absolute_m": absolute,
            "absolute_vendor_m": absolute0, "check_pairs": pairs, "check_observations": obs,
            "tie_observations": manifest["points"]["tie_observations"], "load": os.getloadavg()}


def describe(row: dict) -> str:
    """One size's figures, as a line."""
    parts = [f"{row['n']} products, {row['tie_observations']} tie observations, qgis_process {ALGORITHM}",
             f"{row['wall_s']:.1f} s wall ({row['cpu_s']:.1f} s CPU), peak {row['peak_mb']:.0f} MB",
             f"sigma0 {row['sigma0']:.3f}, tie RMS {row['tie_rmse_before_px']:.2f} -> {row['tie_rmse_px']:.3f} px",
             f"neighbours' misregistration {row['misregistration_px']:.3f} px RMS (vendor "
             f"{row['misregistration_vendor_px']:.2f}; {row['check_pairs']} pairs), absolute {row['absolute_m']:.2f} m "
             f"RMS (vendor {row['absolute_vendor_m']:.2f}; {row['check_observations']} check observations)",
             "load average " + " ".join(f"{v:.2f}" for v in row["load"])]
    return "; ".join(parts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="100,1000")
    ap.add_argument("--ties", type=int, default=2000, help="tie observations per product")
    ap.add_argument("--correction", default="drift", help="RPC_CORRECTION: shift, drift or affine")
    ap.add_argument("--rpc-sigma", type=float, default=10.0, help="RPC_SIGMA (px): 20 m / 2.1 m")
    ap.add_argument("--tie-height-sigma", type=float, default=3.0, help="TIE_HEIGHT_SIGMA (m) with the region's DEM")
    ap.add_argument("--no-forward-ties", dest="forward_ties", action="store_false",
                    help="leave out tie points seen only by consecutive products of one strip")
    ap.add_argument("--drift-m", type=float, default=DRIFT_M, help="the simulated vendor drift (m at the last row)")
    ap.add_argument("--out", default="out/bench_region")
    # bench_region.region_folder's fields: the regions of the first seed, without corner GCPs
    ap.set_defaults(corner_gcps=False, seed=SEED)
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_region_qgis_") as tmp:
        env = qgis_environment(Path(tmp))
        enabled = subprocess.run([QGIS_PROCESS, "plugins", "enable", PLUGIN], env=env, capture_output=True, text=True,
                                 stdin=subprocess.DEVNULL)
        if enabled.returncode:
            raise SystemExit(f"qgis_process cannot enable {PLUGIN}:\n{enabled.stdout}\n{enabled.stderr}")
        for n in (int(s) for s in args.sizes.split(",")):
            folder = simulate(args, n)
            row = run_qgis(args, folder, env, folder / f"qgis_{args.correction}")
            rows.append(row)
            print(describe(row), flush=True)
    growth = [f"{a['n']} -> {b['n']}: time n^{exponent(a, b, 'wall_s'):.2f} wall and n^{exponent(a, b, 'cpu_s'):.2f} "
              f"CPU, memory n^{exponent(a, b, 'peak_mb'):.2f}" for a, b in zip(rows, rows[1:])]
    print("\n".join(f"growth {line}" for line in growth))
    print(f"on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
