"""The GCP dock's session without its widgets: the scenes of the block (each a raw image opened with
its scene, :func:`core.measure.sources.open_image_source`), the one shown, the points being measured
(:class:`core.measure.gcpmeasure.PointEditor`) and every action on them, each returning the sentence
the dock shows or raising a PushbroomError whose message it shows instead.

Frames and units as in :mod:`core.measure.gcpmeasure`: image (col, row) GDAL px, ground WGS84 lon,
lat (deg) and ellipsoidal h (m). The dock turns clicks into these calls and draws what they leave.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import InputError, PushbroomError
from ..measure.gcpmeasure import (PointEditor, Prediction, predict, snap_to_reference, snap_to_scene,
                                  surface_for)
from ..measure.sources import ImageSource
from ..measure.tiematching import View
from ..observations.gcps import read_gpkg, write_gpkg
from ..observations.tables import Heights
from .base import FilesInUse, Terrain, surface_from
from .docks import files_read

GCP_LAYER = "GCP layer"  # how refusals of the save name its file
NEAR_PX = 1.0  # image px: predictions this close to an earlier one share its marker's label


def nearest_reference(name: str, xy, lonlatz, click: tuple[float, float], units_per_px: float,
                      tolerance_px: float) -> tuple[float, float, float | None]:
    """(lon, lat deg, z or None) of the point of the reference layer ``name`` nearest to ``click``:
    ``xy`` (n, >=2) its points and ``click`` in the map's units (``units_per_px`` per screen px),
    ``lonlatz`` (n, 3) their lon, lat and Z (NaN: none). InputError without points, or none within
    ``tolerance_px`` screen px: the user meant the click itself, or another point."""
    if len(xy) == 0:
        raise InputError(f"The reference layer {name} holds no point")
    xy, lonlatz = np.asarray(xy, dtype=float), np.asarray(lonlatz, dtype=float)
    distance = np.hypot(xy[:, 0] - click[0], xy[:, 1] - click[1])
    k = int(np.argmin(distance))
    pixels = distance[k] / max(units_per_px, 1e-12)
    if pixels > tolerance_px:
        raise InputError(f"No point of the reference layer {name} within {tolerance_px} screen px of the click (the "
                         f"nearest is {pixels:.0f} px away): click nearer, or choose no reference layer to take the "
                         "click itself")
    lon, lat, z = (float(v) for v in lonlatz[k])
    return lon, lat, z if np.isfinite(z) else None


def point_rows(points, scene: str | None, camera: str | None) -> list[tuple[list[tuple], str]]:
    """The table's rows: per point, (cells [(text, sort key or None)]: id, role, images, residual (px)
    in ``scene``'s ``camera`` (blank without one), h (m), where h came from; a tooltip listing its
    observations). Keys sort ids naturally (G2 before G10) and numbers as numbers."""
    rows = []
    for point in points:
        seen = point.observation(scene, camera) if scene is not None else None
        residual = math.hypot(*seen.residual) if seen is not None and seen.residual is not None else None
        ground = point.ground
        cells = [(point.id, re.sub(r"\d+", lambda m: m.group().zfill(12), point.id)), (point.role, None),
                 (str(len(point.observations)), len(point.observations)),
                 (f"{residual:.2f}" if residual is not None else "", residual if residual is not None else -1.0),
                 (f"{ground.h:.1f}" if ground else "", ground.h if ground else -math.inf),
                 (ground.height_from if ground else "no ground yet", None)]
        tip = "\n".join(f"{o.scene}/{o.camera}: col {o.col:.2f}, row {o.row:.2f} px"
                        + (f", residual {o.residual[0]:+.2f}, {o.residual[1]:+.2f} px" if o.residual is not None
                           else "") for o in point.observations)
        rows.append((cells, tip))
    return rows


@dataclass
class GcpSession:
    """The block's ``views`` (in the order added), the (file opened, source) of each, the index of
    the one ``current``ly shown (None: none), the ``editor``, the ``predictions`` of the selected
    point in the current view (:meth:`markers` makes them) and the last DEM read ((file, datum), Dem)."""
    editor: PointEditor = field(default_factory=PointEditor)
    views: list[View] = field(default_factory=list)
    sources: list[tuple[str, ImageSource]] = field(default_factory=list)
    current: int | None = None
    predictions: list[Prediction] = field(default_factory=list)
    dem_read: tuple = ((), None)

    # --- the block's scenes -----------------------------------------------------------------------
    def add(self, opened: str, source: ImageSource, names: Callable[[list[str]], list[str]]) -> View:
        """Add the raw image ``source`` (opened from file ``opened``), its scene named as ``names``
        (the block's scene files -> their names) names it among the block's; the view added. InputError
        when its scene and camera are in the block already."""
        scene_files = list(dict.fromkeys([s.scene_path for _, s in self.sources] + [source.scene_path]))
        view = View(names(scene_files)[scene_files.index(source.scene_path)], source.scene, source.camera,
                    source.image)
        if any(v.label == view.label for v in self.views):
            raise InputError(f"{view.label} is in the block already")
        self.views.append(view)
        self.sources.append((opened, source))
        return view

    def surface(self, heights: Heights, view: View):
        """The surface rays are met with: a DEM read and checked as the use cases read one
        (:func:`core.runs.base.surface_from`: heights no terrain has are refused), kept for the next
        call (the dock asks at every redraw); else the constant of
        :func:`core.measure.gcpmeasure.surface_for` (in its datum at the centre of ``view``'s image)."""
        if heights.source != "dem" or not isinstance(heights.dem, (str, Path)):
            return surface_for(heights, view)
        key = (str(heights.dem), heights.datum)
        if self.dem_read[0] != key:
            self.dem_read = (key, surface_from(Terrain(*key))[0])
        return self.dem_read[1]

    def view(self) -> View:
        if self.current is None:
            raise InputError("add a scene of the block first (Add scene…)")
        return self.views[self.current]

    # --- measuring ----------------------------------------------------------------------------------
    def new_point(self) -> str:
        self.editor.new_point()
        return "New point: click it on the image, and press Ground"

    def measure(self, col: float, row: float) -> str:
        """Measure the selected point (a new one when none is) at (col, row) px of the current view."""
        view = self.view()
        if self.editor.selected is None:
            self.editor.new_point()
        cam = view.scene.cameras[view.camera]
        done = self.editor.measure(view.scene_name, view.camera_name, col, row, (cam.cols, cam.rows))
        return (f"Point {self.editor.current().id} {done} in {view.label} at col {col:.2f}, row {row:.2f} px")

    def set_ground(self, lon: float, lat: float, z: float | None, source: str, heights: Heights, words: str) -> str:
        """The selected point's ground at (lon, lat) deg from ``source`` ('canvas', 'reference'), its
        height as ``heights`` say (``words``: where from, in words; ``z``: the picked point's Z)."""
        ground = self.editor.set_ground_at(lon, lat, heights, z, source, words)
        return (f"Point {self.editor.current().id}: ground lon {ground.lon:.6f}, lat {ground.lat:.6f} from the "
                f"{source}, h {ground.h:.1f} m (ellipsoidal) from {words}")

    def snap(self, heights: Heights, to_reference: bool, reference: tuple[str, str] | None = None) -> str:
        """Snap the selected point's observation in the current view (undoable): to the reference
        orthoimage ``reference`` (file, name) when ``to_reference``, else to the other scene whose image
        matches it best (the highest correlation: another date, a cloud or a shadow can spoil one)."""
        view, point = self.view(), self.editor.current()
        surface = self.surface(heights, view)
        if to_reference:
            if reference is None:
                raise InputError("choose the reference orthoimage layer to snap to")
            result, target = snap_to_reference(point, view, reference[0], surface), reference[1]
        else:
            others = [v for v in self.views if v.scene_name != view.scene_name
                      and point.observation(v.scene_name, v.camera_name) is not None]
            if not others:
                raise InputError(f"point {point.id} is measured in no other scene: measure it there first, or snap "
                                 "to a reference orthoimage")
            results, reasons = [], []
            for other in others:
                try:
                    results.append((other.label, snap_to_scene(point, view, other, surface)))
                except PushbroomError as exc:
                    reasons.append(f"{other.label}: {exc}")
            if not results:
                raise InputError("; ".join(reasons))
            target, result = max(results, key=lambda item: item[1].correlation)
        self.editor.snapped(view.scene_name, view.camera_name, result)
        return (f"Snapped by {result.shift[0]:+.2f}, {result.shift[1]:+.2f} px to {target} (sigma "
                f"{result.sigma_px:.2f} px, correlation {result.correlation:.2f}); Undo restores the click")

    def rename(self, text: str) -> None:
        """The selected point's id from an edit box (nothing when none is selected or it is unchanged)."""
        if self.editor.selected is not None and text.strip() != self.editor.current().id:
            self.editor.edit(point_id=text)

    def edit_sigmas(self, sigma_xy: float, sigma_z: float, sigma_px: float) -> None:
        """The selected point's ground sigmas (m; when it has a ground) and its image sigma (px) in the
        current view (when measured there)."""
        if self.editor.selected is None:
            return
        point, change = self.editor.current(), {}
        if point.ground is not None:
            change.update(sigma_xy=sigma_xy, sigma_z=sigma_z)
        if self.current is not None and point.observation(self.view().scene_name, self.view().camera_name):
            change["sigma_px"] = (self.view().scene_name, self.view().camera_name, sigma_px)
        self.editor.edit(**change)

    def undo(self) -> str:
        what = self.editor.undo()
        return f"Undone: {what}" if what else "Nothing to undo"

    def delete(self) -> str:
        return ("Point deleted (Ctrl+Z brings it back)" if self.editor.delete_selected()
                else "Select a point in the table first")

    # --- what the dock draws ------------------------------------------------------------------------
    def markers(self, heights: Heights) -> tuple[list[tuple[float, float, str, str]], str]:
        """(markers [(col, row px, kind, label)] in the current view, a problem to show or ''): the
        selected point's predictions ('ground', 'scene': estimates within NEAR_PX of an earlier one
        share its label, which names them all; a prediction that fails is the problem), then every
        point measured there ('selected' or 'measured')."""
        self.predictions, found, problem = [], [], ""
        if self.current is None:
            return [], ""
        view = self.views[self.current]
        if self.editor.selected is not None:
            point = self.editor.current()
            try:
                self.predictions = predict(point, view, {v.scene_name: v for v in self.views},
                                           self.surface(heights, view))
            except PushbroomError as exc:
                problem = str(exc)
            shown = [p for p in self.predictions if np.isfinite(p.col) and np.isfinite(p.row)]
            for k, p in enumerate(shown):
                near = [q.source for q in shown if abs(q.col - p.col) < NEAR_PX and abs(q.row - p.row) < NEAR_PX]
                first = next(i for i, q in enumerate(shown) if q.source == near[0])
                found.append((p.col, p.row, "ground" if p.source == "ground" else "scene",
                              f"{point.id} ({', '.join(near)})" if first == k else ""))
        for i, point in enumerate(self.editor.points):
            seen = point.observation(view.scene_name, view.camera_name)
            if seen is not None:
                found.append((seen.col, seen.row, "selected" if i == self.editor.selected else "measured", point.id))
        return found, problem

    def shown(self) -> tuple[str | None, str | None]:
        """(scene name, camera name) of the current view; (None, None) when none is shown."""
        view = self.views[self.current] if self.current is not None else None
        return (view.scene_name, view.camera_name) if view is not None else (None, None)

    def selected_values(self) -> tuple | None:
        """(id, role, sigma_xy, sigma_z m (None without a ground), sigma_px (None when not measured in the
        current view)) of the selected point, for the form; None when none is selected."""
        if self.editor.selected is None:
            return None
        point = self.editor.current()
        seen = point.observation(*self.shown()) if self.current is not None else None
        ground = point.ground
        return (point.id, point.role, ground.sigma_xy if ground else None, ground.sigma_z if ground else None,
                seen.sigma_px if seen else None)

    def ground_marks(self) -> list[tuple[str, float, float, bool]]:
        """(id, lon, lat deg, selected) of the points with a ground, the selected one last (on top)."""
        return sorted(((p.id, p.ground.lon, p.ground.lat, i == self.editor.selected)
                       for i, p in enumerate(self.editor.points) if p.ground is not None), key=lambda m: m[3])

    def selected_pixels(self) -> list[tuple[float, float]]:
        """The selected point in the current view: its measurement, else the mean of its predictions."""
        if self.editor.selected is None or self.current is None:
            return []
        view = self.views[self.current]
        seen = self.editor.current().observation(view.scene_name, view.camera_name)
        if seen is not None:
            return [(seen.col, seen.row)]
        at = [(p.col, p.row) for p in self.predictions if np.isfinite(p.col) and np.isfinite(p.row)]
        return [tuple(np.mean(at, axis=0))] if at else []

    # --- files ----------------------------------------------------------------------------------------
    def files_read(self, dem: str | None) -> dict[str, list[str]]:
        """{what: files} the session reads (``dem``: the DEM's file, None for none)."""
        files = {}
        for view, (opened, source) in zip(self.views, self.sources):
            files.update(files_read(view.label, opened, source))
        return {**files, "DEM": [dem] if dem else []}

    def save(self, path: str, dem: str | None) -> str:
        """Write the points to GeoPackage ``path`` (layer gcps, replaced whole, or not at all), as
        pushbroom:importgcps writes its layer; never over a file the session reads."""
        FilesInUse(self.files_read(dem)).check({GCP_LAYER: [path]})
        table = self.editor.table()
        write_gpkg(table, path)
        return f"{len(table)} observations of {len(self.editor.points)} points saved to {path}"

    def open_layer(self, path: str) -> str:
        """Continue from a saved GCP layer or bundleadjust's adjusted GCPs (OUTPUT_GCPS, with their
        residuals); its scenes must be in the block (those that are not are named)."""
        self.editor.load(read_gpkg(path), list(dict.fromkeys(v.scene_name for v in self.views)), path,
                         f"the layer {Path(path).name}")
        with_residuals = sum(o.residual is not None for p in self.editor.points for o in p.observations)
        return (f"{len(self.editor.points)} points read from {path}"
                + (f", {with_residuals} observations with their residuals" if with_residuals else ""))
