"""The relief between the nodes of an orthoimage's mapping (:mod:`core.products.mapping`).

The exact image position of an output pixel is the scene's ground -> image of its ground point
at the DEM's height there. Interpolated bilinearly from the nodes of a cell, it is exact to the
extent that the DEM between the nodes is the bilinear interpolation of the nodes' heights: a
step of a DSM (a building's wall) between two nodes shifts the true position by the height's
departure times the rate d(image position)/d(height) (px per m: the parallax of the view), which
no interpolation of the nodes can follow. So, per cell of the node grid:

- :func:`departure_bound` bounds (m) how far the DEM leaves the bilinear interpolation of the
  cell's corner heights anywhere in the cell, from the DEM's own nodes (the DEM is bilinear
  between them): where the DEM is finer than the cell, from its nodes' departures from the cell's
  interpolation (each DEM value is a convex combination of DEM nodes, so its departure is at most
  theirs plus the curvature the cell's interpolation has on a DEM cell); where it is coarser, from
  its kinks (slope jumps across the DEM's grid lines, which bound linear interpolation's error by
  a quarter of the interval times their sum) and its twist.
- cells whose bound, times the rate, exceeds a share of the tolerance are corrected pixel by pixel
  (:func:`relief_corrections`): each pixel's DEM value is sampled at its DEM coordinates
  (interpolated from the nodes: a map projection is smooth) and the position moved by the rate
  times the departure of that height from the interpolated one. What is left is second order: half
  the rate's change with height times the departure squared, plus the rate's change across the
  cell times the departure; both are bounded and reported.

Frames: output pixels (i = row, j = column, pixel-centre units, tile-local); DEM pixel
coordinates (u = column, v = row, GDAL's); DEM node indices of a :class:`core.dem.HeightGrid`
(fu, fv); heights in the DEM's own datum (a geoid DEM's undulation is smooth and cancels in the
departure).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..dem import HeightGrid

RELIEF_SHARE = 0.5     # share of the tolerance the DEM's bounded departure may take before pixels are corrected
FINE_DEM_PX = 3.0      # a DEM whose nodes are closer than this (output px) is corrected pixel by pixel throughout
HEIGHT_STEP = 10.0     # m: the height step of the finite differences of the rate d(position)/d(height)
RATE_SPACING = 256     # output px between the nodes where the rate is evaluated (interpolated between)


@dataclass
class ReliefNodes:
    """At the nodes of a node grid (each (na, nb)): DEM pixel coordinates (u, v), DEM values z
    (m, the DEM's datum; NaN off the DEM or on nodata), the rate of the image position with
    height (dcol, drow: px per m) and the size of its change with height (d2: px per m², the
    norm of the second derivatives)."""
    u: np.ndarray
    v: np.ndarray
    z: np.ndarray
    dcol: np.ndarray
    drow: np.ndarray
    d2: np.ndarray

    def window(self, a: int, b: int, na: int, nb: int) -> "ReliefNodes":
        """The nodes (a .. a + na, b .. b + nb)."""
        part = np.s_[a:a + na, b:b + nb]
        return ReliefNodes(*(x[part] for x in (self.u, self.v, self.z, self.dcol, self.drow, self.d2)))


def corners(a: np.ndarray) -> np.ndarray:
    """The four corner values of each cell of node values a (na, nb): (4, na-1, nb-1)."""
    return np.stack([a[:-1, :-1], a[1:, :-1], a[:-1, 1:], a[1:, 1:]])


def cell_rates(relief: ReliefNodes) -> np.ndarray:
    """The largest rate |d(position)/d(height)| (px per m) at the corners of each cell: (na-1, nb-1)."""
    return corners(np.hypot(relief.dcol, relief.drow)).max(axis=0)


def departure_bound(grid: HeightGrid, relief: ReliefNodes, step: int, enough: float = 0.0,
                    fine: bool = False) -> np.ndarray | None:
    """A bound (m) of |DEM value - bilinear interpolation of the cell's corner values| over each
    cell (na-1, nb-1) of the node grid (spacing ``step`` output px), from the DEM's nodes in
    ``grid``; inf where the DEM has nodata near the cell. Where one bound for the whole tile is
    within ``enough`` m, that bound for every cell (what a smooth DEM gets, cheaply). None when
    the DEM's nodes are closer than FINE_DEM_PX output px (every cell is then corrected), unless
    ``fine`` asks for the bound there too."""
    fu, fv = grid.node_indices(relief.u, relief.v)
    na, nb = fu.shape
    to_dem, origin = _affine(np.stack([fv, fu]), step)
    det = abs(to_dem[0, 0] * to_dem[1, 1] - to_dem[0, 1] * to_dem[1, 0])
    if not det > 0:  # also NaN: no two nodes on the DEM
        return np.full((na - 1, nb - 1), np.inf)
    spacing = 1.0 / np.sqrt(det)
    if spacing < FINE_DEM_PX and not fine:
        return None
    if spacing < step / 2:
        return _sampled_bound(grid, relief.z, to_dem, origin, fu, fv, step, enough)
    return _kink_bound(grid, to_dem, fu, fv, step)


def _affine(f: np.ndarray, step: int) -> tuple[np.ndarray, np.ndarray]:
    """The affine map output px (i, j; node (0, 0) at 0) -> f (2, na, nb) at the nodes (DEM node
    units): ([[df0/di, df0/dj], [df1/di, df1/dj]], f at (0, 0)). A projection is smooth, so over a
    tile the map is affine: from the corner nodes, or from the mean differences where one of them
    is off the DEM."""
    na, nb = f.shape[1:]
    corner = f[:, [0, 0, -1, -1], [0, -1, 0, -1]]
    if np.isfinite(corner).all():
        di = (corner[:, 2] + corner[:, 3] - corner[:, 0] - corner[:, 1]) / (2.0 * (na - 1) * step)
        dj = (corner[:, 1] + corner[:, 3] - corner[:, 0] - corner[:, 2]) / (2.0 * (nb - 1) * step)
        to_dem = np.stack([di, dj], axis=1)
        return to_dem, corner.mean(axis=1) - to_dem @ np.array([(na - 1) * step, (nb - 1) * step]) / 2.0
    with np.errstate(invalid="ignore"):
        to_dem = np.array([[np.nanmean(np.diff(g, axis=axis)) / step for axis in (0, 1)] for g in f])
        ii, jj = np.meshgrid(np.arange(na) * float(step), np.arange(nb) * float(step), indexing="ij")
        origin = np.nanmean(f - to_dem[:, :1, None] * ii - to_dem[:, 1:, None] * jj, axis=(1, 2))
    return to_dem, origin


def _sampled_bound(grid: HeightGrid, z_nodes: np.ndarray, to_dem: np.ndarray, origin: np.ndarray,
                   fu: np.ndarray, fv: np.ndarray, step: int, enough: float) -> np.ndarray:
    """The bound of :func:`departure_bound` for a DEM finer than half a cell. Let H be the node
    grid's interpolation (bilinear per cell; past the tile's edge, the edge cell's extended). A
    DEM value is the convex combination of the nodes of its DEM cell, so its departure from H is
    at most the largest departure of those nodes from H (nodes in the cell or its 8 neighbours)
    plus how far H departs from its own interpolation on that DEM cell: a quarter of the DEM
    cell's extent times the slope jumps of H it crosses (the node heights' second differences
    over the node spacing) plus the curvature a cell's twist takes on it."""
    na, nb = z_nodes.shape
    ny, nx = grid.z.shape
    finite = np.isfinite(fu) & np.isfinite(fv)
    v0, v1 = max(int(np.floor(fv[finite].min())) - 1, 0), min(int(np.ceil(fv[finite].max())) + 1, ny - 1)
    u0, u1 = max(int(np.floor(fu[finite].min())) - 1, 0), min(int(np.ceil(fu[finite].max())) + 1, nx - 1)
    if v0 > v1 or u0 > u1:  # the tile lies off the DEM
        return np.full((na - 1, nb - 1), np.inf)
    (a, b), (c, d) = to_dem
    back = np.array([[d, -b], [-c, a]]) / (a * d - b * c)  # output px per DEM node unit: rows (i, j), columns (fv, fu)
    gv, gu = np.arange(v0, v1 + 1)[:, None] - origin[0], np.arange(u0, u1 + 1)[None, :] - origin[1]
    i_n, j_n = back[0, 0] * gv + back[0, 1] * gu, back[1, 0] * gv + back[1, 1] * gu
    # each DEM node against H: its own cell's interpolation (nodes past the tile's edge: the edge cell's)
    a = np.minimum(np.maximum(i_n // step, 0), na - 2).astype(int)
    b = np.minimum(np.maximum(j_n // step, 0), nb - 2).astype(int)
    s, t = i_n / step - a, j_n / step - b
    interpolated = (z_nodes[a, b] * (1 - s) * (1 - t) + z_nodes[a + 1, b] * s * (1 - t)
                    + z_nodes[a, b + 1] * (1 - s) * t + z_nodes[a + 1, b + 1] * s * t)
    departure = np.abs(grid.z[v0:v1 + 1, u0:u1 + 1] - interpolated)
    reach_i, reach_j = (abs(back[0, 0]) + abs(back[0, 1])) / step, (abs(back[1, 0]) + abs(back[1, 1])) / step
    second = np.zeros((2, na, nb))  # |second differences| of the node heights along i and j (0 at the edges)
    second[0, 1:-1] = np.abs(z_nodes[:-2] - 2 * z_nodes[1:-1] + z_nodes[2:])
    second[1, :, 1:-1] = np.abs(z_nodes[:, :-2] - 2 * z_nodes[:, 1:-1] + z_nodes[:, 2:])
    twist = np.abs(z_nodes[:-1, :-1] - z_nodes[1:, :-1] - z_nodes[:-1, 1:] + z_nodes[1:, 1:])
    curvature = twist * (abs(back[0, 0] * back[1, 0]) + abs(back[0, 1] * back[1, 1])) / (4.0 * step * step)
    whole = departure.max() + (reach_i * second[0].max() + reach_j * second[1].max()) / 4.0 + curvature.max()
    if whole <= enough:  # NaN (a hole) never is
        return np.full((na - 1, nb - 1), whole)
    departure[~np.isfinite(departure)] = np.inf
    own = ndimage.maximum(departure, labels=a * (nb - 1) + b, index=np.arange((na - 1) * (nb - 1)))
    own = np.asarray(own, dtype=float).reshape(na - 1, nb - 1)
    # over the 4 x 4 nodes of the 3 x 3 cells around each cell
    second = ndimage.maximum_filter(np.nan_to_num(second, nan=np.inf), size=(1, 4, 4), mode="constant",
                                    origin=(0, -1, -1))[:, :-1, :-1]
    bound = ndimage.maximum_filter(own, size=3, mode="constant") + (reach_i * second[0] + reach_j * second[1]) / 4.0 \
        + curvature
    return np.where(np.isfinite(bound), bound, np.inf)


def _kink_bound(grid: HeightGrid, to_dem: np.ndarray, fu: np.ndarray, fv: np.ndarray, step: int) -> np.ndarray:
    """The bound of :func:`departure_bound` for a DEM coarser than half a cell: between the DEM's
    grid lines the DEM is bilinear, so a row (or column) of the cell departs from its linear
    interpolation by at most a quarter of the cell times the slope jumps it crosses (second
    differences of the DEM across the lines it meets), plus the curvature the DEM's twist takes
    along the cell's rows and columns."""
    cu, cv = corners(fu), corners(fv)
    u_lo, u_hi = np.floor(np.min(cu, axis=0)), np.floor(np.max(cu, axis=0))
    v_lo, v_hi = np.floor(np.min(cv, axis=0)), np.floor(np.max(cv, axis=0))
    ok = np.isfinite(u_lo + u_hi + v_lo + v_hi)
    if not ok.any():
        return np.full(ok.shape, np.inf)
    u_lo, u_hi, v_lo, v_hi = (np.where(ok, x, x[ok].min()).astype(int) for x in (u_lo, u_hi, v_lo, v_hi))
    # the DEM's window of the tile, a node more each way (NaN beyond the DEM: no bound there)
    p0, q0 = int(v_lo.min()) - 1, int(u_lo.min()) - 1
    ny, nx = int(v_hi.max()) + 3 - p0, int(u_hi.max()) + 3 - q0
    z = np.full((ny, nx), np.nan)
    a0, b0 = max(p0, 0), max(q0, 0)
    a1, b1 = min(p0 + ny, grid.z.shape[0]), min(q0 + nx, grid.z.shape[1])
    if a1 > a0 and b1 > b0:
        z[a0 - p0:a1 - p0, b0 - q0:b1 - q0] = grid.z[a0:a1, b0:b1]
    kink_u = np.full(z.shape, np.inf)  # across the DEM's lines u = const (inf where unknown)
    kink_v = np.full(z.shape, np.inf)
    kink_u[:, 1:-1] = np.abs(z[:, :-2] - 2 * z[:, 1:-1] + z[:, 2:])
    kink_v[1:-1] = np.abs(z[:-2] - 2 * z[1:-1] + z[2:])
    twist = np.abs(z[:-1, :-1] - z[1:, :-1] - z[:-1, 1:] + z[1:, 1:])
    kink_u, kink_v, twist = (np.where(np.isfinite(k), k, np.inf) for k in (kink_u, kink_v, twist))
    # the DEM nodes of the DEM cells the cell meets: rows v_lo .. v_hi + 1, columns u_lo .. u_hi + 1
    span_v, span_u = int((v_hi - v_lo).max()) + 2, int((u_hi - u_lo).max()) + 2
    dv, du = np.meshgrid(np.arange(span_v), np.arange(span_u), indexing="ij")
    p = v_lo[None] - p0 + dv.ravel()[:, None, None]
    q = u_lo[None] - q0 + du.ravel()[:, None, None]
    node = (p <= v_hi[None] - p0 + 1) & (q <= u_hi[None] - q0 + 1)
    cell = (p <= v_hi[None] - p0) & (q <= u_hi[None] - q0)
    worst_u = np.where(node, kink_u[p, q], 0.0).max(axis=0)
    worst_v = np.where(node, kink_v[p, q], 0.0).max(axis=0)
    worst_t = np.where(cell, twist[np.minimum(p, ny - 2), np.minimum(q, nx - 2)], 0.0).max(axis=0)
    lines_u, lines_v = u_hi - u_lo, v_hi - v_lo  # DEM lines crossing the cell
    across_u = abs(to_dem[1, 0]) + abs(to_dem[1, 1])  # DEM columns a cell's row and column pass, per px
    across_v = abs(to_dem[0, 0]) + abs(to_dem[0, 1])
    with np.errstate(invalid="ignore"):
        bound = (step / 4.0 * (np.where(lines_u > 0, lines_u * worst_u * across_u, 0.0)
                               + np.where(lines_v > 0, lines_v * worst_v * across_v, 0.0))
                 + step * step / 4.0 * worst_t * (abs(to_dem[0, 0] * to_dem[1, 0]) + abs(to_dem[0, 1] * to_dem[1, 1])))
    return np.where(ok & np.isfinite(bound), bound, np.inf)


def relief_corrections(dem, relief: ReliefNodes, cells: np.ndarray, step: int, shape: tuple[int, int]):
    """Per-pixel corrections of the bilinear positions in ``cells`` (bool (na-1, nb-1)) of a tile
    of ``shape`` (rows, cols): (i, j) pixel indices, (dcol, drow) px to add (NaN where the DEM has
    no value: the pixel has no position), and per cell the bound (px) of what is left (second
    order in the departure)."""
    ci, cj = np.nonzero(cells)
    f = np.arange(step) / step
    s, t = f[None, :, None], f[None, None, :]

    def bilinear(a):
        c00, c10, c01, c11 = (x[ci, cj][:, None, None] for x in (a[:-1, :-1], a[1:, :-1], a[:-1, 1:], a[1:, 1:]))
        return c00 + (c10 - c00) * s + (c01 - c00) * t + (c11 - c10 - c01 + c00) * s * t

    ii = ci[:, None, None] * step + np.arange(step)[None, :, None]
    jj = cj[:, None, None] * step + np.arange(step)[None, None, :]
    keep = (ii < shape[0]) & (jj < shape[1])  # (n, step, step): the cells' pixels inside the tile
    u, v = bilinear(relief.u), bilinear(relief.v)
    grid = dem.grid_at(u[keep], v[keep])
    departure = (grid.sample(u, v) if grid is not None else np.full(u.shape, np.nan)) - bilinear(relief.z)
    rate_col, rate_row = (corners(r)[:, ci, cj].mean(axis=0)[:, None, None] for r in (relief.dcol, relief.drow))
    largest = np.where(keep & np.isfinite(departure), np.abs(departure), 0.0).max(axis=(1, 2))
    change = np.hypot(*(np.ptp(corners(r)[:, ci, cj], axis=0) for r in (relief.dcol, relief.drow)))
    left = np.zeros(cells.shape)
    left[ci, cj] = 0.5 * corners(relief.d2)[:, ci, cj].max(axis=0) * largest ** 2 + change * largest
    ii, jj = np.broadcast_to(ii, keep.shape)[keep], np.broadcast_to(jj, keep.shape)[keep]
    return (ii, jj), ((rate_col * departure)[keep], (rate_row * departure)[keep]), left
