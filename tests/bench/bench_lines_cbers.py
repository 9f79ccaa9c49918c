"""Control points and control lines on simulated CBERS-02B HRC: the comparison of
Tommaselli & Marcato Junior 2012 (seed 002, Tab. 2-4: 55 GCPs; 12 GCPs; 12 GCPs + 73 lines;
73 lines alone), lines of one direction only, and 10 % wrong lines. Prints figures.

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_lines_cbers.py [--seed 2]

The setting follows seed 002: one CBERS-02B HRC scene (12246 x 12246 px, 2.36 m GSD) with the
preset's onboard trajectory errors (~400 m), the three CCDs aligned (seed 002 adjusts exterior
parameters only), a polynomial trajectory (position order 1, attitude order 2: 15 parameters)
and NO onboard pseudo-observations (seed 002's CBERS-2B lacked star-sensor data and the EOP
are estimated from ground control alone). GCPs: 0.5 px image, 0.5 m / 1 m ground noise; 100
check points. Roads: 73 straight and curved roads of 2-6 km (map noise 1 m across, 2 m in
height), 12 image points per road measured with 0.5 px noise.

Experiments (check-point horizontal RMSE, m, single-ray back-projection at the known height):
  A  55 GCPs                       F  12 GCPs
  G  12 GCPs + 73 lines            B  73 lines alone
  one direction: the straight roads within DIRECTION_WINDOW deg of the best-populated azimuth,
     alone (with 100 m onboard position sigmas, the only thing holding the along-line shift)
     and with 12 GCPs: the report names the undetermined direction
  wrong: 10 % of the lines wrong, (a) shifted 20-200 m or turned off by 20-200 m in the map
     (the simulator's wrong roads), (b) paired to the wrong road (image-line ids swapped):
     share named, false alarms, check RMSE against the run without them
"""
from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from pathlib import Path

import numpy as np
from osgeo import ogr

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.observations import gcps as G  # noqa: E402
from pushbroom_adjust.core.observations.tables import Heights  # noqa: E402
from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust  # noqa: E402
from pushbroom_adjust.core.adjust.linepoints import ControlLines  # noqa: E402
from pushbroom_adjust.core.observations.lines import ImageLines, read_ground_lines, read_image_lines  # noqa: E402
from pushbroom_adjust.simulation.roads import RoadSettings  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.simulation.measurements import GcpSettings  # noqa: E402
from pushbroom_adjust.simulation.simulator import simulate  # noqa: E402

GSD = 2.36
DIRECTION_WINDOW = 4.0   # deg
GCP_SETTINGS = GcpSettings(n_gcps=200, check_fraction=0.5, image_noise=0.5, ground_noise_xy=0.5, ground_noise_z=1.0)
ERRORS = dict(ccd_shift=0.0, ccd_rotation=0.0)


def settings(**kw) -> AdjustmentSettings:
    base = dict(position_model="polynomial", position_order=1, attitude_model="polynomial", attitude_order=2,
                position_sigma=None, attitude_sigma=None)
    return AdjustmentSettings(**{**base, **kw})


def dataset(folder: Path, seed: int, wrong: float = 0.0):
    """(onboard scene, GCP table, ControlLines, {line id: kind}) of a simulated scene."""
    result = simulate("cbers02b_hrc", folder, seed=seed, gcp_settings=GCP_SETTINGS, errors=ERRORS,
                      road_settings=RoadSettings(n_lines=73, wrong_fraction=wrong))
    table = G.read_csv(result.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                       Heights("z", datum="ellipsoid"), sigma_px=0.5, sigma_xy=0.5, sigma_z=1.0)
    lines = ControlLines(read_ground_lines(result.lines), read_image_lines(result.lines))
    ds = ogr.Open(str(result.lines))
    kinds = {f.GetField("line_id"): f.GetField("kind") or "correct" for f in ds.GetLayer("ground_lines")}
    return load_scene(result.onboard_scene), table, lines, kinds


def with_control(table: G.GcpTable, n: int) -> G.GcpTable:
    """The first n control points and all check points."""
    control = np.nonzero(table.role == "control")[0]
    return table.select(np.sort(np.r_[control[:n], np.nonzero(table.role == "check")[0]]))


def image_subset(image: ImageLines, keep_ids) -> ImageLines:
    keep = np.isin(image.line_id, list(keep_ids))
    vertex = keep[image.vertex_part()]
    return ImageLines(image.line_id[keep], image.camera[keep], np.r_[0, np.cumsum(np.diff(image.start)[keep])],
                      image.col[vertex], image.row[vertex], image.sigma_px[vertex])


def run(label: str, scene, table, lines=None, **kw) -> dict:
    r = adjust(scene, table, settings(**kw), lines=lines)
    cp = r.report["check_points"]["ground"]
    rep = r.report.get("lines")
    extra = ""
    if rep:
        extra = f"  lines {rep['lines']}, points {rep['points']}, across RMSE {rep['across_rmse_m']:.2f} m, " \
                f"flagged lines {rep['flagged_lines']}"
    print(f"{label:38s} check RMSE {cp['rmse']:6.2f} m = {cp['rmse'] / GSD:5.2f} GSD (E {cp['rmse_east']:.2f}, "
          f"N {cp['rmse_north']:.2f} m)  dof {r.report['observations']['degrees_of_freedom']:.0f}{extra}")
    return r.report


def azimuth_of_lines(lines: ControlLines) -> dict:
    """Straight line id -> azimuth in [0, 180) deg (lines whose first and last segments differ
    by less than 1 deg)."""
    g = lines.ground

    def azimuth(a, b):
        de = (g.lon[b] - g.lon[a]) * np.cos(np.radians(g.lat[a]))
        return float(np.degrees(np.arctan2(de, g.lat[b] - g.lat[a])) % 180.0)

    out = {}
    for i in range(len(g)):
        a, b = g.start[i], g.start[i + 1] - 1
        bend = abs((azimuth(a, a + 1) - azimuth(b - 1, b) + 90.0) % 180.0 - 90.0)
        if bend < 1.0:
            out[str(g.id[i])] = azimuth(a, b)
    return out


def one_direction(scene, table, lines: ControlLines) -> None:
    az = azimuth_of_lines(lines)
    ids = np.array(list(az))
    values = np.array([az[i] for i in ids])
    centres = np.arange(0.0, 180.0, 1.0)
    dist = np.abs((values[None, :] - centres[:, None] + 90.0) % 180.0 - 90.0)
    best = centres[np.argmax((dist <= DIRECTION_WINDOW).sum(axis=1))]
    chosen = ids[np.abs((values - best + 90.0) % 180.0 - 90.0) <= DIRECTION_WINDOW]
    sub = ControlLines(lines.ground, image_subset(lines.image, chosen))
    print(f"\none direction: {chosen.size} lines within {DIRECTION_WINDOW:g} deg of azimuth {best:.0f} deg")
    for label, n, kw in (("  lines alone (onboard position 100 m)", 0, dict(position_sigma=100.0)),
                         ("  12 GCPs + these lines", 12, {})):
        rep = run(label, scene, with_control(table, n), sub, **kw)
        print(f"    directions: {rep['lines']['directions']['message']}")


def named(report: dict, wrong_ids: set) -> tuple[int, int]:
    flagged = set(report["lines"]["flagged_line_ids"])
    return len(flagged & wrong_ids), len(flagged - wrong_ids)


def wrong_lines(folder: Path, seed: int, clean_data: tuple) -> None:
    scene, table, lines, kinds = dataset(folder / "wrong", seed, wrong=0.1)
    t12 = with_control(table, 12)
    wrong = {k for k, v in kinds.items() if v != "correct"}
    shown = set(np.unique(lines.image.line_id))
    wrong &= shown
    print(f"\n(a) map lines wrong: {len(wrong)} of {len(shown)} lines "
          f"({', '.join(sorted(f'{k} {kinds[k]}' for k in wrong))})")
    clean = run("  12 GCPs + the correct lines only", scene, t12,
                ControlLines(lines.ground, image_subset(lines.image, shown - wrong)))
    rep = run("  12 GCPs + all lines", scene, t12, lines)
    hit, false = named(rep, wrong)
    ratio = rep["check_points"]["ground"]["rmse"] / clean["check_points"]["ground"]["rmse"]
    print(f"  named {hit} of {len(wrong)} wrong lines ({100 * hit / max(len(wrong), 1):.0f} %), {false} correct lines "
          f"named; check RMSE {100 * (ratio - 1):+.1f} % against the clean run")
    # (b) the correct lines of the clean data set, 10 % paired to the wrong road
    scene, table, lines, _ = clean_data
    t12 = with_control(table, 12)
    ids = np.unique(lines.image.line_id)
    rng = np.random.default_rng(seed)
    swapped = rng.choice(ids, int(round(0.1 * ids.size)), replace=False)
    relabel = dict(zip(swapped, np.roll(swapped, 1)))       # each takes the next one's id: a wrong road
    image = lines.image
    new_ids = np.array([relabel.get(i, i) for i in image.line_id])
    wrong_image = ImageLines(new_ids, image.camera, image.start, image.col, image.row, image.sigma_px)
    print(f"\n(b) paired to the wrong road: {swapped.size} of {ids.size} image lines ({', '.join(sorted(swapped))})")
    clean = run("  12 GCPs + the correctly paired lines", scene, t12,
                ControlLines(lines.ground, image_subset(image, set(ids) - set(swapped))))
    rep = run("  12 GCPs + all lines", scene, t12, ControlLines(lines.ground, wrong_image))
    hit, false = named(rep, set(relabel.values()))
    ratio = rep["check_points"]["ground"]["rmse"] / clean["check_points"]["ground"]["rmse"]
    print(f"  named {hit} of {swapped.size} wrongly paired lines ({100 * hit / swapped.size:.0f} %), {false} correct "
          f"lines named; check RMSE {100 * (ratio - 1):+.1f} % against the clean run")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seed", type=int, default=2)
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        clean = dataset(folder / "clean", args.seed)
        scene, table, lines, _ = clean
        print("seed 002's experiments on simulated CBERS-02B HRC (GSD 2.36 m):")
        a = run("A  55 GCPs", scene, with_control(table, 55))
        f = run("F  12 GCPs", scene, with_control(table, 12))
        g = run("G  12 GCPs + 73 lines", scene, with_control(table, 12), lines)
        run("B  73 lines alone", scene, with_control(table, 0), lines)
        rmse = {k: v["check_points"]["ground"]["rmse"] for k, v in (("A", a), ("F", f), ("G", g))}
        print(f"G / A = {rmse['G'] / rmse['A']:.2f} (done when <= 1.10); F / G = {rmse['F'] / rmse['G']:.1f}")
        one_direction(scene, table, lines)
        wrong_lines(folder, args.seed, clean)


if __name__ == "__main__":
    main()
