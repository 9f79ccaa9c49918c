"""Orthorectification against the known ground texture of a rendered simulated scene:
sub-pixel registration overall and along the CCD seams, bad input, no partial output."""

import numpy as np
import pytest
from osgeo import gdal
from pyproj import CRS, Transformer

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import Cancelled, InputError
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.products.mapping import Mapper, OrthoGrid
from pushbroom_adjust.core.products.ortho import common_grid, default_grid, orthorectify
from tests.support.dems import blob_holes, read_dem, western_part, with_holes
from tests.support.ortho_compare import read_band, rendered_cut, shift_against_texture


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """A 1200-row cut of a CBERS-02B scene (three staggered CCDs), rendered from the texture."""
    folder = tmp_path_factory.mktemp("ortho")
    scene, _, dem, frame = rendered_cut(folder, seed=3, rows=1200)
    return scene, dem, frame, folder


@pytest.mark.parametrize("resampling", ["bilinear", "cubic"])
def test_orthoimage_lies_on_the_texture_within_a_twentieth_of_a_pixel(rendered, tmp_path, resampling):
    scene, dem, frame, folder = rendered
    out = tmp_path / "ortho.tif"
    figures = orthorectify(scene, folder / "raw.tif", dem, out, resampling=resampling)
    assert figures["densification_error_px"] < 0.01
    d, n = shift_against_texture(out, frame)
    assert n == 400_000 and np.hypot(*d) < 0.05, d
    ds = gdal.Open(str(out))
    band = ds.GetRasterBand(1)
    assert band.GetNoDataValue() == 0 and band.GetOverviewCount() > 0
    assert ds.GetMetadata("IMAGE_STRUCTURE")["COMPRESSION"] == "DEFLATE"
    assert band.GetBlockSize() == [512, 512]


def test_no_seam_across_the_staggered_ccds(rendered, tmp_path):
    """Strips of the orthoimage over the two CCD boundaries register as well as the rest."""
    scene, dem, frame, folder = rendered
    out = tmp_path / "ortho.tif"
    orthorectify(scene, folder / "raw.tif", dem, out)
    ds = gdal.Open(str(out))
    gt = ds.GetGeoTransform()
    # where the boundaries fall on the ground: the ground points of the seam columns
    cam = scene.cameras[0]
    rows = np.linspace(100, cam.rows - 100, 40)
    for boundary in (c.col_offset for c in cam.chips[1:]):
        lon, lat, _ = ecef_to_geodetic(scene.image_to_ground_dem(np.full(rows.size, boundary), rows, dem))
        x, y = Transformer.from_crs(CRS.from_epsg(4326), CRS.from_wkt(ds.GetProjection()), always_xy=True).transform(lon, lat)
        j = ((x - gt[0]) / gt[1]).astype(int)
        i = ((y - gt[3]) / gt[5]).astype(int)
        mask = np.zeros((ds.RasterYSize, ds.RasterXSize), bool)
        for a, b in zip(i, j):  # 40 seam samples, a 30-px square around each
            mask[max(a - 15, 0):a + 15, max(b - 15, 0):b + 15] = True
        d, n = shift_against_texture(out, frame, mask)
        assert n > 20_000 and np.hypot(*d) < 0.05, (boundary, d)


def test_bad_input_is_refused_and_nothing_is_left(rendered, tmp_path):
    scene, dem, frame, folder = rendered
    small = tmp_path / "small.tif"
    gdal.GetDriverByName("GTiff").Create(str(small), 100, 100, 1, gdal.GDT_Byte)
    with pytest.raises(InputError, match=r"small.tif: the raster is 100 x 100 px but camera HRC .* 12246 x 1200"):
        orthorectify(scene, small, dem, tmp_path / "o.tif")
    with pytest.raises(InputError, match="resampling must be one of nearest, bilinear, cubic"):
        orthorectify(scene, folder / "raw.tif", dem, tmp_path / "o.tif", resampling="lanczos")
    with pytest.raises(InputError, match="cannot be opened as a raster"):
        orthorectify(scene, tmp_path / "missing.tif", dem, tmp_path / "o.tif")
    with pytest.raises(InputError, match=r"cannot write .*o.tif: folder .*no such folder does not exist"):
        orthorectify(scene, folder / "raw.tif", dem, tmp_path / "no such folder" / "o.tif")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["small.tif"]


def test_a_dem_covering_part_of_the_scene(rendered, tmp_path, caplog):
    """Without an extent the grid cannot be planned (error naming the DEM); on a given grid the
    output pixels of the image's footprint with no height are nodata, and the warning counts them
    pixel by pixel (off the DEM, on its holes): exactly the footprint's pixels the orthoimage leaves
    empty."""
    scene, dem, frame, folder = rendered
    part = Dem(western_part(dem.path, tmp_path / "west.tif"), datum="geoid")
    with pytest.raises(InputError, match=rf"DEM {part.path} does not cover the scene .*: the image's (centre|border) "
                                         r"does not meet it \(the scene puts the image's centre at latitude"):
        default_grid(scene, 0, part)
    grid = default_grid(scene, 0, dem)
    full = orthorectify(scene, folder / "raw.tif", dem, tmp_path / "full.tif", grid=grid)
    footprint = read_band(str(tmp_path / "full.tif")) > 0
    assert full["dem_gap_share"] == 0 and full["footprint_pixels"] == pytest.approx(footprint.sum(), rel=1e-4)
    figures = orthorectify(scene, folder / "raw.tif", part, tmp_path / "o.tif", grid=grid)
    empty = footprint & (read_band(str(tmp_path / "o.tif")) == 0)
    assert 0.3 < figures["dem_gap_share"] < 0.7
    assert figures["dem_gap_pixels"] == pytest.approx(empty.sum(), rel=1e-3)
    assert figures["dem_gap_share"] == pytest.approx(empty.sum() / footprint.sum(), abs=1e-3)
    assert figures["dem_hole_pixels"] == 0
    assert f"DEM {part.path} gives no height for {figures['dem_gap_pixels']} of {figures['footprint_pixels']} " \
           "output pixels of the image's footprint (" in caplog.text and "off its extent)" in caplog.text


def test_a_dem_cut_to_the_orthoimage_counts_only_the_pixels_it_leaves_empty(rendered, tmp_path):
    """Issue 28's warning said the DEM gave no height for 9.8 % of the footprint while 0.1 % of the
    orthoimage was empty: the share was counted on the node grid, whose last nodes lie past the
    grid's edge, beyond a DEM cut to it. Measured on a 1024 x 1024 px window and the DEM cut to its
    extent: the previous count said 2.0 %, the footprint's empty pixels are 0.23 %."""
    scene, dem, frame, folder = rendered
    g = default_grid(scene, 0, dem)
    n = 1024
    grid = OrthoGrid(g.crs, g.x0 + 5000 * g.resolution, g.y0 - 1200 * g.resolution, g.resolution, n, n)
    x = grid.x0 + np.array([0, n, 0, n]) * grid.resolution
    y = grid.y0 - np.array([0, 0, n, n]) * grid.resolution
    lon, lat = Transformer.from_crs(grid.crs, CRS.from_epsg(4326), always_xy=True).transform(x, y)
    gdal.Warp(str(tmp_path / "cut.tif"), dem.path, outputBounds=(lon.min(), lat.min(), lon.max(), lat.max()),
              xRes=1 / 3600, yRes=1 / 3600, resampleAlg="bilinear")
    full = orthorectify(scene, folder / "raw.tif", dem, tmp_path / "full.tif", grid=grid)
    figures = orthorectify(scene, folder / "raw.tif", Dem(tmp_path / "cut.tif", "geoid"), tmp_path / "o.tif", grid=grid)
    footprint = read_band(str(tmp_path / "full.tif")) > 0
    empty = footprint & (read_band(str(tmp_path / "o.tif")) == 0)
    assert full["dem_gap_pixels"] == 0 and 0 < empty.sum() < 0.01 * footprint.sum()
    assert figures["dem_gap_pixels"] == pytest.approx(empty.sum(), rel=0.02)
    assert figures["dem_gap_share"] == pytest.approx(empty.sum() / footprint.sum(), rel=0.02)


@pytest.mark.parametrize("nodata", [None, -32768])
def test_a_dem_with_holes(rendered, tmp_path, caplog, nodata):
    """A DEM with voids inside the footprint, as NaN or as a nodata value: no error, the pixels
    on the voids are nodata and counted as on its holes, the rest mapped within the tolerance."""
    scene, dem, frame, folder = rendered
    z, gt, _ = read_dem(dem.path)
    holes = blob_holes(z.shape, 0.02, size=8)
    holey = Dem(with_holes(dem.path, tmp_path / "holes.tif", holes, nodata), datum="geoid")
    grid = default_grid(scene, 0, dem)
    grid = OrthoGrid(grid.crs, grid.x0 + 2048 * grid.resolution, grid.y0 - 1024 * grid.resolution, grid.resolution,
                     2048, 2048)
    full = orthorectify(scene, folder / "raw.tif", dem, tmp_path / "full.tif", grid=grid)
    figures = orthorectify(scene, folder / "raw.tif", holey, tmp_path / "o.tif", grid=grid)
    footprint = read_band(str(tmp_path / "full.tif")) > 0
    empty = footprint & (read_band(str(tmp_path / "o.tif")) == 0)
    assert full["dem_gap_pixels"] == 0 and figures["dem_hole_pixels"] == figures["dem_gap_pixels"] > 1000
    assert figures["dem_gap_pixels"] == pytest.approx(empty.sum(), rel=1e-3)
    assert figures["densification_error_px"] <= 0.01
    assert "on its nodata holes)" in caplog.text and "off its extent" not in caplog.text
    check = np.random.default_rng(0).integers(0, 2048, (2, 20_000))
    mapper = Mapper(scene, 0, holey, grid)
    col, row = mapper.exact(*check.astype(float))
    inside = footprint[check[0], check[1]]
    assert np.array_equal(np.isfinite(col)[inside], (read_band(str(tmp_path / "o.tif"))[check[0], check[1]] > 0)[inside])


def test_cancel_or_a_failure_midway_leaves_no_file(rendered, tmp_path, monkeypatch):
    scene, dem, frame, folder = rendered
    calls = []

    def cancel_after_three():
        calls.append(1)
        return len(calls) > 3
    with pytest.raises(Cancelled):
        orthorectify(scene, folder / "raw.tif", dem, tmp_path / "o.tif", is_cancelled=cancel_after_three)
    assert list(tmp_path.iterdir()) == []
    from pushbroom_adjust.core.products import resampling
    real = resampling._overview_blocks

    def fail_at_tile_five(*args, _n=[0]):
        _n[0] += 1
        if _n[0] == 5:
            raise RuntimeError("No space left on device")
        return real(*args)
    monkeypatch.setattr(resampling, "_overview_blocks", fail_at_tile_five)
    with pytest.raises(InputError, match=r"cannot write .*o.tif: no space left on the device holding .*o.tif"):
        orthorectify(scene, folder / "raw.tif", dem, tmp_path / "o.tif")
    assert list(tmp_path.iterdir()) == []


def test_overviews_are_means_of_the_valid_pixels(rendered, tmp_path):
    scene, dem, frame, folder = rendered
    out = tmp_path / "o.tif"
    orthorectify(scene, folder / "raw.tif", dem, out)
    ds = gdal.Open(str(out))
    band = ds.GetRasterBand(1)
    full = band.ReadAsArray().astype(float)
    for k in range(band.GetOverviewCount()):
        ovr = band.GetOverview(k)
        f = int(round(ds.RasterXSize / ovr.XSize))
        assert ovr.XSize == -(-ds.RasterXSize // f) and ovr.YSize == -(-ds.RasterYSize // f)
        h, w = ds.RasterYSize // f * f, ds.RasterXSize // f * f
        cells = full[:h, :w].reshape(h // f, f, w // f, f)
        count = (cells > 0).sum(axis=(1, 3))
        with np.errstate(invalid="ignore"):
            expected = np.where(count > 0, np.rint(cells.sum(axis=(1, 3)) / count), 0)
        got = ovr.ReadAsArray()[:h // f, :w // f]
        assert np.array_equal(got, expected), (f, np.abs(got - expected).max())


def test_every_band_and_data_type_is_kept(rendered, tmp_path):
    """A two-band 16-bit image gives a two-band 16-bit orthoimage whose bands are the single
    8-bit band's orthoimage transformed as the input bands were (nearest: exactly); a float band
    stays float; cubic overshoot of an integer band is clipped to the type's range."""
    scene, dem, frame, folder = rendered
    src = gdal.Open(str(folder / "raw.tif"))
    dn = src.GetRasterBand(1).ReadAsArray().astype(np.uint16)
    multi = tmp_path / "multi.tif"
    ds = gdal.GetDriverByName("GTiff").Create(str(multi), src.RasterXSize, src.RasterYSize, 2, gdal.GDT_UInt16)
    ds.GetRasterBand(1).WriteArray(dn * 200)
    ds.GetRasterBand(2).WriteArray(65535 - dn * 200)
    ds = None
    for name, kind in (("steps.tif", gdal.GDT_UInt16), ("steps_float.tif", gdal.GDT_Float32)):
        # sharp steps up to the 16-bit maximum: the cubic spline overshoots there
        ds = gdal.GetDriverByName("GTiff").Create(str(tmp_path / name), src.RasterXSize, src.RasterYSize, 1, kind)
        ds.GetRasterBand(1).WriteArray(np.where(dn > 127, 65535, 30000))
        ds = None
    orthorectify(scene, folder / "raw.tif", dem, tmp_path / "one.tif", resampling="nearest")
    orthorectify(scene, multi, dem, tmp_path / "two.tif", resampling="nearest")
    one, two = gdal.Open(str(tmp_path / "one.tif")), gdal.Open(str(tmp_path / "two.tif"))
    assert two.RasterCount == 2 and two.GetRasterBand(2).DataType == gdal.GDT_UInt16
    ref = one.GetRasterBand(1).ReadAsArray().astype(np.int64)
    valid = ref > 0
    assert valid.mean() > 0.2  # a 1200-row cut: a thin strip across its bounding box
    assert np.array_equal(two.GetRasterBand(1).ReadAsArray()[valid], ref[valid] * 200)
    assert np.array_equal(two.GetRasterBand(2).ReadAsArray()[valid], 65535 - ref[valid] * 200)
    assert np.all(two.GetRasterBand(2).ReadAsArray()[~valid] == 0)
    # an image beyond the memory budget is read window by window: the same orthoimage
    orthorectify(scene, multi, dem, tmp_path / "windows.tif", resampling="nearest", memory_budget=0)
    windows = gdal.Open(str(tmp_path / "windows.tif"))
    assert np.array_equal(windows.ReadAsArray(), two.ReadAsArray())
    for name in ("steps", "steps_float"):
        orthorectify(scene, tmp_path / f"{name}.tif", dem, tmp_path / f"cubic_{name}.tif", resampling="cubic")
    cubic, cubic_float = (gdal.Open(str(tmp_path / f"cubic_{n}.tif")) for n in ("steps", "steps_float"))
    u16 = cubic.GetRasterBand(1).ReadAsArray()[valid]
    f32 = cubic_float.GetRasterBand(1).ReadAsArray()[valid]
    assert u16.dtype == np.uint16 and f32.dtype == np.float32 and f32.max() > 70000  # overshoot happened
    assert np.array_equal(u16, np.clip(np.rint(f32), 0, 65535))  # rounded and clipped, never wrapped


def test_the_common_grid_of_several_is_their_overlap_on_their_lattice():
    utm = CRS.from_epsg(32636)
    a = OrthoGrid(utm, 1000.0, 5000.0, 0.5, 400, 300)   # x 1000-1200, y 4850-5000
    b = OrthoGrid(utm, 1050.5, 5020.0, 0.5, 500, 200)   # x 1050.5-1300.5, y 4920-5020
    g = common_grid([a, b])
    assert (g.x0, g.y0, g.resolution, g.cols, g.rows) == (1050.5, 5000.0, 0.5, 299, 160)
    assert g.crs.equals(utm)
    with pytest.raises(InputError, match="do not overlap"):
        common_grid([a, OrthoGrid(utm, 1300.0, 5000.0, 0.5, 10, 10)])
    with pytest.raises(InputError, match="CRS or resolution"):
        common_grid([a, OrthoGrid(utm, 1000.0, 5000.0, 1.0, 200, 150)])
    with pytest.raises(InputError, match="CRS or resolution"):
        common_grid([a, OrthoGrid(CRS.from_epsg(32637), 1000.0, 5000.0, 0.5, 400, 300)])
