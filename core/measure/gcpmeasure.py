"""Measuring ground control points on the raw images of a block of scenes, without any user
interface: the points being measured (id, role, ground position with its sigmas and where it
came from, one image observation per scene and camera), add / move / delete with undo, where a
point should appear in an image (predicted through every scene's current model), Snap (the
clicked position refined by least-squares template matching, :mod:`core.measure.pointsnap`)
and the GCP table (:class:`core.observations.gcps.GcpTable`, every row naming its scene) to save
with :func:`core.observations.gcps.write_gpkg` and to continue from after
:func:`core.observations.gcps.read_gpkg`.

Frames and units: image (col, row) GDAL px (pixel centres at +0.5, rows down); ground WGS84
lon, lat (deg) and ellipsoidal height h (m); ECEF metres inside. A scene of the block is a
:class:`core.measure.tiematching.View` (its name, model, camera, raw image); a surface is
anything with ``height(lon, lat)`` (ellipsoidal m) and ``height_range`` (:class:`core.dem.Dem`,
:class:`core.dem.ConstantHeight`).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..dem import ConstantHeight, Dem, to_ellipsoidal
from ..errors import InputError
from ..geodesy import ecef_to_geodetic, geodetic_to_ecef
from ..observations.gcps import DEFAULT_SIGMA_PX, DEFAULT_SIGMA_XY, DEFAULT_SIGMA_Z, ROLES, GcpTable
from ..observations.tables import Heights, ellipsoidal_heights, listed
from .pointsnap import PointSnap, PointSnapSettings, local_map, snap_point
from .reference import ImageReference, Reference
from .tiematching import View

GROUND_SOURCES = ("canvas", "reference", "layer")  # a map click + height, a reference layer's point, a saved layer


@dataclass
class Ground:
    """A point's ground: lon, lat (deg), h (ellipsoidal m), its sigmas (m), where it came from
    (one of GROUND_SOURCES) and where its height came from, in words a list can show ('the DEM
    dem.tif', 'the constant 0.0 m (no DEM chosen)'; '' when not stated)."""
    lon: float
    lat: float
    h: float
    sigma_xy: float = DEFAULT_SIGMA_XY
    sigma_z: float = DEFAULT_SIGMA_Z
    source: str = "canvas"
    height_from: str = ""

    def ecef(self) -> np.ndarray:
        """(1, 3) ECEF m."""
        return geodetic_to_ecef(np.array([self.lon]), np.array([self.lat]), np.array([self.h]))


@dataclass
class Observation:
    """The point in one scene's camera: (col, row) px, its sigma (px) and, read from an adjusted
    GCP layer, its residual (res_col, res_row) px, predicted minus measured (None: none, or the
    observation moved since)."""
    scene: str
    camera: str
    col: float
    row: float
    sigma_px: float = DEFAULT_SIGMA_PX
    residual: tuple[float, float] | None = None


@dataclass
class MeasuredPoint:
    """A GCP: id, role ('control' | 'check'), ground (None: not yet given) and observations."""
    id: str
    role: str = "control"
    ground: Ground | None = None
    observations: list[Observation] = field(default_factory=list)

    def observation(self, scene: str, camera: str) -> Observation | None:
        return next((o for o in self.observations if (o.scene, o.camera) == (scene, camera)), None)


@dataclass
class Prediction:
    """Where a point should be in an image: (col, row) px (NaN: not seen) from ``source``,
    'ground' (its ground position) or the name of the scene whose observation it comes from."""
    source: str
    col: float
    row: float


@dataclass
class PointEditor:
    """The points being measured, the ``selected`` one's index (None: none) and the undo
    ``history``: before every change, (the points, the selection, what the change was)."""
    points: list[MeasuredPoint] = field(default_factory=list)
    selected: int | None = None
    history: list[tuple[list[MeasuredPoint], int | None, str]] = field(default_factory=list)

    # --- changes (each undoable) --------------------------------------------------------------
    def _record(self, what: str) -> None:
        self.history.append((copy.deepcopy(self.points), self.selected, what))

    def new_point(self, point_id: str = "") -> int:
        """Add a point (id ``point_id``, or the next free 'G<n>') and select it; its index."""
        point_id = point_id.strip() or next(f"G{n}" for n in range(1, len(self.points) + 2)
                                            if f"G{n}" not in self.ids())
        self._require_new_id(point_id)
        self._record("new point")
        self.points.append(MeasuredPoint(point_id))
        self.selected = len(self.points) - 1
        return self.selected

    def measure(self, scene: str, camera: str, col: float, row: float, size: tuple[int, int]) -> str:
        """Measure the selected point at (col, row) px of ``scene``'s ``camera`` whose image is
        ``size`` (cols, rows) px: 'measured', or 'moved' when it was measured there already.
        InputError (nothing changed) outside the image or without a selected point."""
        point = self.current()
        if not (np.isfinite(col) and np.isfinite(row) and 0 <= col <= size[0] and 0 <= row <= size[1]):
            raise InputError(f"({col:.1f}, {row:.1f}) px is outside the image of {scene} ({size[0]} x {size[1]} "
                             "px): click inside it")
        seen = point.observation(scene, camera)
        self._record("move" if seen else "measure")
        if seen:
            seen.col, seen.row, seen.residual = float(col), float(row), None
            return "moved"
        point.observations.append(Observation(scene, camera, float(col), float(row)))
        return "measured"

    def snapped(self, scene: str, camera: str, snap: PointSnap) -> None:
        """Put the snap's position and sigma on the selected point's observation in ``scene``."""
        seen = self._seen(scene, camera)
        self._record("snap")
        seen.col, seen.row, seen.sigma_px, seen.residual = snap.col, snap.row, snap.sigma_px, None

    def set_ground(self, ground: Ground) -> None:
        """Give the selected point its ground."""
        point = self.current()
        if ground.source not in GROUND_SOURCES:
            raise InputError(f"ground source must be one of {', '.join(GROUND_SOURCES)} (got {ground.source!r})")
        self._record("ground")
        point.ground = ground

    def set_ground_at(self, lon: float, lat: float, heights: Heights, z: float | None = None,
                      source: str = "canvas", height_from: str = "") -> Ground:
        """The selected point's ground at (lon, lat) deg, its height as ``heights`` says (``z``: the
        picked point's Z, in heights.datum; ``height_from`` says where it came from, in words);
        its sigmas kept from the ground it had. InputError (nothing changed) when the height
        cannot be had: a DEM that does not cover the point is named."""
        self.current()
        h = float(ellipsoidal_heights(np.array([lon]), np.array([lat]), heights,
                                      None if z is None else np.array([z]), np.array([self.current().id]),
                                      "the ground position")[0])
        old = self.current().ground or Ground(lon, lat, h)
        self.set_ground(Ground(float(lon), float(lat), h, old.sigma_xy, old.sigma_z, source, height_from))
        return self.current().ground

    def edit(self, point_id: str | None = None, role: str | None = None, sigma_xy: float | None = None,
             sigma_z: float | None = None, sigma_px: tuple[str, str, float] | None = None) -> None:
        """Change the selected point's id, role, ground sigmas (m) or one observation's sigma
        (scene, camera, px); nothing is recorded when nothing changes. InputError (nothing
        changed) for an id taken or empty, an unknown role, a sigma not > 0 (sigma_xy, sigma_z
        >= 0)."""
        point = self.current()
        if point_id is not None and point_id.strip() != point.id:
            self._require_new_id(point_id.strip())
        if role is not None and role not in ROLES:
            raise InputError(f"role must be 'control' or 'check' (got {role!r})")
        for name, value, low in (("sigma_xy", sigma_xy, 0.0), ("sigma_z", sigma_z, 0.0),
                                 ("sigma_px", None if sigma_px is None else sigma_px[2], None)):
            if value is not None and not (value > 0 or (low is not None and value == low)):
                raise InputError(f"{name} of point {point.id} must be {'>= 0' if low is not None else '> 0'} "
                                 f"(got {value})")
        if (sigma_xy is not None or sigma_z is not None) and point.ground is None:
            raise InputError(f"point {point.id} has no ground yet: give it first, then its sigmas")
        if sigma_px is not None:
            self._seen(*sigma_px[:2])
        changed = copy.deepcopy(point)
        changed.id = point.id if point_id is None else point_id.strip()
        changed.role = role or point.role
        if sigma_xy is not None:
            changed.ground.sigma_xy = float(sigma_xy)
        if sigma_z is not None:
            changed.ground.sigma_z = float(sigma_z)
        if sigma_px is not None:
            changed.observation(*sigma_px[:2]).sigma_px = float(sigma_px[2])
        if changed != point:  # an edit that changes nothing leaves nothing to undo
            self._record("edit")
            self.points[self.selected] = changed

    def delete_observation(self, scene: str, camera: str) -> None:
        """Remove the selected point's observation in ``scene``'s ``camera``."""
        seen = self._seen(scene, camera)
        self._record("delete observation")
        self.current().observations.remove(seen)

    def delete_selected(self) -> bool:
        """Delete the selected point; False when none is selected."""
        if self.selected is None:
            return False
        self._record("delete point")
        del self.points[self.selected]
        self.selected = None
        return True

    def undo(self) -> str:
        """Undo the last change: what it was ('' when there is nothing to undo)."""
        if not self.history:
            return ""
        self.points, self.selected, what = self.history.pop()
        return what

    # --- queries ------------------------------------------------------------------------------
    def ids(self) -> list[str]:
        return [p.id for p in self.points]

    def select(self, index: int | None) -> None:
        if index is not None and not 0 <= index < len(self.points):
            raise InputError(f"there is no point {index + 1} (there are {len(self.points)})")
        self.selected = index

    def current(self) -> MeasuredPoint:
        """The selected point; InputError when none is."""
        if self.selected is None:
            raise InputError("no point selected: add a point (New point) or select one in the list")
        return self.points[self.selected]

    def _seen(self, scene: str, camera: str) -> Observation:
        seen = self.current().observation(scene, camera)
        if seen is None:
            raise InputError(f"point {self.current().id} is not measured in {scene} ({camera}) yet: click it there "
                             "first")
        return seen

    def _require_new_id(self, point_id: str) -> None:
        if not point_id:
            raise InputError("a point id cannot be empty")
        if point_id in self.ids():
            raise InputError(f"there is a point {point_id!r} already: choose another id")

    # --- the GCP table ------------------------------------------------------------------------
    def table(self) -> GcpTable:
        """Every observation of every point as a GcpTable row naming its scene.
        InputError naming the points without a ground or without an observation."""
        if not self.points:
            raise InputError("no point to save: measure at least one")
        for what, bad in (("have no ground position: pick each on the map (or a reference layer)",
                           [p.id for p in self.points if p.ground is None]),
                          ("are not measured in any image: click each on a raw image",
                           [p.id for p in self.points if not p.observations])):
            if bad:
                raise InputError(f"point(s) {listed(np.array(bad))} {what}")
        rows = [(p, o) for p in self.points for o in p.observations]
        column = {k: np.array([getattr(o, k) for _, o in rows]) for k in ("scene", "camera", "col", "row", "sigma_px")}
        ground = {k: np.array([getattr(p.ground, k) for p, _ in rows]) for k in ("lon", "lat", "h", "sigma_xy",
                                                                                 "sigma_z")}
        return GcpTable(np.array([p.id for p, _ in rows]), np.array([p.role for p, _ in rows]), column["camera"],
                        column["col"], column["row"], ground["lon"], ground["lat"], ground["h"], column["sigma_px"],
                        ground["sigma_xy"], ground["sigma_z"], scene=column["scene"])

    def load(self, table: GcpTable, scenes: list[str], source: str = "the GCP layer", height_from: str = "") -> None:
        """Continue from a saved table (replacing the points held; undo history cleared), with
        the residuals of an adjusted GCP layer (bundleadjust's OUTPUT_GCPS) where it has them. Every
        row's scene must be one of ``scenes`` (the block's names; '' stands for the only one of a
        block of one scene); rows of one id must share their ground; ``height_from`` says where their
        heights came from (default: ``source``, the name errors give the layer). InputError naming the
        scenes or ids otherwise (nothing changed)."""
        scene = table.scene.copy()
        if len(scenes) == 1:
            scene[scene == ""] = scenes[0]
        unknown = sorted(set(scene.tolist()) - set(scenes))
        if unknown:
            names = ", ".join(repr(s) for s in unknown)
            raise InputError(f"{source} names scene(s) {names} that are not in the block ({', '.join(scenes) or 'none'}"
                             "): add those scenes first")
        _, first, point = np.unique(table.id, return_index=True, return_inverse=True)
        spread = np.hypot((table.lon - table.lon[first][point]) * 111e3 * np.cos(np.radians(table.lat)),
                          (table.lat - table.lat[first][point]) * 111e3) + np.abs(table.h - table.h[first][point])
        if (spread > 1e-3).any():
            raise InputError(f"{source}: the rows of point(s) {listed(np.unique(table.id[spread > 1e-3]))} hold "
                             "different ground positions; one point has one ground")
        points = [MeasuredPoint(str(table.id[k]), str(table.role[k]),
                                Ground(float(table.lon[k]), float(table.lat[k]), float(table.h[k]),
                                       float(table.sigma_xy[k]), float(table.sigma_z[k]), "layer",
                                       height_from or source))
                  for k in np.sort(first)]
        residual = table.residuals
        known = np.zeros(len(table), bool) if residual is None else residual.inside & np.isfinite(residual.col)
        by_id = {p.id: p for p in points}
        for k in range(len(table)):
            point = by_id[str(table.id[k])]
            if point.observation(scene[k], str(table.camera[k])) is not None:
                raise InputError(f"{source}: point {table.id[k]} is measured twice in {scene[k]} "
                                 f"({table.camera[k]})")
            point.observations.append(Observation(
                str(scene[k]), str(table.camera[k]), float(table.col[k]), float(table.row[k]),
                float(table.sigma_px[k]), (float(residual.col[k]), float(residual.row[k])) if known[k] else None))
        self.points, self.selected, self.history = points, None, []


# --- where to look ----------------------------------------------------------------------------------
def surface_for(heights: Heights, view: View):
    """The surface rays are met with: the DEM when ``heights`` take them from one, else a constant
    at ``heights.value`` (in its datum, made ellipsoidal at the centre of ``view``'s image: the
    geoid varies by centimetres over a scene)."""
    if heights.source == "dem":
        if heights.dem is None:
            raise InputError("heights from a DEM were asked for but no DEM was given: choose the DEM layer")
        return Dem(heights.dem, heights.datum) if isinstance(heights.dem, (str, Path)) else heights.dem
    cam = view.scene.cameras[view.camera]
    lon, lat, _ = ecef_to_geodetic(view.scene.image_to_ground(np.array([cam.cols / 2]), np.array([cam.rows / 2]),
                                                              float(heights.value), view.camera))
    return ConstantHeight(float(to_ellipsoidal(lon, lat, np.array([float(heights.value)]), heights.datum)[0]))


def predict(point: MeasuredPoint, target: View, views: dict[str, View], surface) -> list[Prediction]:
    """Where ``point`` should be in ``target``'s image, by ``target``'s model: from its ground when
    given, and from each observation in another scene (its ray through that scene's model met
    with ``surface``). Predictions outside the image keep their values; NaN where a ray misses."""
    sources, ground = [], []
    if point.ground is not None:
        sources.append("ground")
        ground.append(point.ground.ecef())
    for o in point.observations:
        if o.scene == target.scene_name or o.scene not in views:
            continue
        view = views[o.scene]
        sources.append(o.scene)
        ground.append(view.scene.image_to_ground_dem(np.array([o.col]), np.array([o.row]), surface,
                                                     view.scene.camera_index(o.camera)))
    if not sources:
        return []
    ground = np.concatenate(ground)
    met = np.all(np.isfinite(ground), axis=1)  # a ray that leaves the DEM or meets it on a hole has no ground
    col, row = np.full(len(ground), np.nan), np.full(len(ground), np.nan)
    if met.any():
        col[met], row[met] = target.scene.ground_to_image(ground[met], target.camera)
    return [Prediction(s, float(c), float(r)) for s, c, r in zip(sources, col, row)]


# --- snapping ---------------------------------------------------------------------------------------
def snap_to_scene(point: MeasuredPoint, target: View, other: View, surface,
                  settings: PointSnapSettings = PointSnapSettings()) -> PointSnap:
    """Snap ``point``'s observation in ``target`` to its observation in ``other`` (another scene's
    raw image), see :mod:`core.measure.pointsnap`."""
    here, there = _observed(point, target), _observed(point, other)
    template = ImageReference(other.scene, other.camera, other.image, 1.0, budget=0)
    return _snap(here, target, template, there.col - 0.5, there.row - 0.5, template.ground_pixel, surface, settings,
                 f"{other.scene_name} ({other.camera_name})")


def snap_to_reference(point: MeasuredPoint, target: View, reference_path, surface,
                      settings: PointSnapSettings = PointSnapSettings()) -> PointSnap:
    """Snap ``point``'s observation in ``target`` to the reference orthoimage at ``reference_path``
    around the point's ground."""
    here = _observed(point, target)
    if point.ground is None:
        raise InputError(f"point {point.id} has no ground position: give it before snapping to the reference")
    reference = Reference(reference_path, budget=0)
    tx, ty = reference.pixel(point.ground.lon, point.ground.lat)
    return _snap(here, target, reference, float(tx), float(ty), reference.ground_pixel, surface, settings,
                 f"reference {reference_path}")


def _observed(point: MeasuredPoint, view: View) -> Observation:
    seen = point.observation(view.scene_name, view.camera_name)
    if seen is None:
        raise InputError(f"point {point.id} is not measured in {view.scene_name} ({view.camera_name}): click it "
                         "there first")
    return seen


def _snap(here: Observation, target: View, template: Reference, tx: float, ty: float, to_template, surface,
          settings: PointSnapSettings, what: str) -> PointSnap:
    jacobian = local_map(target.scene, target.camera, here.col, here.row, surface, to_template, settings.window / 2)
    image = ImageReference(target.scene, target.camera, target.image, 1.0, budget=0)
    return snap_point(image, here.col, here.row, template, tx, ty, jacobian, settings, what)
