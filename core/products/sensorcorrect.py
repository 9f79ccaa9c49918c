"""Sensor-corrected (virtual linear array) images: a raw pushbroom image resampled, through its
rigorous model, onto one straight, distortion-free virtual detector line with a constant line
period, so that one RPC describes the result to hundredths of a pixel.

A camera of several separately aligned CCD chips (staggered, rotated, shifted, distorted)
steps at the chip seams, which one smooth RPC cannot follow (about 1 px RMS, 2-3 px at the
seams on CBERS-02B HRC). The virtual camera has one chip of as many detectors as the image has
columns, on the line fitted through the real detectors' normalised image-plane coordinates
(so it sees the same ground), with the camera's focal length, the principal point on the
optical axis, no distortion, the camera's installation and the same platform trajectory
(with any adjustment correction); rows keep their first and last times, at a constant period.

For every virtual pixel (col, row) (GDAL convention, centres at +0.5) the ground point is the
virtual line of sight's intersection with the surface (DEM or constant height) and the raw
image position is that point's ground -> image through the real (adjusted) model; the raw
image is resampled there. The mapping is evaluated on a node grid and densified as in
:mod:`core.products.mapping` (checked per tile, cells along the former seams mapped pixel by pixel).
"""
from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Callable

import numpy as np
from osgeo import gdal_array

from ..model.camera import Camera, Chip, LineTiming
from ..dem import ConstantHeight, no_height_words, surface_name
from ..errors import InputError
from ..geodesy import ecef_to_geodetic
from ..files import atomic_outputs, check_destination
from .footprint import rays_without_height
from .mapping import Mapper
from .rawimage import RawImage, open_raw
from .resampling import check_resampling, write_resampled
from ..formats.rpcfiles import image_vrt_with_rpc, sidecar_path, write_rpc
from .rpcfit import dem_height_range, fit_rpc
from ..formats.scene_json import save_scene
from ..model.sensor import SceneModel
from ..validation import check_nodata

log = logging.getLogger(__name__)

CONSTANT_HEIGHT_SPAN = 500.0  # m each side of a constant height over which the RPC is fitted
LINE_SAMPLES = 4097           # columns at which the real detectors' image-plane coordinates are fitted
SEAM_ZONE = 6.0               # px from a chip boundary within which both chips' positions are compared
                              # (misaligned chips leave gaps and duplicates of up to a few px)


def virtual_camera(cam: Camera) -> Camera:
    """The virtual camera of a real one (any chips): one focal-plane chip of ``cam.cols``
    detectors at column 0, no distortion, principal point (0, 0), ``cam``'s focal length and
    installation; across track its detectors follow the straight line (uy linear in column)
    fitted by least squares through the real detectors' uy, along track they look at the mean
    ux of the chips with the smallest time offset (the chips whose rows are the image rows);
    constant line period from the first to the last row's time (a reverse scan: the two rows' times in a
    table), with no chip time offset."""
    cols = np.linspace(0.5, cam.cols - 0.5, min(LINE_SAMPLES, cam.cols))
    ux, uy = cam.image_plane(cols)
    slope, intercept = np.polyfit(cols, uy, 1)
    offsets = np.abs(cam.time_offset(cam.chip_index(cols)))
    ux0 = float(np.mean(ux[offsets == offsets.min()]))
    f = float(cam.focal_length)
    # detector d (col = d + 0.5) at y = y0 + d * pitch * cos(theta): theta 0 or pi sets the direction
    chip = Chip(col_offset=0.0, n_pixels=cam.cols, kind="focal_plane", x0=ux0 * f,
                y0=float(intercept + 0.5 * slope) * f, pitch=abs(float(slope)) * f,
                theta=0.0 if slope > 0 else np.pi, name=f"{cam.name}-virtual")
    t_first, t_last = (float(t) for t in cam.timing.time(np.array([0.5, cam.rows - 0.5])))
    period = (t_last - t_first) / (cam.rows - 1) if cam.rows > 1 else cam.timing.mean_period()
    # a reverse scan's times decrease with the row: a table of the first and last lines' times
    timing = LineTiming(t0=t_first, period=period) if period > 0 else \
        LineTiming(lines=np.array([0.0, cam.rows - 1.0]), times=np.array([t_first, t_last]))
    return Camera(name=cam.name, cols=cam.cols, rows=cam.rows, timing=timing,
                  chips=[chip], focal_length=f, principal_point=(0.0, 0.0), distortion={},
                  installation=cam.installation.copy())


def virtual_scene(scene: SceneModel, camera: int, info: dict | None = None) -> SceneModel:
    """A scene of the virtual camera of ``scene``'s camera ``camera`` (:func:`virtual_camera`):
    the same epoch, platform (with its correction) and corrections; ``info`` is the scene's (but
    its source file and reader warnings) with ``sensor_corrected`` saying how it was made (plus
    ``info``'s own entries there)."""
    cam = scene.cameras[camera]
    how = {"camera": cam.name, "chips": len(cam.chips),
           "virtual_camera": "one straight distortion-free detector line fitted through the real detectors, "
                             "focal length of the camera, principal point on the optical axis, constant line "
                             "period over the same time span"}
    how.update(info or {})
    inherited = {k: v for k, v in scene.info.items() if k not in ("source", "warnings")}  # of the real scene's file
    return SceneModel(epoch=scene.epoch, platform=scene.platform, cameras=[virtual_camera(cam)],
                      aberration=scene.aberration, refraction=scene.refraction,
                      info={**inherited, "sensor_corrected": how})


class VirtualMapper(Mapper):
    """Virtual image pixels -> raw image positions: the virtual line of sight on the surface,
    then the real camera's ground -> image. Pixels whose ray misses the surface are NaN. The
    virtual and real lines of sight nearly coincide, so the mapping hardly depends on the relief:
    it is checked at the cells' centres, the relief between the nodes bounded as for an
    orthoimage (the DEM's departure times the rate along the virtual line of sight), and cells
    where that could pass half the tolerance (tall buildings) mapped exactly."""

    maps_ground = False
    corrects_relief = False

    def __init__(self, scene: SceneModel, camera: int, virtual: SceneModel, surface):
        self.scene, self.camera, self.virtual, self.surface = scene, camera, virtual, surface
        self.cam = scene.cameras[camera]
        self.dem = surface if hasattr(surface, "values_at") else None

    def at_height_steps(self, i: np.ndarray, j: np.ndarray, steps) -> list[tuple[np.ndarray, np.ndarray]]:
        """Raw (col, row) of virtual positions (i, j) with their ground moved along the virtual line
        of sight by each of ``steps`` (m) in height from the surface's mean height."""
        h = float(np.mean(self.surface.height_range))
        col, row = np.ravel(j) + 0.5, np.ravel(i) + 0.5
        return [tuple(a.reshape(np.shape(i)) for a in self._raw_positions(self.virtual.image_to_ground(col, row,
                                                                                                      h + dh, 0)))
                for dh in steps]

    def _exact(self, i, j) -> tuple[np.ndarray, ...]:
        """:meth:`exact` (raw (col, row) of virtual positions: i = row, j = col, float, pixel-centre
        units), and with a DEM the DEM pixel coordinates (u, v) and values z of the ground points."""
        i, j = np.broadcast_arrays(np.asarray(i, dtype=float), np.asarray(j, dtype=float))
        ground = self.virtual.image_to_ground_dem(j.ravel() + 0.5, i.ravel() + 0.5, self.surface, 0)
        col, row = (a.reshape(i.shape) for a in self._raw_positions(ground))
        if self.dem is None:
            return col, row
        lon, lat, _ = ecef_to_geodetic(ground)
        u, v = self.dem.pixel_coordinates(lon, lat)
        return col, row, u.reshape(i.shape), v.reshape(i.shape), self.dem.values_at(u, v).reshape(i.shape)

    def _raw_positions(self, ground: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw (col, row) (n,) of ground points (n, 3); NaN where a point is; near a seam as
        :meth:`_across_seam` puts them."""
        col, row = np.full(len(ground), np.nan), np.full(len(ground), np.nan)
        ok = np.all(np.isfinite(ground), axis=1)
        if ok.any():
            col[ok], row[ok] = self.scene.ground_to_image(ground[ok], self.camera)
            bounds = np.array([c.col_offset for c in self.cam.chips[1:]] or [np.inf])
            near = ok & (np.abs(np.nan_to_num(col, nan=np.inf)[:, None] - bounds).min(axis=1) < SEAM_ZONE)
            if near.any():
                col[near], row[near] = self._across_seam(ground[near], col[near], row[near])
        return col, row

    def _across_seam(self, ground: np.ndarray, col: np.ndarray, row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw (col, row) of ground points (n, 3) near a seam, found at (col, row) on one chip, so that
        resampling reads only pixels that see them: the position on the left chip when it falls
        in or before the centre of that chip's last delivered column (b - 0.5, b the seam), else
        on the right chip when it falls in or after the centre of that chip's first (b + 0.5), and
        for ground in a gap between those two centres (misaligned chips) the point between them
        that divides the gap as the ground point does (distances in each chip's own pixels; the
        row likewise between the two chips' rows)."""
        starts = np.array([c.col_offset for c in self.cam.chips])
        right = np.argmin(np.abs(col[:, None] - starts[None, 1:]), axis=1) + 1
        b = starts[right]
        col_left, row_left = self.scene.ground_to_image_on_chip(ground, self.camera, right - 1, col, row)
        col_right, row_right = self.scene.ground_to_image_on_chip(ground, self.camera, right, col, row)
        past_left = col_left - (b - 0.5)      # > 0: beyond the left chip's last delivered centre
        before_right = (b + 0.5) - col_right  # > 0: before the right chip's first delivered centre
        with np.errstate(invalid="ignore", divide="ignore"):
            share = past_left / (past_left + before_right)
        left, inside = past_left <= 0, before_right <= 0
        out_col = np.where(left, col_left, np.where(inside, col_right, b - 0.5 + share))
        out_row = np.where(left, row_left, np.where(inside, row_right, row_left + share * (row_right - row_left)))
        ok = np.isfinite(out_col) & np.isfinite(out_row)
        return np.where(ok, out_col, col), np.where(ok, out_row, row)


def output_files(output_path) -> dict[str, Path]:
    """The files :func:`sensor_correct` writes beside its image ``<stem>.tif``: ``rpc``
    ``<stem>_RPC.TXT`` (GDAL finds it for the image), ``report`` its JSON, ``vrt`` ``<stem>.vrt``
    (the image with the RPC in its metadata)."""
    output_path = Path(output_path)
    rpc = sidecar_path(output_path)
    return {"rpc": rpc, "report": Path(f"{rpc}.json"), "vrt": output_path.with_suffix(".vrt")}


def rpc_height_range(scene: SceneModel, camera: int, surface) -> tuple[float, float]:
    """Heights (m, ellipsoidal) the RPC is fitted over: the DEM's over the image with a margin
    (:func:`core.products.rpcfit.dem_height_range`; InputError naming the DEM where it does not cover the
    image), or a constant height +- CONSTANT_HEIGHT_SPAN."""
    if isinstance(surface, ConstantHeight):
        return surface.value - CONSTANT_HEIGHT_SPAN, surface.value + CONSTANT_HEIGHT_SPAN
    return dem_height_range(scene, surface, camera)


def sensor_correct(scene: SceneModel, camera: int, image_path, surface, output_path, scene_path=None,
                   resampling: str = "bilinear", nodata: float | None = 0.0, tile: int = 512, step: int = 32,
                   max_error: float = 0.01, memory_budget: float = 2 ** 30, info: dict | None = None,
                   progress: Callable[[float, str | None], None] | None = None,
                   is_cancelled: Callable[[], bool] | None = None) -> dict:
    """Resample the raw image ``image_path`` of ``scene``'s camera ``camera`` onto its virtual
    camera (:func:`virtual_scene`) over ``surface`` (core.dem.Dem or ConstantHeight), and write,
    all or none: the image (tiled, compressed GeoTIFF with overviews, no georeferencing: raw
    image geometry) to ``output_path``, its RPC fitted to the virtual model beside it
    (:func:`output_files`: ``<stem>_RPC.TXT`` with its JSON report, and ``<stem>.vrt``), and with
    ``scene_path`` the virtual scene JSON. ``info`` goes into the virtual scene's
    ``sensor_corrected`` entry. Returns figures: files, seconds, densification error (px), the
    RPC check (rms/max px) and the virtual camera's line."""
    t_start = time.perf_counter()
    check_resampling(resampling, tile, step)
    camera = scene.camera_index(camera)
    cam = scene.cameras[camera]
    report = progress or (lambda fraction, message=None: None)
    src = open_raw(image_path, cam)
    if nodata is not None:
        check_nodata(nodata, gdal_array.GDALTypeCodeToNumericTypeCode(src.GetRasterBand(1).DataType))
    output_path = Path(output_path)
    paths = output_files(output_path)
    for path in (output_path, *paths.values(), *([scene_path] if scene_path else [])):
        check_destination(path)
    heights = rpc_height_range(scene, camera, surface)  # also: the DEM covers the image
    virtual = virtual_scene(scene, camera, {"resampling": resampling, "surface": surface_name(surface),
                                            **(info or {})})
    report(0.0, "virtual camera: image positions on the node grid")
    mapper = VirtualMapper(scene, camera, virtual, surface)
    raw = RawImage(image_path, src, memory_budget)
    cancelled = is_cancelled or (lambda: False)
    try:
        planned = mapper.nodes(0, cam.rows, 0, cam.cols, step, is_cancelled=cancelled)
        _check_coverage(planned, cam.rows, cam.cols, virtual, surface)
        report(0.1, "resampling the raw image")
        with atomic_outputs() as files:
            mapped = write_resampled(raw, mapper, planned, (cam.rows, cam.cols), output_path, resampling, nodata,
                                    tile, max_error, progress=lambda f: report(0.1 + 0.8 * f), is_cancelled=cancelled,
                                    files=files)
            raw.close()
            report(0.9, "fitting the RPC to the virtual camera")
            rpc, fit = fit_rpc(virtual, 0, heights)
            fit.update(image=str(output_path), scene=str(scene_path) if scene_path else None)
            write_rpc(rpc, paths["rpc"], fit, files)
            image_vrt_with_rpc(rpc, files.path(output_path), paths["vrt"], cam.cols, cam.rows, files,
                               shown_as=output_path)
            if scene_path:
                save_scene(virtual, scene_path, files)
    finally:
        raw.close()
    report(1.0, None)
    vcam = virtual.cameras[0]
    figures = {"image": str(output_path), **{k: str(v) for k, v in paths.items()},
               "scene": str(scene_path) if scene_path else None, "cols": cam.cols, "rows": cam.rows,
               "densification_error_px": mapped.error_px, "mapping": mapped.sentence(max_error, relief=False),
               "rpc_check_rms_px": fit["check"]["rms_px"],
               "rpc_check_max_px": fit["check"]["max_px"], "height_range": list(heights),
               "virtual_line": {"focal_length_m": vcam.focal_length, "pitch_m": vcam.chips[0].pitch,
                                "line_period_s": vcam.timing.mean_period()},
               "seconds": time.perf_counter() - t_start}
    log.info("sensor-corrected image %d x %d in %.1f s; %s; RPC check RMS %.4f px, "
             "max %.4f px", cam.cols, cam.rows, figures["seconds"], figures["mapping"], figures["rpc_check_rms_px"],
             figures["rpc_check_max_px"])
    if mapped.no_height:
        figures["holes"] = (f"{surface_name(surface)} "
                            f"{no_height_words(0, mapped.no_height, mapped.pixels, 'pixels of the image')}: "
                            "their lines of sight meet it only there; those pixels are nodata")
        log.warning(figures["holes"])
    return figures


def _check_coverage(planned, rows: int, cols: int, virtual: SceneModel, surface) -> None:
    """InputError naming the DEM when some of the virtual image's nodes have no ground point other
    than on the DEM's nodata holes (the DEM ends inside the footprint); pixels on holes stay nodata."""
    inside_rows = planned.r0 + np.arange(planned.ncol.shape[0]) * planned.step <= rows
    inside_cols = planned.c0 + np.arange(planned.ncol.shape[1]) * planned.step <= cols
    missing = ~np.isfinite(planned.ncol[np.ix_(inside_rows, inside_cols)])
    if not missing.any():
        return
    i, j = np.nonzero(missing)
    _, hole = rays_without_height(virtual, 0, planned.c0 + j * planned.step + 0.5,
                                  planned.r0 + i * planned.step + 0.5, surface)
    if not hole.all():
        words = no_height_words(int((~hole).sum()), int(hole.sum()), missing.size, "virtual pixels on the node grid")
        raise InputError(f"{surface_name(surface)} does not cover the image: it {words}; use a DEM covering the "
                         "whole footprint, or a constant height")
