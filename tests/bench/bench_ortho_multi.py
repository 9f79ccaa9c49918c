"""Every camera of a TH-1 three-line scene in one run: threads against a local two-worker Dask
cluster, and the same run camera by camera. Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_ortho_multi.py [--rows 1500]

The scene: TH-1 three-line camera (12000 px per line, 5 m GSD), seed 7, cut to its first
``--rows`` rows per camera and rendered from the known texture; orthorectified with the true
model onto each camera's default grid (UTM, its own GSD), bilinear. Figures: wall time of
``orthorectify_products`` (all cameras), of the three single-camera ``orthorectify`` calls, of
the all-camera run with ``scheduler=`` a LocalCluster (2 worker processes, 1 thread each,
loopback; the cluster's start not counted), whether the outputs are byte-identical, and each
orthoimage's registration to the texture (px).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)
from pushbroom_adjust.core.products.ortho import (  # noqa: E402
    default_grid, orthorectify, orthorectify_products, strip_products)
from tests.support.ortho_compare import rendered_cameras, shift_against_texture  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--rows", type=int, default=1500)
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="bench_ortho_multi_"))
    scene, _, dem, frame, images = rendered_cameras(folder / "sim", "th1_tlc", seed=7, rows=args.rows)
    products = strip_products(scene, [0, 1, 2])
    grids = [default_grid(scene, p.camera, dem, rows=p.rows) for p in products]
    pixels = sum(g.cols * g.rows for g in grids)
    print(f"TH-1, 3 cameras of 12000 x {args.rows} px; grids "
          + ", ".join(f"{g.cols} x {g.rows}" for g in grids) + f" ({pixels / 1e6:.0f} Mpx)")
    runs = {}
    for name in ("threads", "single"):
        out = folder / name
        out.mkdir()
        t = time.perf_counter()
        if name == "threads":
            orthorectify_products(scene, images, dem, out, products, grids)
        else:
            for p, g in zip(products, grids):
                orthorectify(scene, images[p.camera], dem, out / p.name, p.camera, g, rows=p.rows)
        runs[name] = time.perf_counter() - t
    from distributed import LocalCluster
    with LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        out = folder / "dask"
        out.mkdir()
        t = time.perf_counter()
        orthorectify_products(scene, images, dem, out, products, grids, scheduler=cluster.scheduler_address)
        runs["dask"] = time.perf_counter() - t
    for name, seconds in runs.items():
        same = all((folder / name / p.name).read_bytes() == (folder / "threads" / p.name).read_bytes()
                   for p in products)
        print(f"{name:8s} {seconds:6.1f} s  byte-identical to the threaded run: {same}")
    for p in products:
        (dx, dy), n = shift_against_texture(folder / "threads" / p.name, frame)
        print(f"{p.name}: registration to the texture dx {dx:+.4f} px, dy {dy:+.4f} px ({n} pixels)")


if __name__ == "__main__":
    main()
