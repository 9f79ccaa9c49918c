"""Output layers of an adjustment: the GCP layer with the adjusted residuals and flags, the
tie-point layer at the adjusted ground positions, and ground residual vectors. GeoPackage via
OGR (no QGIS), each written under a temporary name and renamed
(:func:`core.vector_io.write_layer`), so an output is complete or absent.

Conventions: image residuals are predicted minus measured (col, row) in GDAL pixels, as in
:class:`core.adjust.engine.AdjustmentResult`; the ground residual of a point is where the
adjusted scene sees its measured (col, row) at the GCP's ellipsoidal height, minus the GCP, in
the point's local east/north frame (metres).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from osgeo import ogr, osr

from ..errors import InputError
from ..files import OutputSet
from ..observations.gcps import GcpTable, Residuals, write_gpkg
from ..geodesy import A, F, enu_rotations
from ..model.sensor import SceneModel
from ..observations.tiepoints import GPKG_LAYER, point_wkt
from ..observations.lines import ground_layer
from ..observations.tables import SCENE_METADATA_KEY
from ..vector_io import LayerData, open_layer, wgs84_3d, write_layer, write_layers
from .linepoints import ControlLines, subset_lines

ogr.UseExceptions()

ADJUSTMENT_FIELDS = ("w_col", "w_row", "redundancy", "weight", "flagged")
E2 = F * (2.0 - F)  # WGS84 first eccentricity squared


def ground_residuals(scene: SceneModel, table: GcpTable, cameras=None) -> np.ndarray:
    """(n, 2) east, north metres from each GCP to where ``scene`` sees its measured image
    position at the GCP's ellipsoidal height; NaN where the ray misses.

    cameras: (n,) camera names of the rows (default the table's); pass an adjustment's
    ``points['camera']``, where empty cameras of single-camera scenes are resolved.
    """
    cameras = np.asarray(table.camera if cameras is None else cameras)
    en = np.full((len(table), 2), np.nan)
    for c, cam in enumerate(scene.cameras):  # one vectorised call per camera
        m = cameras == cam.name
        if m.any():
            seen = scene.image_to_ground(table.col[m], table.row[m], table.h[m], c)
            en[m] = np.einsum("nij,nj->ni", enu_rotations(table.lon[m], table.lat[m]),
                              seen - table.select(m).ecef())[:, :2]
    return en


def write_adjusted_gcps(table: GcpTable, points: dict, path, scene: SceneModel | None = None, *,
                        en: np.ndarray | None = None, scene_path: str = "", source=None,
                        source_layer: str | None = None, files: OutputSet | None = None) -> None:
    """The GCP layer with the adjustment's results, as a GeoPackage Point Z layer in EPSG:4979.

    Fields: those of the GCP layer (:func:`core.gcps.write_gpkg`: id, role, camera, col, row, h,
    sigmas, inside) with res_col, res_row, res_px (px, predicted - measured) and res_m (ground
    length, m) now the adjusted residuals, then w_col, w_row (normalised residuals), redundancy
    (share), weight (final robust weight factor) and flagged (1 = gross error); then any other
    fields of ``source`` (the input GeoPackage and its layer ``source_layer``, read feature by
    feature in the order :func:`core.gcps.read_gpkg` read them), e.g. notes a user added.

    points: :attr:`AdjustmentResult.points` (rows as in ``table``). res_m comes from ``en``
    (:func:`ground_residuals`), or is computed with the adjusted ``scene``; NaN without either.
    scene_path: the adjusted scene file, kept as layer metadata PUSHBROOM_SCENE. files: write as
    part of that :class:`core.files.OutputSet` (committed by its owner).
    """
    n = len(table)
    _check_rows(points, n)
    cameras = np.asarray(points.get("camera", table.camera))
    if en is None:
        en = ground_residuals(scene, table, cameras) if scene is not None else np.full((n, 2), np.nan)
    inside = table.residuals.inside if table.residuals is not None else np.ones(n, bool)
    res = Residuals(np.asarray(points["res_col"], float), np.asarray(points["res_row"], float),
                    np.asarray(points["res_px"], float), np.hypot(en[:, 0], en[:, 1]), inside)
    extra = {k: np.asarray(points[k], dtype=float) for k in ADJUSTMENT_FIELDS if k != "flagged"}
    extra["flagged"] = np.asarray(points["flagged"]).astype(int)
    if source is not None:
        extra.update({k: v for k, v in _other_fields(source, source_layer, n).items() if k not in extra})
    write_gpkg(replace(table, camera=cameras, residuals=res, scene_path=scene_path or table.scene_path), path,
               extra=extra, files=files)


TIE_FIELDS = ("id", "camera", "col", "row", "res_col", "res_row", "res_px", "w_col", "w_row", "weight", "flagged")


def write_adjusted_tie_points(tie_points: dict, path, *, scene_path: str = "", files: OutputSet | None = None) -> None:
    """The tie observations with the adjustment's results, as a GeoPackage Point Z layer
    'tie_points' in EPSG:4979, one feature per input observation (input order) at its point's
    adjusted ground position (lon, lat, ellipsoidal h; empty geometry for a point left out).

    Fields :data:`TIE_FIELDS`: id, camera, col, row (GDAL px), res_col, res_row, res_px (px,
    predicted - measured), w_col, w_row (normalised residuals), weight (final robust weight
    factor), flagged (1 = gross error); residuals NULL for the observations left out.
    tie_points: :attr:`AdjustmentResult.tie_points`. scene_path: the adjusted scene file, kept as
    layer metadata PUSHBROOM_SCENE. files: as for :func:`write_adjusted_gcps`."""
    columns, ground = _tie_columns(tie_points)
    write_layer(path, GPKG_LAYER, wgs84_3d(), ogr.wkbPoint25D, columns, ground,
                {SCENE_METADATA_KEY: scene_path} if scene_path else None, files)


def _tie_columns(tie_points: dict) -> tuple[dict, object]:
    """The :data:`TIE_FIELDS` columns of per-observation tie results and their points' WKT."""
    missing = [k for k in (*TIE_FIELDS, "lon", "lat", "h") if k != "res_px" and k not in tie_points]
    if missing:
        raise InputError(f"adjustment results lack the tie-point arrays {', '.join(missing)}")
    columns = {k: np.hypot(np.asarray(tie_points["res_col"], float), np.asarray(tie_points["res_row"], float))
               if k == "res_px" else np.asarray(tie_points[k]) for k in TIE_FIELDS}
    columns["flagged"] = columns["flagged"].astype(int)
    return columns, point_wkt(*(tie_points[k] for k in ("lon", "lat", "h")))


BLOCK_TIE_FIELDS = ("scene", "rays", "scenes", "convergence_deg")


def write_block_tie_points(tie_points: dict, points: dict, scene: np.ndarray, path, *,
                           files: OutputSet | None = None) -> None:
    """The tie observations of a block adjustment (:func:`core.adjust.block.adjust_block`), as
    :func:`write_adjusted_tie_points` writes them (one feature per observation at its point's
    adjusted ground; camera the name within its scene), with the fields of
    :data:`BLOCK_TIE_FIELDS` after them: scene (the product the observation was measured in),
    and of its point: rays (observations used), scenes (scenes it was seen in), convergence_deg
    (the largest angle between its onboard rays, deg; NULL without). tie_points: the composite's
    per-observation :attr:`AdjustmentResult.tie_points` (cameras ``<scene>/<camera>``); points:
    :attr:`BlockResult.tie_points` (per point, ids sorted); scene: (n,) scene names of the
    observations."""
    ids = np.asarray(tie_points["id"], dtype=str)
    at = np.searchsorted(np.asarray(points["id"], dtype=str), ids)
    per_point = {k: np.asarray(points[k])[at] if k in points else np.full(ids.size, np.nan)
                 for k in BLOCK_TIE_FIELDS[1:]}
    columns, ground = _tie_columns(tie_points)
    columns["camera"] = np.char.partition(np.asarray(columns["camera"], dtype=str), "/")[:, 2]
    columns.update(scene=np.asarray(scene, dtype=str), rays=per_point["rays"].astype(int),
                   scenes=per_point["scenes"].astype(int), convergence_deg=per_point["convergence_deg"].astype(float))
    write_layer(path, GPKG_LAYER, wgs84_3d(), ogr.wkbPoint25D, columns, ground, None, files)


def write_residual_vectors(scene: SceneModel | None, table: GcpTable, points: dict, path, scale: float, *,
                           en: np.ndarray | None = None, files: OutputSet | None = None) -> None:
    """Lines (EPSG:4326), one per point whose ground residual is known, from the GCP's ground
    position along its ground residual exaggerated ``scale`` times. Fields id, role, camera,
    res_px (image residual, px), res_m (unexaggerated ground length, m), flagged (0/1). The
    scale is kept as layer metadata PUSHBROOM_SCALE.

    en: (n, 2) east/north ground residuals (:func:`ground_residuals`); computed with the
    adjusted ``scene`` when not given. files: as for :func:`write_adjusted_gcps`.
    """
    n = len(table)
    _check_rows(points, n)
    if not scale > 0:
        raise InputError(f"the residual vector exaggeration must be positive (got {scale})")
    cameras = np.asarray(points.get("camera", table.camera))
    if en is None:
        if scene is None:
            raise InputError("residual vectors need the adjusted scene or the ground residuals")
        en = ground_residuals(scene, table, cameras)
    # metres -> degrees with the ellipsoid's meridian and prime-vertical radii at each point
    s = np.sin(np.radians(table.lat))
    w = np.sqrt(1.0 - E2 * s * s)
    meridian, normal = A * (1.0 - E2) / w ** 3, A / w
    lon2 = table.lon + np.degrees(scale * en[:, 0] / (normal * np.cos(np.radians(table.lat))))
    lat2 = table.lat + np.degrees(scale * en[:, 1] / meridian)
    ok = np.isfinite(lon2) & np.isfinite(lat2)
    lines = [f"LINESTRING ({a!r} {b!r}, {c!r} {d!r})" for a, b, c, d in  # WKT per feature, for OGR
             zip(table.lon[ok].tolist(), table.lat[ok].tolist(), lon2[ok].tolist(), lat2[ok].tolist())]
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    columns = {"id": table.id[ok], "role": table.role[ok], "camera": cameras[ok],
               "res_px": np.asarray(points["res_px"], float)[ok], "res_m": np.hypot(en[ok, 0], en[ok, 1]),
               "flagged": np.asarray(points["flagged"])[ok].astype(int)}
    write_layer(path, "residuals", srs, ogr.wkbLineString, columns, lines, {"PUSHBROOM_SCALE": repr(float(scale))},
                files)


def _check_rows(points: dict, n: int) -> None:
    missing = [k for k in ("res_col", "res_row", "res_px", *ADJUSTMENT_FIELDS) if k not in points]
    if missing:
        raise InputError(f"adjustment results lack {', '.join(missing)}")
    bad = [k for k in ("res_col", "res_row", "res_px", *ADJUSTMENT_FIELDS) if len(points[k]) != n]
    if bad:
        raise InputError(f"adjustment results {', '.join(bad)} do not have one value per GCP ({n})")


_SCHEMA = {"fid", "id", "role", "camera", "col", "row", "h", "sigma_px", "sigma_xy", "sigma_z", "res_col", "res_row",
           "res_px", "res_m", "inside", *ADJUSTMENT_FIELDS}


def _other_fields(source, layer: str | None, n: int) -> dict:
    """Fields of a GCP GeoPackage outside the GCP and adjustment schema, as arrays: integers
    (float when some are NULL), reals, and everything else as text ('' for NULL)."""
    ds, lyr = open_layer(source, layer)
    defn = lyr.GetLayerDefn()
    fields = [(defn.GetFieldDefn(i).GetName(), defn.GetFieldDefn(i).GetType()) for i in range(defn.GetFieldCount())]
    fields = [(name, kind) for name, kind in fields if name.lower() not in _SCHEMA]
    if not fields:
        return {}
    rows = [[f.GetField(name) if f.IsFieldSetAndNotNull(name) else None for name, _ in fields]
            for f in lyr]  # OGR reads feature by feature
    if len(rows) != n:
        raise InputError(f"{source}: {len(rows)} features, but the adjustment has {n} points")
    out = {}
    for j, (name, kind) in enumerate(fields):
        values = [r[j] for r in rows]
        if kind in (ogr.OFTInteger, ogr.OFTInteger64) and None not in values:
            out[name] = np.array(values, dtype=np.int64)
        elif kind in (ogr.OFTInteger, ogr.OFTInteger64, ogr.OFTReal):
            out[name] = np.array([np.nan if v is None else v for v in values], dtype=float)
        else:
            out[name] = np.array(["" if v is None else str(v) for v in values], dtype=object)
    return out


def write_line_residuals(path, lines: ControlLines, points: dict, report: dict, files=None) -> None:
    """One GeoPackage: layer ``line_points`` (points at their adjusted ground, EPSG:4979: per
    line point line_id, camera, col, row, res_col, res_row (px), across_m, height_m (m, the
    ray's distance from the line through the adjusted scene), across_before_m, flagged,
    line_flagged; scene, the product of a block each point was measured in, when ``points`` has it:
    :attr:`core.adjust.block.BlockResult.line_points`) and layer ``ground_lines`` (the paired
    lines with points, rms_across_m, max_across_m, points_flagged, flagged = named wrong as a
    whole)."""
    geoms = [f"POINT Z ({a!r} {b!r} {c!r})" for a, b, c in zip(points["lon"].tolist(), points["lat"].tolist(),
                                                                  points["h"].tolist())]
    columns = {k: points[k] for k in ("line_id", "scene", "camera", "col", "row", "res_col", "res_row", "across_m",
                                      "height_m", "across_before_m") if k in points}
    columns.update(flagged=points["flagged"].astype(int), line_flagged=points["line_flagged"].astype(int))
    per = report["per_line"]
    used = np.isin(lines.ground.id, per["line_id"])
    ground = subset_lines(lines.ground, used)
    index = {i: k for k, i in enumerate(per["line_id"])}
    k = [index[i] for i in ground.id]
    extra = {name: np.asarray(per[name])[k] for name in ("points", "rms_across_m", "max_across_m", "points_flagged")}
    extra["flagged"] = np.asarray(per["flagged"], dtype=int)[k]
    write_layers(path, [LayerData("line_points", wgs84_3d(), ogr.wkbPoint25D, columns, geoms),
                        ground_layer(ground, extra)], files)

