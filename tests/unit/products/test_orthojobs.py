"""Every camera of a three-line scene, every scene of a strip, in one run; and the same tiles as
picklable jobs on a Dask distributed cluster (the same bytes as the threaded run).

A TH-1 three-line strip of two scenes (Zhang et al. 2015's camera) is simulated, cut to its
first 128 rows per camera (two scenes of 64 rows) and rendered from the known texture."""
import pickle
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.errors import Cancelled, InputError
from pushbroom_adjust.core.products.ortho import default_grid, orthorectify, orthorectify_products, strip_products
from pushbroom_adjust.core.products.orthojobs import OrthoJob, run_job, surface_description
from tests.support.ortho_compare import rendered_cameras, shift_against_texture

RESOLUTION = 40.0  # m: small grids keep the test quick; the mapping is exact at any resolution


@pytest.fixture(scope="module")
def strip(tmp_path_factory):
    """(cut scene, DEM, texture frame, images by camera, products, grids) of the rendered strip."""
    folder = tmp_path_factory.mktemp("th1")
    scene, _, dem, frame, images = rendered_cameras(folder, "th1_tlc", seed=4, rows=128, n_scenes=2)
    products = strip_products(scene, [0, 1, 2])
    grids = [default_grid(scene, p.camera, dem, resolution=RESOLUTION, rows=p.rows) for p in products]
    return scene, dem, frame, images, products, grids


@pytest.fixture(scope="module")
def all_cameras(strip, tmp_path_factory) -> Path:
    """The folder of one run over every camera and scene."""
    scene, dem, _, images, products, grids = strip
    folder = tmp_path_factory.mktemp("all")
    orthorectify_products(scene, images, dem, folder, products, grids)
    return folder


def test_every_camera_and_scene_lies_on_the_texture(strip, all_cameras):
    scene, _, frame, _, products, _ = strip
    assert [p.name for p in products] == [f"ortho_{c}_s{k}.tif" for c in ("NAD", "FWD", "BWD") for k in (1, 2)]
    assert [p.rows for p in products[:2]] == [(0, 64), (64, 128)]
    assert sorted(f.name for f in all_cameras.iterdir()) == sorted(p.name for p in products)
    for p in products:
        (dx, dy), used = shift_against_texture(all_cameras / p.name, frame)
        assert used > 5000, p.name
        assert abs(dx) < 0.01 and abs(dy) < 0.01, (p.name, dx, dy)


def test_the_two_scenes_of_a_camera_meet_without_overlap(strip, all_cameras):
    """Each scene holds only its own rows: on a common grid their valid pixels barely touch
    (one output row along the boundary at most) and together cover the camera's strip."""
    scene, dem, _, images, products, grids = strip
    grid = default_grid(scene, 1, dem, resolution=RESOLUTION)
    valid = []
    for p in products[2:4]:  # FWD s1, s2 on the whole strip's grid
        out = all_cameras.parent / f"common_{p.name}"
        orthorectify(scene, images[1], dem, out, 1, grid, rows=p.rows)
        ds = gdal.Open(str(out))
        valid.append(ds.GetRasterBand(1).ReadAsArray() > 0)
    both = valid[0] & valid[1]
    assert valid[0].sum() > 5000 and valid[1].sum() > 5000
    assert both.sum() < 0.02 * valid[0].sum()


def test_each_orthoimage_is_the_single_camera_run_byte_for_byte(strip, all_cameras, tmp_path):
    scene, dem, _, images, products, grids = strip
    for p, grid in zip(products, grids):
        single = tmp_path / p.name
        orthorectify(scene, images[p.camera], dem, single, p.camera, grid, rows=p.rows)
        assert single.read_bytes() == (all_cameras / p.name).read_bytes(), p.name


def test_a_failure_or_a_cancel_leaves_no_orthoimage(strip, tmp_path):
    scene, dem, _, images, products, grids = strip
    reached = [0.0]
    with pytest.raises(Cancelled):  # cancelled past half the run: the first orthoimages are complete
        orthorectify_products(scene, images, dem, tmp_path, products, grids, progress=lambda f: reached.append(f),
                              is_cancelled=lambda: reached[-1] > 0.6)
    assert list(tmp_path.iterdir()) == []
    fractions = []
    orthorectify_products(scene, images, dem, tmp_path, products[:2], grids[:2], progress=fractions.append)
    assert fractions == sorted(fractions) and fractions[-1] == pytest.approx(1.0)
    assert 0.3 < fractions[len(fractions) // 2] < 0.7  # one progress over the whole run


def test_a_job_is_plain_data_and_runs_alone(strip, tmp_path):
    """An OrthoJob survives pickling and a worker's run of it gives the tile of the threaded run."""
    scene, dem, _, images, products, grids = strip
    from pushbroom_adjust.core.products.mapping import Mapper
    from pushbroom_adjust.core.formats.scene_json import scene_to_dict
    import json
    p, grid = products[0], grids[0]
    whole = tmp_path / "whole.tif"
    orthorectify(scene, images[0], dem, whole, 0, grid, rows=p.rows)
    planned = Mapper(scene, 0, dem, grid, p.rows).nodes(0, grid.rows, 0, grid.cols, 32)
    window = (0, min(512, grid.rows), 512, min(1024, grid.cols))
    job = OrthoJob(json.dumps(scene_to_dict(scene)), 0, images[0],
                   (grid.crs.to_wkt(), grid.x0, grid.y0, grid.resolution, grid.cols, grid.rows), window,
                   surface_description(dem), "bilinear", 0.0, str(tmp_path / "tile.tif"), p.rows,
                   nodes=planned.window(*window))
    assert run_job(pickle.loads(pickle.dumps(job))).error_px <= 0.01
    r0, r1, c0, c1 = window
    tile, ref = gdal.Open(str(tmp_path / "tile.tif")), gdal.Open(str(whole))
    expected = ref.GetRasterBand(1).ReadAsArray(c0, r0, c1 - c0, r1 - r0)
    assert np.array_equal(tile.GetRasterBand(1).ReadAsArray(), expected) and expected.any()


def test_a_dask_cluster_writes_the_same_bytes(strip, all_cameras, tmp_path):
    distributed = pytest.importorskip("distributed", reason="Dask distributed is not installed "
                                                           "(Debian: python3-distributed; scripts/setup.sh installs it)")
    scene, dem, _, images, products, grids = strip
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        for k in (0, 3):  # NAD s1, FWD s2
            out = tmp_path / products[k].name
            orthorectify(scene, images[products[k].camera], dem, out, products[k].camera, grids[k],
                         rows=products[k].rows, scheduler=cluster.scheduler_address)
            assert out.read_bytes() == (all_cameras / products[k].name).read_bytes()
        assert sorted(f.name for f in tmp_path.iterdir()) == sorted(products[k].name for k in (0, 3))


def test_an_unreachable_scheduler_is_named_before_any_work(strip, tmp_path):
    pytest.importorskip("distributed", reason="Dask distributed is not installed")
    scene, dem, _, images, products, grids = strip
    import socket
    with socket.socket() as s:  # a free loopback port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(InputError, match=rf"SCHEDULER: cannot reach the Dask scheduler at 'tcp://127.0.0.1:{port}'"):
        orthorectify(scene, images[0], dem, tmp_path / "o.tif", 0, grids[0], scheduler=f"tcp://127.0.0.1:{port}")
    assert list(tmp_path.iterdir()) == []
