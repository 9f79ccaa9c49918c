"""core.measure.matching and simulation.reference on a small rendered scene with known truth (tests/matchscene.py)."""
import numpy as np
import pytest
from osgeo import gdal
from pyproj import CRS, Transformer

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.measure.correlation import find_peaks, masked_ncc, ncc, sample
from pushbroom_adjust.core.measure.lsm import refine
from pushbroom_adjust.core.measure.finepass import SIGMA_FLOOR
from pushbroom_adjust.core.measure.matching import REASONS, MatchSettings, match_gcps
from pushbroom_adjust.simulation.texture import texture_at
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.measure.tiematching import match_tiepoints
from tests.support.matchscene import SEARCH, manifest, mini_scene, mini_tlc_scene, true_errors


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    return mini_scene(tmp_path_factory.mktemp("mini"))


@pytest.fixture(scope="module")
def matched(mini):
    scene = load_scene(mini.onboard_scene)
    return match_gcps(scene, 0, mini.images["HRC"], mini.reference, Dem(mini.dem, "geoid"),
                      MatchSettings(spacing=60, search=SEARCH))


def test_ncc_recovers_a_known_subpixel_shift():
    yy, xx = np.mgrid[0:47, 0:47].astype(float)
    shift = np.array([[2.3, -1.7], [-4.6, 3.2], [0.0, 0.5]])  # (dx, dy) of the search content
    search = np.stack([texture_at(xx * 1e-5, yy * 1e-5, (0.0, 0.0), 0.3, 4) for _ in shift]) * 200
    templates = np.stack([texture_at((xx[8:39, 8:39] + dx) * 1e-5, (yy[8:39, 8:39] + dy) * 1e-5, (0.0, 0.0), 0.3, 4)
                          for dx, dy in shift]) * 200
    peaks = find_peaks(ncc(templates, search), 4)
    # the template taken at (8 + d) of the search is found at offset 8 + d
    np.testing.assert_allclose(peaks.dx - 8, shift[:, 0], atol=0.08)
    np.testing.assert_allclose(peaks.dy - 8, shift[:, 1], atol=0.08)
    assert np.all(peaks.value > 0.9) and not peaks.border.any()


def _texture(shape, seed: int = 4) -> np.ndarray:
    """A band-limited texture (DN) of ``shape``: the simulator's, sampled at 1 px = 1e-5 units."""
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    return 200 * texture_at(xx * 1e-5, yy * 1e-5, (0.0, 0.0), 0.3, seed)


def test_least_squares_matching_recovers_shift_gain_and_offset():
    """Chips of a texture moved by known sub-pixel shifts (up to 1.2 px from where the search starts),
    their grey values scaled and offset (another date's radiometry) and noise added: the fit finds
    each shift to 0.02 px and the gain and offset."""
    image = _texture((160, 160)).astype(np.float32)
    w = 31
    k = np.arange(w) - (w - 1) / 2
    uu, vv = np.meshgrid(k, k)
    start = np.array([[50.0, 60.0], [80.0, 90.0], [110.0, 70.0], [70.0, 110.0]])     # (x, y)
    shift = np.array([[0.3, -0.7], [1.2, 0.4], [-0.45, 0.05], [0.0, 0.0]])
    gain, offset = np.array([0.6, 1.7, 1.0, 0.8]), np.array([40.0, -25.0, 0.0, 12.0])
    x, y = start[:, 0] + shift[:, 0], start[:, 1] + shift[:, 1]
    chips = offset[:, None, None] + gain[:, None, None] * sample(image, 0, 0, x[:, None, None] + uu,
                                                                  y[:, None, None] + vv)
    chips += np.random.default_rng(2).normal(0.0, 0.5, chips.shape)
    fit = refine(chips, image, 0, 0, start[:, 0], start[:, 1])
    assert fit.converged.all()
    np.testing.assert_allclose(fit.x, x, atol=0.02)
    np.testing.assert_allclose(fit.y, y, atol=0.02)
    # the chip is T = offset + gain G, so the fit's G -> T map is the same
    np.testing.assert_allclose(fit.gain, gain, rtol=0.02)
    np.testing.assert_allclose(fit.offset, offset, atol=2.0)
    assert np.all(fit.sigma < 0.02) and np.all(np.abs(fit.affine) < 0.005)


def test_least_squares_matching_recovers_an_affine_window():
    """A chip sheared and stretched by 5 % (a slope's parallax the models leave): the affine terms
    find it, and the centre is still found to 0.02 px."""
    image = _texture((160, 160), seed=7).astype(np.float32)
    w = 31
    k = np.arange(w) - (w - 1) / 2
    uu, vv = np.meshgrid(k, k)
    a = np.array([[0.05, 0.03], [-0.02, 0.04]])
    x, y = 80.4, 79.7
    chip = sample(image, 0, 0, x + (1 + a[0, 0]) * uu + a[0, 1] * vv, y + a[1, 0] * uu + (1 + a[1, 1]) * vv)
    fit = refine(chip[None], image, 0, 0, np.array([80.0]), np.array([80.0]))
    assert fit.converged[0]
    assert abs(fit.x[0] - x) < 0.02 and abs(fit.y[0] - y) < 0.02
    np.testing.assert_allclose(fit.affine[0], a, atol=0.005)


def test_a_chip_without_its_match_does_not_converge():
    """The chip's texture is not in the image at all (another texture): the fit moves away from the
    start or ends with a gain at 0, and says so rather than returning a position."""
    image = _texture((160, 160), seed=4).astype(np.float32)
    chip = _texture((31, 31), seed=11)[None]
    fit = refine(chip, image, 0, 0, np.array([80.0]), np.array([80.0]))
    assert not fit.converged[0]


def test_masked_correlation_finds_an_offset_through_holes():
    """A template with a hole (nodata) and an image that holds the template's content at a known
    place, half of it outside the image's data: the masked correlation's peak is there, 1.0 where
    the two overlap; placements of tiny overlap are not considered."""
    ground = _texture((200, 260))
    template = ground[60:140, 70:170].copy()
    template[10:30, 10:40] = np.nan
    image = np.full((200, 260), np.nan)
    image[:, :120] = ground[:, :120]                     # the image holds only the ground's left part
    c, overlap = masked_ncc(template, image, 500)
    i, j = np.unravel_index(np.argmax(c), c.shape)
    assert (i, j) == (60, 70) and c[i, j] > 0.999
    assert overlap[i, j] == np.isfinite(template[:, :50]).sum()   # the template's columns 0-49 over the data
    assert np.all(c[overlap < 500] == -1.0)


def test_the_matchers_second_peak_is_a_peak_not_the_flank_of_the_first():
    """A single broad peak (smooth, oversampled images) whose flank stays high 3-6 px out has no
    second local maximum, while its plain second value (what snapping asks for) is high; a separate
    bump of 0.9 is a second peak either way."""
    yy, xx = np.mgrid[-8:9, -8:9].astype(float)
    broad = np.exp(-(xx ** 2 + yy ** 2) / (2 * 6.0 ** 2))
    bump = broad + 0.9 * np.exp(-((xx - 6) ** 2 + yy ** 2) / 2) * (1 - broad)
    local, plain = find_peaks(np.stack([broad, bump]), 2, local=True), find_peaks(np.stack([broad, bump]), 2)
    assert local.ratio[0] < 0.5 and 0.85 < local.ratio[1] < 1.0 and plain.ratio[0] > 0.85
    assert not local.border.any() and np.allclose(local.dx, [8, 8], atol=0.3)


def test_reference_shows_the_rendered_ground_at_its_geotransform(mini):
    frame = manifest(mini.folder)["texture"]
    info = frame["reference"]
    ds = gdal.Open(str(mini.reference))
    gt, a = ds.GetGeoTransform(), ds.ReadAsArray().astype(float)
    assert gt[1] == 5.0 and list(gt) == info["geotransform"]
    crs = CRS.from_wkt(ds.GetProjection())
    assert crs.to_epsg() == 32600 + int((frame["centre"][0] + 180) // 6) + 1  # the UTM zone of the centre
    rng = np.random.default_rng(0)
    i, j = rng.integers(0, a.shape[0], 4000), rng.integers(0, a.shape[1], 4000)
    x, y = gt[0] + (j + 0.5) * gt[1], gt[3] + (i + 0.5) * gt[5]
    lon, lat = Transformer.from_crs(crs, CRS.from_epsg(4326), always_xy=True).transform(x, y)
    expected = texture_at(lon, lat, frame["centre"], frame["gsd_m"], frame["seed"])
    s = info["settings"]
    changed = np.zeros(i.size, bool)
    for cx, cy, r in info["changed_discs_utm_m"] + info["cloud_discs_utm_m"]:
        changed |= np.hypot(x - cx, y - cy) < r
    dn = s["offset"] + s["gain"] * (20 + 215 * expected ** s["gamma"])
    diff = a[i, j] - dn
    # the blur (0.6 px) and noise (2 DN) make the difference; patches differ wholly
    assert np.median(np.abs(diff[~changed])) < 4.0
    assert np.median(np.abs(diff[changed])) > 8.0
    assert 0.02 < changed.mean() < 0.15


def test_matched_gcps_are_accurate_against_the_truth(mini, matched):
    e = true_errors(mini.folder, matched.table)
    assert len(matched.table) >= 400
    assert np.median(e) <= 0.1
    assert np.mean(e > 1.0) <= 0.03
    # every grid point is either matched or counted under one reason
    assert sum(matched.rejected.values()) + len(matched.table) == matched.grid_points
    assert set(matched.rejected) == set(REASONS)
    assert matched.rejected["low correlation"] > 0  # clouds and changed land cover are seen
    assert np.all(matched.table.sigma_px >= SIGMA_FLOOR) and np.all(matched.quality >= 0.6)
    # the onboard model is ~200 m off: the matches found it, not a local optimum near zero
    assert np.hypot(*np.median(matched.offset, axis=0)) > 50


def test_sigma_and_quality_rank_the_errors(mini, matched):
    """Points the matcher calls weaker (lower correlation) are really less accurate."""
    e = true_errors(mini.folder, matched.table)
    weak = matched.quality < np.median(matched.quality)
    assert np.median(e[weak]) > np.median(e[~weak])


def test_an_onboard_error_beyond_the_search_range_is_named(mini):
    scene = load_scene(mini.onboard_scene)
    with pytest.raises(InputError, match="increase the search range"):
        match_gcps(scene, 0, mini.images["HRC"], mini.reference, Dem(mini.dem, "geoid"),
                   MatchSettings(spacing=60, search=60.0))


def test_grid_count_and_settings_are_checked(mini):
    scene = load_scene(mini.onboard_scene)
    with pytest.raises(InputError, match="window"):
        match_gcps(scene, 0, mini.images["HRC"], mini.reference, Dem(mini.dem, "geoid"), MatchSettings(window=30))
    few = match_gcps(scene, 0, mini.images["HRC"], mini.reference, Dem(mini.dem, "geoid"),
                     MatchSettings(count=100, search=SEARCH))
    assert 70 <= few.grid_points <= 130


def test_tie_points_between_the_three_cameras_of_a_line_scanner(tmp_path):
    """TH-1-like three-line scene: FWD and BWD (+-25 deg) matched to NAD in NAD's geometry; each
    observation against the true scene's projection of the NAD point's true ground."""
    sim = mini_tlc_scene(tmp_path)
    onboard, true, dem = load_scene(sim.onboard_scene), load_scene(sim.true_scene), Dem(sim.dem, "geoid")
    images = {k: sim.images[c.name] for k, c in enumerate(onboard.cameras)}
    table, rejected = match_tiepoints(onboard, images, dem, MatchSettings(spacing=50, search=300.0))
    base = table.camera == "NAD"
    where = {i: k for k, i in enumerate(table.id[base])}
    assert np.unique(table.id[base]).size == base.sum()  # one NAD observation per tie point
    for k, name in ((1, "FWD"), (2, "BWD")):
        sel = table.camera == name
        b = np.array([where[i] for i in table.id[sel]])
        ground = true.image_to_ground_dem(table.col[base][b], table.row[base][b], dem, 0)
        col, row = true.ground_to_image(ground, k)
        e = np.hypot(col - table.col[sel], row - table.row[sel])
        assert sel.sum() >= 400 and np.median(e) <= 0.1 and np.mean(e > 1) <= 0.03, (name, np.median(e))
        assert sum(rejected[name].values()) + sel.sum() == 667  # every grid point (23 x 29) matched or counted
