"""Screenshots of the digitising docks (and of Processing dialogs) in the real QGIS desktop, for
docs/digitising.md. From the repository's root:

    PROJ_DATA=/usr/share/proj /usr/bin/python3 scripts/screenshots.py [--out docs/images]
        [--dialogs pushbroom:bundleadjust ...] [--work DIR]

It simulates (seeded: the same pictures on every run) a tri-stereo block of TH-1 nadir scenes
(800 x 800 px, rendered, with a reference orthoimage and a DEM) and a TH-1 scene with four roads,
then starts QGIS with a fresh profile under a virtual display (tests/support/desktop.py; xvfb-run,
which scripts/setup.sh installs) and runs scripts/screenshots_driver.py in it. The driver measures
five GCPs in the three scenes of the block by clicks at their true pixels (the ground picked on the
main map, heights from the DEM), adjusts the block to them with pushbroom:bundleadjust, opens the
adjusted GCPs back (the table shows their residuals), digitises two roads in the line dock, pairs and
snaps them, and saves into --out:

    gcp-dock.png       QGIS's main window with the GCP dock
    lines-dock.png     QGIS's main window with the line dock
    <id>-dialog.png    the Processing dialog of each algorithm of --dialogs (e.g. bundleadjust-dialog.png)
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import tests.support.plugin_package  # noqa: F401 (the repository as the package pushbroom_adjust)
from pushbroom_adjust.simulation.block import simulate_block
from pushbroom_adjust.simulation.layouts import one_camera, tri_stereo
from pushbroom_adjust.simulation.presets import PRESETS, cut_preset
from pushbroom_adjust.simulation.simulator import simulate
from tests.support.desktop import run_desktop
from tests.support.paths import REPO

SIZE = 800   # px: the simulated images' side
SEED = 5


def simulated(work: Path) -> dict:
    """The block and the road scene the driver shows: the paths it needs."""
    th1 = cut_preset(one_camera(PRESETS["th1_tlc"]), SIZE, SIZE)
    block = simulate_block(tri_stereo(th1), work / "block", seed=SEED, n_gcps=16,
                           n_tie_points=0, image_noise=0.0, render=True)
    roads = simulate(th1, work / "roads", seed=SEED, n_gcps=10, n_lines=4, render=True)
    return {"block": {"names": list(block.members), "scenes": [str(m["onboard_scene"]) for m in block.members.values()],
                      "gcps": str(block.gcps), "dem": str(block.dem), "reference": str(block.reference)},
            "roads": {"scene": str(roads.onboard_scene), "lines": str(roads.lines), "dem": str(roads.dem),
                      "points": str(roads.folder / "line_points.csv"), "reference": str(roads.reference)}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(REPO / "docs" / "images"), help="folder of the PNG files")
    parser.add_argument("--dialogs", nargs="*", default=[], help="algorithm ids whose dialogs to photograph")
    parser.add_argument("--work", help="folder for the simulated data and QGIS's profile (default: a temporary one)")
    args = parser.parse_args()
    work = Path(args.work or tempfile.mkdtemp(prefix="pushbroom-screens-"))
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    seen, stderr = run_desktop(REPO / "scripts" / "screenshots_driver.py",
                               {**simulated(work), "work": str(work), "out": str(out), "dialogs": args.dialogs},
                               work / "desktop")
    for line in seen.get("messages", []):
        print(line)
    for error in seen.get("exceptions", []):
        print(error, file=sys.stderr)
    if stderr.strip():
        print(f"QGIS's stderr:\n{stderr}", file=sys.stderr)
    print("\n".join(seen.get("saved", [])))
    sys.exit(1 if seen.get("exceptions") else 0)


if __name__ == "__main__":
    main()
