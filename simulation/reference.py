"""A simulated reference orthoimage of a rendered scene's ground: the map a user would match
the raw image against (a national orthophoto, a Sentinel-2 scene, an earlier product).

It shows the same ground texture as the raw images (:mod:`simulation.texture`), on a north-up grid
in the UTM zone of the scene centre, and differs from them like a real reference does:

- another ground sample distance (default 5 m, at least twice the scene's) and an optical blur (Gaussian, sigma in
  reference pixels);
- another radiometry: DN = offset + gain * (20 + 215 * v ** gamma), plus Gaussian noise (DN);
- patches of changed land cover (discs where the texture has another seed) and clouds (bright
  smooth discs blended over the ground), placed at random over a set share of the area.

The ground position of every reference pixel is exact: its centre (geotransform) in the
UTM CRS, so a match against it has a known truth. Everything drawn is returned for the
simulation manifest.
"""
from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from typing import Callable

import numpy as np
from osgeo import gdal
from pyproj import CRS, Transformer
from scipy.ndimage import gaussian_filter, map_coordinates

from ..core.errors import Cancelled, InputError
from ..core.files import check_closed, closing_errors
from ..core.model.sensor import SceneModel
from ..core.products.mapping import utm_crs
from ..core.products.ortho import default_grid
from .radiometry import CHANGED_SEED_OFFSET, disc_weight, patches, radiometric_dn
from .texture import texture_at

gdal.UseExceptions()

REFERENCE_NAME = "reference.tif"
TILE_ROWS = 512
NODE_STEP = 32               # px between exactly projected nodes of the reference grid


@dataclass(frozen=True)
class ReferenceSettings:
    """How the reference differs from the raw images. gsd (m), blur (Gaussian sigma, reference
    px), gain, offset (DN), gamma, noise (DN, standard deviation), changed / cloud (share of the
    area covered by changed land cover / clouds), patch_radius (m, (min, max)), margin (m
    beyond the scene's true footprint, so an onboard error of hundreds of metres stays inside)."""
    gsd: float = 5.0
    blur: float = 0.6
    gain: float = 0.85
    offset: float = 12.0
    gamma: float = 1.25
    noise: float = 2.0
    changed: float = 0.04
    cloud: float = 0.03
    patch_radius: tuple[float, float] = (150.0, 500.0)
    margin: float = 2000.0

    def validate(self) -> None:
        if not (self.gsd > 0 and self.blur >= 0 and self.gain > 0 and self.gamma > 0 and self.noise >= 0
                and 0 <= self.changed < 1 and 0 <= self.cloud < 1 and self.margin >= 0
                and 0 < self.patch_radius[0] <= self.patch_radius[1]):
            raise InputError(f"implausible reference settings: {self}")


def _lonlat(to_lonlat: Transformer, x: np.ndarray, y: np.ndarray, step: int = NODE_STEP):
    """(lon, lat) of the map grid (x, y) (2-D, regular): exact every ``step`` pixels and bilinear
    between (the map projection's curvature over a few hundred metres is far below a millimetre)."""
    rows, cols = x.shape
    i, j = np.r_[0:rows:step, rows - 1], np.r_[0:cols:step, cols - 1]
    lon, lat = to_lonlat.transform(x[np.ix_(i, j)], y[np.ix_(i, j)])
    fi, fj = np.interp(np.arange(rows), i, np.arange(i.size)), np.interp(np.arange(cols), j, np.arange(j.size))
    where = np.meshgrid(fi, fj, indexing="ij")
    return (map_coordinates(np.asarray(lon), where, order=1), map_coordinates(np.asarray(lat), where, order=1))


def write_reference(scene: SceneModel, dem, frame: dict, path, seed: int,
                    settings: ReferenceSettings | None = None,
                    is_cancelled: Callable[[], bool] | None = None) -> dict:
    """Write the reference orthoimage of ``scene``'s ground (the true scene; every camera's
    footprint on ``dem`` plus the margin) with the texture of ``frame``
    (:func:`simulation.texture.texture_frame`) into an 8-bit GeoTIFF at ``path``. Default
    settings: :class:`ReferenceSettings` with pixels of 5 m or twice the scene's GSD, whichever
    is larger (a 60 km TH-1 scene stays at 44 Mpx).
    Returns its description (CRS, geotransform, settings, discs)."""
    settings = settings or ReferenceSettings(gsd=max(5.0, 2.0 * float(frame["gsd_m"])))
    settings.validate()
    cancelled = is_cancelled or (lambda: False)
    centre = tuple(frame["centre"])
    crs = utm_crs(*centre)
    grids = [default_grid(scene, k, dem, crs, settings.gsd) for k in range(len(scene.cameras))]
    res, m = settings.gsd, settings.margin
    x0 = math.floor((min(g.x0 for g in grids) - m) / res) * res
    y0 = math.ceil((max(g.y0 for g in grids) + m) / res) * res
    x1 = max(g.x0 + g.cols * res for g in grids) + m
    y1 = min(g.y0 - g.rows * res for g in grids) - m
    cols, rows = int(math.ceil((x1 - x0) / res)), int(math.ceil((y0 - y1) / res))
    rng = np.random.default_rng(seed + 104729)
    extent = (x0, y0 - rows * res, x0 + cols * res, y0)
    changed = patches(extent, settings.changed, settings.patch_radius, rng)
    clouds = patches(extent, settings.cloud, settings.patch_radius, rng)
    to_lonlat = Transformer.from_crs(crs, CRS.from_epsg(4326), always_xy=True)
    gsd_raw, tex_seed = float(frame["gsd_m"]), int(frame["seed"])
    halo = int(math.ceil(4 * settings.blur)) + 1

    def tile(r0: int) -> np.ndarray:
        if cancelled():
            raise Cancelled("simulation cancelled by the user")
        ra, rb = max(r0 - halo, 0), min(r0 + TILE_ROWS + halo, rows)
        x, y = np.meshgrid(x0 + (np.arange(cols) + 0.5) * res, y0 - (np.arange(ra, rb) + 0.5) * res)
        lon, lat = _lonlat(to_lonlat, x, y)
        v = texture_at(lon, lat, centre, gsd_raw, tex_seed).astype(np.float32)
        inside = disc_weight(x, y, changed, soft=False) > 0
        v[inside] = texture_at(lon[inside], lat[inside], centre, gsd_raw, tex_seed + CHANGED_SEED_OFFSET)
        cloud = disc_weight(x, y, clouds, soft=True)
        v = v + cloud * (1.05 - v)
        dn = radiometric_dn(v, settings.gain, settings.offset, settings.gamma)
        if settings.blur > 0:
            dn = gaussian_filter(dn, settings.blur, mode="nearest")
        dn = dn[r0 - ra:r0 - ra + min(TILE_ROWS, rows - r0)]
        noise = np.random.default_rng([seed, r0]).normal(0.0, settings.noise, dn.shape)
        return np.clip(np.rint(dn + noise), 0, 255).astype(np.uint8)

    ds = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Byte,
                                              ["TILED=YES", "COMPRESS=DEFLATE", "PREDICTOR=2", "BIGTIFF=IF_SAFER"])
    ds.SetGeoTransform((x0, res, 0.0, y0, 0.0, -res))
    ds.SetProjection(crs.to_wkt())
    ds.SetMetadata({"PUSHBROOM_REFERENCE": "simulated", "PUSHBROOM_TEXTURE_SEED": str(tex_seed)})
    band = ds.GetRasterBand(1)
    try:
        with ThreadPoolExecutor(max_workers=min(2, os.cpu_count() or 1)) as pool:
            for r0, block in zip(range(0, rows, TILE_ROWS), pool.map(tile, range(0, rows, TILE_ROWS))):
                band.WriteArray(block, 0, r0)
    finally:
        with closing_errors() as closing:
            band = ds = None  # closes the file, also when cancelled
    check_closed(path, closing)
    return {"file": os.path.basename(str(path)), "crs": f"EPSG:{crs.to_epsg()}",
            "geotransform": [x0, res, 0.0, y0, 0.0, -res], "size": [cols, rows],
            "settings": asdict(settings), "changed_discs_utm_m": changed.round(1).tolist(),
            "cloud_discs_utm_m": clouds.round(1).tolist()}
