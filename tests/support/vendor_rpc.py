"""A Maxar scene's rigorous model against the RPB that comes with it: image points of a grid put
on the ground by the RPB at three heights, and the distance of the model's projections from them."""
import numpy as np

from pushbroom_adjust.core.formats.maxar import read_maxar_rpc
from pushbroom_adjust.core.formats.vendor_xml import parse_xml
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import geodetic_to_ecef


def rpb_grid(path, n=15):
    """(scene, rpc, ground points (3 n n, 3) ECEF, RPB col, RPB row): n x n image points at the
    lowest, middle and highest height of the RPB, put on the ground by the RPB."""
    scene, rpc = load_scene(path), read_maxar_rpc(path)
    cam = scene.cameras[0]
    c, r = (a.ravel() for a in np.meshgrid(np.linspace(0.5, cam.cols - 0.5, n), np.linspace(0.5, cam.rows - 0.5, n)))
    lo, hi = scene.info["height_range"]
    ground, cols, rows = [], [], []
    for h in (lo, 0.5 * (lo + hi), hi):
        lon, lat = rpc.image_to_ground(c, r, h)
        ground.append(geodetic_to_ecef(lon, lat, h))
        cols.append(c)
        rows.append(r)
    return scene, rpc, np.concatenate(ground), np.concatenate(cols), np.concatenate(rows)


def projected(scene, ground, aberration=True, refraction=True):
    """The scene's ground_to_image (col, row) with the corrections switched as given."""
    scene.aberration, scene.refraction = aberration, refraction
    scene.clear_guesses()
    try:
        c, r = scene.ground_to_image(ground)
    finally:
        scene.aberration = scene.refraction = True
        scene.clear_guesses()
    assert np.all(np.isfinite(c)) and np.all(np.isfinite(r))
    return c, r


def misfit(scene, ground, col, row, aberration=True, refraction=True):
    """(max, RMS) px distance between the scene's ground_to_image and the RPB image points."""
    c, r = projected(scene, ground, aberration, refraction)
    d = np.hypot(c - col, r - row)
    return d.max(), np.sqrt(np.mean(d * d))


def imd_corner_misses(path, scene) -> dict[str, float]:
    """Per IMD corner (UL, UR, LR, LL) of the Maxar file ``path``: the distance (px) between the
    scene's projection of the corner's coordinates and the corner pixel's centre (the IMD corners are
    the centres of the corner pixels, 0-based vendor (0, 0) ... (cols-1, rows-1): GDAL half-integers)."""
    band = parse_xml(path).find("IMD/BAND_P")
    cam = scene.cameras[0]
    expected = {"UL": (0.5, 0.5), "UR": (cam.cols - 0.5, 0.5), "LR": (cam.cols - 0.5, cam.rows - 0.5),
                "LL": (0.5, cam.rows - 0.5)}
    out = {}
    for corner, (c, r) in expected.items():
        lon, lat, h = (float(band.findtext(corner + k)) for k in ("LON", "LAT", "HAE"))
        col, row = scene.ground_to_image_geodetic(lon, lat, h)
        out[corner] = float(np.hypot(col[0] - c, row[0] - r))
    return out
