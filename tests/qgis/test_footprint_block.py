"""pushbroom:footprint of a block or region (SCENES, issue 31): the simulated three strips of four
TH-1 nadir-camera products (800 x 800 px of 5 m, strips 3 km apart) given as their folder: one
polygon per product, named as the tie points name it, with the products it overlaps; a block that
does not hold together is drawn and warned of, naming its products; a folder without products is
refused naming it."""
import numpy as np
import pytest
from qgis.core import QgsProcessingException

import processing
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.products.footprint import footprints
from pushbroom_adjust.simulation.block import simulate_block
from tests.support.processing import RecordingFeedback
from tests.unit.measure.test_pairmatching import MEMBERS

OVERLAPS = {"s1": "s2,s2fwd", "s2": "s1,s2fwd,s3", "s2fwd": "s1,s2,s3", "s3": "s2,s2fwd"}


@pytest.fixture(scope="module")
def region(provider, tmp_path_factory):
    folder = tmp_path_factory.mktemp("region")
    result = simulate_block(MEMBERS, folder, seed=4, n_gcps=10, n_tie_points=20)
    return {"folder": folder, "dem": str(result.dem),
            "scenes": {n: str(f["onboard_scene"]) for n, f in result.members.items()}}


def outline(region, scenes, feedback=None):
    return processing.run("pushbroom:footprint", {"SCENES": scenes, "DEM": region["dem"], "DEM_DATUM": "geoid",
                                                  "SAMPLES": 32, "OUTPUT": "memory:"}, feedback=feedback)["OUTPUT"]


def test_every_product_of_a_folder_outlined_and_named(region):
    log = RecordingFeedback()
    layer = outline(region, [str(region["folder"])], log)
    features = {f["scene"]: f for f in layer.getFeatures()}
    assert layer.crs().authid() == "EPSG:4326" and list(features) == ["s1", "s2", "s2fwd", "s3"]
    assert {n: f["overlapping"] for n, f in features.items()} == OVERLAPS
    assert [f["overlaps"] for f in features.values()] == [2, 3, 3, 2]
    dem = Dem(region["dem"], "geoid")
    for name, f in features.items():
        assert f["file"] == region["scenes"][name] and f["cameras"] == "NAD"
        (truth,) = footprints(load_scene(region["scenes"][name]), dem, samples_per_edge=32)
        assert f["area_km2"] == pytest.approx(truth.area_km2, rel=1e-3) and 14 < f["area_km2"] < 22  # about 4 x 4 km
        ring = np.array([(p.x(), p.y()) for p in f.geometry().asPolygon()[0]])
        assert np.abs(ring.min(axis=0) - [truth.lon.min(), truth.lat.min()]).max() < 1e-9
    assert any(line.startswith(f"SCENES folder {region['folder']}: 4 product(s); ") for line in log.lines)
    assert "4 products, 5 overlapping pairs" in log.lines


def test_a_block_that_does_not_hold_together_is_drawn_and_warned_of(region, tmp_path):
    listed = tmp_path / "apart.txt"
    listed.write_text(f"{region['scenes']['s1']}\n{region['scenes']['s3']}\n")
    log = RecordingFeedback()
    layer = outline(region, [str(listed)], log)
    assert [f["scene"] for f in layer.getFeatures()] == ["s1", "s3"] and {f["overlaps"] for f in layer.getFeatures()} \
        == {0}
    assert any("SCENES: the block is not connected by overlaps: s1, s3 overlap no other product (other ground?)"
               in w for w in log.warnings)


def test_a_folder_without_products_is_refused_naming_it(region, tmp_path):
    with pytest.raises(QgsProcessingException, match=rf"^SCENES: {tmp_path}: no product found in the folder or its "
                                                     r"subfolders \(looked for scene JSON"):
        outline(region, [str(tmp_path)])
