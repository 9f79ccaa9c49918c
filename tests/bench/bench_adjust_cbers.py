"""The CBERS-02B long-strip experiment of seed 000, on a simulated strip with known truth.
Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_adjust_cbers.py EXPERIMENT
      [--scenes 50] [--gcps 100000] [--out DIR]

The strip: --scenes CBERS-02B HRC scenes (12246 x 12246 px each) with the preset's onboard
errors (position bias/drift, attitude bias/drift/2nd order: ~400 m on the ground) and left/right
CCD shifts of 1-3 px and rotations of 3e-4-1e-3 rad (the middle CCD is the reference); --gcps
ground points with 0.7 px image noise and 3 m / 10 m ground noise (seed 000's matched points),
half of them check points. Trajectory: orientation images every 20 s (4-point Lagrange) for
position and attitude, onboard GPS as 100 m pseudo-observations, weighted ground (the strip and
these settings: tests/support/cbers_strip.py).

Experiments:
  table2        seed 000 Table II: schemes 1-11 of interior parameters; image residual RMSE of
                the control points (col = across track, row = along track), the image noise
                each implies (variance component x sigma: weighted ground takes part of the
                misfit, so raw residuals are smaller than the noise), and check-point RMSE (m)
  realisations  20 noise realisations of one strip: spread of the CCD estimates against their
                reported sigmas, bias against the truth, and check-point RMSE against the floor
                of an adjustment with the true interior parameters fixed
  gross         10 % gross errors of 5-100 px: share flagged, false alarms, check-point RMSE
                against the same strip without gross errors
  intervals     orientation-image intervals 3, 13, 20, 50, 80 s: check-point RMSE and the
                trajectory corrections against time (seed 000 Fig. 7-11), plotted to
                DIR/intervals.png
  speed         a 500 000-GCP strip (use --gcps 500000), robust adjustment: wall time and
                peak memory of the adjustment alone (reading and simulating excluded)
"""
from __future__ import annotations

import argparse
import json
import resource
import sys
import tempfile
import time
import tracemalloc
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.observations import gcps as G  # noqa: E402
from pushbroom_adjust.core.adjust import adjust  # noqa: E402
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, enu_rotations  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from tests.support.cbers_strip import GROUND_XY, GROUND_Z, IMAGE_NOISE, model_error, settings, strip  # noqa: E402

SCHEMES = [  # seed 000 Table II: x0, y0, a0 = left chip (HRC-1), x1.. middle (HRC-2), x2.. right (HRC-3)
    ("1", "HRC.f, HRC-1.*, HRC-2.*, HRC-3.*"), ("2", "HRC-1.*, HRC-2.*, HRC-3.*"),
    ("3", "HRC.f, HRC-1.*, HRC-3.*"), ("4", "HRC-1.*, HRC-3.*"),
    ("5", "HRC.f, HRC-1.dx, HRC-1.theta, HRC-3.dx, HRC-3.theta"), ("6", "HRC-1.dx, HRC-1.theta, HRC-3.dx, HRC-3.theta"),
    ("7", "HRC.f, HRC-1.dx, HRC-1.dy, HRC-3.dx, HRC-3.dy"), ("8", "HRC-1.dx, HRC-1.dy, HRC-3.dx, HRC-3.dy"),
    ("9", "HRC.f, HRC-1.dx, HRC-3.dx"), ("10", "HRC-1.dx, HRC-3.dx"), ("11", ""),
]


def truth_of(result) -> dict:
    """{'HRC-1.dx': metres, ...} of the simulated CCD errors."""
    chips = json.loads(result.manifest.read_text())["truth"]["interior"][0]["chips"]
    out = {}
    for c in chips:
        out.update({f"{c['chip']}.dx": c["dx_m"], f"{c['chip']}.dy": c["dy_m"], f"{c['chip']}.theta": c["dtheta_rad"]})
    return out


# --- experiments ------------------------------------------------------------------------------
def table2(args) -> None:
    result, scene, table = strip(args.out / "strip", args.scenes, args.gcps)
    n_control = int(np.sum(table.role == "control"))
    print(f"strip: {args.scenes} scenes, {len(table)} GCPs ({n_control} control, the rest check), image noise "
          f"{IMAGE_NOISE} px, ground noise {GROUND_XY} m / {GROUND_Z} m")
    print(f"{'ID':>3} {'parameters':<46} {'RMS col':>8} {'RMS row':>8} {'max col':>8} {'max row':>8} "
          f"{'noise':>6} {'chk E m':>8} {'chk N m':>8} {'chk px':>7} {'model px':>8}  determinability")
    checks = np.nonzero(table.role == "check")[0]
    for sid, interior in SCHEMES:
        t0 = time.perf_counter()
        out = adjust(scene, table, settings(interior=interior))
        rep = out.report
        r = rep["control_residuals"]
        noise = rep["variance_components"]["image"]["sigma0"] * IMAGE_NOISE
        chk = rep["check_points"]
        det = "; ".join(f"{', '.join(d['parameters'][:4])}{'...' if len(d['parameters']) > 4 else ''} "
                        f"not determinable: fixed {d['fixed']}" for d in rep["determinability"]) or "ok"
        print(f"{sid:>3} {interior or 'none':<46} {r['rmse_col']:8.3f} {r['rmse_row']:8.3f} {r['max_col']:8.2f} "
              f"{r['max_row']:8.2f} {noise:6.3f} {chk['ground']['rmse_east']:8.2f} {chk['ground']['rmse_north']:8.2f} "
              f"{chk['image']['rmse']:7.3f} {model_error(out.scene, result, checks):8.3f}  {det}  "
              f"[{time.perf_counter() - t0:.1f} s]")
    print(f"simulated image noise {IMAGE_NOISE} px; 'noise' = image variance component x sigma_px, what the "
          "residuals imply the image noise is; 'model px' = RMSE of the adjusted model at the true check points "
          "(no measurement noise)")


def add_noise(table: G.GcpTable, rng: np.random.Generator) -> G.GcpTable:
    """A noise realisation of a noise-free table: image and ground (east/north/up) noise."""
    enu = rng.normal(0.0, 1.0, (len(table), 3)) * [GROUND_XY, GROUND_XY, GROUND_Z]
    xyz = table.ecef() + np.einsum("nji,nj->ni", enu_rotations(table.lon, table.lat), enu)
    lon, lat, h = ecef_to_geodetic(xyz)
    return replace(table, col=table.col + rng.normal(0.0, IMAGE_NOISE, len(table)),
                   row=table.row + rng.normal(0.0, IMAGE_NOISE, len(table)), lon=lon, lat=lat, h=h)


def realisations(args) -> None:
    result, scene, clean = strip(args.out / "strip0", args.scenes, args.gcps, image_noise=0.0, ground_noise_xy=0.0,
                                 ground_noise_z=0.0)
    truth = truth_of(result)
    names = [n for n in truth if not n.startswith("HRC-2")]
    true_scene = load_scene(result.true_scene)
    floor_scene = replace(scene, cameras=true_scene.cameras)  # onboard trajectory, true interior
    estimates, sigmas, checks, floors = [], [], [], []
    for k in range(args.realisations):
        table = add_noise(clean, np.random.default_rng(100 + k))
        rep = adjust(scene, table, settings(interior="HRC-1.*, HRC-3.*")).report
        p = {q["name"]: q for q in rep["parameters"]}
        estimates.append([p[n]["value"] for n in names])
        sigmas.append([p[n]["sigma"] for n in names])
        checks.append(rep["check_points"]["ground"]["rmse"])
        floors.append(adjust(floor_scene, table, settings()).report["check_points"]["ground"]["rmse"])
    est, sig = np.array(estimates), np.array(sigmas)
    spread, mean_sigma = est.std(axis=0, ddof=1), sig.mean(axis=0)
    print(f"{args.realisations} noise realisations, strip of {args.scenes} scenes, {args.gcps} GCPs")
    print(f"{'parameter':<12} {'truth':>12} {'mean est.':>12} {'spread':>11} {'mean sigma':>11} {'spread/sigma':>12} "
          f"{'|bias|/sigma':>12} {'max |err|/sigma':>15}")
    for j, n in enumerate(names):
        err = np.abs(est[:, j] - truth[n]) / sig[:, j]
        print(f"{n:<12} {truth[n]:12.4e} {est[:, j].mean():12.4e} {spread[j]:11.3e} {mean_sigma[j]:11.3e} "
              f"{spread[j] / mean_sigma[j]:12.2f} {abs(est[:, j].mean() - truth[n]) / mean_sigma[j]:12.2f} "
              f"{err.max():15.2f}")
    ratio = np.array(checks) / np.array(floors)
    print(f"check-point RMSE (m): mean {np.mean(checks):.3f}; floor with the true interior fixed {np.mean(floors):.3f}; "
          f"ratio mean {ratio.mean():.3f}, max {ratio.max():.3f}")


def gross(args) -> None:
    _, scene, clean = strip(args.out / "clean", args.scenes, args.gcps)
    result, _, table = strip(args.out / "gross", args.scenes, args.gcps, gross_fraction=0.1)
    is_gross = np.genfromtxt(result.gcps, delimiter=",", names=True, usecols=("gross",), dtype=int)["gross"] == 1
    base = adjust(scene, clean, settings(interior="HRC-1.*, HRC-3.*")).report
    for method in ("selection", "snooping"):
        t0 = time.perf_counter()
        out = adjust(scene, table, settings(interior="HRC-1.*, HRC-3.*", robust=method))
        wall = time.perf_counter() - t0
        flagged = out.points["flagged"]
        for role in ("control", "check"):
            m = table.role == role
            print(f"{method:<9} {role:<7}: {int((m & is_gross).sum())} gross errors, flagged "
                  f"{100 * flagged[m & is_gross].mean():.2f} %; good points flagged {100 * flagged[m & ~is_gross].mean():.2f} %")
        rob = out.report["check_points"]["without_blunders"]
        print(f"{method:<9} check-point RMSE without blunders {rob['ground']['rmse']:.3f} m / {rob['image']['rmse']:.3f} px;"
              f" without gross errors in the data {base['check_points']['ground']['rmse']:.3f} m / "
              f"{base['check_points']['image']['rmse']:.3f} px (ratio {rob['ground']['rmse'] / base['check_points']['ground']['rmse']:.3f});"
              f" sigma0 {out.report['sigma0']:.3f}; {wall:.1f} s")


def intervals(args) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    _, scene, table = strip(args.out / "strip", args.scenes, args.gcps)
    fig, axes = plt.subplots(2, 3, figsize=(15, 7), sharex=True)
    for interval in (3.0, 13.0, 20.0, 50.0, 80.0):
        rep = adjust(scene, table, settings(interior="HRC-1.*, HRC-3.*", position_interval=interval,
                                            attitude_interval=interval)).report
        chk = rep["check_points"]
        print(f"orientation images every {interval:4.0f} s: {len(rep['trajectory']['attitude_knots'])} knots, "
              f"sigma0 {rep['sigma0']:.3f}, check RMSE E {chk['ground']['rmse_east']:.2f} m N "
              f"{chk['ground']['rmse_north']:.2f} m ({chk['image']['rmse']:.3f} px)")
        tr = rep["trajectory"]
        t = np.array(tr["time"])
        for a in range(3):
            axes[0, a].plot(t, np.array(tr["position"])[:, a], label=f"{interval:.0f} s")
            axes[1, a].plot(t, np.degrees(np.array(tr["attitude"])[:, a]) * 3600, label=f"{interval:.0f} s")
    for a, (pos, ang) in enumerate(zip("XYZ", ("roll", "pitch", "yaw"))):
        axes[0, a].set_title(f"position correction {pos} (m, ECEF)")
        axes[1, a].set_title(f"attitude correction {ang} (arcsec)")
        axes[1, a].set_xlabel("time (s from the strip's middle)")
    axes[0, 0].legend(title="interval")
    fig.tight_layout()
    fig.savefig(args.out / "intervals.png", dpi=90)
    plt.close(fig)
    print(f"plot: {args.out / 'intervals.png'}")


def speed(args) -> None:
    _, scene, table = strip(args.out / "strip", args.scenes, args.gcps, gross_fraction=0.1)
    chosen = settings(interior="HRC-1.*, HRC-3.*", robust="selection")
    t0 = time.perf_counter()
    out = adjust(scene, table, chosen)
    wall = time.perf_counter() - t0
    # Memory in a second, traced run (tracing slows allocations): numpy reports its buffers to
    # tracemalloc, so this is the adjustment's own peak.
    tracemalloc.start()
    adjust(scene, table, chosen)
    peak = tracemalloc.get_traced_memory()[1] / 2 ** 20
    tracemalloc.stop()
    process_peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    rep = out.report
    print(f"{len(table)} GCPs ({rep['observations']['image_observations']} control observations, "
          f"{rep['observations']['unknowns']} parameters + {rep['observations']['ground_unknowns']} ground unknowns), "
          f"10 % gross errors, selection weights: {wall:.1f} s wall, {len(rep['robust']['passes'])} robust passes, "
          f"peak memory of the adjustment {peak:,.0f} MiB (traced); process peak resident {process_peak:,.0f} MiB "
          "(simulation included)")
    print(f"sigma0 {rep['sigma0']:.3f}, flagged {rep['robust']['flagged']}, check RMSE without blunders "
          f"{rep['check_points']['without_blunders']['ground']['rmse']:.2f} m")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("experiment", choices=["table2", "realisations", "gross", "intervals", "speed"])
    parser.add_argument("--scenes", type=int, default=50)
    parser.add_argument("--gcps", type=int, default=100_000)
    parser.add_argument("--realisations", type=int, default=20)
    parser.add_argument("--out", type=Path, default=None, help="folder for the simulation and plots (default: temporary)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        args.out = args.out or Path(tmp)
        args.out.mkdir(parents=True, exist_ok=True)
        globals()[args.experiment](args)


if __name__ == "__main__":
    main()
