"""Output pixels -> raw image positions for resampling a raw image (orthoimages, sensor-corrected
images): the output grid of an orthoimage and the mapping that evaluates the exact ground ->
image geometry on a coarse node grid and densifies it, within a stated tolerance everywhere.

The exact mapping (for an orthoimage: the terrain height from the DEM at each output pixel, then
the scene's ground -> image) is evaluated on a node grid per tile (every ``step`` output pixels)
and densified by bilinear interpolation. Per cell of the grid:

- the densification is checked at the cell's centre against the exact mapping, and where the
  DEM between the nodes departs from the interpolation of their heights (a DSM's steps), the
  departure is bounded from the DEM's own nodes (:mod:`core.products.relief`); cells where the
  bound could take the error past half the tolerance have their relief corrected pixel by pixel
  (each pixel's own DEM height, the position moved along the rate d(position)/d(height));
- a tile whose checks fail in many cells is redone with half the step (down to MIN_STEP);
  cells that still fail, cells whose corners fall on different CCD chips (a seam of a staggered
  array, where the mapping jumps) and cells touching pixels with no position (image, DEM edges
  and holes) are mapped exactly, pixel by pixel.

What was met is measured and counted (:class:`MappingFigures`): the largest error at the checks
(with the bounds where pixels were not checked one by one), and the output pixels corrected for
relief, refined and mapped exactly.
Coordinates: image positions in the GDAL convention (pixel centres at +0.5); output pixel
centres at the geotransform's +0.5.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Callable

import numpy as np
from pyproj import CRS, Transformer

from ..errors import Cancelled
from ..geodesy import geodetic_to_ecef
from ..model.sensor import SceneModel
from .relief import (HEIGHT_STEP, RATE_SPACING, RELIEF_SHARE, ReliefNodes, cell_rates, corners, departure_bound,
                     relief_corrections)

SEAM_MARGIN = 8.0  # px from a chip boundary within which cells are mapped pixel by pixel
MIN_STEP = 4       # output px: the finest node grid a tile is refined to before failing cells are mapped exactly


@dataclass
class OrthoGrid:
    """The output grid: CRS (pyproj), origin (x0, y0) of the upper-left corner, pixel size
    (m) and size (cols, rows)."""
    crs: CRS
    x0: float
    y0: float
    resolution: float
    cols: int
    rows: int

    def geotransform(self) -> tuple:
        return (self.x0, self.resolution, 0.0, self.y0, 0.0, -self.resolution)


def utm_crs(lon: float, lat: float) -> CRS:
    """The WGS84 UTM zone CRS of a point."""
    zone = int((lon + 180.0) // 6.0) % 60 + 1
    return CRS.from_epsg((32600 if lat >= 0 else 32700) + zone)


@dataclass
class Nodes:
    """Exact image positions (col, row) at output nodes (i, j) = (r0 + a*step, c0 + b*step)
    (ncol, nrow: (na, nb)) and at the cell centres between them (ecol, erow: (na-1, nb-1));
    with a DEM, what the nodes' relief needs (:class:`core.products.relief.ReliefNodes`)."""
    r0: int
    c0: int
    step: int
    ncol: np.ndarray
    nrow: np.ndarray
    ecol: np.ndarray
    erow: np.ndarray
    relief: ReliefNodes | None = None

    def window(self, r0: int, r1: int, c0: int, c1: int) -> "Nodes":
        """The nodes of a tile whose corners (r0, c0) lie on the node grid, to at least (r1, c1)."""
        a, b = (r0 - self.r0) // self.step, (c0 - self.c0) // self.step
        na, nb = -(-(r1 - r0) // self.step) + 1, -(-(c1 - c0) // self.step) + 1
        return Nodes(r0, c0, self.step, self.ncol[a:a + na, b:b + nb], self.nrow[a:a + na, b:b + nb],
                     self.ecol[a:a + na - 1, b:b + nb - 1], self.erow[a:a + na - 1, b:b + nb - 1],
                     None if self.relief is None else self.relief.window(a, b, na, nb))


@dataclass
class MappingFigures:
    """What mapping output pixels measured, summed over tiles (:meth:`merge`).

    error_px: the largest error of the image positions (px) at the checks: each cell's centre
    against the exact model, plus the bound of the DEM's departure between the nodes where the
    relief was interpolated, or of what the correction leaves where it was corrected. Output
    pixels: all, with the relief corrected pixel by pixel, in tiles whose node grid was refined,
    mapped exactly (seams, image and DEM edges and holes, cells failing the check). The image's
    footprint in the output: pixels in the image, and those of them with no height (of which on
    the DEM's nodata holes; the rest lie off its extent)."""
    error_px: float = 0.0
    pixels: int = 0
    relief: int = 0
    refined: int = 0
    exact: int = 0
    footprint: int = 0
    no_height: int = 0
    holes: int = 0

    def merge(self, other: "MappingFigures") -> "MappingFigures":
        return MappingFigures(max(self.error_px, other.error_px),
                              *(getattr(self, f.name) + getattr(other, f.name) for f in fields(self)[1:]))

    def share(self, count: int) -> float:
        """``count`` output pixels as a share of all (%)."""
        return 100.0 * count / max(self.pixels, 1)

    @property
    def gap_share(self) -> float:
        """The share (0..1) of the image's footprint in the output with no height (nodata)."""
        return self.no_height / max(self.footprint, 1)

    def sentence(self, max_error: float, relief: bool = True) -> str:
        """The figures in words, for the log (``relief``: of a mapping over a DEM's relief)."""
        return (f"image positions within {self.error_px:.1e} px of the exact model (tolerance {max_error:g} px; the "
                "largest error at the checks of the node grid's cells"
                + (", with the DEM's bounded relief between them); relief corrected pixel by pixel in "
                   f"{self.share(self.relief):.1f} % of the output, node grid" if relief else "); node grid")
                + f" refined in {self.share(self.refined):.1f} %, mapped exactly in {self.share(self.exact):.1f} % "
                "(CCD seams, image and DEM edges and holes, cells failing the check)")


def interpolation_matrix(positions: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """Weights (len(positions), len(knots)) of linear interpolation between increasing knots
    (extrapolating beyond the last interval; a single knot is constant)."""
    m = np.zeros((positions.size, knots.size))
    if knots.size == 1:
        m[:, 0] = 1.0
        return m
    k = np.clip(np.searchsorted(knots, positions, side="right") - 1, 0, knots.size - 2)
    t = (positions - knots[k]) / (knots[k + 1] - knots[k])
    m[np.arange(positions.size), k] = 1 - t
    m[np.arange(positions.size), k + 1] = t
    return m


class Mapper:
    """Output pixel centres of a tile -> image positions (col, row) of the raw image; ``rows``:
    (first, end) image rows of one scene of a strip, outside which the tile is nodata."""

    rows: tuple[int, int] | None = None  # subclasses that map onto the whole raw image keep it
    dem = None                           # the DEM whose relief is bounded (None: no relief)
    maps_ground = True                   # output pixels are ground positions (their footprint is counted)
    corrects_relief = True               # relief corrected pixel by pixel (else: those cells mapped exactly)

    def __init__(self, scene: SceneModel, camera: int, surface, grid: OrthoGrid,
                 rows: tuple[int, int] | None = None):
        self.scene, self.camera, self.surface, self.grid, self.rows = scene, camera, surface, grid, rows
        self.to_lonlat = Transformer.from_crs(grid.crs, CRS.from_epsg(4326), always_xy=True)
        self.cam = scene.cameras[camera]
        self.dem = surface if hasattr(surface, "values_at") else None

    def ground(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lon, lat) degrees of output positions (i = row, j = col, float, pixel-centre units)."""
        g = self.grid
        return self.to_lonlat.transform(g.x0 + (j + 0.5) * g.resolution, g.y0 - (i + 0.5) * g.resolution)

    def exact(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Image (col, row) of output positions (i = row, j = col, float, pixel-centre units)."""
        return self._exact(i, j)[:2]

    def _exact(self, i, j) -> tuple[np.ndarray, ...]:
        """:meth:`exact`, and with a DEM the DEM pixel coordinates (u, v) and values z there."""
        lon, lat = self.ground(i, j)
        if self.dem is None:
            return self.at_heights(lon, lat, self.surface.height(lon, lat))
        u, v = self.dem.pixel_coordinates(lon, lat)
        z = self.dem.values_at(u, v)
        return (*self.at_heights(lon, lat, z + self.dem.datum_offset(lon, lat)), u, v, z)

    def at_heights(self, lon, lat, h) -> tuple[np.ndarray, np.ndarray]:
        """Image (col, row) of ground points (lon, lat degrees, ellipsoidal h m); NaN where h is,
        or where the output CRS gives no (lon, lat) (a grid beyond its domain)."""
        col = np.full(np.shape(lon), np.nan)
        row = np.full(np.shape(lon), np.nan)
        ok = np.isfinite(h) & np.isfinite(lon) & np.isfinite(lat)
        if ok.any():
            col[ok], row[ok] = self.scene.ground_to_image(geodetic_to_ecef(lon[ok], lat[ok], h[ok]), self.camera)
        return col, row

    def exact_many(self, i: np.ndarray, j: np.ndarray, chunk: int = 250_000,
                   is_cancelled: Callable[[], bool] | None = None, relief: bool = False) -> tuple[np.ndarray, ...]:
        """:meth:`exact` for many positions (any equal shapes), in chunks of bounded memory; with
        ``relief`` also the DEM pixel coordinates and values (u, v, z) there."""
        fi, fj = i.ravel(), j.ravel()
        parts = []
        for k in range(0, i.size, chunk):
            if is_cancelled and is_cancelled():
                raise Cancelled("orthorectification cancelled by the user")
            parts.append(self._exact(fi[k:k + chunk], fj[k:k + chunk]) if relief
                         else self.exact(fi[k:k + chunk], fj[k:k + chunk]))
        return tuple(np.concatenate(p).reshape(i.shape) for p in zip(*parts))

    def nodes(self, r0: int, r1: int, c0: int, c1: int, step: int,
              is_cancelled: Callable[[], bool] | None = None) -> "Nodes":
        """Exact image positions at the nodes (every ``step`` output pixels, from (r0, c0) to at
        least (r1, c1)) and at the centres of the cells between them; with a DEM, the nodes' relief."""
        ni = np.arange(r0, r1 + step, step, dtype=float)
        nj = np.arange(c0, c1 + step, step, dtype=float)
        ncol, nrow, *dem = self.exact_many(*np.meshgrid(ni, nj, indexing="ij"), is_cancelled=is_cancelled,
                                           relief=self.dem is not None)
        ecol, erow = self.exact_many(*np.meshgrid(ni[:-1] + step / 2, nj[:-1] + step / 2, indexing="ij"),
                                     is_cancelled=is_cancelled)
        relief = ReliefNodes(*dem, *self._rates(ni, nj, step)) if dem else None
        return Nodes(r0, c0, step, ncol, nrow, ecol, erow, relief)

    def _rates(self, ni: np.ndarray, nj: np.ndarray, step: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The rate of the image position with height at the nodes (ni x nj output rows and
        columns): (dcol, drow) px per m and the norm of its change with height (px per m²), by
        central differences of HEIGHT_STEP m at every RATE_SPACING px (they vary slowly),
        interpolated between."""
        k = max(1, RATE_SPACING // step)
        ia, ja = (np.unique(np.r_[np.arange(0, n.size, k), n.size - 1]) for n in (ni, nj))
        (c0, r0), (c1, r1), (c2, r2) = self.at_height_steps(*np.meshgrid(ni[ia], nj[ja], indexing="ij"),
                                                            (-HEIGHT_STEP, 0.0, HEIGHT_STEP))
        rates = [(c2 - c0) / (2 * HEIGHT_STEP), (r2 - r0) / (2 * HEIGHT_STEP),
                 np.hypot(c2 - 2 * c1 + c0, r2 - 2 * r1 + r0) / HEIGHT_STEP ** 2]
        wi, wj = interpolation_matrix(ni, ni[ia]), interpolation_matrix(nj, nj[ja])
        out = []
        for rate in rates:
            finite = np.isfinite(rate)
            filled = np.where(finite, rate, np.abs(rate[finite]).max() if finite.any() else 0.0)
            out.append(wi @ filled @ wj.T)
        return tuple(out)

    def at_height_steps(self, i: np.ndarray, j: np.ndarray, steps) -> list[tuple[np.ndarray, np.ndarray]]:
        """Image (col, row) of output positions (i, j) with the ground moved by each of ``steps``
        (m) in height from the surface's (its mean height where it has none)."""
        lon, lat = self.ground(i, j)
        h = self.surface.height(lon, lat)
        h = np.where(np.isfinite(h), h, float(np.mean(self.surface.height_range)))
        return [self.at_heights(lon, lat, h + dh) for dh in steps]

    def tile(self, r0: int, r1: int, c0: int, c1: int, step: int, max_error: float,
             planned: "Nodes | None" = None) -> tuple[np.ndarray, np.ndarray, MappingFigures]:
        """(col, row) arrays (r1-r0, c1-c0) of a tile, and what mapping it measured.
        planned: nodes of the whole grid at ``step`` (:meth:`nodes`), sliced instead of computed."""
        nodes = planned.window(r0, r1, c0, c1) if planned is not None and planned.step == step else None
        refined = False
        h, w = r1 - r0, c1 - c0
        while True:
            nodes = nodes or self.nodes(r0, r1, c0, c1, step)
            seam, relief, error = self._check(nodes, max_error)
            failing = ~seam & (error > max_error)
            half = step // 2
            refinement = (-(-h // half) + 1) * (-(-w // half) + 1) if half else 0  # nodes a refined tile evaluates
            if not failing.any() or half < MIN_STEP or failing.sum() * step * step <= 3 * refinement:
                break
            step, nodes, refined = half, None, True
        exact = seam | failing | (relief if not self.corrects_relief else False)
        col, row = self._densify(nodes.ncol, nodes.nrow, h, w, step)
        corrected = relief & ~exact
        if corrected.any():
            (ii, jj), (dcol, drow), left = relief_corrections(self.dem, nodes.relief, corrected, step, (h, w))
            col[ii, jj] += dcol
            row[ii, jj] += drow
            error = error + left
        if exact.any():
            self._exact_in_cells(col, row, exact, r0, c0, step)
        pixels = _cell_pixels(h, w, step, exact.shape)
        figures = MappingFigures(float(np.max(error[~exact], initial=0.0)), h * w, int(pixels[corrected].sum()),
                                 h * w if refined else 0, int(pixels[exact].sum()))
        if self.maps_ground:
            self._count_footprint(figures, col, row, nodes, (h, w))
        else:  # every pixel is the image's; one without a position met the surface only on a hole
            figures.footprint = h * w
            figures.no_height = figures.holes = int((~np.isfinite(col)).sum())
        return col, row, figures

    def _check(self, nodes: Nodes, max_error: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per cell: (seam: mapped exactly, relief: corrected pixel by pixel, error px: at the
        centre against the exact model, plus the bound of the relief left interpolated)."""
        ncol, nrow, ecol, erow = nodes.ncol, nodes.nrow, nodes.ecol, nodes.erow
        icol, irow = corners(ncol).mean(axis=0), corners(nrow).mean(axis=0)
        # Seam cells: corners on different chips, or a centre the exact mapping puts on
        # another chip (a seam duplicate: both pixels see the point).
        centre_chip = self.cam.chip_index(np.nan_to_num(ecol, nan=-1.0))
        seam = self._seam_cells(ncol) | (centre_chip != self.cam.chip_index(np.nan_to_num(ncol[:-1, :-1], nan=-1.0)))
        relief = np.zeros(seam.shape, bool)
        allowance = np.zeros(seam.shape)
        r = nodes.relief
        rates = cell_rates(r) if r is not None else np.zeros(seam.shape)
        # cells nodata however mapped (the relief moves a pixel by at most the rate times the DEM's
        # span): neither corrected nor checked
        away = self._off_image(ncol, nrow, rates * float(np.ptp(self.surface.height_range)))
        if r is not None and not away.all():
            finite = np.isfinite(r.u) & np.isfinite(r.v)
            grid = self.dem.grid_at(r.u[finite], r.v[finite]) if finite.any() else None
            enough = RELIEF_SHARE * max_error / max(float(rates.max()), 1e-12)
            bound = (departure_bound(grid, r, nodes.step, enough, fine=not self.corrects_relief) if grid is not None
                     else np.zeros(seam.shape))
            if bound is None:
                relief = ~away
            else:
                with np.errstate(invalid="ignore"):
                    allowance = np.where(np.isinf(bound), np.inf, rates * bound)
                relief = (allowance > RELIEF_SHARE * max_error) & ~away
                allowance[relief | away] = 0.0
            ci, cj = np.nonzero(relief & ~seam)
            if ci.size:  # the centre as its pixels get it: bilinear, plus the rate times the departure there
                u, v, z, dcol, drow = (corners(a)[:, ci, cj].mean(axis=0) for a in (r.u, r.v, r.z, r.dcol, r.drow))
                departure = self.dem.values_at(u, v) - z
                icol[ci, cj] += dcol * departure
                irow[ci, cj] += drow * departure
        err = np.hypot(icol - ecol, irow - erow)
        neither = ~np.isfinite(icol) & ~np.isfinite(ecol)  # no position either way (a DEM hole)
        err = np.where(np.isfinite(err), err, np.where(neither, 0.0, np.inf))
        return seam, relief, np.where(away, 0.0, err + allowance)

    def _off_image(self, ncol: np.ndarray, nrow: np.ndarray, margin: np.ndarray) -> np.ndarray:
        """Cells whose four corners all lie beyond one side of the image (or of ``rows``) by more
        than ``margin`` px (per cell): without relief the mapping is nearly affine over a cell, so
        all its pixels do."""
        top, bottom = self.rows or (0, self.cam.rows)
        c, r = corners(ncol), corners(nrow)
        with np.errstate(invalid="ignore"):
            return ((c < -margin).all(axis=0) | (c > self.cam.cols + margin).all(axis=0)
                    | (r < top - margin).all(axis=0) | (r > bottom + margin).all(axis=0))

    def _seam_cells(self, ncol: np.ndarray) -> np.ndarray:
        """Cells (nodes - 1 each way) whose corners are on different chips, off the image, or
        within SEAM_MARGIN px of a chip boundary (misaligned chips leave gaps and duplicates
        a few pixels wide there, where the mapping has no single smooth answer)."""
        finite = np.isfinite(ncol)
        safe = np.nan_to_num(ncol, nan=-1.0)
        chip = np.where(finite, self.cam.chip_index(safe), -1)
        bounds = np.array([c.col_offset for c in self.cam.chips[1:]] or [np.inf])
        near = (np.abs(safe[..., None] - bounds).min(axis=-1) < SEAM_MARGIN) & finite
        chip = np.where(near, -2, chip)  # a mark that never matches a neighbour
        c = corners(chip)
        return (c.min(axis=0) != c.max(axis=0)) | (c.min(axis=0) < 0)

    def _count_footprint(self, figures: MappingFigures, col, row, nodes: Nodes, shape) -> None:
        """Count the tile's pixels of the image's footprint into ``figures``: pixels in the image,
        and pixels with no position that fall in the image at the surface's mean height (no height
        there: on the DEM's holes, or off its extent)."""
        missing = ~np.isfinite(col)
        if not missing.any():  # per cell: all corners in the image, none (a cell is small), or some
            c = corners(self.in_image(nodes.ncol, nodes.nrow))
            all_in, some = c.all(axis=0), c.any(axis=0) & ~c.all(axis=0)
            pixels = _cell_pixels(*shape, nodes.step, all_in.shape)
            figures.footprint += int(pixels[all_in].sum())
            if some.any():
                big = np.kron(some, np.ones((nodes.step, nodes.step), bool))[:shape[0], :shape[1]]
                figures.footprint += int(self.in_image(col[big], row[big]).sum())
            return
        inside = self.in_image(col, row)
        lost = np.zeros(shape, bool)
        if missing.any():
            lost = missing & self.in_image(*self._flat_positions(nodes, shape, missing))
        figures.footprint += int(inside.sum() + lost.sum())
        figures.no_height += int(lost.sum())
        if lost.any() and nodes.relief is not None:
            u, v = (self._densify(nodes.relief.u, nodes.relief.v, *shape, nodes.step))
            rows, cols = self.dem.shape
            on_dem = (u >= 0.5) & (v >= 0.5) & (u <= cols - 0.5) & (v <= rows - 0.5)
            figures.holes += int((lost & on_dem).sum())

    def _flat_positions(self, nodes: Nodes, shape: tuple[int, int], wanted: np.ndarray):
        """Image (col, row) of a tile's pixels (shape) on the surface's mean height, interpolated
        from the nodes; exact at the ``wanted`` pixels of cells with a corner that has none."""
        h = float(np.mean(self.surface.height_range))
        ni, nj = (start + nodes.step * np.arange(n, dtype=float) for start, n in zip((nodes.r0, nodes.c0),
                                                                                     nodes.ncol.shape))
        lon, lat = self.ground(*np.meshgrid(ni, nj, indexing="ij"))
        ncol, nrow = self.at_heights(lon, lat, np.full(lon.shape, h))
        col, row = self._densify(ncol, nrow, *shape, nodes.step)
        lacking = corners(~np.isfinite(ncol)).any(axis=0)
        ii, jj = np.nonzero(wanted & np.kron(lacking, np.ones((nodes.step, nodes.step), bool))[:shape[0], :shape[1]])
        if ii.size:
            col[ii, jj], row[ii, jj] = self.at_heights(*self.ground(ii + float(nodes.r0), jj + float(nodes.c0)),
                                                       np.full(ii.size, h))
        return col, row

    def in_image(self, col, row) -> np.ndarray:
        """Image positions inside the image (and inside ``rows``, one scene of a strip)."""
        inside = self.cam.in_image(col, row)
        if self.rows is not None:
            inside &= (row >= self.rows[0]) & (row <= self.rows[1])
        return inside

    @staticmethod
    def _densify(ncol, nrow, h: int, w: int, step: int):
        """Bilinear interpolation of node values to every pixel of the tile: two small matrix
        products (separable weights), so it costs little per pixel."""
        wi = interpolation_matrix(np.arange(h, dtype=float), step * np.arange(ncol.shape[0], dtype=float))
        wj = interpolation_matrix(np.arange(w, dtype=float), step * np.arange(ncol.shape[1], dtype=float))
        fill = lambda a: np.where(np.isfinite(a), a, 0.0)  # noqa: E731  (NaN nodes: handled as seam cells)
        return wi @ fill(ncol) @ wj.T, wi @ fill(nrow) @ wj.T

    def _exact_in_cells(self, col, row, seam, r0, c0, step) -> None:
        """Exact mapping for the pixels of the flagged cells (seams, image or DEM borders)."""
        h, w = col.shape
        ci, cj = np.nonzero(seam)
        ii = (ci[:, None, None] * step + np.arange(step)[None, :, None]).repeat(step, 2)
        jj = (cj[:, None, None] * step + np.arange(step)[None, None, :]).repeat(step, 1)
        keep = (ii < h) & (jj < w)
        ii, jj = ii[keep], jj[keep]
        ecol, erow = self.exact(ii + r0, jj + c0)
        col[ii, jj], row[ii, jj] = ecol, erow


def _cell_pixels(h: int, w: int, step: int, cells: tuple[int, int]) -> np.ndarray:
    """Output pixels of each cell (cells: (na-1, nb-1)) of a tile (h, w): cells at the tile's
    far edges are cut."""
    rows = np.clip(h - step * np.arange(cells[0]), 0, step)
    cols = np.clip(w - step * np.arange(cells[1]), 0, step)
    return np.outer(rows, cols)
