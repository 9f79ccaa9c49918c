"""Each real vendor product of tests/data against its own RPC, and what the check costs on load,
printed (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_vendorcheck.py [--repeat 5]

For every rigorous product (and the GeoEye-1-like and DIMAP 2.15 products the tests derive from them,
tests/support/vendor_variants.py): the check's figures (core.formats.vendorcheck: RMS and max px over
11 x 11 image points x 3 heights), the median wall time of load_scene (check included) and of the check
alone (check_vendor_rpc on the loaded scene, its trajectory table already built by the load), over
``--repeat`` runs.
"""
from __future__ import annotations

import argparse
import logging
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.formats import load_scene, read_xml_scene  # noqa: E402
from pushbroom_adjust.core.formats.vendorcheck import check_vendor_rpc  # noqa: E402
from tests.support.paths import TEST_DATA  # noqa: E402
from tests.support.vendor_variants import edited, geoeye_like, reverse_scan, write_dimap215  # noqa: E402

WV1 = "worldview1/WV01_20210201005130_10200100A1865800_21FEB01005130-P1BS-016263048010_01_P001.xml"
PRODUCTS = [WV1, "worldview2/wv_mvp_1.xml", "worldview2/wv_mvp_2.xml", "worldview3/1040010074793300.xml",
            "pleiades/PHRDIMAP_P1BP--2018122638935449CP.XML"]


def derived(folder: Path) -> dict[str, Path]:
    """The products the tests derive: GeoEye-1-like (radians), reversed too, and DIMAP 2.15."""
    def both(root):
        geoeye_like(root)
        reverse_scan(root)
    out = {}
    for name, edit in (("GeoEye-1-like, radians", geoeye_like), ("GeoEye-1-like, reverse scan", both)):
        path = folder / f"{name.split(', ')[1].replace(' ', '_')}.xml"
        path.write_text(edited(TEST_DATA / WV1, edit))
        out[name] = path
    out["Pleiades DIMAP 2.15"] = write_dimap215(TEST_DATA / PRODUCTS[-1], folder)[0]
    return out


def median_seconds(run, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        run()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    logging.disable(logging.WARNING)  # the WorldView-3 product's warning at every load
    with tempfile.TemporaryDirectory() as tmp:
        products = {Path(p).name: TEST_DATA / p for p in PRODUCTS} | derived(Path(tmp))
        print(f"{'product':<46} {'RMS px':>8} {'max px':>8} {'load s':>8} {'check s':>8}")
        for name, path in products.items():
            scene = load_scene(path)
            _, vendor = read_xml_scene(path)
            check = scene.info["rpc_check"]
            load = median_seconds(lambda: load_scene(path), args.repeat)
            alone = median_seconds(lambda: check_vendor_rpc(scene, vendor, str(path)), args.repeat)
            print(f"{name[:46]:<46} {check['rms_px']:8.4f} {check['max_px']:8.4f} {load:8.3f} {alone:8.4f}")


if __name__ == "__main__":
    main()
