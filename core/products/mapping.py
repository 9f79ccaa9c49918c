"""Output pixels -> raw image positions for resampling a raw image (orthoimages, sensor-corrected
images): the output grid of an orthoimage and the mapping that evaluates the exact ground ->
image geometry on a coarse node grid and densifies it.

The exact mapping (for an orthoimage: the terrain height from the DEM at each output pixel, then
the scene's ground -> image) is evaluated on a node grid per tile (every ``step`` output pixels)
and densified by bilinear interpolation, which is checked at the cell centres against the exact
mapping: a tile whose check exceeds ``max_error`` px is redone with half the step. Cells whose
corners fall on different CCD chips straddle a seam of a staggered array, where the mapping
jumps: their pixels are mapped exactly, one by one, so no seam is smeared.
Coordinates: image positions in the GDAL convention (pixel centres at +0.5); output pixel
centres at the geotransform's +0.5.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from pyproj import CRS, Transformer

from ..errors import Cancelled
from ..geodesy import geodetic_to_ecef
from ..model.sensor import SceneModel

SEAM_MARGIN = 8.0  # px from a chip boundary within which cells are mapped pixel by pixel


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
    (ncol, nrow: (na, nb)) and at the cell centres between them (ecol, erow: (na-1, nb-1))."""
    r0: int
    c0: int
    step: int
    ncol: np.ndarray
    nrow: np.ndarray
    ecol: np.ndarray
    erow: np.ndarray

    def window(self, r0: int, r1: int, c0: int, c1: int) -> "Nodes":
        """The nodes of a tile whose corners (r0, c0) lie on the node grid, to at least (r1, c1)."""
        a, b = (r0 - self.r0) // self.step, (c0 - self.c0) // self.step
        na, nb = -(-(r1 - r0) // self.step) + 1, -(-(c1 - c0) // self.step) + 1
        return Nodes(r0, c0, self.step, self.ncol[a:a + na, b:b + nb], self.nrow[a:a + na, b:b + nb],
                     self.ecol[a:a + na - 1, b:b + nb - 1], self.erow[a:a + na - 1, b:b + nb - 1])


class Mapper:
    """Output pixel centres of a tile -> image positions (col, row) of the raw image; ``rows``:
    (first, end) image rows of one scene of a strip, outside which the tile is nodata."""

    rows: tuple[int, int] | None = None  # subclasses that map onto the whole raw image keep it

    def __init__(self, scene: SceneModel, camera: int, surface, grid: OrthoGrid,
                 rows: tuple[int, int] | None = None):
        self.scene, self.camera, self.surface, self.grid, self.rows = scene, camera, surface, grid, rows
        self.to_lonlat = Transformer.from_crs(grid.crs, CRS.from_epsg(4326), always_xy=True)
        self.cam = scene.cameras[camera]

    def exact(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Image (col, row) of output positions (i = row, j = col, float, pixel-centre units)."""
        g = self.grid
        x = g.x0 + (j + 0.5) * g.resolution
        y = g.y0 - (i + 0.5) * g.resolution
        lon, lat = self.to_lonlat.transform(x, y)
        h = self.surface.height(lon, lat)
        col = np.full(np.shape(lon), np.nan)
        row = np.full(np.shape(lon), np.nan)
        ok = np.isfinite(h)
        if ok.any():
            col[ok], row[ok] = self.scene.ground_to_image(geodetic_to_ecef(lon[ok], lat[ok], h[ok]), self.camera)
        return col, row

    def exact_many(self, i: np.ndarray, j: np.ndarray, chunk: int = 250_000,
                   is_cancelled: Callable[[], bool] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`exact` for many positions (any equal shapes), in chunks of bounded memory."""
        col, row = np.empty(i.size), np.empty(i.size)
        fi, fj = i.ravel(), j.ravel()
        for k in range(0, i.size, chunk):
            if is_cancelled and is_cancelled():
                raise Cancelled("orthorectification cancelled by the user")
            col[k:k + chunk], row[k:k + chunk] = self.exact(fi[k:k + chunk], fj[k:k + chunk])
        return col.reshape(i.shape), row.reshape(i.shape)

    def nodes(self, r0: int, r1: int, c0: int, c1: int, step: int,
              is_cancelled: Callable[[], bool] | None = None) -> "Nodes":
        """Exact image positions at the nodes (every ``step`` output pixels, from (r0, c0) to at
        least (r1, c1)) and at the centres of the cells between them."""
        ni = np.arange(r0, r1 + step, step, dtype=float)
        nj = np.arange(c0, c1 + step, step, dtype=float)
        ncol, nrow = self.exact_many(*np.meshgrid(ni, nj, indexing="ij"), is_cancelled=is_cancelled)
        ecol, erow = self.exact_many(*np.meshgrid(ni[:-1] + step / 2, nj[:-1] + step / 2, indexing="ij"),
                                     is_cancelled=is_cancelled)
        return Nodes(r0, c0, step, ncol, nrow, ecol, erow)

    def dem_gap_share(self, planned: "Nodes") -> float:
        """Share of the image's nodes in the output that the surface gives no height (they stay
        nodata): nodes without a height that fall in the image at the surface's mean height."""
        nodes = np.argwhere(np.isnan(planned.ncol)).astype(float)
        if nodes.size == 0:
            return 0.0
        i, j = nodes[:, 0] * planned.step + planned.r0, nodes[:, 1] * planned.step + planned.c0
        lon, lat = self.to_lonlat.transform(self.grid.x0 + (j + 0.5) * self.grid.resolution,
                                            self.grid.y0 - (i + 0.5) * self.grid.resolution)
        no_height = ~np.isfinite(self.surface.height(lon, lat))
        if not no_height.any():
            return 0.0
        h = float(np.mean(self.surface.height_range))
        ground = geodetic_to_ecef(lon[no_height], lat[no_height], np.full(no_height.sum(), h))
        col, row = self.scene.ground_to_image(ground, self.camera)
        missing = int(np.sum(self.cam.in_image(col, row)))
        covered = int(np.sum(self.cam.in_image(planned.ncol, planned.nrow)))
        return missing / max(missing + covered, 1)

    def tile(self, r0: int, r1: int, c0: int, c1: int, step: int, max_error: float,
             planned: "Nodes | None" = None) -> tuple[np.ndarray, np.ndarray, float]:
        """(col, row) arrays (r1-r0, c1-c0) of a tile, and the densification error measured (px).
        planned: nodes of the whole grid at ``step`` (:meth:`nodes`), sliced instead of computed."""
        nodes = planned.window(r0, r1, c0, c1) if planned is not None and planned.step == step else None
        while True:
            nodes = nodes or self.nodes(r0, r1, c0, c1, step)
            ncol, nrow, ecol, erow = nodes.ncol, nodes.nrow, nodes.ecol, nodes.erow
            # check at the cell centres where the four corners lie on one chip
            icol = 0.25 * (ncol[:-1, :-1] + ncol[1:, :-1] + ncol[:-1, 1:] + ncol[1:, 1:])
            irow = 0.25 * (nrow[:-1, :-1] + nrow[1:, :-1] + nrow[:-1, 1:] + nrow[1:, 1:])
            # Seam cells: corners on different chips, or a centre the exact mapping puts on
            # another chip (a seam duplicate: both pixels see the point).
            centre_chip = self.cam.chip_index(np.nan_to_num(ecol, nan=-1.0))
            seam = self._seam_cells(ncol) | (centre_chip != self.cam.chip_index(np.nan_to_num(
                ncol[:-1, :-1], nan=-1.0)))
            err = np.hypot(icol - ecol, irow - erow)[~seam]
            worst = float(np.nanmax(err, initial=0.0))
            if worst <= max_error or step <= 2:
                break
            step //= 2
            nodes = None
        col, row = self._densify(ncol, nrow, r1 - r0, c1 - c0, step)
        if seam.any():
            self._exact_in_cells(col, row, seam, r0, c0, step)
        return col, row, worst

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
        corners = np.stack([chip[:-1, :-1], chip[1:, :-1], chip[:-1, 1:], chip[1:, 1:]])
        return (corners.min(axis=0) != corners.max(axis=0)) | (corners.min(axis=0) < 0)

    @staticmethod
    def _densify(ncol, nrow, h: int, w: int, step: int):
        """Bilinear interpolation of node values to every pixel of the tile: two small matrix
        products (separable weights), so it costs little per pixel."""
        def weights(n_pix, n_nodes):
            f = np.arange(n_pix) / step
            k = np.minimum(f.astype(int), n_nodes - 2)
            t = f - k
            m = np.zeros((n_pix, n_nodes))
            m[np.arange(n_pix), k] = 1 - t
            m[np.arange(n_pix), k + 1] = t
            return m
        wi, wj = weights(h, ncol.shape[0]), weights(w, ncol.shape[1])
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
