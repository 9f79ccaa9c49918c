"""Regions of RPC products (issue 31): simulated without images (simulation.rpcregion: ZY-3-like
nadir products, 2.1 m, 51 km swath, 20 % side-lap, 15 % forward overlap, vendor biases of 5-20 m
and drifts of up to 2 m, 0.3 px noise, ~2,000 tie observations per product, no GCPs) at 100, 300 and
1,000 products (3,000 with --sizes), and adjusted by the use case behind pushbroom:bundleadjust with
SCENES (core.runs.bundleadjust.run: reading the products and the tie file, the block adjustment,
writing every output). Prints figures (no assertions).

Per size: the simulation's time and peak; the adjustment's wall and CPU time and peak resident
memory (tests/bench/peak.py; in a child process, so neither the simulation nor an earlier size
counts); accuracy against the truth at the check points: the misregistration of neighbouring
products (the same check point through two adjusted products: the difference of their image
errors, px RMS over every pair of products seeing a point) and the absolute error (m RMS: each
product's true image position of a check point through its adjusted model to the point's true
height, against the true ground), both also for the vendor RPCs, and the absolute check RMSE in px
(the true ground through the adjusted model against through the true one); then the growth exponents
of time and memory between sizes (log ratio over log ratio of the products).

Absolute accuracy against the statistics (issue 31 'Done when' 2): every product's true horizontal
RMS error at its check points against its prior (within: <= sqrt(2) x RPC_SIGMA x its GSD, the
prior's radial sigma; the count and the worst), against what the report predicts
(core.adjust.report_accuracy: the products whose posterior sigma is within their prior); the block's
mean error (the vector mean over products of each product's mean east/north error, m) against the
report's predicted sigma of the block's common shift and prior x sqrt(2 / n); with
--tie-height-sigma the adjusted tie points' heights (adjusted_tie_points.gpkg) against the truth and
against the DEM, and 1.5 x the sigma; and the block mean error's fall between sizes.

--corner-gcps (issue 31 'Done when' 3): the region simulated with RegionSettings(corner_gcps=True)
(the 4 ground points nearest the region's corners control, the others check; its own folder
region_..._corners), the points given to the adjustment as a GeoPackage (gcps.gpkg beside them).

Tie points seen only by consecutive products of one strip (the forward overlaps) are left out
unless --forward-ties: those products see them along the same rays (one pass, one detector line),
so their heights are undetermined without a height reference, and today's intersection of the
tie points started them on the rays' meeting point, towards the Earth's centre (the run stopped at
100 products); they now start on their first ray at a height (core.adjust.ties.start_from_height) and
the DEM holds their heights: run --forward-ties --tie-height-sigma.

A size is run only when the peak memory extrapolated from the smaller sizes (at their growth
exponent) fits in the memory available now; otherwise the estimate is printed and the size left out
(--force runs it anyway).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_region.py
      [--sizes 100,300,1000] [--ties 2000] [--correction shift] [--rpc-sigma 10] [--out out/bench_region]
      [--drift-m 2] [--forward-ties] [--force] [--corner-gcps] [--seeds N (regions per size)] [--seed S (the first)]
      [--tie-height-sigma M (the tie heights held to the region's DEM at M metres)]
The simulated regions are kept in --out and reused.
"""
from __future__ import annotations

import argparse
import json
import logging
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from osgeo import ogr

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)
from tests.bench.peak import peak_mb, reset_peak  # noqa: E402

from pushbroom_adjust.core.adjust import AdjustmentSettings  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.core.formats.rpcfiles import read_rpc_text  # noqa: E402
from pushbroom_adjust.core.geodesy import enu_rotations, geodetic_to_ecef  # noqa: E402
from pushbroom_adjust.core.observations import gcps as G  # noqa: E402
from pushbroom_adjust.core.runs import bundleadjust  # noqa: E402
from pushbroom_adjust.core.dem import Dem  # noqa: E402
from pushbroom_adjust.core.runs.adjustinputs import AdjustRequest, LayerFile  # noqa: E402
from pushbroom_adjust.simulation.memory import available_bytes  # noqa: E402
from pushbroom_adjust.simulation.region import RegionLayout  # noqa: E402
from pushbroom_adjust.simulation.rpcregion import RegionSettings, simulate_region  # noqa: E402
from tests.bench.bench_block import read_columns  # noqa: E402

# strips x products per strip of each size (wider than long: strips of 51 km, products 44 km apart)
LAYOUTS = {100: (10, 10), 300: (15, 20), 1000: (25, 40), 3000: (50, 60)}
SIDE_LAP, FORWARD = 0.2, 0.15
SEED = 31  # the first region's seed (the regions cached in --out so far are seed 31's)
DRIFT_M = RegionSettings().drift_m   # m: the vendor drift's largest displacement of the last row, per axis
log = logging.getLogger("bench_region")


def layout_of(n: int) -> RegionLayout:
    strips, per = LAYOUTS.get(n, (max(2, round(math.sqrt(n))), math.ceil(n / max(2, round(math.sqrt(n))))))
    return RegionLayout(strips, per, side_lap=SIDE_LAP, forward_overlap=FORWARD, dates=3)


def settings_of(args) -> AdjustmentSettings:
    """The adjustment's settings: the RPC correction asked, the vendor accuracy as the prior, robust
    selection with variance components (the defaults), the DEM height reference with --tie-height-sigma."""
    return AdjustmentSettings(rpc_correction=args.correction, rpc_sigma=args.rpc_sigma,
                              **height_reference(args, region_folder(args, args.child)))


def height_reference(args, folder: Path) -> dict:
    """The fields of AdjustmentSettings that hold tie points' heights to the region's DEM (issue 31
    'A height reference': DEM + TIE_HEIGHT_SIGMA, core.adjust.tieheights), {} without
    --tie-height-sigma. The simulated DEM (EGM96 heights) is the truth the tie points lie on; its
    stated sigma is --tie-height-sigma."""
    if args.tie_height_sigma is None:
        return {}
    return {"dem": str(folder / "dem.tif"), "dem_datum": "geoid", "tie_height_sigma": args.tie_height_sigma}


def check_errors(scenes: dict, truth: dict, g: dict) -> dict:
    """Errors of ``scenes`` {name: model} against ``truth`` at the check points of ``g`` (gcps.csv's
    columns; control points left out): ``image`` (n, 2) px (the true ground through the model minus
    through the truth), ``enu`` (n, 3) m (the true image position through the model to the point's
    true height minus the true ground, east/north/up at the point), ``scene`` (n,) and ``id`` (n,)."""
    check = g["role"] == "check"
    ids, names = g["id"][check], g["scene"][check]
    lon, lat, h = (g[k][check].astype(float) for k in ("lon_true", "lat_true", "h_true"))
    col_t, row_t = (g[k][check].astype(float) for k in ("col_true", "row_true"))
    image, enu = np.full((ids.size, 2), np.nan), np.full((ids.size, 3), np.nan)
    rot = enu_rotations(lon, lat)
    for name, scene in scenes.items():
        m = names == name
        if not m.any():
            continue
        c, r = scene.ground_to_image_geodetic(lon[m], lat[m], h[m])
        tc, tr = truth[name].ground_to_image_geodetic(lon[m], lat[m], h[m])
        image[m] = np.stack([c - tc, r - tr], axis=1)
        d = scene.image_to_ground(col_t[m], row_t[m], h[m]) - geodetic_to_ecef(lon[m], lat[m], h[m])
        enu[m] = np.einsum("nij,nj->ni", rot[m], d)
    return {"image": image, "enu": enu, "scene": names, "id": ids}


def misregistration(err: dict) -> tuple[float, int]:
    """(px RMS, pairs) of the difference of two products' image errors at one check point, over
    every pair of products seeing a point."""
    order = np.argsort(err["id"], kind="stable")
    ids, image = err["id"][order], err["image"][order]
    start = np.nonzero(np.r_[True, ids[1:] != ids[:-1]])[0]
    diffs = []
    for a, b in zip(start, np.r_[start[1:], ids.size]):  # a few observations per point: pairs within each
        i, j = np.triu_indices(b - a, 1)
        diffs.append(image[a:b][i] - image[a:b][j])
    d = np.concatenate(diffs) if diffs else np.zeros((0, 2))
    return float(np.sqrt(np.mean(np.sum(d ** 2, axis=1)))), len(d)


def product_truth(err: dict, priors: dict) -> dict:
    """Per product its true absolute error at its check points, against its prior: ``priors``
    {name: vendor sigma m per axis} (the report's vendor_sigma_m); a product is within when its
    horizontal RMS error is within sqrt(2) x prior (the prior's radial sigma). Returns the count
    within, the worst ratio and product, and the block's mean error (the vector mean over products
    of each product's mean east/north error, m)."""
    means, ratios = [], {}
    for name, prior in priors.items():
        m = err["scene"] == name
        if not m.any():
            continue
        e = err["enu"][m, :2]
        means.append(e.mean(axis=0))
        ratios[name] = float(np.sqrt(np.mean(np.sum(e ** 2, axis=1)))) / (math.sqrt(2) * prior)
    worst = max(ratios, key=ratios.get)
    return {"products": len(ratios), "within": sum(r <= 1 for r in ratios.values()), "worst": worst,
            "worst_ratio": ratios[worst], "block_mean_m": float(np.linalg.norm(np.mean(means, axis=0)))}


def tie_heights(out: Path, folder: Path) -> dict:
    """The adjusted tie points' heights (out/adjusted_tie_points.gpkg) against the truth (the
    simulated points' true heights, on the region's DEM) and against the DEM at their adjusted
    position: RMS m over the points adjusted, and the points left out."""
    layer = ogr.Open(str(out / "adjusted_tie_points.gpkg"))
    got = {}
    for f in layer.GetLayer():
        geom = f.GetGeometryRef()
        if geom is not None and not geom.IsEmpty():
            got[f.GetField("id")] = (geom.GetX(), geom.GetY(), geom.GetZ())
    t = read_columns(folder / "tie_points.csv")
    ids, first = np.unique(t["id"], return_index=True)
    h_true = dict(zip(ids, t["h_true"][first].astype(float)))
    adjusted = np.array(list(got.values()))
    dem = Dem(folder / "dem.tif", datum="geoid").height(adjusted[:, 0], adjusted[:, 1])
    truth = np.array([h_true[i] for i in got])
    rms = lambda a: float(np.sqrt(np.nanmean(a ** 2)))  # noqa: E731
    return {"points": len(got), "left_out": int(ids.size - len(got)), "truth_rms_m": rms(adjusted[:, 2] - truth),
            "dem_rms_m": rms(adjusted[:, 2] - dem), "off_dem": int(np.isnan(dem).sum())}


def gcp_layer(folder: Path) -> LayerFile:
    """The region's ground points (gcps.csv: the corner control points and the check points) as the
    GeoPackage bundleadjust reads (folder/gcps.gpkg, written once), each row's camera and scene the
    product's name."""
    path = folder / "gcps.gpkg"
    if not path.exists():
        g = read_columns(folder / "gcps.csv")
        f = {k: g[k].astype(float) for k in ("col", "row", "lon", "lat", "h", "sigma_px", "sigma_xy", "sigma_z")}
        G.write_gpkg(G.GcpTable(g["id"], g["role"], g["camera"], f["col"], f["row"], f["lon"], f["lat"], f["h"],
                                f["sigma_px"], f["sigma_xy"], f["sigma_z"], scene=g["scene"]), path)
    return LayerFile(str(path))


def run_child(args, n: int) -> None:
    """The child process: adjust the region of ``n`` products, print a JSON line of figures."""
    logging.getLogger().setLevel(logging.WARNING)
    folder = region_folder(args, n)
    manifest = json.loads((folder / "region.json").read_text())
    products = {p["name"]: str(folder / p["rpc"]) for p in manifest["products"]}
    out = folder / f"adjusted_{args.correction}"
    request = AdjustRequest(scenes=products, ties=LayerFile(str(folder / "tie_points.csv")),
                            gcps=gcp_layer(folder) if args.corner_gcps else None,
                            settings=settings_of(args), folder=str(out))
    reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    result = bundleadjust.run(request)
    wall, cpu, peak = time.perf_counter() - t0, time.process_time() - c0, peak_mb()
    report = result.figures["report"]
    block = report["block"]
    truth = {name: load_scene(folder / p["true_scene"]) for name, p in zip(products, manifest["products"])}
    adjusted = {name: load_scene(out / f"{name}_adjusted.json") for name in products}
    vendor = {name: read_rpc_text(Path(path)) for name, path in products.items()}
    g = read_columns(folder / "gcps.csv")
    err, err0 = check_errors(adjusted, truth, g), check_errors(vendor, truth, g)
    (mis, pairs), (mis0, _) = misregistration(err), misregistration(err0)
    rms = lambda a: float(np.sqrt(np.nanmean(np.sum(a ** 2, axis=1))))  # noqa: E731
    priors = {name: s["vendor_sigma_m"] for name, s in report["scenes"].items()}
    accuracy = block.get("accuracy") or {}
    shift = accuracy.get("common_shift") or {}
    row = {"n": n, "wall_s": wall, "cpu_s": cpu, "peak_mb": peak, "sigma0": block["sigma0"],
           "tie_rmse_before_px": block["tie_rmse_before_px"], "tie_rmse_px": block["tie_rmse_px"],
           "misregistration_px": mis, "misregistration_vendor_px": mis0, "absolute_m": rms(err["enu"]),
           "absolute_vendor_m": rms(err0["enu"]), "absolute_px": rms(err["image"]),
           "absolute_vendor_px": rms(err0["image"]), "check_pairs": pairs, "check_observations": len(err["id"]),
           "control_points": manifest["points"]["control_points"],
           "tie_observations": manifest["points"]["tie_observations"],
           "truth": product_truth(err, priors), "vendor_truth": product_truth(err0, priors),
           "predicted": {"within": (accuracy.get("products") or {}).get("within"),
                         "block_mean_m": shift.get("horizontal_m"), "virtual_control_m": shift.get("virtual_control_m"),
                         "sentences": accuracy.get("sentences", [])}}
    if args.tie_height_sigma is not None:
        row["heights"] = {**tie_heights(out, folder), "limit_m": 1.5 * args.tie_height_sigma}
    print(json.dumps(row))


def region_folder(args, n: int) -> Path:
    drift = "" if args.drift_m == DRIFT_M else f"_drift{args.drift_m:g}"
    corners = "_corners" if args.corner_gcps else ""
    seed = "" if args.seed == SEED else f"_seed{args.seed}"
    return Path(args.out) / f"region_{n}_{args.ties}{'_forward' if args.forward_ties else ''}{drift}{corners}{seed}"


def simulate(args, n: int) -> Path:
    folder = region_folder(args, n)
    if not (folder / "region.json").exists():
        reset_peak()
        t0 = time.perf_counter()
        simulate_region(layout_of(n), folder, seed=args.seed,
                        settings=RegionSettings(ties_per_product=args.ties, forward_ties=args.forward_ties,
                                                drift_m=args.drift_m, corner_gcps=args.corner_gcps))
        print(f"{n} products: simulated in {time.perf_counter() - t0:.1f} s, peak {peak_mb():.0f} MB "
              f"({layout_of(n).strips} strips x {layout_of(n).products_per_strip}; not timed below)", flush=True)
    return folder


def print_accuracy(row: dict) -> None:
    """The absolute accuracy figures of one size against the truth and against the report's."""
    t, v, p = row["truth"], row["vendor_truth"], row["predicted"]
    print(f"  absolute check RMSE {row['absolute_px']:.3f} px, {row['absolute_m']:.2f} m (vendor "
          f"{row['absolute_vendor_px']:.2f} px; {row['control_points']} control points)")
    print(f"  products within their prior (true horizontal RMS <= sqrt(2) x RPC_SIGMA): {t['within']} of "
          f"{t['products']}, worst {t['worst']} at {t['worst_ratio']:.2f} x (vendor: {v['within']}, worst "
          f"{v['worst_ratio']:.2f} x); the report predicts {p['within']} within")
    vc = "-" if p["virtual_control_m"] is None else f"{p['virtual_control_m']:.2f}"
    bm = "-" if p["block_mean_m"] is None else f"{p['block_mean_m']:.2f}"
    print(f"  block mean error (vector mean of the products' mean errors): {t['block_mean_m']:.2f} m (vendor "
          f"{v['block_mean_m']:.2f} m); the report predicts {bm} m (1 sigma, radial; priors alone over "
          f"{t['products']} products {vc} m)")
    h = row.get("heights")
    if h:
        print(f"  tie heights: {h['truth_rms_m']:.2f} m RMS against the truth, {h['dem_rms_m']:.2f} m against the DEM "
              f"(limit 1.5 x sigma = {h['limit_m']:.2f} m) over {h['points']} points ({h['left_out']} left out, "
              f"{h['off_dem']} off the DEM)")
    for sentence in p["sentences"]:
        print(f"  report: {sentence}")


def run_size(args, n: int) -> dict | None:
    """Simulate (or reuse) the region of ``n`` products of seed args.seed, adjust it in a child process
    and print its figures; the child's row, None when it failed (said)."""
    simulate(args, n)
    child = [sys.executable, __file__, "--child", str(n), "--ties", str(args.ties), "--out", args.out,
             "--correction", args.correction, "--rpc-sigma", str(args.rpc_sigma), "--seed", str(args.seed)]
    child += (["--forward-ties"] if args.forward_ties else []) + ["--drift-m", str(args.drift_m)]
    child += ["--corner-gcps"] if args.corner_gcps else []
    if args.tie_height_sigma is not None:
        child += ["--tie-height-sigma", str(args.tie_height_sigma)]
    done = subprocess.run(child, capture_output=True, text=True)
    if done.returncode:
        print(f"{n} products: the adjustment failed (exit {done.returncode}):\n{done.stderr[-2000:]}", flush=True)
        return None
    row = json.loads(done.stdout.strip().splitlines()[-1])
    seed = "" if args.seeds == 1 else f" (seed {args.seed})"
    print(f"{n} products{seed}, {row['tie_observations']} tie observations: adjusted in {row['wall_s']:.1f} s wall "
          f"({row['cpu_s']:.1f} s CPU), peak {row['peak_mb']:.0f} MB; sigma0 {row['sigma0']:.3f}, tie RMS "
          f"{row['tie_rmse_before_px']:.2f} -> {row['tie_rmse_px']:.3f} px; neighbours' misregistration "
          f"{row['misregistration_px']:.3f} px RMS (vendor {row['misregistration_vendor_px']:.2f}; "
          f"{row['check_pairs']} pairs), absolute {row['absolute_m']:.2f} m RMS (vendor "
          f"{row['absolute_vendor_m']:.2f}; {row['check_observations']} check observations)", flush=True)
    print_accuracy(row)
    return row


def print_mean_error_spread(by_size: dict) -> None:
    """With several seeds per size: the RMS over the seeds of the block's mean error (the adjusted products'
    and the vendors'), against the report's predicted sigma of the block's common shift (mean over the
    seeds; 1 sigma radial, whose expected RMS it is), and its fall between sizes against the sqrt(n) law."""
    rms = {}
    for n, rows in by_size.items():
        adjusted = [r["truth"]["block_mean_m"] for r in rows]
        vendor = [r["vendor_truth"]["block_mean_m"] for r in rows]
        predicted = [r["predicted"]["block_mean_m"] for r in rows if r["predicted"]["block_mean_m"] is not None]
        rms[n] = float(np.sqrt(np.mean(np.square(adjusted))))
        said = f"{np.mean(predicted):.2f} m" if predicted else "-"
        print(f"block mean error over {len(rows)} regions of {n} products: RMS {rms[n]:.2f} m (vendors' "
              f"{float(np.sqrt(np.mean(np.square(vendor)))):.2f} m; each {', '.join(f'{a:.2f}' for a in adjusted)}); "
              f"the report predicts {said} (1 sigma radial)")
    sizes = sorted(rms)
    for a, b in zip(sizes, sizes[1:]):
        print(f"block mean error RMS {a} -> {b} products: {rms[a]:.2f} -> {rms[b]:.2f} m (sqrt(n) law: "
              f"{rms[a] * math.sqrt(a / b):.2f} m)")


def exponent(a: dict, b: dict, key: str) -> float:
    return math.log(b[key] / a[key]) / math.log(b["n"] / a["n"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="100,300,1000")
    ap.add_argument("--ties", type=int, default=2000, help="tie observations per product")
    ap.add_argument("--correction", default="shift", help="RPC_CORRECTION: shift, drift or affine")
    ap.add_argument("--rpc-sigma", type=float, default=10.0, help="RPC_SIGMA (px): 20 m / 2.1 m")
    ap.add_argument("--tie-height-sigma", type=float, default=None, help="m: tie heights held to the DEM")
    ap.add_argument("--forward-ties", action="store_true",
                    help="also tie points seen only by consecutive products of one strip (parallel rays: their "
                         "heights need --tie-height-sigma)")
    ap.add_argument("--drift-m", type=float, default=DRIFT_M, help="the simulated vendor drift (m at the last row)")
    ap.add_argument("--corner-gcps", action="store_true",
                    help="the 4 ground points nearest the region's corners control, the rest check (own folder)")
    ap.add_argument("--out", default="out/bench_region")
    ap.add_argument("--force", action="store_true", help="run a size even when its memory estimate does not fit")
    ap.add_argument("--seeds", type=int, default=1,
                    help="regions per size (seeds --seed, --seed + 1, ...): the block mean error's RMS over them against the "
                         "report's predicted sigma")
    ap.add_argument("--seed", type=int, default=SEED, help="the first region's seed (the child's: its region's)")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    if args.child:
        run_child(args, args.child)
        return
    rows, by_size, first = [], {}, args.seed
    for n in (int(s) for s in args.sizes.split(",")):
        if len(rows) >= 2 and not args.force:
            k = exponent(rows[-2], rows[-1], "peak_mb")
            estimate = rows[-1]["peak_mb"] * (n / rows[-1]["n"]) ** k
            have = available_bytes() / 2 ** 20
            if estimate > 0.8 * have:
                print(f"{n} products: not run; the adjustment's peak extrapolated at n^{k:.2f} is about "
                      f"{estimate / 1024:.1f} GB, more than 80 % of the {have / 1024:.1f} GB available", flush=True)
                continue
        for seed in range(first, first + args.seeds):
            args.seed = seed
            row = run_size(args, n)
            if row is None:
                break
            by_size.setdefault(n, []).append(row)
        if n not in by_size:
            break
        rows.append(by_size[n][0])
    if args.seeds > 1:
        print_mean_error_spread(by_size)
    for a, b in zip(rows, rows[1:]):
        print(f"block mean error {a['n']} -> {b['n']} products: {a['truth']['block_mean_m']:.2f} -> "
              f"{b['truth']['block_mean_m']:.2f} m (sqrt(n) law: {a['truth']['block_mean_m'] * math.sqrt(a['n'] / b['n']):.2f} m)")
        print(f"growth {a['n']} -> {b['n']} products: time n^{exponent(a, b, 'wall_s'):.2f} wall, "
              f"n^{exponent(a, b, 'cpu_s'):.2f} CPU, memory n^{exponent(a, b, 'peak_mb'):.2f}")
    load = os.getloadavg()
    print(f"load average (1, 5, 15 min): {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
