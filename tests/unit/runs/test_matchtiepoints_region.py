"""core.runs.matchtiepoints on a region (issue 31): a rendered block of three neighbouring strips (four
TH-1 nadir-camera products, 800 x 800 px of 5 m; s1 and s3 share no ground, so the star of the first
image refused it) given as a folder or a list file, its images found beside its scenes, every
overlapping pair matched on this machine's threads, in this process one after the other, or on a
local Dask cluster (the same ties to the bit), the figures per pair; and the region's refusals: a
folder with no product, a list line naming no file, a product of other ground, a disconnected
block, a product the ties leave apart."""
import os
from dataclasses import replace

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.observations import tiepoints
from pushbroom_adjust.core.runs import matchtiepoints as use_case
from pushbroom_adjust.core.runs.base import Terrain
from pushbroom_adjust.simulation.block import simulate_block
from pushbroom_adjust.simulation.simulator import simulate
from tests.unit.measure.test_pairmatching import MEMBERS
from tests.unit.measure.test_tiematching import ONE

MATCHING = {"spacing": 30.0, "search": 400.0}
PAIRS = ["s1/NAD-s2/NAD", "s1/NAD-s2fwd/NAD", "s2/NAD-s2fwd/NAD", "s2/NAD-s3/NAD", "s2fwd/NAD-s3/NAD"]


@pytest.fixture(scope="module")
def region(tmp_path_factory):
    folder = tmp_path_factory.mktemp("region")
    result = simulate_block(MEMBERS, folder, seed=4, n_gcps=10, n_tie_points=20, render=True)
    return {"folder": folder, "dem": str(result.dem),
            "scenes": [str(f["onboard_scene"]) for f in result.members.values()]}


def run(region, output, scenes, **kw):
    terrain = kw.pop("terrain", Terrain(region["dem"], "geoid"))
    return use_case.run(use_case.MatchTiesRequest(str(output), kw.pop("images", ()), scenes=tuple(scenes),
                                                  terrain=terrain, matching=MATCHING, **kw))


@pytest.fixture(scope="module")
def matched(region, tmp_path_factory):
    """The region given as its folder, the images found beside the scenes, the pairs on threads."""
    out = tmp_path_factory.mktemp("m") / "ties.gpkg"
    return run(region, out, [str(region["folder"])]), tiepoints.read_gpkg(str(out))


def test_a_folder_gives_its_products_and_every_pair_is_matched(region, matched):
    """Measured: 125, 150, 600, 125, 115 of 625 grid points matched per pair; 665 points in two images,
    225 in three; no chain refused, no weak pair."""
    result, table = matched
    f = result.figures
    assert [p["pair"] for p in f["overlap_pairs"]] == PAIRS
    assert [p["matched"] for p in f["overlap_pairs"]] == pytest.approx([125, 150, 600, 125, 115], abs=15)
    assert all(p["grid_points"] == 625 and p["chained"] == p["matched"] and not p["failure"]
               for p in f["overlap_pairs"])
    assert f["overlap_pairs"][2]["overlap_km2"] == pytest.approx(16.0, rel=0.15)    # one strip's two views
    assert f["weak_pairs"] == [] and f["inconsistent_chains"] == 0 and f["points_by_rays"][3] > 200
    assert set(table.scene) == {"s1", "s2", "s2fwd", "s3"} and f["points"] == len(set(table.id))
    texts = [line.text for line in result.lines]
    assert any(t.startswith(f"SCENES folder {region['folder']}: 4 product(s); ") for t in texts)
    assert [t.split(":")[0] for t in texts if ": matched " in t] == PAIRS
    assert any(t.startswith("s2/NAD-s2fwd/NAD: matched ") and t.endswith(" km2") for t in texts)
    assert f"scene s3 ({region['folder'] / 's3' / 'onboard_scene.json'}): camera NAD, image " \
           f"{region['folder'] / 's3' / 'image_NAD.tif'}" in texts


def same_figures(a: dict, b: dict) -> bool:
    """Figures equal (rms_px, NaN for a block's layer without a-priori intersection, left out)."""
    return {k: v for k, v in a.items() if k != "rms_px"} == {k: v for k, v in b.items() if k != "rms_px"}


def arrays_equal(a, b) -> None:
    for name in a.ARRAYS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_a_list_file_one_process_and_a_dask_cluster_give_the_same_ties(region, matched, tmp_path):
    """The list (relative paths), the pairs one after the other in this process, and on two Dask
    worker processes (the scenes travelling as their files): the same ties to the bit."""
    listed = tmp_path / "region.txt"
    listed.write_text("# the region\n" + "\n".join(os.path.relpath(p, tmp_path) for p in region["scenes"]) + "\n\n")
    alone = run(region, tmp_path / "one.gpkg", [str(listed)], processes=1)
    assert alone.lines[0].text == f"SCENES list {listed}: 4 product(s)"
    assert same_figures(alone.figures, matched[0].figures)
    arrays_equal(tiepoints.read_gpkg(str(tmp_path / "one.gpkg")), matched[1])
    distributed = pytest.importorskip("distributed", reason="Dask distributed is not installed "
                                                           "(Debian: python3-distributed)")
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        dask = run(region, tmp_path / "dask.gpkg", region["scenes"], scheduler=cluster.scheduler_address)
    assert same_figures(dask.figures, matched[0].figures)
    arrays_equal(tiepoints.read_gpkg(str(tmp_path / "dask.gpkg")), matched[1])


@pytest.fixture(scope="module")
def far(tmp_path_factory):
    """Two products of ground 1 degree east of the region (overlapping each other), with blank
    images of their size."""
    spec = replace(ONE, centre=(ONE.centre[0] + 1.0, ONE.centre[1]))
    out = {}
    for seed, name in ((1, "farA"), (2, "farB")):
        folder = tmp_path_factory.mktemp("far") / name
        scene = simulate(spec, folder, seed=seed, n_gcps=5).onboard_scene
        image = folder / "image_NAD.tif"
        ds = gdal.GetDriverByName("GTiff").Create(str(image), 800, 800, 1, gdal.GDT_Byte)
        ds.GetRasterBand(1).Fill(100)
        ds = None
        out[name] = str(scene)
    return out


@pytest.mark.parametrize("scenes, message", [
    (lambda r, f: [r["scenes"][0], r["scenes"][1], f["farA"]],
     r"^the block is not connected by overlaps: farA/NAD overlaps no other product \(other ground\?\)"),
    (lambda r, f: [r["scenes"][0], r["scenes"][1], f["farA"], f["farB"]],
     r"the others fall in 2 groups that do not overlap each other: \(s1/NAD, s2/NAD\); \(farA/NAD, farB/NAD\)"),
])
def test_other_ground_and_a_disconnected_block_are_refused_naming_them(region, far, tmp_path, scenes, message):
    """On a constant height (the far products lie off the region's DEM): refused before any matching."""
    output = tmp_path / "t.gpkg"
    with pytest.raises(InputError, match=message) as refused:
        run(region, output, scenes(region, far), terrain=Terrain(height=500.0))
    assert refused.value.parameter == "scenes" and not output.exists()


def test_a_folder_without_products_and_a_bad_list_line_are_refused(region, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.json").write_text('{"not": "a scene"}')
    with pytest.raises(InputError, match=rf"^{empty}: no product found in the folder or its subfolders \(looked for "
                                         r"scene JSON, DIMAP .*; 1 file\(s\) skipped, .*: notes.json\)") as refused:
        run(region, tmp_path / "t.gpkg", [str(empty)])
    assert refused.value.parameter == "scenes"
    listed = tmp_path / "scenes.txt"
    listed.write_text(f"{region['scenes'][0]}\nmissing/onboard_scene.json\n")
    with pytest.raises(InputError, match=rf"^{listed}, line 2: 'missing/onboard_scene.json' is no such file") as refused:
        run(region, tmp_path / "t.gpkg", [str(listed)])
    assert refused.value.parameter == "scenes" and not (tmp_path / "t.gpkg").exists()


def test_a_product_the_ties_leave_apart_is_refused_naming_it(region, tmp_path):
    """s3's image replaced by noise: its two pairs match nothing, the footprints tie it but the ties
    do not; refused, naming s3 and why its pairs failed (not adjusted on its own prior)."""
    noise = tmp_path / "noise.tif"
    ds = gdal.GetDriverByName("GTiff").Create(str(noise), 800, 800, 1, gdal.GDT_Byte)
    ds.GetRasterBand(1).WriteArray(np.random.default_rng(1).integers(0, 255, (800, 800), dtype=np.uint8))
    ds = None
    images = [str(region["folder"] / n / "image_NAD.tif") for n in ("s1", "s2", "s2fwd")] + [str(noise)]
    with pytest.raises(InputError, match=r"^the tie points do not connect the block: s3/NAD overlaps no other "
                                         r"product .*s2/NAD-s3/NAD: .*s2fwd/NAD-s3/NAD: ") as refused:
        run(region, tmp_path / "t.gpkg", region["scenes"], images=tuple(images))
    assert refused.value.parameter == "scenes" and not (tmp_path / "t.gpkg").exists()


def test_images_given_as_a_folder_or_a_list_file(region, tmp_path):
    """INPUTS one folder (each scene's image found there by the scene's name) or one list file (one image
    per line, relative to the list): the views take them; a scene without its image there is named."""
    images = tmp_path / "images"
    images.mkdir()
    for name in ("s1", "s2", "s2fwd", "s3"):
        (images / f"{name}.tif").symlink_to(region["folder"] / name / "image_NAD.tif")
    views, _, _ = use_case.block_views((str(region["folder"]),), (str(images),))
    assert [str(v.image) for v in views] == [str(images / f"{n}.tif") for n in ("s1", "s2", "s2fwd", "s3")]
    listed = images / "images.txt"
    listed.write_text("s3.tif\ns2fwd.tif\ns2.tif\ns1.tif\n")
    views, _, _ = use_case.block_views(tuple(region["scenes"][::-1]), (str(listed),))
    assert [(v.scene_name, v.image.name) for v in views] == [(n, f"{n}.tif") for n in ("s3", "s2fwd", "s2", "s1")]
    (images / "s2.tif").unlink()
    with pytest.raises(InputError, match=rf"^no raw image found for scene s2 \(looked for s2, s2_<NAD>, image_<NAD> "
                                         rf"with .tif, .* in {images}\)") as refused:
        use_case.block_views((str(region["folder"]),), (str(images),))
    assert refused.value.parameter == "images"
