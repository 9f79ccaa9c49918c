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
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import LinearNDInterpolator
from scipy.spatial import cKDTree

from . import corrections as corr
from .camera import Camera
from .errors import InputError
from .geodesy import ecef_to_geodetic, enu_rotation, geodetic_to_ecef, ray_height_intersection, up_vector
from .trajectory import Platform

log = logging.getLogger(__name__)

DEFAULT_HEIGHT_RANGE = (-500.0, 5000.0)


@dataclass
class SceneModel:
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

    def time_span(self) -> tuple[float, float]:
        """(first, last) acquisition time (s) over all cameras and chips."""
        ts = []
        for cam in self.cameras:
            t = cam.timing.time(np.array([0.0, cam.rows]))
            ts += [t.min() + min(cam._time_offsets), t.max() + max(cam._time_offsets)]
        return min(ts), max(ts)

    def prepare(self) -> None:
        """Tabulate the trajectory over the scene's time span (done once, lazily)."""
        if self.platform._cache is None:
            self.platform.prepare(*self.time_span())

    @property
    def height_range(self) -> tuple[float, float]:
        return tuple(self.info.get("height_range", DEFAULT_HEIGHT_RANGE))

    # --- image -> ground -----------------------------------------------------------------
    def line_of_sight(self, col, row, camera: int = 0):
        """Apparent lines of sight of image points.

        Returns (t (n,) s, S (n,3) ECEF m, v (n,3) m/s, u (n,3) apparent unit directions ECEF).
        """
        self.prepare()
        cam = self.cameras[camera]
        col, row = _as_points(col, row)
        k = cam.chip_index(col)
        t = cam.timing.time(row) + cam.time_offset(k)
        s, v, r = self.platform.state(t)
        los = cam.los_camera(col, k) @ cam.installation.T
        u = np.einsum("nij,nj->ni", r, los)
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        return t, s, v, u

    def _geometric_ray(self, s, v, u_app, rho) -> np.ndarray:
        """Geometric unit direction for apparent directions, given approximate ranges rho (m)."""
        if not self.aberration:
            return u_app
        return corr.geometric_from_apparent(u_app, corr.aberration_velocity(v, -rho[:, None] * u_app))

    def image_to_ground(self, col, row, height, camera: int = 0) -> np.ndarray:
        """ECEF points (n, 3) seen at image points (col, row) on the surface of ellipsoidal
        height ``height`` (m, scalar or (n,)). NaN where the ray misses."""
        return self._intersect(col, row, camera, lambda lon, lat, h_now: np.broadcast_to(height, np.shape(lon)))

    def image_to_ground_dem(self, col, row, dem, camera: int = 0, tol: float = 1e-4,
                            max_iter: int = 60) -> np.ndarray:
        """ECEF points (n, 3) where image rays meet a DEM (any object with ``height(lon, lat)``
        returning ellipsoidal metres, NaN where uncovered). NaN for rays that leave the DEM."""
        return self._intersect(col, row, camera, lambda lon, lat, h_now: dem.height(lon, lat),
                               tol=tol, max_iter=max_iter, h_start=np.mean(getattr(dem, "height_range", (0, 0))))

    def _intersect(self, col, row, camera, surface, tol=1e-4, max_iter=60, h_start=None) -> np.ndarray:
        """Intersect apparent rays with a surface h = surface(lon, lat, h_current).

        Each step intersects the (aberration-corrected) ray with the height the surface has
        under the current point, moving along the ray by the height misfit over the ray's
        vertical rate; refraction shifts the ground point toward nadir.
        """
        camera = self.camera_index(camera)
        _, s, v, u_app = self.line_of_sight(col, row, camera)
        n = s.shape[0]
        h0 = surface(*ecef_to_geodetic(s)[:2], None) if h_start is None else np.full(n, h_start)
        h0 = np.where(np.isfinite(h0), h0, np.nanmean(h0) if np.any(np.isfinite(h0)) else 0.0)
        u = self._geometric_ray(s, v, u_app, np.linalg.norm(s, axis=1) - 6.371e6)
        dist = ray_height_intersection(s, u, h0)
        u = self._geometric_ray(s, v, u_app, dist)
        dist = ray_height_intersection(s, u, h0)
        active = np.isfinite(dist)
        p = np.full((n, 3), np.nan)
        for _ in range(max_iter):
            idx = np.nonzero(active)[0]
            if idx.size == 0:
                break
            q = s[idx] + dist[idx, None] * u[idx]
            lon, lat, h = ecef_to_geodetic(q)
            up = up_vector(lon, lat)
            ground = q
            if self.refraction:
                hor, cos_z = corr.horizontal_direction(u[idx], up)
                ground = q - corr.refraction_offset(cos_z, h)[:, None] * hor
                lon, lat, _ = ecef_to_geodetic(ground)
            target = surface(lon, lat, h)
            misfit = h - target
            rate = np.einsum("ni,ni->n", u[idx], up)
            dist[idx] -= misfit / rate
            p[idx] = ground
            done = np.abs(misfit) < tol
            lost = ~np.isfinite(misfit)
            dist[idx[lost]] = np.nan
            p[idx[lost]] = np.nan
            if self.aberration:
                u[idx] = self._geometric_ray(s[idx], v[idx], u_app[idx], dist[idx])
            active[idx[done | lost]] = False
        if active.any():
            log.warning("%d rays did not settle on the surface within %d iterations", active.sum(), max_iter)
            p[active] = np.nan
        return p

    # --- ground -> image -----------------------------------------------------------------
    def ground_to_image(self, xyz, camera: int = 0, tol: float = 1e-8, max_iter: int = 30):
        """Image coordinates (col (n,), row (n,)) of ECEF points (n, 3) in one camera.

        Newton iteration on (col, row) from a first guess interpolated in a grid of the
        scene's own image->ground at two heights; staggered chips are tried in turn until
        the solution falls in the columns the chip delivers. NaN where no solution exists
        (point behind the camera or the iteration fails).
        """
        camera = self.camera_index(camera)
        self.prepare()
        cam = self.cameras[camera]
        p = np.atleast_2d(np.asarray(xyz, dtype=float))
        col, row = self._first_guess(camera, p)
        k = cam.chip_index(col)
        col, row, ok = self._solve_on_chip(cam, p, col, row, k, tol, max_iter)
        for _ in range(len(cam.chips)):
            k_new = cam.chip_index(col)
            redo = ok & (k_new != k)
            if not redo.any():
                break
            c2, r2, ok2 = self._solve_on_chip(cam, p[redo], col[redo], row[redo], k_new[redo], tol, max_iter)
            # In a gap between chips (neither owns the solution) keep the first chip's answer.
            back = ok2 & (cam.chip_index(c2) == k_new[redo])
            sel = np.nonzero(redo)[0][back]
            col[sel], row[sel], k[sel] = c2[back], r2[back], k_new[redo][back]
            if not back.any():
                break
        col[~ok] = np.nan
        row[~ok] = np.nan
        return col, row

    def _project(self, cam: Camera, p, row, k):
        """Normalised camera-frame coordinates (ux, uy) of ECEF points p seen at row on chip k."""
        t = cam.timing.time(row) + cam.time_offset(k)
        s, v, r = self.platform.state(t)
        g = p - s
        rho = np.linalg.norm(g, axis=1)
        u = g / rho[:, None]
        if self.refraction:
            up = up_vector(*ecef_to_geodetic(p)[:2])
            hor, cos_z = corr.horizontal_direction(u, up)
            shift = corr.refraction_offset(cos_z, ecef_to_geodetic(p)[2])
            g = g + shift[:, None] * hor
            rho = np.linalg.norm(g, axis=1)
            u = g / rho[:, None]
        if self.aberration:
            u = corr.apparent_from_geometric(u, corr.aberration_velocity(v, -g))
        w = np.einsum("nji,nj->ni", r, u) @ cam.installation  # ECEF -> body -> camera
        with np.errstate(divide="ignore", invalid="ignore"):
            ux = np.where(w[:, 2] > 0, w[:, 0] / w[:, 2], np.nan)
            uy = np.where(w[:, 2] > 0, w[:, 1] / w[:, 2], np.nan)
        return ux, uy

    def _solve_on_chip(self, cam: Camera, p, col, row, k, tol, max_iter):
        """Newton on (col, row) with the chip fixed.

        The Jacobian comes from one-pixel finite differences, refreshed on the first two
        steps and every fourth (a chord method: the geometry is nearly linear over a pixel).
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
            c, r, kk, pp = col[idx], row[idx], k[idx], p[idx]
            uxp, uyp = self._project(cam, pp, r, kk)
            uxd, uyd = cam.image_plane(c, kk)
            if jac is None or it < 2 or it % 4 == 0:
                uxp1, uyp1 = self._project(cam, pp, r + 1.0, kk)
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

    def _first_guess(self, camera: int, p) -> tuple[np.ndarray, np.ndarray]:
        """Interpolated (col, row) from a grid of image->ground at the scene's two bounding
        heights, in a local east-north frame; nearest grid node outside the grid."""
        g = self._guess.get(camera)
        if g is None:
            g = self._guess[camera] = self._build_guess_grid(camera)
        enu = (p - g["origin"]) @ g["rot"].T
        h = ecef_to_geodetic(p)[2]
        guesses = []
        for interp, tree, values in g["levels"]:
            est = interp(enu[:, :2])
            miss = ~np.all(np.isfinite(est), axis=1)
            if miss.any():
                est[miss] = values[tree.query(enu[miss, :2])[1]]
            guesses.append(est)
        (lo, hi) = g["heights"]
        w = np.clip((h - lo) / (hi - lo), -1.0, 2.0)[:, None]
        est = guesses[0] * (1 - w) + guesses[1] * w
        return est[:, 0].copy(), est[:, 1].copy()

    def _build_guess_grid(self, camera: int) -> dict:
        cam = self.cameras[camera]
        n_rows = int(np.clip(cam.rows / 256, 16, 4096))
        cols = np.linspace(0, cam.cols, 17)
        rows = np.linspace(0, cam.rows, n_rows)
        cc, rr = np.meshgrid(cols, rows)
        cc, rr = cc.ravel(), rr.ravel()
        lo, hi = self.height_range
        centre = self.image_to_ground(np.array([cam.cols / 2]), np.array([cam.rows / 2]), 0.5 * (lo + hi), camera)[0]
        lon0, lat0, _ = ecef_to_geodetic(centre)
        rot = enu_rotation(float(lon0), float(lat0))
        levels = []
        for h in (lo, hi):
            ground = self.image_to_ground(cc, rr, h, camera)
            ok = np.all(np.isfinite(ground), axis=1)
            if ok.sum() < 4:
                raise InputError(f"camera {cam.name!r}: its lines of sight do not reach the Earth at {h:.0f} m")
            en = ((ground[ok] - centre) @ rot.T)[:, :2]
            values = np.stack([cc[ok], rr[ok]], axis=1)
            levels.append((LinearNDInterpolator(en, values), cKDTree(en), values))
        return {"origin": centre, "rot": rot, "levels": levels, "heights": (lo, hi)}

    # --- convenience -------------------------------------------------------------------------
    def ground_to_image_geodetic(self, lon, lat, h, camera: int = 0):
        """ground_to_image for (lon, lat) degrees and ellipsoidal heights (m)."""
        return self.ground_to_image(geodetic_to_ecef(lon, lat, h), camera)


def _as_points(col, row) -> tuple[np.ndarray, np.ndarray]:
    col = np.atleast_1d(np.asarray(col, dtype=float))
    row = np.atleast_1d(np.asarray(row, dtype=float))
    col, row = np.broadcast_arrays(col, row)
    if not (np.all(np.isfinite(col)) and np.all(np.isfinite(row))):
        raise InputError("image coordinates contain NaN or infinite values")
    return col.astype(float), row.astype(float)
