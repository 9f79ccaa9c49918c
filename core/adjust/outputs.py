"""Output layers of an adjustment: the GCP layer with the adjusted residuals and flags, and
ground residual vectors (GeoPackage, written completely or not at all)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from osgeo import ogr, osr

from ..gcps import GcpTable, Residuals, write_gpkg
from ..geodesy import enu_rotations
from ..sensor import SceneModel
from ..vector_io import write_layer

M_PER_DEG_LAT = 110540.0
M_PER_DEG_LON_EQUATOR = 111320.0
ADJUSTMENT_FIELDS = ("w_col", "w_row", "redundancy", "weight", "flagged")


def ground_residuals(scene: SceneModel, table: GcpTable) -> np.ndarray:
    """(n, 2) east, north metres from each GCP to where the scene sees its measured image
    position at the GCP's height."""
    en = np.full((len(table), 2), np.nan)
    for c, cam in enumerate(scene.cameras):
        m = table.camera == cam.name
        if m.any():
            seen = scene.image_to_ground(table.col[m], table.row[m], table.h[m], c)
            en[m] = np.einsum("nij,nj->ni", enu_rotations(table.lon[m], table.lat[m]),
                              seen - table.select(m).ecef())[:, :2]
    return en


def write_adjusted_gcps(table: GcpTable, points: dict, en: np.ndarray, path, scene_path: str = "") -> None:
    """The GCP layer (schema of pushbroom:importgcps) with the adjusted residuals (res_col,
    res_row, res_px in px, res_m in m on the ground) and the fields w_col, w_row (normalised
    residuals), redundancy, weight (robust weight factor) and flagged (1 = gross error)."""
    inside = table.residuals.inside if table.residuals is not None else np.ones(len(table), bool)
    res = Residuals(points["res_col"], points["res_row"], points["res_px"], np.hypot(en[:, 0], en[:, 1]), inside)
    extra = {k: np.asarray(points[k], dtype=float) for k in ADJUSTMENT_FIELDS if k != "flagged"}
    extra["flagged"] = np.asarray(points["flagged"], dtype=int)
    write_gpkg(replace(table, residuals=res, scene=scene_path or table.scene), path, extra=extra)


def write_residual_vectors(table: GcpTable, points: dict, en: np.ndarray, path, scale: float) -> None:
    """Lines (EPSG:4326) from each GCP along its ground residual exaggerated ``scale`` times;
    fields id, role, camera, res_px, res_m (true length, m), flagged."""
    lat_r = np.radians(table.lat)
    lon2 = table.lon + scale * en[:, 0] / (M_PER_DEG_LON_EQUATOR * np.cos(lat_r))
    lat2 = table.lat + scale * en[:, 1] / M_PER_DEG_LAT
    ok = np.isfinite(lon2) & np.isfinite(lat2)
    lines = [f"LINESTRING ({a!r} {b!r}, {c!r} {d!r})" for a, b, c, d in
             zip(table.lon[ok].tolist(), table.lat[ok].tolist(), lon2[ok].tolist(), lat2[ok].tolist())]
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    columns = {"id": table.id[ok], "role": table.role[ok], "camera": table.camera[ok],
               "res_px": np.asarray(points["res_px"])[ok], "res_m": np.hypot(en[ok, 0], en[ok, 1]),
               "flagged": np.asarray(points["flagged"])[ok].astype(int)}
    write_layer(path, "residuals", srs, ogr.wkbLineString, columns, lines, {"PUSHBROOM_SCALE": str(scale)})
