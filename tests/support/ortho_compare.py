"""Comparing orthoimages: with the known texture of a rendered simulated scene, and with
another orthoimage of the same grid (the shift between them by least squares on image
gradients, overall and per block), and our mapping with GDAL's RPC transformer."""
from __future__ import annotations

import numpy as np
from osgeo import gdal
from pyproj import CRS, Transformer

from dataclasses import replace

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.products.mapping import Mapper, MappingFigures, OrthoGrid
from pushbroom_adjust.simulation.texture import texture_at, texture_frame
from pushbroom_adjust.simulation.render import render_image
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.scene_json import save_scene
from pushbroom_adjust.simulation.simulator import simulate

gdal.UseExceptions()


def rendered_cut(folder, seed: int, rows: int, model: str = "true_scene", surface=None,
                 preset: str = "cbers02b_hrc"):
    """A scene of ``preset`` (default CBERS-02B) simulated into ``folder``, its ``model``
    (true_scene or onboard_scene) cut to the first camera's first ``rows`` rows, and the cut's
    raw image rendered from the texture into folder/raw.tif over ``surface`` (default: the
    simulated DEM). Returns (cut scene, simulation result, geoid DEM, texture frame)."""
    result = simulate(preset, folder, seed=seed, n_gcps=5)
    full = load_scene(getattr(result, model))
    scene = replace(full, cameras=[replace(full.cameras[0], rows=rows)], _guess={})
    dem = Dem(result.dem, datum="geoid")
    frame = texture_frame(full, dem, seed)
    render_image(scene, 0, surface or dem, folder / "raw.tif", frame)
    return scene, result, dem, frame


def saved_cut(folder, seed: int, rows: int) -> tuple[str, str, str]:
    """(scene JSON, raw image, geoid DEM) paths of a :func:`rendered_cut` of the true camera,
    the cut scene saved as folder/cut.json."""
    scene, result, _, _ = rendered_cut(folder, seed=seed, rows=rows)
    save_scene(scene, folder / "cut.json")
    return str(folder / "cut.json"), str(folder / "raw.tif"), str(result.dem)


def rendered_cameras(folder, preset: str, seed: int, rows: int, n_scenes: int = 1):
    """A ``preset`` strip of ``n_scenes`` simulated into ``folder``, its true scene cut to the
    first ``rows`` rows of every camera (``info.n_scenes`` kept: the cut is a strip of
    ``n_scenes`` scenes of rows / n_scenes rows), and each camera's cut rendered into
    folder/raw_<CAMERA>.tif. Returns (cut scene, simulation result, geoid DEM, texture frame,
    image paths by camera index)."""
    result = simulate(preset, folder, seed=seed, n_scenes=n_scenes, n_gcps=5)
    full = load_scene(result.true_scene)
    scene = replace(full, cameras=[replace(cam, rows=rows) for cam in full.cameras], _guess={})
    dem = Dem(result.dem, datum="geoid")
    frame = texture_frame(full, dem, seed)
    images = {}
    for k, cam in enumerate(scene.cameras):
        images[k] = str(folder / f"raw_{cam.name}.tif")
        render_image(scene, k, dem, images[k], frame)
    return scene, result, dem, frame, images


def gdalwarp_rpc(raw, dem_path, grid: OrthoGrid, output) -> None:
    """gdalwarp with the RPC beside ``raw`` and RPC_DEM ``dem_path``, bilinear, onto ``grid``."""
    gdal.Warp(str(output), str(raw), rpc=True, transformerOptions=[f"RPC_DEM={dem_path}"],
              dstSRS=grid.crs.to_wkt(), outputBounds=(grid.x0, grid.y0 - grid.rows * grid.resolution,
                                                      grid.x0 + grid.cols * grid.resolution, grid.y0),
              width=grid.cols, height=grid.rows, resampleAlg="bilinear", dstNodata=0)


def shift_against_texture(path, frame, mask=None, n: int = 400_000) -> tuple[np.ndarray, int]:
    """(dx, dy) px of the orthoimage against the texture: least squares on the texture's
    gradient at up to n sampled valid pixels (inside ``mask`` if given), and how many were used."""
    ds = gdal.Open(str(path))
    gt = ds.GetGeoTransform()
    img = ds.GetRasterBand(1).ReadAsArray().astype(float)
    ok = img > 0
    ok[[0, -1], :] = ok[:, [0, -1]] = False
    if mask is not None:
        ok &= mask
    i, j = np.nonzero(ok)
    pick = np.random.default_rng(0).choice(i.size, min(n, i.size), replace=False)
    i, j = i[pick], j[pick]
    to_lonlat = Transformer.from_crs(CRS.from_wkt(ds.GetProjection()), CRS.from_epsg(4326), always_xy=True)

    def truth(di=0.0, dj=0.0):
        lon, lat = to_lonlat.transform(gt[0] + (j + 0.5 + dj) * gt[1], gt[3] + (i + 0.5 + di) * gt[5])
        return 20.0 + 215.0 * texture_at(lon, lat, tuple(frame["centre"]), frame["gsd_m"], frame["seed"])

    t0 = truth()
    gx = (truth(dj=0.5) - truth(dj=-0.5))
    gy = (truth(di=0.5) - truth(di=-0.5))
    d, *_ = np.linalg.lstsq(np.stack([gx, gy], axis=1), img[i, j] - t0, rcond=None)
    return -d, int(i.size)


def shift_normals(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Normal equations (N 2x2, u 2) of the shift (dx, dy) px of b against a, by least squares
    on a's gradients where both are valid and textured, and the number of pixels used."""
    gy, gx = np.gradient(a)
    ok = (a > 0) & (b > 0)
    ok[[0, -1], :] = ok[:, [0, -1]] = False
    ok &= np.hypot(gx, gy) > 1
    g = np.stack([gx[ok], gy[ok]], axis=1).astype(np.float64)
    return g.T @ g, g.T @ (a - b)[ok].astype(np.float64), int(ok.sum())


def read_band(path: str) -> np.ndarray:
    ds = gdal.Open(path)  # held while reading: a band outliving its dataset crashes GDAL
    return ds.GetRasterBand(1).ReadAsArray().astype(np.float32)


def image_difference(ours: str, theirs: str, blocks: int = 8) -> dict:
    """Shift of gdalwarp's orthoimage against ours: overall and the largest of blocks x blocks
    blocks (with over 50 000 textured pixels), mean |difference| and coverage differences."""
    a, b = (read_band(path) for path in (ours, theirs))
    total_n, total_u, used, worst = np.zeros((2, 2)), np.zeros(2), 0, 0.0
    h, w = a.shape
    for bi in range(blocks):
        for bj in range(blocks):
            sl = np.s_[bi * h // blocks:(bi + 1) * h // blocks, bj * w // blocks:(bj + 1) * w // blocks]
            n, u, count = shift_normals(a[sl], b[sl])
            total_n, total_u, used = total_n + n, total_u + u, used + count
            if count > 50_000:
                worst = max(worst, float(np.hypot(*np.linalg.solve(n, u))))
    both = (a > 0) & (b > 0)
    return {"shift_px": [float(v) for v in np.linalg.solve(total_n, total_u)], "pixels": used,
            "worst_block_shift_px": worst, "mean_abs_difference_dn": float(np.mean(np.abs(a - b)[both])),
            "coverage_only_ours": int(((a > 0) & ~(b > 0)).sum()), "coverage_only_gdal": int((~(a > 0) & (b > 0)).sum())}


def gdal_rpc_against_rigorous(scene, dem_path, raw_path, grid: OrthoGrid, n: int = 200_000,
                              seed: int = 1) -> np.ndarray:
    """|image position by our rigorous model - by GDAL's RPC transformer| (px of the raw image)
    at n random output positions of ``grid`` that fall inside the image, both on the DEM at
    ``dem_path`` (ellipsoidal heights; GDAL reads the RPC beside ``raw_path``)."""
    mapper = Mapper(scene, 0, Dem(dem_path, datum="ellipsoid"), grid)
    rng = np.random.default_rng(seed)
    i, j = rng.uniform(0, grid.rows, n), rng.uniform(0, grid.cols, n)
    col, row = mapper.exact(i - 0.5, j - 0.5)  # exact() takes pixel-centre units
    lon, lat = mapper.to_lonlat.transform(grid.x0 + j * grid.resolution, grid.y0 - i * grid.resolution)
    raw = gdal.Open(str(raw_path))
    tr = gdal.Transformer(raw, None, ["METHOD=RPC", f"RPC_DEM={dem_path}"])
    pts = np.array(tr.TransformPoints(1, np.stack([lon, lat, np.zeros_like(lon)], axis=1).tolist())[0])
    inside = (col > 1) & (col < raw.RasterXSize - 1) & (row > 1) & (row < raw.RasterYSize - 1)
    return np.hypot(pts[:, 0] - col, pts[:, 1] - row)[inside]


def mapped_positions(mapper: Mapper, grid: OrthoGrid, step: int = 32, tile: int = 512, max_error: float = 0.01):
    """(col, row, MappingFigures) of every output pixel of ``grid`` as orthorectify maps them
    (the planned node grid, then tile by tile)."""
    planned = mapper.nodes(0, grid.rows, 0, grid.cols, step)
    col, row = np.empty((grid.rows, grid.cols)), np.empty((grid.rows, grid.cols))
    figures = MappingFigures()
    for r0 in range(0, grid.rows, tile):
        for c0 in range(0, grid.cols, tile):
            r1, c1 = min(r0 + tile, grid.rows), min(c0 + tile, grid.cols)
            col[r0:r1, c0:c1], row[r0:r1, c0:c1], tiled = mapper.tile(r0, r1, c0, c1, step, max_error, planned)
            figures = figures.merge(tiled)
    return col, row, figures


def exact_errors(mapper: Mapper, grid: OrthoGrid, col: np.ndarray, row: np.ndarray) -> np.ndarray:
    """|mapped - exact| image position (px) at every output pixel of ``grid`` that lies in the image
    (the exact model: the scene's ground -> image of the pixel's ground point at the DEM's height);
    AssertionError where one has a position and the other not."""
    i, j = np.meshgrid(np.arange(grid.rows, dtype=float), np.arange(grid.cols, dtype=float), indexing="ij")
    ecol, erow = mapper.exact_many(i, j)
    assert np.array_equal(np.isfinite(ecol), np.isfinite(col)), "pixels with a position in one mapping only"
    inside = mapper.in_image(ecol, erow)
    return np.hypot(col - ecol, row - erow)[inside]
