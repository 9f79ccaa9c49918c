"""Simulated roads: control lines with known truth for :func:`simulation.simulator.simulate`.

A road is a smooth curve on the ground, defined in the texture plane of :mod:`simulation.texture`
(x east, y north, metres about the texture centre) by its centre (x0, y0), its azimuth at the
centre (rad, clockwise from north), its length (m) and a curvature varying linearly along it:
kappa(s) = k0 + k1 s (1/m, s from -length/2 to length/2; k0 = k1 = 0 for a straight road).
It lies on the terrain (heights from the DEM). From each road the simulator writes:

- the **road map** (layer ``ground_lines`` of ``lines.gpkg``, see :mod:`core.observations.lines`): the road
  with a vertex every ``vertex_spacing`` m, horizontal noise ``map_sigma`` and height noise
  ``map_sigma_h``; a share ``wrong_fraction`` of the lines is wrong as a real map's can be:
  shifted as a whole by 20-200 m ('shifted'), or turned about a point of the road so that it
  ends 20-200 m off ('rotated'), each with its kind and largest displacement (m) in the
  fields ``kind`` and ``shift_m`` (truth, not read by the adjustment);
- its **image lines** in every camera that sees it (layer ``image_lines``): points along the
  road's true image (true scene, ground -> image) with noise ``image_noise`` px; and the
  same points as a user's **clicks** with ``click_noise`` px error (layer ``image_clicks``);
- ``line_points.csv``: per image point the measured, clicked and true (col, row) and the
  true ground point (lon, lat, ellipsoidal h).

With rendering, the roads are drawn into the raw images as bright bands ``width`` GSD wide
(:class:`RoadPainter`, called by :func:`simulation.render.render_image`), centred on the true road,
so snapping is tested on pixels.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..core.errors import InputError
from ..core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from ..core.observations.lines import GroundLines, ImageLines, image_layer, write_gpkg
from .measurements import write_csv
from .texture import plane_to_lonlat, texture_frame, texture_plane

LINES_FILE = "lines.gpkg"
POINTS_FILE = "line_points.csv"
CLICKS_LAYER = "image_clicks"
FINE_STEP = 0.5   # m: integration step of road curves
POINT_COLUMNS = ("line_id", "camera", "col", "row", "col_click", "row_click", "col_true", "row_true", "lon_true",
                 "lat_true", "h_true")


@dataclass(frozen=True)
class RoadSettings:
    """How roads are simulated. n_lines: roads; length (m, (min, max)); curved_fraction: share
    of curved roads; wrong_fraction: share of wrong map lines, off by shift_min..shift_max m;
    map_sigma, map_sigma_h (m): map noise (also the lines' stated sigmas); vertex_spacing (m);
    points: image points per road and camera; image_noise, click_noise (px); width (GSD) and
    brightness (0..1) of the rendered road."""
    n_lines: int = 0
    length: tuple[float, float] = (2000.0, 6000.0)
    curved_fraction: float = 0.5
    wrong_fraction: float = 0.0
    shift_min: float = 20.0
    shift_max: float = 200.0
    map_sigma: float = 1.0
    map_sigma_h: float = 2.0
    vertex_spacing: float = 50.0
    points: int = 12
    image_noise: float = 0.5
    click_noise: float = 2.0
    width: float = 3.0
    brightness: float = 0.95

    def validate(self) -> None:
        if not 0 <= self.n_lines <= 10000:
            raise InputError(f"n_lines must be between 0 and 10000 (got {self.n_lines})")
        for name in ("curved_fraction", "wrong_fraction", "brightness"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise InputError(f"{name} must be between 0 and 1 (got {getattr(self, name)})")
        for name in ("map_sigma", "map_sigma_h", "image_noise", "click_noise"):
            if not getattr(self, name) > 0:
                raise InputError(f"{name} must be > 0 (got {getattr(self, name)})")
        if not (0 < self.shift_min <= self.shift_max and 0 < self.length[0] <= self.length[1]
                and self.vertex_spacing > 0 and self.points >= 2 and self.width > 0):
            raise InputError("road settings: need 0 < shift_min <= shift_max, 0 < length min <= max, "
                             "vertex_spacing > 0, points >= 2 and width > 0")


def road_curve(road: dict, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Plane coordinates (x, y) (n,) m of a road's centre line sampled every ~spacing m (the
    same curve whatever the spacing: integrated on a fine step, then sampled)."""
    n = max(int(math.ceil(road["length"] / spacing)) + 1, 2)
    fine = max(int(math.ceil(road["length"] / min(spacing, FINE_STEP))) + 1, 2)
    s = np.linspace(-0.5 * road["length"], 0.5 * road["length"], fine)
    heading = road["azimuth"] + road["k0"] * s + 0.5 * road["k1"] * s * s
    ds = s[1] - s[0]
    # trapezoidal integration of the unit tangent; the road's centre (s = 0) at (x0, y0)
    dx, dy = np.sin(heading), np.cos(heading)
    x = np.r_[0.0, np.cumsum(0.5 * (dx[1:] + dx[:-1]) * ds)]
    y = np.r_[0.0, np.cumsum(0.5 * (dy[1:] + dy[:-1]) * ds)]
    x, y = x - np.interp(0.0, s, x), y - np.interp(0.0, s, y)
    at = np.linspace(s[0], s[-1], n)
    return road["x0"] + np.interp(at, s, x), road["y0"] + np.interp(at, s, y)


def draw_roads(scene, dem, settings: RoadSettings, centre, rng: np.random.Generator) -> list[dict]:
    """Road definitions (see the module docstring) centred at random points of camera 0's image."""
    cam = scene.cameras[0]
    n = settings.n_lines
    col = rng.uniform(0.1, 0.9, n) * cam.cols
    row = rng.uniform(0.1, 0.9, n) * cam.rows
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground_dem(col, row, dem, 0))
    x0, y0 = texture_plane(lon, lat, centre)
    length = rng.uniform(*settings.length, n)
    curved = rng.uniform(0.0, 1.0, n) < settings.curved_fraction
    k0 = np.where(curved, rng.choice([-1.0, 1.0], n) * rng.uniform(1 / 8000.0, 1 / 2000.0, n), 0.0)
    k1 = np.where(curved, rng.uniform(-1.0, 1.0, n) * np.abs(k0) / length, 0.0)
    azimuth = rng.uniform(0.0, math.pi, n)
    return [{"id": f"R{i + 1}", "x0": float(x0[i]), "y0": float(y0[i]), "azimuth": float(azimuth[i]),
             "length": float(length[i]), "k0": float(k0[i]), "k1": float(k1[i])} for i in range(n)]


def _map_line(road: dict, settings: RoadSettings, wrong: str, rng) -> tuple[np.ndarray, np.ndarray, float]:
    """(x, y) of a road's map line and its largest displacement (m) from the road."""
    x, y = road_curve(road, settings.vertex_spacing)
    x = x + rng.normal(0.0, settings.map_sigma, x.size)
    y = y + rng.normal(0.0, settings.map_sigma, y.size)
    size = rng.uniform(settings.shift_min, settings.shift_max)
    if wrong == "shifted":
        angle = rng.uniform(0.0, 2 * math.pi)
        return x + size * math.sin(angle), y + size * math.cos(angle), size
    if wrong == "rotated":
        k = int(rng.integers(0, x.size))
        reach = float(np.max(np.hypot(x - x[k], y - y[k])))
        turn = rng.choice([-1.0, 1.0]) * 2.0 * math.asin(min(size / (2.0 * reach), 1.0))
        c, s = math.cos(turn), math.sin(turn)
        return x[k] + c * (x - x[k]) + s * (y - y[k]), y[k] - s * (x - x[k]) + c * (y - y[k]), size
    return x, y, 0.0


def simulate_roads(true_scene, dem, settings: RoadSettings, seed: int, folder, files) -> dict:
    """Draw the roads, write ``lines.gpkg`` and ``line_points.csv`` into ``folder`` (through the
    :class:`core.files.OutputSet` ``files``); returns the manifest entry {settings, centre,
    roads (with kind and shift_m)} that :class:`RoadPainter` renders."""
    settings.validate()
    rng = np.random.default_rng([seed, 11])  # its own stream: the other outputs do not change with roads
    frame = texture_frame(true_scene, dem, seed)
    centre = tuple(frame["centre"])
    roads = draw_roads(true_scene, dem, settings, centre, rng)
    kinds = np.full(len(roads), "", dtype=object)
    n_wrong = int(round(settings.wrong_fraction * len(roads)))
    picked = rng.choice(len(roads), n_wrong, replace=False)
    kinds[picked] = np.where(np.arange(n_wrong) % 2 == 0, "shifted", "rotated")
    parts, shifts = [], []
    for road, kind in zip(roads, kinds):
        x, y, shift = _map_line(road, settings, kind, rng)
        lon, lat = plane_to_lonlat(x, y, centre)
        parts.append(np.stack([lon, lat, dem.height(lon, lat) + rng.normal(0.0, settings.map_sigma_h, x.size)], 1))
        road["kind"], road["shift_m"] = kind or "correct", shift
        shifts.append(shift)
    ground = GroundLines([r["id"] for r in roads], np.r_[0, np.cumsum([len(p) for p in parts])],
                         *np.concatenate(parts).T, settings.map_sigma, settings.map_sigma_h)
    points = _image_points(true_scene, dem, roads, settings, centre, rng)
    measured, clicks = (_image_lines(points, k, s) for k, s in (("", settings.image_noise),
                                                                ("_click", settings.click_noise)))
    clicks_layer = image_layer(clicks)
    clicks_layer.name = CLICKS_LAYER
    write_gpkg(files.path(folder / LINES_FILE), ground, measured,
               extra_ground={"kind": np.array([r["kind"] for r in roads]), "shift_m": np.array(shifts)},
               extra_layers=[clicks_layer], files=None)
    write_csv(files.path(folder / POINTS_FILE), POINT_COLUMNS, points)
    return {"settings": asdict(settings), "centre": list(centre), "gsd_m": frame["gsd_m"], "roads": roads}


def _image_points(scene, dem, roads, settings: RoadSettings, centre, rng) -> dict:
    """Columns of the image points: ``points`` evenly along each road, in every camera that
    sees at least two of them, with measured and clicked positions."""
    cols = {k: [] for k in POINT_COLUMNS}
    for road in roads:
        x, y = road_curve(road, road["length"] / (settings.points - 1))
        lon, lat = plane_to_lonlat(x, y, centre)
        h = dem.height(lon, lat)
        xyz = geodetic_to_ecef(lon, lat, h)
        for k, cam in enumerate(scene.cameras):
            col, row = scene.ground_to_image(xyz, k)
            inside = np.isfinite(col) & (col > 0) & (col < cam.cols) & (row > 0) & (row < cam.rows)
            if inside.sum() < 2:
                continue
            m = int(inside.sum())
            for key, value in (("line_id", [road["id"]] * m), ("camera", [cam.name] * m), ("col_true", col[inside]),
                               ("row_true", row[inside]), ("lon_true", lon[inside]), ("lat_true", lat[inside]),
                               ("h_true", h[inside])):
                cols[key].append(np.asarray(value))
    out = {k: np.concatenate(v) if v else np.zeros(0) for k, v in cols.items() if k in cols and v}
    n = out["col_true"].size if out else 0
    if n == 0:
        raise InputError("no simulated road is seen in any image")
    for suffix, sigma in (("", settings.image_noise), ("_click", settings.click_noise)):
        out[f"col{suffix}"] = out["col_true"] + rng.normal(0.0, sigma, n)
        out[f"row{suffix}"] = out["row_true"] + rng.normal(0.0, sigma, n)
    return out


def _image_lines(points: dict, suffix: str, sigma: float) -> ImageLines:
    """Image lines of one (line_id, camera) each from the points' columns col<suffix>, row<suffix>."""
    key = np.char.add(np.char.add(points["line_id"].astype(str), "\x00"), points["camera"].astype(str))
    change = np.r_[True, key[1:] != key[:-1]]
    first = np.nonzero(change)[0]
    return ImageLines(points["line_id"][first], points["camera"][first], np.r_[first, key.size],
                      points[f"col{suffix}"], points[f"row{suffix}"], sigma)


class RoadPainter:
    """Draws roads (a manifest entry of :func:`simulate_roads`) over texture values: a bright
    band ``width`` GSD wide with soft edges (half a GSD), symmetric about the road's centre."""

    def __init__(self, entry: dict, gsd: float):
        spacing = 0.5 * gsd
        curves = [np.stack(road_curve(r, spacing), axis=1) for r in entry["roads"]]
        self.points = np.concatenate(curves)
        ends = np.cumsum([len(c) for c in curves])
        idx = np.arange(self.points.shape[0])
        starts = np.r_[0, ends[:-1]]
        road = np.repeat(np.arange(len(curves)), [len(c) for c in curves])
        self.prev = np.maximum(idx - 1, starts[road])
        self.next = np.minimum(idx + 1, ends[road] - 1)
        self.tree = cKDTree(self.points)
        settings = entry["settings"]
        self.half = 0.5 * settings["width"] * gsd
        self.soft = 0.5 * gsd
        self.reach = self.half + 4.0 * self.soft
        self.brightness = settings["brightness"]
        # occupancy of coarse cells (a cheap test before the tree is queried)
        self.cell = max(self.reach, spacing) * 2.0
        self.origin = self.points.min(axis=0) - 2 * self.cell
        ij = np.floor((self.points - self.origin) / self.cell).astype(np.int64)
        shape = ij.max(axis=0) + 3
        occ = np.zeros(tuple(shape), bool)
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                occ[ij[:, 0] + di, ij[:, 1] + dj] = True
        self.occupied = occ

    def distance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Distance (m) of plane points (any shape) to the nearest road; inf beyond reach."""
        out = np.full(x.shape, np.inf)
        i = np.floor((x - self.origin[0]) / self.cell).astype(np.int64)
        j = np.floor((y - self.origin[1]) / self.cell).astype(np.int64)
        ok = (i >= 0) & (j >= 0) & (i < self.occupied.shape[0]) & (j < self.occupied.shape[1])
        ok[ok] = self.occupied[i[ok], j[ok]]
        if not ok.any():
            return out
        p = np.stack([x[ok], y[ok]], axis=1)
        _, k = self.tree.query(p, distance_upper_bound=self.reach + self.cell)
        found = k < self.points.shape[0]
        k = k[found]
        q = p[found]
        d = np.minimum(_segment_distance(q, self.points[self.prev[k]], self.points[k]),
                       _segment_distance(q, self.points[k], self.points[self.next[k]]))
        sub = out[ok]
        sub[found] = d
        out[ok] = sub
        return out

    def paint(self, x: np.ndarray, y: np.ndarray, value: np.ndarray) -> np.ndarray:
        """Texture values (same shape as x, y) with the roads drawn over them."""
        alpha = 0.5 * (1.0 - np.tanh((self.distance(x, y) - self.half) / self.soft))
        return value * (1.0 - alpha) + self.brightness * alpha


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances (n,) of points p (n,2) to segments a -> b (n,2) (a point when a == b)."""
    d = b - a
    dd = np.einsum("ni,ni->n", d, d)
    t = np.clip(np.einsum("ni,ni->n", p - a, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    return np.linalg.norm(p - a - t[:, None] * d, axis=1)


def painter_for(frame: dict) -> RoadPainter | None:
    """The painter of a texture frame's roads (``frame['roads']``), None without roads."""
    entry = frame.get("roads")
    return RoadPainter(entry, float(frame["gsd_m"])) if entry and entry.get("roads") else None

