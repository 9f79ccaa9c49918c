"""Ground points of a region of RPC products (:mod:`simulation.rpcregion`): drawn uniformly over the
union of the products' footprints on the DEM, projected through every true model that sees them,
and written as the tie-point and GCP tables the plugin imports.

Each product draws candidates uniformly in its footprint's bounding box and keeps those its own
image holds and no product before it sees (so the density is uniform over the union, overlaps not
counted twice); each kept point is projected through the products whose boxes meet the product's.
Loops run over products only; every array operation runs over all of a product's points at once.

Frames: (lon, lat) degrees, ellipsoidal heights (m), image coordinates GDAL (col, row) px.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..core.errors import InputError
from ..core.geodesy import ecef_to_geodetic
from ..core.model.rpcscene import RpcScene

EDGE_PX = 3.0        # true positions at least this far inside the image: noise keeps them in it
CHUNK = 200_000      # rows formatted and written at a time
MAX_PASSES = 4       # draws of candidates before giving up on the density asked for


@dataclass
class DrawnPoints:
    """Points (lon, lat, h: (n,)) and their noise-free observations: point (m,) index into the
    points, product (m,) index of the product, col, row (m,) px through its true model."""
    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    point: np.ndarray
    product: np.ndarray
    col: np.ndarray
    row: np.ndarray
    n_products: int

    @property
    def n_points(self) -> int:
        return int(self.lon.size)

    @property
    def n_observations(self) -> int:
        return int(self.point.size)

    def per_product(self) -> np.ndarray:
        """Observations (n_products,) of each product."""
        return np.bincount(self.product, minlength=self.n_products)

    def per_product_summary(self) -> dict:
        counts = self.per_product()
        return {"least": int(counts.min()), "median": float(np.median(counts)), "most": int(counts.max())}

    def keep(self, points: np.ndarray) -> "DrawnPoints":
        """The points of the sorted indices ``points`` and their observations, renumbered."""
        new = np.full(self.n_points, -1)
        new[points] = np.arange(points.size)
        m = new[self.point] >= 0
        return DrawnPoints(self.lon[points], self.lat[points], self.h[points], new[self.point[m]], self.product[m],
                           self.col[m], self.row[m], self.n_products)

    def columns(self, names: list[str], noise: float, rng: np.random.Generator, point_ids: np.ndarray) -> dict:
        """The tie-point CSV columns (:data:`simulation.measurements.TIE_COLUMNS`): camera and scene the
        product's name, col / row measured with ``noise`` px, the truth beside."""
        m = self.n_observations
        product = np.asarray(names)[self.product]
        return {"id": point_ids[self.point], "camera": product, "scene": product,
                "col": self.col + rng.normal(0.0, noise, m), "row": self.row + rng.normal(0.0, noise, m),
                "col_true": self.col, "row_true": self.row, "lon_true": self.lon[self.point],
                "lat_true": self.lat[self.point], "h_true": self.h[self.point], "gross": np.zeros(m, int)}

    def corner_points(self, bounds: tuple[float, float, float, float]) -> np.ndarray:
        """Indices of the points nearest the 4 corners of ``bounds`` (lon_min, lat_min, lon_max, lat_max)."""
        lon0, lat0, lon1, lat1 = bounds
        corners = np.array([[lon0, lat0], [lon1, lat0], [lon0, lat1], [lon1, lat1]])
        scale = np.array([math.cos(math.radians((lat0 + lat1) / 2)), 1.0])
        d = np.hypot(*((np.stack([self.lon, self.lat], 1)[None] - corners[:, None]) * scale).transpose(2, 0, 1))
        return np.unique(d.argmin(axis=1))

    def gcp_fields(self, control: np.ndarray, noise: float) -> dict:
        """The GCP columns a check/control table adds to :meth:`columns`: role (control for the
        points ``control``, else check), exact ground coordinates and the sigmas."""
        role = np.full(self.n_points, "check", dtype=object)
        role[control] = "control"
        m = self.n_observations
        return {"role": role[self.point].astype(str), "lon": self.lon[self.point], "lat": self.lat[self.point],
                "h": self.h[self.point], "sigma_px": np.full(m, max(noise, 1e-3)), "sigma_xy": np.full(m, 1e-3),
                "sigma_z": np.full(m, 1e-3)}


def ids(prefix: str, n: int) -> np.ndarray:
    """Point ids prefix1 .. prefix<n> (n,)."""
    return np.char.add(prefix, np.arange(1, n + 1).astype(str))


def boxes(scenes: list[RpcScene], heights: tuple[float, float]) -> np.ndarray:
    """(n, 4) lon_min, lat_min, lon_max, lat_max of each product's image corners (through its model,
    correction included) at both heights."""
    out = np.empty((len(scenes), 4))
    for k, scene in enumerate(scenes):
        cam = scene.camera
        col = np.tile([0.0, cam.cols, 0.0, cam.cols], 2)
        row = np.tile([0.0, 0.0, cam.rows, cam.rows], 2)
        h = np.repeat(heights, 4)
        lon, lat, _ = ecef_to_geodetic(scene.image_to_ground(col, row, h))
        out[k] = lon.min(), lat.min(), lon.max(), lat.max()
    return out


def neighbours(scenes: list[RpcScene], heights: tuple[float, float]) -> list[np.ndarray]:
    """For each product, the indices of the other products whose footprint boxes meet its own (all
    pairs at once: n^2 booleans, 9 M for 3,000 products)."""
    b = boxes(scenes, heights)
    meet = ((b[:, None, 0] <= b[None, :, 2]) & (b[None, :, 0] <= b[:, None, 2])
            & (b[:, None, 1] <= b[None, :, 3]) & (b[None, :, 1] <= b[:, None, 3]))
    np.fill_diagonal(meet, False)
    return [np.nonzero(row)[0] for row in meet]


def _inside(scene: RpcScene, col, row) -> np.ndarray:
    cam = scene.camera
    with np.errstate(invalid="ignore"):
        return (col >= EDGE_PX) & (col <= cam.cols - EDGE_PX) & (row >= EDGE_PX) & (row <= cam.rows - EDGE_PX)


def _draw_pass(scenes: list[RpcScene], near: list[np.ndarray], dem, box: np.ndarray, per_product: int,
               min_rays: int, rng: np.random.Generator, progress: Callable[[float], None],
               strip: np.ndarray | None) -> DrawnPoints:
    """One draw of ``per_product`` candidates in each product's box (see the module docstring);
    with ``strip`` (n_products,) only points seen by products of two strips or more."""
    parts: dict[str, list] = {k: [] for k in ("lon", "lat", "h", "point", "product", "col", "row")}
    base = 0
    for p, scene in enumerate(scenes):
        if p % 50 == 0:
            progress(p / len(scenes))
        lon = rng.uniform(box[p, 0], box[p, 2], per_product)
        lat = rng.uniform(box[p, 1], box[p, 3], per_product)
        h = dem.height(lon, lat)
        if not np.all(np.isfinite(h)):
            raise InputError(f"product {p + 1}: {int((~np.isfinite(h)).sum())} points fall off the region's DEM")
        col, row = scene.ground_to_image_geodetic(lon, lat, h)
        mine = _inside(scene, col, row)
        lon, lat, h, col, row = lon[mine], lat[mine], h[mine], col[mine], row[mine]
        owned, count, other = np.ones(lon.size, bool), np.ones(lon.size, int), np.zeros(lon.size, bool)
        seen = [(p, np.ones(lon.size, bool), col, row)]
        for q in near[p]:
            cq, rq = scenes[q].ground_to_image_geodetic(lon, lat, h)
            inq = _inside(scenes[q], cq, rq)
            if q < p:
                owned &= ~inq
            count += inq
            if strip is not None and strip[q] != strip[p]:
                other |= inq
            seen.append((q, inq, cq, rq))
        kept = owned & (count >= min_rays) & (other if strip is not None else True)
        number = np.cumsum(kept) - 1 + base
        for q, inq, cq, rq in seen:
            m = inq & kept
            parts["point"].append(number[m])
            parts["product"].append(np.full(int(m.sum()), q))
            parts["col"].append(cq[m])
            parts["row"].append(rq[m])
        for k, v in (("lon", lon), ("lat", lat), ("h", h)):
            parts[k].append(v[kept])
        base += int(kept.sum())
    arrays = {k: np.concatenate(v) for k, v in parts.items()}
    order = np.argsort(arrays["point"], kind="stable")  # a point's observations together, products in order
    return DrawnPoints(arrays["lon"], arrays["lat"], arrays["h"], arrays["point"][order], arrays["product"][order],
                       arrays["col"][order], arrays["row"][order], len(scenes))


def _joined(parts: list[DrawnPoints]) -> DrawnPoints:
    offsets = np.cumsum([0] + [d.n_points for d in parts[:-1]])
    return DrawnPoints(*(np.concatenate([getattr(d, k) for d in parts]) for k in ("lon", "lat", "h")),
                       np.concatenate([d.point + o for d, o in zip(parts, offsets)]),
                       *(np.concatenate([getattr(d, k) for d in parts]) for k in ("product", "col", "row")),
                       parts[0].n_products)


def draw_points(scenes: list[RpcScene], near: list[np.ndarray], dem, per_product: int, min_rays: int,
                rng: np.random.Generator, progress: Callable[[float], None],
                points_per_product: float | None = None, strip: np.ndarray | None = None) -> DrawnPoints:
    """Points seen by ``min_rays`` products or more, uniform over the region, with ``per_product``
    observations per product on average (or, with ``points_per_product``, that many points per
    product in all): candidates drawn until there are enough (at most MAX_PASSES draws), then a
    random subset kept. ``near``: :func:`neighbours`; ``dem``: heights (ellipsoidal m) at (lon, lat);
    ``strip`` (n_products,): only points seen by products of two strips or more (None: all)."""
    n = len(scenes)
    want = per_product if points_per_product is None else points_per_product
    if want == 0 or n == 0:
        return DrawnPoints(*(np.zeros(0),) * 3, *(np.zeros(0, int),) * 2, *(np.zeros(0),) * 2, n)
    heights = tuple(scenes[0].height_range)
    box = boxes(scenes, heights)
    parts, draw, drawn_total = [], per_product, 0
    for k in range(MAX_PASSES):
        parts.append(_draw_pass(scenes, near, dem, box, draw, min_rays, rng,
                                lambda f, k=k: progress((k + f) / MAX_PASSES), strip))
        drawn_total += draw
        drawn = _joined(parts)
        have = drawn.n_observations / n if points_per_product is None else drawn.n_points / n
        if have >= want:
            break
        # candidates per product still needed at the yield so far, 10 % spare
        yield_ = max(have / drawn_total, 1e-3)
        draw = int(min(math.ceil(1.1 * (want - have) / yield_), 20 * per_product))
    else:
        what = "tie observations" if points_per_product is None else "points"
        raise InputError(f"the products overlap too little for {want} {what} per product ({have:.0f} after "
                         f"{MAX_PASSES} draws)", parameter="ties_per_product")
    share = want / have
    keep = np.sort(rng.choice(drawn.n_points, int(round(drawn.n_points * share)), replace=False))
    return drawn.keep(keep)


def write_columns(path: Path, columns: tuple[str, ...], data: dict) -> None:
    """CSV of parallel arrays with a header, CHUNK rows at a time: degrees to 1e-10 (1e-5 m), px to
    1e-6, metres to 1e-4; text and whole numbers as they are. (Formatting is per value: numpy has
    no faster float-to-text; a million rows of 11 columns take about 5 s.)"""
    formats = {"lon": ".10f", "lat": ".10f", "lon_true": ".10f", "lat_true": ".10f", "h": ".4f", "h_true": ".4f"}
    n = len(data[columns[0]])
    with Path(path).open("w", newline="") as f:
        f.write(",".join(columns) + "\n")
        for start in range(0, n, CHUNK):
            cells = []
            for c in columns:
                v = np.asarray(data[c])[start:start + CHUNK]
                if v.dtype.kind in "UOSi":
                    cells.append(v.astype(str).tolist())
                else:
                    spec = formats.get(c, ".6f")
                    cells.append([format(x, spec) for x in v.tolist()])
            f.write("\n".join(map(",".join, zip(*cells))) + "\n")
