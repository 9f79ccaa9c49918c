"""Which RPC_CORRECTION a block of RPC products tied without control points should default to
(issue 28): shift, drift or affine, measured on the real Pleiades pair over Giza and on simulated RPC
blocks with known truth. Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_rpc_datum.py
      [--seeds 0 1 2] [--size 1000] [--out DIR]

Per block and correction: the tie RMS after the ties-only adjustment (px), and how the tie points'
heights moved, triangulated (:func:`core.model.intersection.intersect`) through the input RPCs and
through the adjusted ones: the median height change and the tilt (the height change's plane fitted
over the ties: its height difference across their extent, m); on the simulated blocks also their
heights against the truth, before and after (median error, tilt of the error). Then the datum
directions the adjustment names (:mod:`core.adjust.datumdirections`): how each is held, the priors'
sigma and how far the ties moved along it.

Real: tests/data/pleiades_gizeh, ties matched as tests/scenarios/test_real_crops.py does (40 px grid, 31 px
window, 60 m search) on flat surfaces at 100, 140 and 240 m; RPC_SIGMA 10 px.

Simulated (:func:`simulation.block.simulate_block`, not rendered): the TH-1 nadir camera cut to
--size px, as a tri-stereo (nadir, +-18 deg) and a stereo pair (+-15 deg) of one pass, each member an
RPC product (RPC00B fitted to its onboard scene over the DEM's heights) with the preset's trajectory
errors alone ('trajectory') or with its lens errors as well ('lens': principal point, focal length,
distortion, a few px at the array end, which no image-space correction models); 300 tie points
measured through the true scenes with 0.3 px noise; RPC_SIGMA 30 px (the onboard errors reach about
20 px).
"""
from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.support import plugin_package  # noqa: F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.adjust import AdjustmentSettings
from pushbroom_adjust.core.adjust.block import adjust_block
from pushbroom_adjust.core.dem import ConstantHeight
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.measure.matching import MatchSettings
from pushbroom_adjust.core.measure.tiematching import View, match_block_tiepoints
from pushbroom_adjust.core.observations import tiepoints
from pushbroom_adjust.simulation.block import simulate_block
from pushbroom_adjust.simulation.blockmembers import BlockMember
from pushbroom_adjust.simulation.layouts import STEREO_PITCH, TRI_STEREO_PITCH
from pushbroom_adjust.simulation.presets import PRESETS, ErrorSettings, cut_preset
from tests.support.paths import TEST_DATA
from tests.support.tie_heights import height_change, tie_heights

CORRECTIONS = ("shift", "drift", "affine")
GIZA = ("img1", "img2")


def directions_text(report: dict) -> str:
    return "; ".join(f"{d['direction']} ({d['held_by']}: prior {d['prior_sigma_m']:.1f} m, moved {d['moved_m']:+.1f} m)"
                     for d in report["datum_directions"]) or "-"


def run(label: str, vendor: dict, ties, rpc_sigma: float, truth: np.ndarray | None = None) -> None:
    """Adjust ``vendor`` (name -> RPC scene) with ``ties`` alone in each correction and print the
    figures; ``truth`` (m, 3 lon, lat, h) of the tie points in id order, when known."""
    ids, before = tie_heights(vendor, ties)
    if truth is not None:
        error = height_change(truth, before[:, 2] - truth[:, 2])
        print(f"{label}: before, heights - truth: median {error['median_m']:+.2f} m, tilt {error['tilt_m']:.2f} m "
              f"over {ids.size} tie points")
    for correction in CORRECTIONS:
        out = adjust_block(vendor, None, ties, AdjustmentSettings(rpc_correction=correction, rpc_sigma=rpc_sigma))
        _, after = tie_heights(out.scenes, ties)
        moved = height_change(before, after[:, 2] - before[:, 2])
        rep = out.report
        line = (f"{label} {correction:6s}: tie RMS {rep['block']['tie_rmse_px']:.3f} px, robust passes "
                f"{len(rep['adjustment']['robust']['passes'])}; heights moved median {moved['median_m']:+.2f} m, "
                f"tilt {moved['tilt_m']:.2f} m")
        if truth is not None:
            error = height_change(truth, after[:, 2] - truth[:, 2])
            line += f"; heights - truth: median {error['median_m']:+.2f} m, tilt {error['tilt_m']:.2f} m"
        print(line)
        print(f"    directions: {directions_text(rep)}")


def giza() -> None:
    folder = TEST_DATA / "pleiades_gizeh"
    scenes = {n: load_scene(folder / f"{n}.tif") for n in GIZA}
    for height in (100.0, 140.0, 240.0):
        ties, _ = match_block_tiepoints([View(n, scenes[n], 0, folder / f"{n}.tif") for n in GIZA],
                                        ConstantHeight(height), MatchSettings(spacing=40, window=31, search=60.0))
        run(f"Giza pair, ties at {height:g} m", scenes, ties, 10.0)


def simulated(seeds: list[int], size: int, out: Path) -> None:
    spec = cut_preset(PRESETS["th1_tlc"], size, size)
    spec = replace(spec, name="th1_nad", cameras=spec.cameras[:1])
    trajectory = ErrorSettings(**{k: getattr(spec.errors, k) for k in ("position_bias", "position_drift",
                                                                        "attitude_bias", "attitude_drift")})
    layouts = {"tri-stereo": [("nad", 0.0), ("fwd", TRI_STEREO_PITCH), ("bwd", -TRI_STEREO_PITCH)],
               "stereo pair": [("fwd", STEREO_PITCH), ("bwd", -STEREO_PITCH)]}
    for layout, views in layouts.items():
        for errors, setting in (("trajectory", trajectory), ("lens", spec.errors)):
            for seed in seeds:
                folder = out / f"{layout.replace(' ', '_')}_{errors}_{seed}"
                if not (folder / "block.json").exists():
                    simulate_block([BlockMember(name, spec, view=(pitch, 0.0), errors=setting, rpc=True)
                                    for name, pitch in views], folder, seed=seed, n_gcps=10, n_tie_points=300)
                vendor = {name: load_scene(folder / name / f"{name}_RPC.TXT") for name, _ in views}
                ties = tiepoints.read_csv(folder / "tie_points.csv")
                ties = replace(ties, camera=np.full(len(ties), ""))  # an RPC product's one camera is named after it
                truth_rows = np.genfromtxt(folder / "tie_points.csv", delimiter=",", names=True, dtype=None,
                                           encoding="utf-8")
                ids, first = np.unique(truth_rows["id"], return_index=True)
                truth = np.stack([truth_rows[k][first] for k in ("lon_true", "lat_true", "h_true")], axis=1)
                run(f"{layout}, {errors} errors, seed {seed}", vendor, ties, 30.0, truth)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--size", type=int, default=1000)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    logging.disable(logging.WARNING)
    giza()
    with tempfile.TemporaryDirectory() as tmp:
        simulated(args.seeds, args.size, args.out or Path(tmp))


if __name__ == "__main__":
    main()
