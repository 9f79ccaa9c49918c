"""Robust estimation with wrong a-priori sigmas and a breakdown case, on a simulated CBERS-02B
scene with known truth. Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_robust_sigmas.py
      [--gcps 4000] [--scenes 1] [--out DIR]

The scene: CBERS-02B HRC with the preset's onboard and CCD errors, --gcps ground points with
0.7 px image noise and 3 m / 10 m ground noise, half of them check points, 30 % of the image
measurements displaced by 5-100 px in random directions. Adjusted with selection weights and
the left/right CCD terms (HRC-1.*, HRC-3.*), with the sigmas stated right, x0.5 and x2 (image
and ground together, and in opposite directions): share of the gross errors flagged, share of
the good points flagged (control and check), the check-point RMSE without blunders against the
run with the right sigmas, the estimated image sigma and whether the result is called reliable.

Breakdown: half of the right CCD's (HRC-3) measurements of the gross-free scene shifted by
4, 10 and 20 px in col and row (the same direction): what is named, and the adjusted model's
true error at the check points (ground -> image against the noise-free positions, px) beside
the reported check RMSE. Then 40 % and 50 % random gross errors.
"""
from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.adjust import adjust  # noqa: E402
from tests.support.cbers_strip import model_error, settings, strip  # noqa: E402

STATED = [("right", 1.0, 1.0), ("x0.5", 0.5, 0.5), ("x2", 2.0, 2.0), ("image x0.5, ground x2", 0.5, 2.0),
          ("image x2, ground x0.5", 2.0, 0.5)]


def chosen(**kw):
    return settings(interior="HRC-1.*, HRC-3.*", robust="selection", **kw)


def gross_flags(result) -> np.ndarray:
    return np.genfromtxt(result.gcps, delimiter=",", names=True, usecols=("gross",), dtype=int)["gross"] == 1


def stated(table, image: float, ground: float):
    return replace(table, sigma_px=table.sigma_px * image, sigma_xy=table.sigma_xy * ground,
                   sigma_z=table.sigma_z * ground)


def verdict(rep: dict) -> str:
    rel = rep["reliability"]
    named = "; ".join(f"{p['group']} {p['kind']}" + (f" {100 * p['share']:.0f} %" if p["share"] is not None else "")
                      for p in rel["problems"])
    limit = ", stopped at the pass limit" if rep["robust"]["stopped_at_limit"] else ""
    return ("reliable" if rel["reliable"] else "NOT RELIABLE") + (f" ({named})" if named else "") + limit


def wrong_sigmas(args) -> None:
    result, scene, table = strip(args.out / "gross", args.scenes, args.gcps, gross_fraction=0.3)
    is_gross = gross_flags(result)
    print(f"{len(table)} GCP rows ({int((table.role == 'control').sum())} control), 30 % gross errors "
          f"({int(is_gross.sum())}), image noise 0.7 px, ground noise 3 m / 10 m")
    print(f"{'stated sigmas':<24} {'vc':<4} {'gross flagged ctl/chk %':>24} {'good flagged ctl/chk %':>23} "
          f"{'check RMSE m':>12} {'vs right':>8} {'est. img px':>11}  verdict")
    for vc in (True, False):
        base = None
        for label, image, ground in STATED:
            out = adjust(scene, stated(table, image, ground), chosen(variance_components=vc))
            rep, flagged = out.report, out.points["flagged"]
            shares = {}
            for role in ("control", "check"):
                m = table.role == role
                shares[role] = (100 * flagged[m & is_gross].mean(), 100 * flagged[m & ~is_gross].mean())
            rmse = rep["check_points"]["without_blunders"]["ground"]["rmse"]
            base = base or rmse
            est = rep["variance_components"]["image HRC"]["estimated_sigma"]
            print(f"{label:<24} {'on' if vc else 'off':<4} {shares['control'][0]:11.2f} / {shares['check'][0]:6.2f}     "
                  f"{shares['control'][1]:10.2f} / {shares['check'][1]:6.2f}   {rmse:12.3f} {rmse / base:8.3f} "
                  f"{est:11.3f}  {verdict(rep)}")


def breakdown(args) -> None:
    result, scene, table = strip(args.out / "clean", args.scenes, args.gcps)
    checks = np.nonzero(table.role == "check")[0]
    on_chip = scene.cameras[0].chip_index(table.col) == 2
    moved = on_chip & (np.random.default_rng(5).random(len(table)) < 0.5)
    print(f"\nbreakdown: {int(moved.sum())} of {int(on_chip.sum())} HRC-3 measurements (control and check) shifted "
          "the same way")
    print(f"{'shift px':>8} {'flagged shifted %':>17} {'flagged others %':>16} {'check RMSE m':>12} "
          f"{'true model error px':>19}  verdict")
    for shift in (0.0, 4.0, 10.0, 20.0):
        bad = replace(table, col=table.col + shift * moved, row=table.row + shift * moved)
        out = adjust(scene, bad, chosen())
        flagged, rep = out.points["flagged"], out.report
        print(f"{shift:8.0f} {100 * flagged[moved].mean():17.1f} {100 * flagged[~moved].mean():16.1f} "
              f"{rep['check_points']['without_blunders']['ground']['rmse']:12.2f} "
              f"{model_error(out.scene, result, checks):19.2f}  {verdict(rep)}")
    for share in (0.4, 0.5):
        result, _, table = strip(args.out / f"gross{share}", args.scenes, args.gcps, gross_fraction=share)
        is_gross = gross_flags(result)
        out = adjust(scene, table, chosen())
        flagged = out.points["flagged"]
        print(f"{100 * share:.0f} % random gross errors: {100 * flagged[is_gross].mean():.1f} % flagged, good flagged "
              f"{100 * flagged[~is_gross].mean():.2f} %, check RMSE "
              f"{out.report['check_points']['without_blunders']['ground']['rmse']:.2f} m; {verdict(out.report)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=1)
    parser.add_argument("--gcps", type=int, default=4000)
    parser.add_argument("--out", type=Path, default=None, help="folder for the simulations (default: temporary)")
    args = parser.parse_args()
    logging.getLogger("pushbroom_adjust.core").setLevel(logging.ERROR)  # the verdict column says what the warnings say
    with tempfile.TemporaryDirectory() as tmp:
        args.out = args.out or Path(tmp)
        args.out.mkdir(parents=True, exist_ok=True)
        wrong_sigmas(args)
        breakdown(args)


if __name__ == "__main__":
    main()
