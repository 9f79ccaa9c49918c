"""Every valid RPC accepted, whatever its offsets (core.model.rpcscene.check_image_domain): an image is its
RPC's image when its border at the RPC's height range maps onto the ground within the RPC's latitude/longitude
validity and back. Crops whose RPC keeps the full product's offsets (the crop folded into the numerators) are
accepted as well as crops whose offsets were moved; images that the RPC cannot describe are refused naming the
point, where it landed and the validity box.

Measured: a 1024 x 1024 crop of the Pleiades product of tests/data (Global_RFM, 40000 x 38248 px) at (18144,
20000), its RPC written with the product's offsets, read back maps its pixels as the product's RPC maps the
product's pixels less the origin, to 5e-9 px; the same with the image scale of the crop (LINE_SCALE,
SAMP_SCALE 512 px about the full product's offsets, the form refused before: "the image has 1024 columns but
its RPC covers columns 18144 to 19170") likewise.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pushbroom_adjust.core.errors import MetadataError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.rpcfiles import write_rpc
from pushbroom_adjust.core.model.rpc import RpcModel
from pushbroom_adjust.core.model.rpcscene import check_image_domain, size_from_rpc
from tests.support.ossim_geom import folded_crop_rpc, geom_rpc, read_geom
from tests.support.rpcdata import pleiades_rpc, scaled, write_image

ORIGIN = (18144.0, 20000.0)  # the crop's first pixel in the Pleiades product (40000 x 38248 px)
CROP = 1024


def rescaled_image_coordinates(rpc: RpcModel, samp_off: float, samp_scale: float, line_off: float,
                               line_scale: float) -> RpcModel:
    """The same model with other image offsets and scales: num' = (scale / scale') num + ((off - off') /
    scale') den (exact to rounding)."""
    return replace(rpc, line_num=rpc.line_scale / line_scale * rpc.line_num + (rpc.line_off - line_off) / line_scale
                   * rpc.line_den, line_off=line_off, line_scale=line_scale,
                   samp_num=rpc.samp_scale / samp_scale * rpc.samp_num + (rpc.samp_off - samp_off) / samp_scale
                   * rpc.samp_den, samp_off=samp_off, samp_scale=samp_scale)


@pytest.fixture(scope="module")
def product(shared_data) -> RpcModel:
    """The Pleiades product's vendor RFM with GDAL's origin (0 at the first pixel's centre)."""
    rpc = pleiades_rpc(shared_data)
    return replace(rpc, line_off=rpc.line_off - rpc.origin, samp_off=rpc.samp_off - rpc.origin, origin=0.0)


def crop_files(folder, rpc: RpcModel, name: str = "crop"):
    """A CROP x CROP image with ``rpc`` in an _RPC.TXT beside it; the image's path."""
    folder.mkdir(exist_ok=True)
    write_rpc(rpc, folder / f"{name}_RPC.TXT")
    return write_image(folder / f"{name}.tif", CROP, CROP)


def crop_error_px(product: RpcModel, scene) -> float:
    """Largest distance (px) between the crop scene's image of ground points over it at its height range and
    the product RPC's image of them less the crop's origin."""
    col, row = np.meshgrid(np.linspace(-20, CROP + 20, 9), np.linspace(-20, CROP + 20, 9))
    col, row = np.tile(col.ravel(), 3), np.tile(row.ravel(), 3)
    h = np.repeat([product.height_off - product.height_scale, product.height_off,
                   product.height_off + product.height_scale], col.size // 3)
    lon, lat = product.image_to_ground(col + ORIGIN[0], row + ORIGIN[1], h)
    c, r = scene.ground_to_image_geodetic(lon, lat, h)
    return float(np.max(np.hypot(c - col, r - row)))


@pytest.mark.parametrize("form", ["full product's offsets and scales", "full product's offsets, crop's scales"])
def test_a_crop_whose_rpc_keeps_the_full_products_offsets_is_accepted(product, tmp_path, form):
    """A crop written in the test from a real product's RPC, its origin folded into the numerators: with the
    product's LINE_OFF/SAMP_OFF and scales, and (the form issue 28 was refused with) with the product's offsets
    but the crop's image scales. Read from the image (GDAL pairs the _RPC.TXT) it maps the crop's pixels exactly
    as the product's RPC maps the product's pixels less the origin."""
    rpc = folded_crop_rpc(product, *ORIGIN)
    if form.endswith("crop's scales"):
        rpc = rescaled_image_coordinates(rpc, ORIGIN[0] + CROP / 2, CROP / 2, ORIGIN[1] + CROP / 2, CROP / 2)
    scene = load_scene(crop_files(tmp_path, rpc))
    assert (scene.camera.cols, scene.camera.rows) == (CROP, CROP)
    assert scene.rpc.samp_off == rpc.samp_off and scene.rpc.line_off == rpc.line_off
    assert crop_error_px(product, scene) < 1e-6                         # measured 4.9e-9 px


def test_a_crop_with_its_offsets_moved_is_accepted(product, tmp_path):
    """The other form: LINE_OFF/SAMP_OFF less the crop's origin, numerators unchanged (as gdal_translate -srcwin
    and the Giza crops of tests/data have it)."""
    rpc = replace(product, samp_off=product.samp_off - ORIGIN[0], line_off=product.line_off - ORIGIN[1])
    scene = load_scene(crop_files(tmp_path, rpc))
    assert crop_error_px(product, scene) < 1e-6


@pytest.mark.parametrize("name, origin, size", [("img1", (20500, 5000), (800, 801)), ("img2", (20501, 5476), (795, 801))])
def test_the_giza_crops_are_accepted(shared_data, name, origin, size):
    scene = load_scene(shared_data / "pleiades_gizeh" / f"{name}.tif")
    assert (scene.camera.cols, scene.camera.rows) == size
    vendor = geom_rpc(read_geom(shared_data / "pleiades_gizeh" / f"{name}.geom"))
    assert scene.rpc.samp_off == vendor.samp_off - origin[0] and scene.rpc.line_off == vendor.line_off - origin[1]


def test_the_ventoux_crops_are_accepted_as_their_products_crops(shared_data):
    """The Ventoux crops' RPCs keep the full products' offsets; the image's own size is read."""
    for name, size in (("left_image", (500, 500)), ("right_image", (498, 495))):
        scene = load_scene(shared_data / "pleiades_ventoux" / f"{name}.tif")
        vendor = geom_rpc(read_geom(shared_data / "pleiades_ventoux" / f"{name}.geom"))
        assert (scene.camera.cols, scene.camera.rows) == size and scene.rpc.line_off == vendor.line_off


def test_an_image_far_larger_than_its_rpc_covers_is_refused(shared_data, tmp_path):
    """An image twice as wide as the one the RPC describes: its right corners land three times the RPC's ground
    scale from its centre. The message names the image, the point, where it landed and the validity box."""
    rpc = scaled(pleiades_rpc(shared_data), 16.0)
    cols, rows = size_from_rpc(rpc)
    image = write_image(tmp_path / "big.tif", 2 * cols, rows, rpc)
    with pytest.raises(MetadataError) as refusal:
        load_scene(image)
    message = str(refusal.value)
    assert message.startswith(f"{image}: the image (5000 x 2390 px) cannot be the one its RPC describes: its "
                              "upper-right corner (5000, 0) at 490 m lands at latitude 31.09642, longitude 2.56768, "
                              "3.02 times the RPC's ground scale from its centre; the RPC is valid over latitude "
                              "30.92313 to 31.11423, longitude 2.11840 to 2.34201, heights 490 to 660 m"), message
    assert message.endswith("Is it the image this RPC belongs to?")
    check_image_domain(rpc, cols, rows, "the image it describes")  # the image it describes: accepted


def test_another_products_rpc_is_refused(shared_data, product):
    """The Giza product's RPC (40000 x 13644 px) given an image of the Pleiades product's size (40000 x 38248):
    its lower-left corner lands 2.32 times the Giza RPC's ground scale from its centre (measured; where the cubic
    takes it so far outside: the image's rows past 13644 belong to no ground of that RPC); the other way round the
    Giza image's size
    fits inside the other product, so that only the domain can be checked (accepted)."""
    giza = geom_rpc(read_geom(shared_data / "pleiades_gizeh" / "img1.geom"))
    with pytest.raises(MetadataError, match=r"^img_P1BP\.tif: the image \(40000 x 38248 px\) cannot be the one its "
                                            r"RPC describes: its lower-left corner \(0, 38248\) at 10 m lands at "
                                            r"latitude 29\.85122, longitude 30\.97758, 2\.32 times .* latitude "
                                            r"29\.92087 to 30\.02613, longitude 31\.00691 to 31\.24856"):
        check_image_domain(giza, 40000, 38248, "img_P1BP.tif")
    check_image_domain(product, 40000, 13644, "img1.tif")


def test_an_rpc_that_cannot_be_inverted_over_the_image_is_refused(product):
    """A denominator that vanishes inside the image (its constant term cancelled by its line term at a third of
    the scale): the points there do not map onto the ground and back."""
    den = product.line_den.copy()
    den[1] = 3.0 * den[0]
    broken = replace(product, line_den=den)
    with pytest.raises(MetadataError, match=r"^broken: the image \(40000 x 38248 px\) cannot be the one its RPC "
                                            r"describes: its .* (does not map onto the ground|maps onto ground that "
                                            r"the RPC maps back|lands at)"):
        check_image_domain(broken, 40000, 38248, "broken")
