"""Tie points of a block on its overlap graph (core.measure.pairmatching): a rendered block of
two neighbouring strips, whose outer scenes do not overlap each other (the star of
match_block_tiepoints refuses it), its pairs found from the footprints, each pair matched, the
ties chained into points of up to three images and checked against the true models."""
import logging
import pickle

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import Cancelled, InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.measure.matching import MatchSettings
from pushbroom_adjust.core.measure.pairmatching import (match_overlap_graph, match_pair, overlap_pairs, pair_jobs,
                                                        run_pair_job, weak_pairs)
from pushbroom_adjust.core.measure.tiematching import View, match_block_tiepoints
from pushbroom_adjust.core.products.overlaps import OverlapGraph, tied_graph
from pushbroom_adjust.simulation.block import BlockMember, simulate_block
from tests.unit.measure.test_tiematching import ONE

# 800 px of 5 m = 4 km wide: strips 3 km apart overlap by 1 km; s1 and s3, 6 km apart, not at all
MEMBERS = [BlockMember("s1", ONE), BlockMember("s2", ONE, orbit_offset_km=3.0),
           BlockMember("s2fwd", ONE, view=(18.0, 0.0), orbit_offset_km=3.0),
           BlockMember("s3", ONE, orbit_offset_km=6.0)]
SETTINGS = MatchSettings(spacing=30, search=400.0, workers=1)


@pytest.fixture(scope="module")
def block(tmp_path_factory) -> dict:
    result = simulate_block(MEMBERS, tmp_path_factory.mktemp("strips"), seed=4, n_gcps=10, n_tie_points=20,
                            render=True)
    views = [View(name, load_scene(files["onboard_scene"]), 0, next(iter(files["images"].values())))
             for name, files in result.members.items()]
    return {"views": views, "dem": Dem(result.dem, "geoid"),
            "true": {n: load_scene(f["true_scene"]) for n, f in result.members.items()}}


@pytest.fixture(scope="module")
def graph(block):
    return overlap_pairs(block["views"], block["dem"])


@pytest.fixture(scope="module")
def matched(block, graph):
    return match_overlap_graph(block["views"], graph, block["dem"], SETTINGS)


def small_dem(dem: Dem, folder) -> Dem:
    """The western two thirds of ``dem`` (north up): s1's footprint lies off it."""
    ds = gdal.Open(dem.path)
    path = str(folder / "west_dem.tif")
    gdal.Translate(path, ds, srcWin=[0, 0, ds.RasterXSize * 2 // 3, ds.RasterYSize])
    return Dem(path, dem.datum)


def test_the_pairs_come_from_the_footprints(block, graph, tmp_path):
    assert graph.pair_names() == [("s1/NAD", "s2/NAD"), ("s1/NAD", "s2fwd/NAD"), ("s2/NAD", "s2fwd/NAD"),
                                  ("s2/NAD", "s3/NAD"), ("s2fwd/NAD", "s3/NAD")]
    assert graph.area_km2[2] == pytest.approx(16.0, rel=0.15)             # one strip's two views: 4 x 4 km
    assert graph.area_km2[0] == pytest.approx(4.0, rel=0.25)              # 1 km side-lap x 4 km
    with pytest.raises(InputError, match="does not overlap s1/NAD"):
        match_block_tiepoints(block["views"], block["dem"], SETTINGS)      # the star: s3 is refused
    with pytest.raises(InputError, match=r"s1/NAD, s3/NAD overlap no other product"):
        overlap_pairs([block["views"][0], block["views"][3]], block["dem"])
    with pytest.raises(InputError, match=r"^s1: camera 'NAD': DEM .*west_dem.tif gives no height for \d+ of 129 points of "
                                         r"the image outline \(\d+ off its extent\)") as e:
        overlap_pairs(block["views"], small_dem(block["dem"], tmp_path))
    assert e.value.parameter == "dem"
    with pytest.raises(Cancelled):
        match_overlap_graph(block["views"], graph, block["dem"], SETTINGS, is_cancelled=lambda: True)


def test_every_pair_matched_and_chained_across_the_strips(block, matched):
    """Measured: of 625 grid points 125, 150, 600, 125, 115 matched per pair (the side-lap is a
    fifth of an image), no chain refused, 665 points in two images and 225 in three; the true
    rays of a point's observations meet within 0.009 px (median), 0.022 px (95 %), 0.044 px."""
    chained, reports = matched
    t = chained.table
    assert [r.matched for r in reports] == pytest.approx([125, 150, 600, 125, 115], abs=15)
    assert all(r.grid_points == 625 and r.refused_in_chains == 0 for r in reports) and weak_pairs(reports) == []
    assert set(t.scene) == {"s1", "s2", "s2fwd", "s3"}
    assert chained.inconsistent_chains == 0
    assert chained.points_by_rays[3] > 200                              # s1-s2-s2fwd, s2-s2fwd-s3
    assert len(t) == 2 * chained.points_by_rays[2] + 3 * chained.points_by_rays[3]
    # every point is one ground point: its observations' true rays meet
    ground = np.empty((len(t), 3))
    for name, scene in block["true"].items():
        mine = t.scene == name
        ground[mine] = scene.image_to_ground_dem(t.col[mine], t.row[mine], block["dem"], 0)
    _, point = t.points()
    mean = np.column_stack([np.bincount(point, ground[:, k]) / np.bincount(point) for k in range(3)])[point]
    error = np.empty(len(t))
    for name, scene in block["true"].items():
        mine = t.scene == name
        col, row = scene.ground_to_image(mean[mine], 0)
        error[mine] = np.hypot(col - t.col[mine], row - t.row[mine])
    assert np.median(error) < 0.03 and np.quantile(error, 0.95) < 0.06 and error.max() < 0.15


def test_a_pair_run_as_a_pickled_job_gives_the_same_ties(block, graph):
    """What another process or a Dask worker receives (the job pickled, the DEM reopened from its
    path) matches the pair to the same bits as the run in this process."""
    job = pair_jobs(block["views"], graph, block["dem"], SETTINGS)[3]
    assert (job.first.label, job.second.label) == ("s2/NAD", "s3/NAD")
    here = match_pair(job.first, job.second, block["dem"], SETTINGS, job.overlap_km2)
    there = run_pair_job(pickle.loads(pickle.dumps(job)))
    assert there[1] == here[1] and there[1].matched > 100
    for name in ("col_a", "row_a", "col_b", "row_b", "sigma_px"):
        np.testing.assert_array_equal(getattr(there[0], name), getattr(here[0], name))


def test_pairs_that_match_nothing_are_refused_with_their_reasons(block, graph, caplog):
    """Correlation demanded beyond what any texture gives: the one pair kept says why it failed."""
    only = tied_graph(graph, np.arange(len(graph.pairs)) == 0)
    with pytest.raises(InputError, match=r"no tie point matched in any overlapping pair: s1/NAD-s2/NAD: .*\d+ "
                                         r"low correlation"):
        match_overlap_graph(block["views"], only, block["dem"], MatchSettings(spacing=60, search=400.0, workers=1,
                                                                             min_correlation=0.9999))


def test_a_view_its_pairs_do_not_tie_is_named(block, graph, caplog):
    """A graph claiming s1 and s3 overlap (they do not): the matcher finds no consistent offset
    between them, the pair says so and gives no tie, the others go on, s3 is tied to nothing,
    and the log names it."""
    claimed = OverlapGraph(graph.names, np.array([[0, 1], [0, 3], [1, 2]]), np.array([4.0, 1.0, 16.0]),
                           np.zeros(4, int))
    with caplog.at_level(logging.WARNING, logger="pushbroom_adjust.core.measure.pairmatching"):
        chained, reports = match_overlap_graph(block["views"], claimed, block["dem"],
                                               MatchSettings(spacing=60, search=400.0, workers=1))
    assert [r.chained > 0 for r in reports] == [True, False, True]
    assert reports[1].failure.startswith("no consistent match between the image and reference")
    assert reports[0].failure == reports[2].failure == ""
    assert "s3" not in set(chained.table.scene)
    assert ("the ties do not connect the block although the footprints do: s3/NAD overlaps no other product"
            in caplog.text)
    assert "1 pair with fewer than 20 ties: s1/NAD-s3/NAD (0:" in caplog.text


def test_a_dask_cluster_gives_the_same_ties(block, graph, matched):
    """The pairs run as jobs on two Dask worker processes: the same reports, the same table to the bit."""
    distributed = pytest.importorskip("distributed", reason="Dask distributed is not installed "
                                                           "(Debian: python3-distributed; scripts/setup.sh installs it)")
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        chained, reports = match_overlap_graph(block["views"], graph, block["dem"], SETTINGS,
                                               scheduler=cluster.scheduler_address)
    assert reports == matched[1]
    for name in chained.table.ARRAYS:
        np.testing.assert_array_equal(getattr(chained.table, name), getattr(matched[0].table, name))
