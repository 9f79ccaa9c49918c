"""A rendered block of two scenes for measuring GCPs (tests/unit/measure/test_gcpmeasure.py and the GCP
dock's tests): TH-1 nadir camera cut to 500 x 500 px of 5 m, one scene looking straight down
(``nad``) and one pitched 18 degrees forward (``fwd``), their onboard models 7.5 px RMS off the
truth; GCPs with their true image positions (gcps.csv), display copies of both images (naming
their onboard scenes), the DEM (EGM96 heights) and the reference orthoimage.

The fixture ``gcp_block`` is imported by the test modules that use it."""
import csv
from dataclasses import replace

import numpy as np
import pytest

from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.measure.display import write_display_vrt
from pushbroom_adjust.simulation.block import BlockMember, simulate_block
from pushbroom_adjust.simulation.presets import PRESETS, cut_preset

NAMES = ("nad", "fwd")
MARGIN_PX = 30.0   # GCPs used are this far inside both images: a snapping template fits around them


@pytest.fixture(scope="module")
def gcp_block(tmp_path_factory) -> dict:
    """The block (about 1.5 s): result (simulation.block.BlockResult), true and onboard scenes
    by name, display copies by name, rows of gcps.csv by id and scene, and the ids of the GCPs
    seen MARGIN_PX inside both images."""
    tlc = cut_preset(PRESETS["th1_tlc"], 500, 500)
    one = replace(tlc, name="th1_nad_500", cameras=tlc.cameras[:1])
    folder = tmp_path_factory.mktemp("gcpblock")
    result = simulate_block([BlockMember("nad", one), BlockMember("fwd", one, view=(18.0, 0.0))], folder / "sim",
                            seed=5, n_gcps=12, n_tie_points=0, image_noise=0.0, render=True)
    displays = {}
    for name, files in result.members.items():
        displays[name] = str(folder / f"{name}.vrt")
        write_display_vrt(files["images"]["NAD"], displays[name], str(files["onboard_scene"]), "NAD")
    with open(result.gcps, newline="") as f:
        rows = {(r["id"], r["scene"]): r for r in csv.DictReader(f)}
    inside = [i for i in sorted({i for i, _ in rows}, key=lambda s: int(s[1:]))
              if all((i, n) in rows and all(MARGIN_PX < float(rows[i, n][k]) < 500 - MARGIN_PX
                                            for k in ("col_true", "row_true")) for n in NAMES)]
    return {"result": result, "displays": displays, "rows": rows, "inside": inside,
            "true": {n: load_scene(f["true_scene"]) for n, f in result.members.items()},
            "onboard": {n: load_scene(f["onboard_scene"]) for n, f in result.members.items()}}


def true_pixel(block, point_id: str, scene: str) -> np.ndarray:
    """(col, row) px of a GCP's true image in ``scene``."""
    row = block["rows"][point_id, scene]
    return np.array([float(row["col_true"]), float(row["row_true"])])


def true_ground(block, point_id: str) -> tuple[float, float, float]:
    """(lon, lat deg, h ellipsoidal m) of a GCP's true ground."""
    row = next(r for (i, _), r in block["rows"].items() if i == point_id)
    return float(row["lon_true"]), float(row["lat_true"]), float(row["h_true"])
