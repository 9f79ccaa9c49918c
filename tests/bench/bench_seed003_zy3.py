"""Zhang et al. 2024 (seed 003) on a simulated ZY-3 three-line strip: Plans A-D in one run each,
with 4 corner GCPs, 16 spread GCPs and no GCP, tie points in all cameras. Prints figures (no
assertions); tests/scenarios/test_seed003.py asserts the key ones. The strip, the plans and a run's
figures are in tests/support/zy3_strip.py.

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_seed003_zy3.py
      [--quick] [--seed 3] [--seeds 5] [--scenes 4] [--ties 300] [--preset-errors] [--diagnose] [--details]

Each seed is a new strip (errors, points, noise); all figures of the first are printed, then
issue 10's criterion 2 over all seeds with PASS/FAIL lines: (a) Plan D with 4 corner GCPs
within 10 % of 16 GCPs (per seed, and over all seeds' check points pooled), (b) the
installation angles within 3 sigma of the truth, (c) without GCPs the tie-point residuals at
the noise and the absolute offset within what the onboard pseudo-observations hold. One seed's
ratio is a single draw of the control points' image noise (which sets the datum: with 4 GCPs
it carries about floor * sqrt(p / 4) for p datum terms), so it scatters by +-15 %; the pooled
ratio is the expectation. --diagnose adds Plan D variants that locate the gap (variance
components off, true installation, attitude order 1/0, control points without image noise).

Plans (seed 003 sec. 3.2): A one first-order trajectory correction per camera
(camera_trajectory='per_camera'); B, C, D one correction shared by the cameras, attitude
order 0, 1, 2, plus the installation angles of FWD and BWD against NAD (free, and kept with
interior_selection='keep' so that all six can be compared with the truth; the default
'significant' removes the non-significant ones: its choice for Plan D is printed too).

The strip: --scenes ZY-3 scenes (NAD 24576 x 24576 rows each), GCPs measured in all three
cameras, 0.3 px image noise, 0.1 m ground noise (static GPS, as the seed's). Control: the 4
points nearest the corners of the whole strip (seed 003 sec. 3.3), or 16 on a 2 x 8 grid;
check points: all other GCPs, the same for every run. The onboard GPS (position_sigma 10 m)
and star trackers (attitude_sigma 1e-4 rad, 21") enter as pseudo-observations in every run:
with no GCP they alone hold the datum. The simulated errors are the preset's trajectory
(position bias/drift, attitude bias/drift/quadratic) and installation errors; its sub-pixel
camera terms and CCD alignment errors (which no plan models: ZY-3's lines of sight are
calibrated in orbit) are left out unless --preset-errors.

Figures: check points intersected from all their cameras with the adjusted model, RMSE east,
north, plan and height (m; seed 003 Tables 3 and 5); tie-point image residuals per camera, RMSE
across (col, the scanning direction) and along track (row, the flight direction) in px (Tables 2
and 4: the relative accuracy); installation angles minus truth in sigmas. Without GCPs the
absolute error is set beside the onboard trajectory's own: the check points intersected with
the onboard trajectory and the true cameras.
"""
from __future__ import annotations

import argparse
import logging
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.observations import gcps as G  # noqa: E402
from pushbroom_adjust.core.adjust.checkpoints import intersection_accuracy  # noqa: E402
from pushbroom_adjust.core.adjust.parameters import DEFAULT_INSTALLATION_ARCSEC  # noqa: E402
from pushbroom_adjust.core.rotations import ARCSEC  # noqa: E402
from pushbroom_adjust.simulation.presets import PRESETS  # noqa: E402
from tests.support.zy3_strip import (BASE, NOISE_PX, PLANS, WEIGHTED, Strip, control_layouts,  # noqa: E402
                                     gcp_table, noise_free_control, run, simulate_strip)


def onboard_error(strip: Strip, table: G.GcpTable) -> np.ndarray:
    """(m, 3) east/north/up m: check points intersected with the onboard trajectory and the true
    cameras against their known positions, the error the onboard orbit and attitude alone leave."""
    return intersection_accuracy(strip.onboard_trajectory, table, np.nonzero(table.role == "check")[0])["errors"]


def floor_error(strip: Strip, table: G.GcpTable) -> np.ndarray:
    """(m, 3) east/north/up m: check points intersected with the true scene, the error of their
    image and ground noise alone (the floor no adjustment can beat)."""
    return intersection_accuracy(strip.true, table, np.nonzero(table.role == "check")[0])["errors"]


def rmse(errors: np.ndarray) -> tuple[float, float, float, float]:
    """RMSE east, north, plan, height (m) of (m, 3) east/north/up errors."""
    e, n, u = np.sqrt(np.mean(errors ** 2, axis=0))
    return float(e), float(n), float(np.hypot(e, n)), float(u)


# --- one seed ----------------------------------------------------------------------------------
def measure(seed: int, args) -> dict:
    """Every run of one simulated strip: Plans A-D with 4, 16 and 0 GCPs (interior_selection
    'keep'), Plan D with the default selection, Plans B-D without GCPs with the 30" prior, the
    onboard and noise-floor errors of the check points; with ``args.diagnose`` also Plan D with
    4 and 16 GCPs by the variants of :data:`DIAGNOSES`."""
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        strip = simulate_strip(Path(tmp), seed, args.scenes, args.gcps, args.ties, args.preset_errors)
        layouts = control_layouts(strip)
        tables = {n: gcp_table(strip, layouts, n) for n in layouts}
        results = {(n, p): run(strip, tables[n], p) for n in (4, 16, 0) for p in PLANS}
        default_d = {n: run(strip, tables[n], "D", interior_selection="significant") for n in (4, 16, 0)}
        weighted = {p: run(strip, tables[0], p, interior=WEIGHTED) for p in "BCD"}
        diagnosis = {(label, n): diagnose(strip, tables[n], variant) for label, variant in DIAGNOSES.items()
                     for n in (4, 16)} if args.diagnose else {}
        return {"seed": seed, "results": results, "default_d": default_d, "weighted": weighted,
                "onboard": onboard_error(strip, tables[0]), "floor": floor_error(strip, tables[4]),
                "diagnosis": diagnosis, "seconds": time.perf_counter() - start,
                "adjustments": len(results) + len(default_d) + len(weighted) + len(diagnosis)}


# Plan D variants that test where the 4-vs-16 GCP gap comes from (name -> (scene, settings)):
# the engine's variance components off, the true interior (installation angles fixed at the
# truth, trajectory only), lower attitude orders, the control points' image positions without
# their 0.3 px noise (the check points keep theirs).
DIAGNOSES = {"variance components off": ("onboard", {"variance_components": False}),
             "true installation, trajectory only": ("true_interior", {"interior": ""}),
             "attitude order 1 (Plan C)": ("onboard", {"attitude_order": 1}),
             "attitude order 0 (Plan B)": ("onboard", {"attitude_order": 0}),
             "control without image noise": ("exact_control", {})}


def diagnose(strip: Strip, table: G.GcpTable, variant: tuple[str, dict]) -> dict:
    """Plan D on ``table`` by a :data:`DIAGNOSES` variant."""
    scene, extra = variant
    if scene == "true_interior":
        strip = replace(strip, scene=strip.onboard_trajectory)
    if scene == "exact_control":
        table = noise_free_control(strip, table)
    return run(strip, table, "D", **extra)


# --- printing ----------------------------------------------------------------------------------
def _check_row(label: str, f: dict) -> str:
    c = f["check"]
    ties = "  ".join(f"{cam} {col:.3f}/{row:.3f}" for cam, (col, row) in f["ties"].items())
    return f"{label:<14} {c['east']:7.2f} {c['north']:7.2f} {c['plan']:7.2f} {c['height']:7.2f}   {ties}"


def _installation_rows(label: str, f: dict) -> list[str]:
    fixed = [d["fixed"] for d in f["determinability"]]
    rows = [f"{label:<14} " + "  ".join(f"{name} {v:+6.1f}\"±{s:4.1f} ({z:+.1f}σ)" for name, (v, s, z)
                                        in f["installation"].items())]
    if fixed:
        rows.append(f"{'':<14} not determinable, fixed at 0: {', '.join(fixed)}")
    return rows


def print_details(m: dict, args) -> None:
    """All figures of one seed (:func:`measure`)."""
    results, default_d, weighted, onboard = m["results"], m["default_d"], m["weighted"], m["onboard"]
    any_run = results[(4, "D")]
    print(f"ZY-3 strip of {args.scenes} scenes (seed {m['seed']}), {any_run['tie_points']} tie points, "
          f"{any_run['check_points']} check points, {NOISE_PX} px image noise; "
          f"{'preset errors' if args.preset_errors else 'trajectory and installation errors only'}; "
          f"{m['seconds']:.0f} s for {m['adjustments']} adjustments")
    print("\nCheck points, 3D RMSE (m) and tie-point image RMSE col/row (px) per camera")
    print(f"{'GCPs, plan':<14} {'east':>7} {'north':>7} {'plan':>7} {'height':>7}   tie points")
    for (n, p), f in results.items():
        print(_check_row(f"{n:>2} GCPs, {p}", f))
    _, _, pl, h = rmse(m["floor"])
    print(f"{'true scene':<14} {'':>7} {'':>7} {pl:7.2f} {h:7.2f}   (the noise floor: check points intersected "
          "with the true trajectory and cameras)")
    print("\nInstallation angles (interior_selection='keep'): estimate ± sigma (arcsec), (estimate - truth) / sigma")
    for (n, p), f in results.items():
        if p != "A":
            for line in _installation_rows(f"{n:>2} GCPs, {p}", f):
                print(line)
    for p, f in weighted.items():
        for line in _installation_rows(f" 0 GCPs, {p}, {DEFAULT_INSTALLATION_ARCSEC:g}\" prior", f):
            print(line)
    print("\nPlan D with the default interior_selection='significant':")
    for n, f in default_d.items():
        sel = f["selection"] or {}
        kept = ", ".join(x["name"] for x in sel.get("kept", [])) or "none"
        removed = ", ".join(x["name"] for x in sel.get("removed", [])) or "none"
        print(f"  {n:>2} GCPs: outcome {sel.get('outcome')}; kept {kept}; removed {removed}; "
              f"check plan {f['check']['plan']:.2f} m, height {f['check']['height']:.2f} m")
    print("\nNo GCP: " + results[(0, "D")]["datum"])
    print(f"  the pseudo-observations hold the datum to about {HELD_M:.0f} m (attitude sigma "
          f"{BASE.attitude_sigma / ARCSEC:.0f}\" at {PRESETS['zy3_tlc'].altitude / 1e3:.0f} km) and "
          f"{BASE.position_sigma:.0f} m (position sigma), 1 sigma per axis")
    e, n_, pl, h = rmse(onboard)
    print(f"  onboard trajectory alone (true cameras): RMSE east {e:.2f}, north {n_:.2f}, plan {pl:.2f}, "
          f"height {h:.2f} m; mean offset E/N/U {', '.join(f'{v:+.1f}' for v in onboard.mean(axis=0))} m")
    runs = [(f"Plan {p}", results[(0, p)]) for p in PLANS] + \
        [(f"Plan {p}, {DEFAULT_INSTALLATION_ARCSEC:g}\" prior", f) for p, f in weighted.items()]
    for label, f in runs:
        c = f["check"]
        print(f"  {label:<18} check RMSE plan {c['plan']:6.2f}, height {c['height']:6.2f} m; mean offset E/N/U "
              f"{', '.join(f'{v:+6.1f}' for v in f['errors'].mean(axis=0))} m; tie RMSE col/row "
              + "  ".join(f"{cam} {col:.2f}/{row:.2f}" for cam, (col, row) in f["ties"].items()))


# --- criterion 2 of issue 10 over the seeds ----------------------------------------------------
HELD_M = float(np.hypot(BASE.attitude_sigma * PRESETS["zy3_tlc"].altitude, BASE.position_sigma))
TOLERANCE = 0.10      # Plan D with 4 corner GCPs within 10 % of 16 GCPs
ANGLE_SIGMAS = 3.0    # installation angles within 3 sigma of the truth
OFFSET_SIGMAS = 3.0   # without GCPs, the mean offset within 3 sigma of what the pseudo-observations hold


def _pooled(measured: list[dict], key) -> np.ndarray:
    """(m, 3) east/north/up errors of every seed's check points, by ``key(measure) -> errors``."""
    return np.concatenate([key(m) for m in measured])


def _ratio_line(label: str, four: np.ndarray, sixteen: np.ndarray, width: int = 40) -> tuple[str, list[float]]:
    """A printed line 'plan 4 / 16 GCPs m (ratio - 1), height ...' and the two ratios - 1."""
    _, _, p4, h4 = rmse(four)
    _, _, p16, h16 = rmse(sixteen)
    ratios = [p4 / p16 - 1.0, h4 / h16 - 1.0]
    return (f"{label:<{width}} plan {p4:5.2f} / {p16:5.2f} m ({100 * ratios[0]:+4.0f} %), "
            f"height {h4:5.2f} / {h16:5.2f} m ({100 * ratios[1]:+4.0f} %)"), ratios


def _verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def print_criterion(measured: list[dict]) -> None:
    """Per seed and pooled over the seeds: the three parts of issue 10's criterion 2."""
    n = len(measured)
    print(f"\n=== Issue 10, criterion 2 over {n} seeds ({', '.join(str(m['seed']) for m in measured)}) ===")
    print("\n(a) Plan D, 4 corner GCPs against 16 (check RMSE 4 / 16 GCPs); 'beyond the floor': the error of "
          "the adjusted\n    model alone (each check point's error minus its error through the true scene)")
    per_seed = []
    for m in measured:
        four, sixteen = m["results"][(4, "D")]["errors"], m["results"][(16, "D")]["errors"]
        line, ratios = _ratio_line(f"  seed {m['seed']}", four, sixteen)
        beyond, _ = _ratio_line("    beyond the floor", four - m["floor"], sixteen - m["floor"])
        per_seed.append(ratios)
        print(f"{line}  {'within' if max(ratios) <= TOLERANCE else 'beyond'} 10 %\n{beyond}")
    line, ratios = _ratio_line(f"  pooled, {len(_pooled(measured, lambda m: m['floor']))} check points",
                               _pooled(measured, lambda m: m["results"][(4, "D")]["errors"]),
                               _pooled(measured, lambda m: m["results"][(16, "D")]["errors"]))
    print(line)
    per_seed = 100 * np.array(per_seed)
    mean, se = per_seed.mean(axis=0), per_seed.std(axis=0, ddof=1) / np.sqrt(n) if n > 1 else np.zeros(2)
    print(f"  {'per-seed ratios, mean ± standard error':<38} plan {mean[0]:+.1f} ± {se[0]:.1f} %, "
          f"height {mean[1]:+.1f} ± {se[1]:.1f} %")
    _, _, pf, hf = rmse(_pooled(measured, lambda m: m["floor"]))
    print(f"  {'pooled noise floor (true scene)':<38} plan {pf:5.2f} m, height {hf:5.2f} m")
    for plan in "ABC":
        other, _ = _ratio_line(f"  pooled, Plan {plan} (for comparison)",
                               _pooled(measured, lambda m: m["results"][(4, plan)]["errors"]),
                               _pooled(measured, lambda m: m["results"][(16, plan)]["errors"]))
        print(other)
    print("  seed 003 Table 5, Plan D: plan 1.859 / 1.834 m (+1 %), height 1.876 / 1.717 m (+9 %); "
          "Plan A: plan 2.177 / 1.884 m (+16 %), height 1.571 / 1.505 m (+4 %)")
    within = int(np.sum(per_seed.max(axis=1) <= 100 * TOLERANCE))
    print(f"{_verdict(max(ratios) <= TOLERANCE)} 2a: Plan D with 4 corner GCPs within 10 % of 16 GCPs, pooled over "
          f"{n} seeds (plan {100 * ratios[0]:+.1f} %, height {100 * ratios[1]:+.1f} %); {within} of {n} seeds "
          "within 10 % on their own")
    # Plan B's constant attitude correction cannot follow the simulated attitude drift (FWD and
    # BWD see a point about 60 s apart); the installation angles absorb part of what it leaves,
    # so Plan B is judged apart (seed 003 sec. 3.2 finds Plan B insufficient for the drift).
    angles = [(m["seed"], k, p, name, zz) for m in measured for (k, p), f in m["results"].items() if k and p != "A"
              for name, (_, _, zz) in f["installation"].items()]
    for plans in ("CD", "B"):
        z = np.array([a[-1] for a in angles if a[2] in plans])
        print(f"\n(b) installation angles, Plan{'s' if len(plans) > 1 else ''} {' and '.join(plans)} with 4 and 16 GCPs: "
              f"{z.size} angles, largest |estimate - truth| {np.max(np.abs(z)):.1f} sigma, RMS "
              f"{np.sqrt(np.mean(z ** 2)):.2f} sigma, {int(np.sum(np.abs(z) > ANGLE_SIGMAS))} beyond 3 sigma (a normal "
              f"error exceeds 3 sigma with probability 0.27 %: {0.0027 * z.size:.1f} expected)")
        for seed, k, p, name, zz in angles:
            if p in plans and abs(zz) > ANGLE_SIGMAS:
                print(f"    beyond: seed {seed}, {k} GCPs, Plan {p}, {name} {zz:+.1f} sigma")
    print("    (Plan B: its constant attitude correction leaves the simulated attitude drift unmodelled, and the "
          "installation angles absorb part of it: their sigmas do not cover a model error)")
    beyond = sum(abs(zz) > ANGLE_SIGMAS for _, _, p, _, zz in angles if p in "CD")
    print(f"{_verdict(beyond == 0)} 2b: installation angles within 3 sigma of the truth (Plans C and D)")
    ties = {p: max(max(col, row) for m in measured for col, row in m["results"][(0, p)]["ties"].values())
            for p in PLANS}
    offsets = np.array([np.abs(m["results"][(0, p)]["errors"].mean(axis=0)) for m in measured for p in PLANS])
    named = all(m["results"][(0, p)]["datum"].startswith("datum held by onboard pseudo-observations")
                for m in measured for p in PLANS)
    onboard = np.array([np.abs(m["onboard"].mean(axis=0)) for m in measured])
    print("\n(c) no GCP: largest tie-point RMSE per camera and axis (the relative accuracy), "
          + ", ".join(f"Plan {p} {v:.3f} px" for p, v in ties.items()) + f" (noise {NOISE_PX} px);\n    Plans A-D: "
          f"largest mean offset E/N/U {', '.join(f'{v:.1f}' for v in offsets.max(axis=0))} m against "
          f"{OFFSET_SIGMAS:g} x {HELD_M:.0f} m the pseudo-observations hold (the onboard trajectory's own: "
          f"{', '.join(f'{v:.1f}' for v in onboard.max(axis=0))} m); datum named in every run: {named}")
    ok = ties["D"] < NOISE_PX and bool(np.all(offsets < OFFSET_SIGMAS * HELD_M)) and named
    print(f"{_verdict(ok)} 2c: without GCPs Plan D's relative accuracy at the noise, and every plan's absolute "
          "offset within what the onboard pseudo-observations hold")
    if measured[0]["diagnosis"]:
        print("\nWhere the gap comes from: Plan D variants, pooled over the seeds (4 / 16 GCPs)")
        for label in DIAGNOSES:
            line, _ = _ratio_line(f"  {label}", _pooled(measured, lambda m: m["diagnosis"][(label, 4)]["errors"]),
                                  _pooled(measured, lambda m: m["diagnosis"][(label, 16)]["errors"]))
            print(line)
        line, _ = _ratio_line("  interior_selection 'significant'",
                              _pooled(measured, lambda m: m["default_d"][4]["errors"]),
                              _pooled(measured, lambda m: m["default_d"][16]["errors"]))
        print(line)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="2 scenes, 60 GCPs, 150 tie points")
    parser.add_argument("--seed", type=int, default=3, help="the first seed")
    parser.add_argument("--seeds", type=int, default=5, help="how many seeds (seed, seed + 1, ...)")
    parser.add_argument("--scenes", type=int, default=4)
    parser.add_argument("--gcps", type=int, default=150, help="simulated GCPs (control and check)")
    parser.add_argument("--ties", type=int, default=300)
    parser.add_argument("--preset-errors", action="store_true",
                        help="keep the preset's camera and CCD errors (no plan models them)")
    parser.add_argument("--diagnose", action="store_true", help="Plan D variants: where the 4-vs-16 gap comes from")
    parser.add_argument("--details", action="store_true", help="all figures of every seed (else of the first)")
    args = parser.parse_args()
    if args.quick:
        args.scenes, args.gcps, args.ties = 2, 60, 150
    logging.basicConfig(level=logging.ERROR)
    start = time.perf_counter()
    measured = []
    for k, seed in enumerate(range(args.seed, args.seed + args.seeds)):
        measured.append(measure(seed, args))
        if k == 0 or args.details:
            print_details(measured[-1], args)
            print()
    print_criterion(measured)
    print(f"\n{sum(m['adjustments'] for m in measured)} adjustments of {args.seeds} strips in "
          f"{time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
