"""The block adjustment pushbroom:bundleadjust runs with SCENES (core.adjust.block.adjust_block on
the GCPs importgcps checks per scene and the simulator's tie points), on a simulated TH-1 tri-stereo
(pushbroom:simulateblock, LAYOUT tristereo) as tests/qgis/test_bundleadjust_block.py makes it.
--layout tristereo_and_other_date adds a scene of another date delivered as an RPC product.
Prints figures (no assertions): the wall time of the adjustment and of writing the outputs, and per
scene the check RMSE (px) against the true scene of a 9 x 9 lattice over its image, through the
onboard and through the adjusted scene.

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_block_bundleadjust.py
      [--size 600] [--gcps 24] [--ties 60] [--seed 3] [--layout tristereo]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.adjust import AdjustmentSettings  # noqa: E402
from pushbroom_adjust.core.adjust.block import adjust_block  # noqa: E402
from pushbroom_adjust.core.dem import Dem  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.core.formats.scene_json import save_scene  # noqa: E402
from pushbroom_adjust.core.files import atomic_outputs  # noqa: E402
from pushbroom_adjust.core.observations import gcps, tiepoints  # noqa: E402
from pushbroom_adjust.core.observations.blockscenes import check_against_block, rpc_product_cameras  # noqa: E402
from pushbroom_adjust.core.observations.tables import Heights  # noqa: E402
from pushbroom_adjust.simulation.block import simulate_block  # noqa: E402
from pushbroom_adjust.simulation.layouts import layout_members  # noqa: E402
from pushbroom_adjust.simulation.presets import PRESETS, cut_preset  # noqa: E402

# as the test's ADJUST: POSITION_ORDER 1, ATTITUDE_ORDER 1, POSITION_SIGMA 20 m, ATTITUDE_SIGMA 60 arcsec
SETTINGS = AdjustmentSettings(position_order=1, attitude_order=1, position_sigma=20.0,
                              attitude_sigma=60.0 / 206264.806)


def check_px(true, scene, dem) -> float:
    """RMS (px) of a 9 x 9 lattice over the first camera's image: its true ground through ``scene``."""
    cam = true.cameras[0]
    col, row = (a.ravel() for a in np.meshgrid(np.linspace(10, cam.cols - 10, 9), np.linspace(10, cam.rows - 10, 9)))
    col2, row2 = scene.ground_to_image(true.image_to_ground_dem(col, row, dem, 0), 0)
    return float(np.sqrt(np.mean((col2 - col) ** 2 + (row2 - row) ** 2)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=600)
    parser.add_argument("--gcps", type=int, default=24)
    parser.add_argument("--ties", type=int, default=60)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--layout", default="tristereo")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="bench_block_"))
    t = time.perf_counter()
    sim = simulate_block(layout_members(args.layout, cut_preset(PRESETS["th1_tlc"], args.size, args.size)),
                         folder / "sim", seed=args.seed, n_gcps=args.gcps, n_tie_points=args.ties,
                         check_fraction=0.25)
    print(f"simulated {len(sim.members)} scenes of {args.size} x {args.size} px in {time.perf_counter() - t:.2f} s")
    # each scene's product: its onboard scene JSON, or the RPC file of an RPC member (LAYOUT tristereo_and_other_date)
    paths = {name: str(next(iter(files["rpc"].values()), files["onboard_scene"])) for name, files in sim.members.items()}
    onboard = {name: load_scene(path) for name, path in paths.items()}
    table = gcps.read_csv(sim.gcps, gcps.CsvMapping(z="h", sigma_px="sigma_px", sigma_xy="sigma_xy",
                                                    sigma_z="sigma_z"), "EPSG:4326", Heights("z", "ellipsoid"))
    table = check_against_block(table, onboard, paths)
    raw = tiepoints.read_csv(sim.tie_points)
    ties = rpc_product_cameras(raw, raw.scene, onboard)[0]  # as bundleadjust reads them
    print(f"{len(table)} GCP observations ({int((table.role == 'control').sum())} control), {len(ties)} tie "
          f"observations of {np.unique(ties.id).size} points")
    t = time.perf_counter()
    result = adjust_block(onboard, table, ties, SETTINGS)
    adjust_s = time.perf_counter() - t
    t = time.perf_counter()
    with atomic_outputs() as files:
        for name, scene in result.scenes.items():
            save_scene(scene, folder / f"{name}_adjusted.json", files)
    print(f"adjustment {adjust_s:.2f} s, writing the scenes {time.perf_counter() - t:.2f} s")
    dem = Dem(sim.dem, "geoid")
    for name, files in sim.members.items():
        true = load_scene(files["true_scene"])
        print(f"scene {name}: check RMSE {check_px(true, onboard[name], dem):.2f} px onboard, "
              f"{check_px(true, result.scenes[name], dem):.3f} px adjusted")
    block = result.report["block"]
    print(f"block: sigma0 {block['sigma0']:.3f}, tie RMS {block['tie_rmse_before_px']:.2f} px before, "
          f"{block['tie_rmse_px']:.3f} px after; {result.report['datum']}")


if __name__ == "__main__":
    main()
