"""Simulated point measurements: ground control, check and tie points placed on the DEM and
measured in every camera of the true scene that sees them (noise, gross errors), and the CSV
files they are written to.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.dem import Dem
from ..core.errors import InputError
from ..core.geodesy import A, ecef_to_geodetic
from ..core.model.sensor import SceneModel


NEAR_MARGIN_DEG = 0.02  # about 2 km: far beyond how a camera's border curves between its 65 samples per edge


@dataclass
class GcpSettings:
    """How points are measured. n_gcps: ground points placed uniformly over the reference
    camera's image; check_fraction: share made check points; image_noise (px), ground_noise_xy
    / ground_noise_z (m): standard deviations; gross_fraction: share of image measurements
    displaced by gross_min..gross_max px in a random direction; n_tie_points: ground points
    measured (without ground coordinates) in every camera that sees them."""
    n_gcps: int = 200
    check_fraction: float = 0.0
    image_noise: float = 0.3
    ground_noise_xy: float = 0.0
    ground_noise_z: float = 0.0
    gross_fraction: float = 0.0
    gross_min: float = 5.0
    gross_max: float = 100.0
    n_tie_points: int = 0

    def validate(self) -> None:
        for name in ("n_gcps", "n_tie_points", "image_noise", "ground_noise_xy", "ground_noise_z", "gross_min"):
            if not getattr(self, name) >= 0:
                raise InputError(f"{name} must be >= 0 (got {getattr(self, name)})")
        for name in ("check_fraction", "gross_fraction"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise InputError(f"{name} must be between 0 and 1 (got {getattr(self, name)})")
        if self.gross_max < self.gross_min:
            raise InputError(f"gross_max ({self.gross_max}) must not be below gross_min ({self.gross_min})")


def place_ground_points(scene: SceneModel, dem: Dem, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(ECEF points (n, 3) on the DEM, their rows (n,)) seen at uniformly random positions
    of camera 0."""
    cam = scene.cameras[0]
    col = rng.uniform(0.0, cam.cols, n)
    row = rng.uniform(0.0, cam.rows, n)
    ground = scene.image_to_ground_dem(col, row, dem, 0)
    if not np.all(np.isfinite(ground)):
        raise InputError(f"{int((~np.isfinite(ground[:, 0])).sum())} simulated points miss the DEM")
    return ground, row


def observe(scene: SceneModel, ground: np.ndarray) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """Noise-free image positions of ECEF points in every camera: a list of (camera index,
    point indices, col, row) for the points that fall inside each camera's image. Only the points
    near a camera's image (:func:`near_image`) are projected: in a region most points are far
    from any one scene, and projecting them costs the most (their line times lie beyond the
    scene's trajectory tables)."""
    out = []
    lon, lat, h = ecef_to_geodetic(ground)
    for k, cam in enumerate(scene.cameras):
        near = near_image(scene, k, lon, lat, h)
        col, row = scene.ground_to_image(ground[near], k)
        inside = cam.in_image(col, row)
        out.append((k, near[inside], col[inside], row[inside]))
    return out


def near_image(scene: SceneModel, camera: int, lon: np.ndarray, lat: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Indices of the points (lon, lat degrees, h ellipsoidal m; (n,) each) within the box of
    camera ``camera``'s image border seen at the lowest and highest of their heights and of the
    scene's height range, widened by NEAR_MARGIN_DEG: only these can lie in its image. All the
    points when the border does not meet the Earth or the box spans more than half the globe."""
    everything = np.arange(lon.size)
    if lon.size == 0:
        return everything
    cam = scene.cameras[camera]
    s = np.linspace(0.0, 1.0, 65)
    col = np.concatenate([s * cam.cols, np.full_like(s, cam.cols), s * cam.cols, np.zeros_like(s)])
    row = np.concatenate([np.zeros_like(s), s * cam.rows, np.full_like(s, cam.rows), s * cam.rows])
    low, high = min(float(h.min()), scene.height_range[0]), max(float(h.max()), scene.height_range[1])
    border = [ecef_to_geodetic(scene.image_to_ground(col, row, height, camera))[:2] for height in (low, high)]
    blon, blat = (np.concatenate(v) for v in zip(*border))
    if not (np.all(np.isfinite(blon)) and np.all(np.isfinite(blat))) or np.ptp(blon) > 180.0:
        return everything
    m = NEAR_MARGIN_DEG
    return np.nonzero((lon >= blon.min() - m) & (lon <= blon.max() + m) & (lat >= blat.min() - m) &
                      (lat <= blat.max() + m))[0]


def _gross_offsets(n: int, settings: GcpSettings, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(offsets (n, 2) px, flags (n,)) for gross errors in exactly round(share * n) measurements."""
    flags = _exact_share(n, settings.gross_fraction, rng)
    size = rng.uniform(settings.gross_min, settings.gross_max, n)
    angle = rng.uniform(0.0, 2 * math.pi, n)
    off = np.where(flags[:, None], np.stack([np.cos(angle), np.sin(angle)], axis=1) * size[:, None], 0.0)
    return off, flags


def _exact_share(n: int, share: float, rng: np.random.Generator) -> np.ndarray:
    """Boolean mask (n,) with exactly round(share * n) randomly placed True values."""
    mask = np.zeros(n, bool)
    mask[rng.choice(n, int(round(share * n)), replace=False)] = True
    return mask


def _ground_noise(ground: np.ndarray, settings: GcpSettings, rng: np.random.Generator):
    """(lon, lat, h) of the ground points with planimetric and height noise added."""
    lon, lat, h = ecef_to_geodetic(ground)
    east = rng.normal(0.0, settings.ground_noise_xy, lon.size)
    north = rng.normal(0.0, settings.ground_noise_xy, lon.size)
    up = rng.normal(0.0, settings.ground_noise_z, lon.size)
    lat_r = np.radians(lat)
    # Metres to degrees on the ellipsoid (meridian and prime-vertical radii).
    e2 = 6.69437999014e-3
    w = np.sqrt(1 - e2 * np.sin(lat_r) ** 2)
    m_rad = A * (1 - e2) / w ** 3
    n_rad = A / w
    return (lon + np.degrees(east / ((n_rad + h) * np.cos(lat_r))), lat + np.degrees(north / (m_rad + h)), h + up)


GCP_COLUMNS = ("id", "role", "camera", "col", "row", "lon", "lat", "h", "sigma_px", "sigma_xy", "sigma_z",
               "col_true", "row_true", "lon_true", "lat_true", "h_true", "gross", "scene")
TIE_COLUMNS = ("id", "camera", "col", "row", "col_true", "row_true", "lon_true", "lat_true", "h_true", "gross",
               "scene")


def measure_points(scene: SceneModel, ground: np.ndarray, ids: np.ndarray, settings: GcpSettings,
                   rng: np.random.Generator) -> dict:
    """Columns (dict of (m,) arrays) of the image measurements of ground points in every
    camera that sees them: noise-free and measured (noise and gross errors) positions."""
    lon_t, lat_t, h_t = ecef_to_geodetic(ground)
    cols: dict[str, list] = {k: [] for k in ("id", "camera", "col_true", "row_true", "index")}
    for k, idx, col, row in observe(scene, ground):
        cols["id"].append(ids[idx])
        cols["camera"].append(np.full(idx.size, scene.cameras[k].name))
        cols["col_true"].append(col)
        cols["row_true"].append(row)
        cols["index"].append(idx)
    out = {k: np.concatenate(v) for k, v in cols.items()}
    m = out["id"].size
    offsets, gross = _gross_offsets(m, settings, rng)
    out["col"] = out["col_true"] + rng.normal(0.0, settings.image_noise, m) + offsets[:, 0]
    out["row"] = out["row_true"] + rng.normal(0.0, settings.image_noise, m) + offsets[:, 1]
    out["gross"] = gross.astype(int)
    idx = out.pop("index")
    out["lon_true"], out["lat_true"], out["h_true"] = lon_t[idx], lat_t[idx], h_t[idx]
    out["_index"] = idx
    return out


def write_csv(path: Path, columns: tuple[str, ...], data: dict) -> None:
    """Write parallel arrays as CSV with a header; floats to 15 significant digits (1e-12 deg, 1e-10 px)."""
    n = len(data[columns[0]])
    text = [np.asarray(data[c]).astype(str) if np.asarray(data[c]).dtype.kind in "UOi"
            else np.char.mod("%.15g", np.asarray(data[c], dtype=float)) for c in columns]
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        w.writerows(zip(*text) if n else [])


def gcp_columns(scene: SceneModel, dem: Dem, settings: GcpSettings, n_scenes: int,
                 rng: np.random.Generator) -> dict:
    """The GCP CSV columns: points on the DEM, measured in every camera that sees them."""
    ground, placed_row = place_ground_points(scene, dem, settings.n_gcps, rng)
    data = measure_points(scene, ground, point_ids("G", ground.shape[0]), settings, rng)
    idx = add_ground_columns(data, ground, settings, rng)
    data["scene"] = scene_of_rows(placed_row[idx], scene.cameras[0].rows, n_scenes)
    return data


def point_ids(prefix: str, n: int) -> np.ndarray:
    """Point ids prefix1 .. prefix<n> (n,)."""
    return np.char.add(prefix, np.arange(1, n + 1).astype(str))


def add_ground_columns(data: dict, ground: np.ndarray, settings: GcpSettings, rng: np.random.Generator) -> np.ndarray:
    """Complete measured ground points ``data`` (:func:`measure_points` columns, its '_index'
    popped and returned: each row's index into ``ground`` (n, 3) ECEF) into GCP columns: the ground
    coordinates with noise (lon, lat degrees, h ellipsoidal m; one draw per ground point, shared by
    all its rows), the role (check points drawn as whole ground points) and the sigmas."""
    idx = data.pop("_index")
    lon, lat, h = _ground_noise(ground, settings, rng)
    data["lon"], data["lat"], data["h"] = lon[idx], lat[idx], h[idx]
    # Checks are whole ground points (all their cameras), drawn without regard to position.
    check = _exact_share(ground.shape[0], settings.check_fraction, rng)
    data["role"] = np.where(check[idx], "check", "control")
    n = idx.size
    data["sigma_px"] = np.full(n, max(settings.image_noise, 1e-3))
    data["sigma_xy"] = np.full(n, max(settings.ground_noise_xy, 1e-3))
    data["sigma_z"] = np.full(n, max(settings.ground_noise_z, 1e-3))
    return idx


def tie_columns(scene: SceneModel, dem: Dem, settings: GcpSettings, n_scenes: int,
                rng: np.random.Generator) -> dict:
    """The tie-point CSV columns: points on the DEM, measured (no ground coordinates) in every
    camera that sees them, each observation in the scene its camera sees it in."""
    ground, _ = place_ground_points(scene, dem, settings.n_tie_points, rng)
    tie = measure_points(scene, ground, point_ids("T", ground.shape[0]), settings, rng)
    # the scene of each observation: where a tie point's cameras see it in neighbouring
    # scenes, it ties them
    names, camera = np.unique(tie["camera"], return_inverse=True)
    rows = np.array([scene.cameras[scene.camera_index(n)].rows for n in names])[camera]
    tie["scene"] = scene_of_rows(tie["row_true"], rows, n_scenes)
    return tie


def scene_of_rows(row: np.ndarray, rows, n_scenes: int) -> np.ndarray:
    """The scene (1..n_scenes) that row coordinates (n,) fall in, in a strip of ``rows`` image
    rows (a number, or (n,): each row's camera's)."""
    return 1 + np.clip((np.asarray(row) * n_scenes / rows).astype(int), 0, n_scenes - 1)
