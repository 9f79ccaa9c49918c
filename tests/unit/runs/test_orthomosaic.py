"""core.runs.orthorectify with a block (SCENES): the rendered 2-strip block of four TH-1 nadir-camera
cuts (tests/unit/measure/test_pairmatching.py: s1, s2 and s3 side by side 3 km apart, s2fwd seeing
s2's ground 18 degrees forward) orthorectified on one common grid into a VRT mosaic, and every
overlap checked by phase correlation: with the true models the overlaps co-register within a few
hundredths of a pixel, with the biased onboard models by pixels; the mosaic's order is the one
asked; refusals and cancels leave nothing."""
import xml.etree.ElementTree as ElementTree

import numpy as np
import pytest
from osgeo import gdal
from pyproj import CRS

from pushbroom_adjust.core.errors import Cancelled, InputError
from pushbroom_adjust.core.runs import orthorectify as use_case
from pushbroom_adjust.core.runs.base import Terrain
from pushbroom_adjust.simulation.block import simulate_block
from tests.unit.measure.test_pairmatching import MEMBERS

NAMES = [m.name for m in MEMBERS]
PAIRS = [("s1", "s2"), ("s1", "s2fwd"), ("s2", "s2fwd"), ("s2", "s3"), ("s2fwd", "s3")]


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mosaic")
    simulate_block(MEMBERS, folder / "block", seed=4, n_gcps=10, n_tie_points=20, render=True)
    return folder


def request(block, output, models: str = "true", **fields) -> use_case.OrthoRequest:
    scenes = tuple(str(block / "block" / n / f"{models}_scene.json") for n in NAMES)
    images = tuple(str(block / "block" / n / "image_NAD.tif") for n in NAMES)
    return use_case.OrthoRequest("", str(output), Terrain(str(block / "block" / "dem.tif"), "geoid"),
                                 **{"images": images, "scenes": scenes, **fields})


@pytest.fixture(scope="module")
def true_run(block):
    return use_case.run(request(block, block / "true"))


@pytest.fixture(scope="module")
def onboard_run(block):
    return use_case.run(request(block, block / "onboard", "onboard", mosaic_order="given"))


def vrt_sources(path) -> list[str]:
    return [s.text for s in ElementTree.parse(path).getroot().iter("SourceFilename")]


def test_true_models_co_register_within_hundredths_of_a_pixel(true_run):
    """Measured: 0.018-0.022 px RMS per pair on 18-115 windows of 64 px, the rest of each overlap's
    windows nodata in one of the two (the north-up grids' corners)."""
    checks = true_run.figures["coregistration"]
    assert [(c["first"], c["second"]) for c in checks] == PAIRS          # s1 and s3 do not overlap
    assert all(c["used"] >= 15 and c["rms_px"] < 0.05 for c in checks), checks
    assert checks[2]["used"] > 100                                       # s2 - s2fwd: one ground
    assert all(set(k for k, n in c["left_out"].items() if n) <= {"nodata"} for c in checks)
    assert not any(line.warning for line in true_run.lines)
    assert "co-registration of the 5 overlapping pairs" in "\n".join(line.text for line in true_run.lines)


def test_onboard_models_misregister_by_pixels_and_are_named(onboard_run):
    """Measured: 4.0 px (s2 - s3) to 19.7 px (s1 - s2) RMS, each pair's shift common to its windows."""
    checks = onboard_run.figures["coregistration"]
    assert [(c["first"], c["second"]) for c in checks] == PAIRS
    assert all(c["used"] >= 10 and c["rms_px"] >= 2.0 for c in checks), checks
    assert all(c["max_px"] - c["rms_px"] < 1.0 for c in checks)          # one shift per pair, not noise
    warnings = [line for line in onboard_run.lines if line.warning]
    assert len(warnings) == 1 and warnings[0].text.startswith("5 of 5 overlapping pairs do not co-register")
    assert "bundleadjust" in warnings[0].text


def test_every_orthoimage_on_one_grid(true_run, onboard_run):
    for result in (true_run, onboard_run):
        transforms, crss = [], set()
        for path in result.files[use_case.ORTHOIMAGES]:
            ds = gdal.Open(path)
            transforms.append(ds.GetGeoTransform())
            crss.add(CRS.from_wkt(ds.GetProjection()).to_epsg())
        size = transforms[0][1]
        assert crss == {32649} and all(t[1] == size and t[5] == -size and t[2] == t[4] == 0 for t in transforms)
        origins = np.array([(t[0], t[3]) for t in transforms]) / size
        np.testing.assert_allclose(origins, np.round(origins), rtol=0, atol=1e-9)   # one lattice
        # the coarsest ground sample distance: s2fwd's, seen 19 degrees off nadir
        assert 5.2 < size < 5.35
        mosaic = gdal.Open(result.files[use_case.MOSAIC])
        assert mosaic.GetGeoTransform()[1] == size
        offset = (mosaic.GetGeoTransform()[0] - transforms[0][0]) / size
        assert offset == pytest.approx(round(offset), abs=1e-9)


def test_the_mosaic_is_in_the_order_asked(block, true_run, onboard_run):
    """Default: the least off-nadir on top (the VRT's last source), s2fwd (19.3 degrees at the ground)
    at the bottom; 'given': the first scene on top. Where the upper image has no data the lower shows."""
    angles = true_run.figures["off_nadir_deg"]
    assert angles["s2fwd"] == pytest.approx(19.3, abs=0.2)
    assert all(angles[n] < 0.5 for n in ("s1", "s2", "s3"))
    order = true_run.figures["mosaic_order"]
    assert order[0] == "s2fwd" and order[-1] == min(angles, key=angles.get)
    assert vrt_sources(true_run.files[use_case.MOSAIC]) == [f"ortho_{n}.tif" for n in order]
    assert onboard_run.figures["mosaic_order"] == NAMES[::-1]
    assert vrt_sources(onboard_run.files[use_case.MOSAIC]) == [f"ortho_{n}.tif" for n in NAMES[::-1]]
    # the pixels: each orthoimage pasted in that order, its nodata transparent, gives the mosaic
    folder = block / "true"
    mosaic = gdal.Open(str(folder / "mosaic.vrt"))
    x0, size, _, y0 = mosaic.GetGeoTransform()[:4]
    expected = np.zeros((mosaic.RasterYSize, mosaic.RasterXSize), np.uint16)
    for name in order:
        ds = gdal.Open(str(folder / f"ortho_{name}.tif"))
        t = ds.GetGeoTransform()
        c, r = round((t[0] - x0) / size), round((y0 - t[3]) / size)
        own = ds.GetRasterBand(1).ReadAsArray()
        part = expected[r:r + own.shape[0], c:c + own.shape[1]]
        part[own != 0] = own[own != 0]
    shown = mosaic.GetRasterBand(1).ReadAsArray()
    np.testing.assert_array_equal(shown, expected)
    assert np.count_nonzero(shown) > 0.5 * shown.size


def two_bands(block) -> str:
    """s1's image with its band twice."""
    path = str(block / "s1_two_bands.tif")
    gdal.Translate(path, str(block / "block" / "s1" / "image_NAD.tif"), bandList=[1, 1])
    return path


def test_refusals_and_cancels_write_nothing(block, tmp_path):
    one = request(block, tmp_path / "out")
    cases = [(request(block, tmp_path / "out", scenes=one.scenes[:1], images=one.images[:1]), "scenes", "1 scene given; a block needs two or more"),
             (request(block, tmp_path / "out", extent=lambda crs: (0, 0, 1, 1)), "extent", "EXTENT is for one scene"),
             (request(block, tmp_path / "out", images=one.images[:3]), "images", "3 raw image"),
             (request(block, tmp_path / "out", mosaic_order="newest"), "mosaic_order", "unknown mosaic order"),
             (request(block, tmp_path / "out", images=(two_bands(block), *one.images[1:])), "images",
              r"differ in bands or data type \(s1 2 x Byte, s2 1 x Byte")]
    for req, parameter, message in cases:
        with pytest.raises(InputError, match=message) as refused:
            use_case.run(req)
        assert refused.value.parameter == parameter
    done = [0.0]    # cancelled half-way: two orthoimages written under temporary names, then removed
    with pytest.raises(Cancelled):
        use_case.run(one, lambda f, message=None: done.append(f), lambda: done[-1] > 0.5)
    assert 0.5 < done[-1] < 0.9
    assert list(tmp_path.iterdir()) == []
