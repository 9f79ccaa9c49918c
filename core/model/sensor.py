"""The rigorous pushbroom scene model: image <-> ground for every camera of a scene.

Frames and units: ground points are ECEF metres (EPSG:4978), shape (n, 3); image points
are GDAL (col, row) floats, shape (n,) each; heights are ellipsoidal metres; times are
seconds from ``SceneModel.epoch`` (a UTC ISO string).

For image row ``row`` on chip k the acquisition time is ``timing.time(row) + time_offset_k``;
the camera frame (x along track, y right, z toward the scene) is turned to the body by the
camera's installation and to ECEF by the attitude. Apparent lines of sight become geometric
ones through the velocity-aberration and atmospheric-refraction corrections, each switchable.
"""
from __future__ import annotations

import logging
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import LinearNDInterpolator
from scipy.spatial import cKDTree

from . import corrections as corr
from .camera import Camera
from .kinds import RigorousKind
from ..errors import InputError
from ..geodesy import ecef_to_geodetic, enu_rotation, geodetic_to_ecef, ray_height_intersection, up_vector
from ..validation import ground_points, per_point
from .trajectory import Platform

log = logging.getLogger(__name__)

DEFAULT_HEIGHT_RANGE = (-500.0, 5000.0)


@dataclass
class SceneModel(RigorousKind):
    """Cameras + platform trajectory + switchable corrections for one scene (or strip).

    info holds descriptive metadata (sensor, product id, source file, height_range ...).
    """
    epoch: str
    platform: Platform
    cameras: list[Camera]
    aberration: bool = False
    refraction: bool = False
    info: dict = field(default_factory=dict)
    _guess: dict = field(default_factory=dict, repr=False, compare=False)

    # --- set-up --------------------------------------------------------------------------
    def camera_index(self, camera: int | str) -> int:
        """Index of a camera given by index or name; raises InputError naming the choices."""
        if isinstance(camera, str):
            names = [c.name for c in self.cameras]
            if camera not in names:
                raise InputError(f"camera {camera!r} is not in this scene (cameras: {', '.join(names)})")
            return names.index(camera)
        if not 0 <= int(camera) < len(self.cameras):
            raise InputError(f"camera index {camera} is out of range (scene has {len(self.cameras)} cameras)")
        return int(camera)

    def time_span(self, cameras=None) -> tuple[float, float]:
        """(first, last) acquisition time (s) over all cameras (or the camera indices ``cameras``)
        and their chips. In a block's composite every camera's times count from its own scene's
        epoch: span only the cameras of one scene."""
        spans = self.time_spans(cameras)
        return min(a for a, _ in spans), max(b for _, b in spans)

    def time_spans(self, cameras=None) -> list[tuple[float, float]]:
        """[(first, last) acquisition time (s)] of each camera (or of the camera indices
        ``cameras``) over its lines and chips: a three-line camera's forward and backward views
        see the platform tens of seconds before and after the nadir view, and the gaps between
        need no table."""
        out = []
        for cam in (self.cameras if cameras is None else [self.cameras[c] for c in cameras]):
            t = cam.timing.time(np.array([0.0, cam.rows]))
            out.append((float(t.min() + min(cam.chip_time_offsets)), float(t.max() + max(cam.chip_time_offsets))))
        return out

    def prepare(self, camera: int | None = None) -> None:
        """Tabulate the trajectory over the cameras' time spans (done once, lazily): the platform
        camera ``camera`` (index) sees, or (None) each platform the cameras see (:meth:`platform_of`:
        the scene's, a camera's own correction, a block scene's), over the lines of all the cameras
        that see it. One camera's alone: a block's composite has a platform per scene, and work on
        one camera need not tabulate the others'."""
        if camera is not None and self.platform_of(camera).tabulated:
            return  # already tabulated: every projection asks, and a block's composite has hundreds of cameras
        platforms = [self.platform_of(c) for c in range(len(self.cameras))]
        wanted = platforms if camera is None else [platforms[camera]]
        for platform in {id(p): p for p in wanted}.values():
            if not platform.tabulated:
                platform.prepare(self.time_spans([c for c, p in enumerate(platforms) if p is platform]))

    def platform_of(self, camera: int) -> Platform:
        """The trajectory camera ``camera`` (index) sees: the platform's, or its own correction's
        (an adjustment with one trajectory correction per camera)."""
        return self.platform.for_camera(self.cameras[camera].name)

    @property
    def height_range(self) -> tuple[float, float]:
        return tuple(self.info.get("height_range", DEFAULT_HEIGHT_RANGE))

    # --- image -> ground -----------------------------------------------------------------
    def line_of_sight(self, col, row, camera: int = 0):
        """Apparent lines of sight of image points.

        Returns (t (n,) s, S (n,3) ECEF m, v (n,3) m/s, u (n,3) apparent unit directions ECEF).
        """
        self.prepare(camera)
        cam = self.cameras[camera]
        col, row = as_points(col, row)
        k = cam.chip_index(col)
        t = cam.timing.time(row) + cam.time_offset(k)
        s, v, r = self.platform_of(camera).state(t)
        los = cam.los_camera(col, k) @ cam.installation.T
        u = np.einsum("nij,nj->ni", r, los)
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        return t, s, v, u

    def _geometric_ray(self, s, v, u_app, rho) -> np.ndarray:
        """Geometric unit direction for apparent directions, given approximate ranges rho (m)."""
        if not self.aberration:
            return u_app
        # The light-time term depends on the geometric direction itself: one fixed-point pass
        # (starting from the apparent one) brings it to ~1e-16 rad.
        u = u_app
        for _ in range(2):
            u = corr.geometric_from_apparent(u_app, corr.aberration_velocity(v, -rho[:, None] * u))
        return u

    def image_to_ground(self, col, row, height, camera: int = 0) -> np.ndarray:
        """ECEF points (n, 3) seen at image points (col, row) on the surface of ellipsoidal
        height ``height`` (m): each a single value or (n,) (:func:`as_points`). NaN where the ray
        misses."""
        col, row, height = as_points(col, row, height=height)
        return self._intersect(col, row, camera, lambda lon, lat, idx: height[idx], h_start=height)

    def image_to_ground_dem(self, col, row, dem, camera: int = 0, tol: float = 1e-4,
                            max_iter: int = 30) -> np.ndarray:
        """ECEF points (n, 3) where image rays meet a DEM (any object with ``height(lon, lat)``
        returning ellipsoidal metres, NaN where uncovered). NaN for rays that leave the DEM."""
        return self._intersect(col, row, camera, lambda lon, lat, idx: dem.height(lon, lat),
                               h_start=np.mean(dem.height_range), h_range=dem.height_range, tol=tol,
                               max_iter=max_iter)

    def _intersect(self, col, row, camera, surface, h_start, h_range=None, tol=1e-4, max_iter=60) -> np.ndarray:
        """Intersect apparent rays with a surface: ``surface(lon, lat, idx)`` gives the
        ellipsoidal height (m) under points idx at (lon, lat); h_start is the first height.

        Each step intersects the (aberration-corrected) ray with the height the surface has
        under the current point, moving along the ray by the height misfit over the ray's
        vertical rate; refraction shifts the ground point toward nadir.
        """
        camera = self.camera_index(camera)
        col, row = as_points(col, row)
        self.prepare(camera)
        h_start = np.broadcast_to(h_start, col.shape)
        index = np.arange(col.size)
        h_range = (float(np.min(h_start)), float(np.max(h_start))) if h_range is None else h_range
        return in_chunks(lambda c, r, h0, idx: self._intersect_chunk(
            c, r, camera, lambda lon, lat, sub: surface(lon, lat, idx[sub]), h0, h_range, tol, max_iter),
            col, row, h_start, index)

    def _intersect_chunk(self, col, row, camera, surface, h0, h_range, tol, max_iter) -> np.ndarray:
        _, s, v, u_app = self.line_of_sight(col, row, camera)
        dist = ray_height_intersection(s, u_app, h0, newton_steps=0)
        u = self._geometric_ray(s, v, u_app, dist)
        dist = ray_height_intersection(s, u, h0, newton_steps=0)
        active = np.isfinite(dist)
        search = np.zeros(active.shape, bool)
        p = np.full(s.shape, np.nan)
        for _ in range(max_iter):
            idx = np.nonzero(active)[0]
            if idx.size == 0:
                break
            ground, misfit, rate = self._surface_misfit(s[idx], u[idx], dist[idx], idx, surface)
            # A point off the surface (a DEM's edge or hole) says nothing about where the ray
            # meets it: such rays are searched along their whole length below.
            lost = ~np.isfinite(misfit)
            done = np.abs(misfit) < tol
            keep = idx[~lost]
            dist[keep] -= misfit[~lost] / rate[~lost]
            p[idx] = ground
            if self.aberration:
                u[keep] = self._geometric_ray(s[keep], v[keep], u_app[keep], dist[keep])
            search[idx[lost]] = True
            active[idx[done | lost]] = False
        idx = np.nonzero(active | search)[0]
        if idx.size:
            p[idx] = self._first_crossing(s[idx], u[idx], idx, surface, h_range, tol)
        # The surface is met in front of the satellite or not at all: never a point behind it.
        behind = np.einsum("ni,ni->n", p - s, u) <= 0
        if behind.any():
            log.warning("%d lines of sight meet the surface only behind the satellite: no ground point",
                        behind.sum())
            p[behind] = np.nan
        return p

    def _surface_misfit(self, s, u, dist, idx, surface):
        """(ground point (n,3), height above the surface (n,), d height / d dist (n,)) for
        points ``dist`` along rays (s, u); refraction moves the ground point toward nadir."""
        q = s + dist[:, None] * u
        lon, lat, h = ecef_to_geodetic(q)
        up = up_vector(lon, lat)
        ground = q
        if self.refraction:
            hor, cos_z = corr.horizontal_direction(u, up)
            ground = q - corr.refraction_offset(cos_z, h)[:, None] * hor
            lon, lat, _ = ecef_to_geodetic(ground)
        return ground, h - surface(lon, lat, idx), np.einsum("ni,ni->n", u, up)

    def _first_crossing(self, s, u, idx, surface, h_range, tol) -> np.ndarray:
        """Ground points where rays first cross the surface, by stepping down from the top of
        its height range and bisecting: for steep terrain seen obliquely, where Newton that
        ignores the slope oscillates, and for rays whose Newton point fell off the surface (a
        DEM's edge or hole). NaN where a ray does not cross where the surface is defined."""
        top = ray_height_intersection(s, u, h_range[1] + 1.0, newton_steps=0)
        bottom = ray_height_intersection(s, u, h_range[0] - 1.0, newton_steps=0)
        steps = np.linspace(0.0, 1.0, 129)
        d = top[:, None] + (bottom - top)[:, None] * steps
        n, m = d.shape
        _, misfit, _ = self._surface_misfit(np.repeat(s, m, 0), np.repeat(u, m, 0), d.ravel(),
                                            np.repeat(idx, m), surface)
        misfit = misfit.reshape(n, m)
        below = misfit <= 0
        found = below[:, 1:].any(axis=1)
        j = np.argmax(below[:, 1:], axis=1) + 1
        rows = np.arange(n)
        lo, hi, misfit_lo = d[rows, j - 1], d[rows, j], misfit[rows, j - 1]
        while np.nanmax(np.where(found, hi - lo, 0.0), initial=0.0) > tol:
            mid = 0.5 * (lo + hi)
            _, misfit, _ = self._surface_misfit(s, u, mid, idx, surface)
            above = ~(misfit <= 0)  # off the surface (NaN) too: a crossing may lie further on
            lo, misfit_lo = np.where(above, mid, lo), np.where(above, misfit, misfit_lo)
            hi = np.where(above, hi, mid)
        # A ray that comes onto the surface (past a DEM's edge or out of a hole) already below it
        # crosses where the surface is unknown: that point on the edge is not on the ground.
        found &= misfit_lo > 0
        ground, _, _ = self._surface_misfit(s, u, 0.5 * (lo + hi), idx, surface)
        ground[~found] = np.nan
        if (~found).any():
            log.warning("%d rays do not meet the surface where it is defined (they pass off its "
                        "edge or through a hole, or outside its height range)", (~found).sum())
        return ground

    # --- ground -> image -----------------------------------------------------------------
    def ground_to_image(self, xyz, camera: int = 0, tol: float = 1e-5, max_iter: int = 30):
        """Image coordinates (col (n,), row (n,)) of ECEF points (n, 3), or of one point (3,), in one
        camera (InputError naming ``xyz`` for other shapes: core.validation.ground_points).

        Newton iteration on (col, row) from a first guess interpolated in rasters of the
        scene's own image->ground at two heights; staggered chips are tried in turn until the
        solution falls in the columns the chip delivers. NaN where no solution exists (point
        behind the camera, or the iteration fails). Runs in chunks on all cores.

        tol (px) bounds the last Newton step; the Jacobian is accurate to ~1e-5 relative, so
        the error left after a step below tol is ~1e-5 * tol.
        """
        camera = self.camera_index(camera)
        p = ground_points(xyz)
        self.prepare(camera)
        if camera not in self._guess:
            self._guess[camera] = self._build_guess_rasters(camera)
        return in_chunks(lambda q: self._ground_to_image_chunk(q, camera, tol, max_iter), p)

    def clear_guesses(self) -> None:
        """Forget the first-guess rasters of :meth:`ground_to_image` (after its corrections changed)."""
        self._guess.clear()

    def _ground_to_image_chunk(self, p, camera: int, tol: float, max_iter: int):
        cam = self.cameras[camera]
        lon, lat, height = ecef_to_geodetic(p)
        up = up_vector(lon, lat)
        col, row = self._first_guess(camera, p, height)
        k = cam.chip_index(col)
        col, row, ok = self._newton(cam, p, up, height, col, row, k, tol, max_iter)
        for _ in range(len(cam.chips)):
            k_new = cam.chip_index(col)
            redo = ok & (k_new != k)
            if not redo.any():
                break
            c2, r2, ok2 = self._newton(cam, p[redo], up[redo], height[redo], col[redo], row[redo], k_new[redo],
                                       tol, max_iter)
            # In a gap between chips (neither owns the solution) keep the first chip's answer.
            back = ok2 & (cam.chip_index(c2) == k_new[redo])
            sel = np.nonzero(redo)[0][back]
            col[sel], row[sel], k[sel] = c2[back], r2[back], k_new[redo][back]
            if not back.any():
                break
        col[~ok] = np.nan
        row[~ok] = np.nan
        return col, row

    def _project(self, cam: Camera, p, row, k, up, height):
        """Normalised camera-frame coordinates (ux, uy) of ECEF points p (n,3), with local up
        vectors (n,3) and ellipsoidal heights (n,), seen at image row(s) ``row`` on chip(s) k."""
        t = cam.timing.time(row) + cam.time_offset(k)
        s, v, r = self.platform.for_camera(cam.name).state(t)
        g = p - s
        if self.refraction:
            hor, cos_z = corr.horizontal_direction(g / np.linalg.norm(g, axis=1, keepdims=True), up)
            g = g + corr.refraction_offset(cos_z, height)[:, None] * hor
        u = g / np.linalg.norm(g, axis=1, keepdims=True)
        if self.aberration:
            u = corr.apparent_from_geometric(u, corr.aberration_velocity(v, -g))
        w = np.einsum("nji,nj->ni", r, u) @ cam.installation  # ECEF -> body -> camera
        with np.errstate(divide="ignore", invalid="ignore"):
            front = w[:, 2] > 0
            return np.where(front, w[:, 0] / w[:, 2], np.nan), np.where(front, w[:, 1] / w[:, 2], np.nan)

    def _newton(self, cam: Camera, p, up, height, col, row, k, tol, max_iter):
        """Newton on (col, row) with the chip fixed.

        The Jacobian comes from one-pixel finite differences at the first step, refreshed
        every fourth (a chord method: the geometry is nearly linear over a pixel).
        Returns (col, row, converged).
        """
        col = col.copy()
        row = row.copy()
        ok = np.isfinite(col) & np.isfinite(row)
        active = ok.copy()
        lim = 4.0 * max(cam.rows, cam.cols)
        jac = None
        for it in range(max_iter):
            idx = np.nonzero(active)[0]
            if idx.size == 0:
                break
            c, r, kk, pp, upp, hh = col[idx], row[idx], k[idx], p[idx], up[idx], height[idx]
            uxp, uyp = self._project(cam, pp, r, kk, upp, hh)
            uxd, uyd = cam.image_plane(c, kk)
            if jac is None or it % 4 == 0:
                uxp1, uyp1 = self._project(cam, pp, r + 1.0, kk, upp, hh)
                uxd1, uyd1 = cam.image_plane(c + 1.0, kk)
                jac = (uxp1 - uxp, uxd - uxd1, uyp1 - uyp, uyd - uyd1)  # d(residual)/d(row, col)
            j11, j12, j21, j22 = jac
            rx, ry = uxp - uxd, uyp - uyd
            det = j11 * j22 - j12 * j21
            with np.errstate(divide="ignore", invalid="ignore"):
                drow = np.clip(-(j22 * rx - j12 * ry) / det, -lim, lim)
                dcol = np.clip(-(j11 * ry - j21 * rx) / det, -lim, lim)
            bad = ~(np.isfinite(drow) & np.isfinite(dcol))
            row[idx] = r + np.where(bad, 0.0, drow)
            col[idx] = c + np.where(bad, 0.0, dcol)
            done = ~bad & (np.abs(drow) < tol) & (np.abs(dcol) < tol)
            ok[idx[bad]] = False
            active[idx[done | bad]] = False
            keep = ~(done | bad)
            jac = tuple(a[keep] for a in jac)
        ok &= ~active
        return col, row, ok

    def _first_guess(self, camera: int, p, height) -> tuple[np.ndarray, np.ndarray]:
        """(col, row) first guesses for ECEF points p (n, 3) at ellipsoidal heights (n,).

        Looked up bilinearly in rasters of the inverse mapping (east, north) -> (col, row)
        at the scene's two bounding heights, then interpolated linearly in height. The rasters
        are built once per camera from a grid of exact image->ground; a point off the raster
        takes the nearest grid node. Newton refines the guess, so only closeness matters.
        """
        g = self._guess[camera]
        enu = (p - g["origin"]) @ g["rot"].T
        e0, n0, step, (ny, nx) = g["raster"]
        fx = (enu[:, 0] - e0) / step
        fy = (enu[:, 1] - n0) / step
        inside = (fx >= 0) & (fy >= 0) & (fx <= nx - 1) & (fy <= ny - 1)
        fx = np.clip(fx, 0, nx - 1.000001)
        fy = np.clip(fy, 0, ny - 1.000001)  # cells are (ny - 1) x (nx - 1)
        j0, i0 = fx.astype(np.int64), fy.astype(np.int64)
        wx, wy = (fx - j0)[:, None], (fy - i0)[:, None]
        # One gather per point of its cell's four corners' (col, row) at both heights (p, 4, 4).
        corners = g["table"][(i0 * nx + j0)[:, None] + np.array([0, 1, nx, nx + 1])]
        top = corners[:, 0] * (1 - wx) + corners[:, 1] * wx
        bottom = corners[:, 2] * (1 - wx) + corners[:, 3] * wx
        est = top * (1 - wy) + bottom * wy
        lo, hi = g["heights"]
        w = np.clip((height - lo) / (hi - lo), -1.0, 2.0)[:, None]
        est = est[:, :2] * (1 - w) + est[:, 2:] * w
        miss = ~inside | ~np.all(np.isfinite(est), axis=1)
        if miss.any():
            est[miss] = g["nodes"][g["tree"].query(enu[miss, :2])[1]]
        return est[:, 0].copy(), est[:, 1].copy()

    def _build_guess_rasters(self, camera: int) -> dict:
        cam = self.cameras[camera]
        n_rows = int(np.clip(cam.rows / 256, 16, 4096))
        cc, rr = (a.ravel() for a in np.meshgrid(np.linspace(0, cam.cols, 17), np.linspace(0, cam.rows, n_rows)))
        lo, hi = self.height_range
        centre = self.image_to_ground(np.array([cam.cols / 2]), np.array([cam.rows / 2]), 0.5 * (lo + hi), camera)[0]
        if not np.all(np.isfinite(centre)):
            raise InputError(f"camera {cam.name!r}: the image centre's line of sight does not reach the Earth")
        rot = enu_rotation(*(float(a) for a in ecef_to_geodetic(centre)[:2]))
        nodes = np.stack([cc, rr], axis=1)
        ens = []
        for h in (lo, hi):
            ground = self.image_to_ground(cc, rr, h, camera)
            ens.append(((ground - centre) @ rot.T)[:, :2])
        all_en = np.concatenate(ens)
        ok = np.all(np.isfinite(all_en), axis=1)
        if ok.sum() < 8:
            raise InputError(f"camera {cam.name!r}: its lines of sight do not reach the Earth")
        lo_en, hi_en = all_en[ok].min(axis=0), all_en[ok].max(axis=0)
        step = float(np.sqrt(np.prod(hi_en - lo_en) / 250_000.0)) or 1.0
        shape = (int((hi_en[1] - lo_en[1]) / step) + 2, int((hi_en[0] - lo_en[0]) / step) + 2)
        gy, gx = np.mgrid[0:shape[0], 0:shape[1]]
        query = np.stack([lo_en[0] + gx.ravel() * step, lo_en[1] + gy.ravel() * step], axis=1)
        tables = []
        for en in ens:
            good = np.all(np.isfinite(en), axis=1)
            tables.append(LinearNDInterpolator(en[good], nodes[good])(query))
        good = np.all(np.isfinite(ens[0]), axis=1)
        # (col, row) at both heights per raster node (ny * nx, 4), row-major
        return {"origin": centre, "rot": rot, "heights": (lo, hi), "table": np.hstack(tables),
                "raster": (lo_en[0], lo_en[1], step, shape), "tree": cKDTree(ens[0][good]), "nodes": nodes[good]}

    def ground_to_image_on_chip(self, xyz, camera: int, chip, col, row, tol: float = 1e-5,
                                max_iter: int = 30) -> tuple[np.ndarray, np.ndarray]:
        """Image (col (n,), row (n,)) of ECEF points (n, 3) on the given chip(s) (index, scalar or
        (n,)), whose detector line is extended beyond the columns the chip delivers (where two
        chips meet, the position on each), by Newton from first guesses (col, row). NaN where
        it fails."""
        camera = self.camera_index(camera)
        cam = self.cameras[camera]
        p = np.atleast_2d(np.asarray(xyz, dtype=float))
        self.prepare(camera)
        lon, lat, height = ecef_to_geodetic(p)
        k = np.broadcast_to(np.asarray(chip, dtype=int), (p.shape[0],))
        col, row, ok = self._newton(cam, p, up_vector(lon, lat), height, np.asarray(col, dtype=float),
                                    np.asarray(row, dtype=float), k, tol, max_iter)
        return np.where(ok, col, np.nan), np.where(ok, row, np.nan)

    def ground_to_image_near(self, xyz, camera: int, col, row) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`ground_to_image` of ECEF points (n, 3) in one camera from first guesses (col,
        row) (n,) px near the answers (a point's measurement, its last projection): Newton's method
        on the guess's chip from there, where it converges on that chip; elsewhere (another chip,
        no convergence, guesses far off) :meth:`ground_to_image` itself. The answers are the
        same; the guesses spare it the first-guess raster it builds per camera (a tenth of a
        second and 8 MB each: a block's composite has dozens of cameras)."""
        camera = self.camera_index(camera)
        cam = self.cameras[camera]
        col, row = (np.asarray(a, dtype=float) for a in (col, row))
        chip = cam.chip_index(col)
        got_col, got_row = self.ground_to_image_on_chip(xyz, camera, chip, col, row)
        on_chip = np.isfinite(got_col) & np.isfinite(got_row)
        on_chip[on_chip] = cam.chip_index(got_col[on_chip]) == chip[on_chip]
        if not on_chip.all():
            got_col[~on_chip], got_row[~on_chip] = self.ground_to_image(np.atleast_2d(xyz)[~on_chip], camera)
        return got_col, got_row

    # --- convenience -------------------------------------------------------------------------
    def ground_to_image_geodetic(self, lon, lat, h, camera: int = 0):
        """ground_to_image for (lon, lat) degrees and ellipsoidal heights (m), each a single value or
        (n,) (core.validation.per_point)."""
        return self.ground_to_image(geodetic_to_ecef(*per_point(lon=lon, lat=lat, h=h)), camera)


CHUNK = 32768


def rows_by(key: np.ndarray, n_keys: int) -> list[np.ndarray]:
    """The rows (ascending indices) of each key 0..n_keys-1 of ``key`` (n,) int: one stable sort
    rather than a comparison of every row per key (a block's composite has dozens of cameras)."""
    order = np.argsort(key, kind="stable")
    return np.split(order, np.cumsum(np.bincount(key, minlength=n_keys))[:-1])


def in_chunks(func, *arrays):
    """Apply func to consecutive chunks of the arrays (split along axis 0; after the first, any
    object sliced by ``[a:b]``) on a thread per core, and concatenate its results (one array, or
    a tuple of arrays). numpy releases the GIL in its kernels, and chunks keep temporaries in
    cache."""
    n = arrays[0].shape[0]
    if n <= CHUNK:
        return func(*arrays)
    bounds = range(0, n, CHUNK)
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        parts = list(pool.map(lambda b: func(*(a[b:b + CHUNK] for a in arrays)), bounds))
    if isinstance(parts[0], tuple):
        return tuple(np.concatenate(p) for p in zip(*parts))
    return np.concatenate(parts)


def as_points(col, row, **values) -> tuple[np.ndarray, ...]:
    """Image points (GDAL px) and other per-point ``values`` given by name (height=...) as float
    arrays of one shape (n,), each given as a single value or (n,) (core.validation.per_point):
    (col, row, *values). InputError naming the argument for lengths that differ, other shapes, and
    NaN or infinite values."""
    arrays = {"col": col, "row": row, **values}
    out = tuple(np.asarray(a, dtype=float) for a in per_point(**arrays))
    for name, a in zip(arrays, out):
        if not np.all(np.isfinite(a)):
            raise InputError(f"{name}: contains NaN or infinite values")
    return out
