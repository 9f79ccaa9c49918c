"""The logic of digitising control lines on a raw image, without any user interface: the
image lines being drawn (vertices, undo, delete, pairing to ground lines), the ground line
nearest to a click, and ground lines predicted into the image by the current scene model.

Image coordinates are (col, row) GDAL px: (0, 0) is the upper-left corner of the upper-left
pixel, rows grow downwards (the display copy of :mod:`core.measure.display` shows them as x = col,
y = -row).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..geodesy import geodetic_to_ecef
from ..observations.lines import DEFAULT_SIGMA_PX, M_PER_DEG, ImageLines, build_image_lines
from ..observations.tables import Heights, ellipsoidal_heights
from .snapping import SnapSettings, snap_lines


@dataclass
class DigitisedLine:
    """One image line: vertices [(col, row)] px, the id of the ground line it shows ('' = not
    paired yet) and each vertex's sigma px once snapped or loaded (None: the default)."""
    vertices: list[tuple[float, float]]
    line_id: str = ""
    sigmas: list[float] | None = None


@dataclass
class LineEditor:
    """Image lines being digitised: finished ``lines``, the vertices of the line being drawn
    (``current``) and the ``selected`` line's index (None: none). ``history``: the finished
    lines and snaps, in order, for undo: (line, None) a finished line, (line, (vertices,
    sigmas)) a snap and what the line held before it."""
    lines: list[DigitisedLine] = field(default_factory=list)
    current: list[tuple[float, float]] = field(default_factory=list)
    selected: int | None = None
    history: list[tuple[DigitisedLine, tuple | None]] = field(default_factory=list)

    def add_vertex(self, col: float, row: float) -> None:
        """Add a vertex (px) to the line being drawn (a repeated click is ignored)."""
        point = (float(col), float(row))
        if not np.all(np.isfinite(point)):
            raise InputError(f"vertex ({col}, {row}) is not a pixel position")
        if not self.current or self.current[-1] != point:
            self.current.append(point)

    def finish(self) -> int:
        """End the line being drawn; it becomes the selected line. Its index. InputError (the
        vertices kept) when it has fewer than two vertices."""
        if len(self.current) < 2:
            raise InputError(f"a line needs at least two vertices (this one has {len(self.current)}); "
                             "click more points or undo")
        self.lines.append(DigitisedLine(self.current))
        self.history.append((self.lines[-1], None))
        self.current = []
        self.selected = len(self.lines) - 1
        return self.selected

    def undo(self) -> str:
        """Remove the last vertex of the line being drawn, or else undo the last finish or snap
        of a line still held (lines loaded or without history: the last line); what was undone
        ('vertex', 'line', 'snap' or '' when nothing was left)."""
        if self.current:
            self.current.pop()
            return "vertex"
        while self.history:
            line, before = self.history.pop()
            if not any(line is held for held in self.lines):
                continue  # deleted since
            if before is not None:
                line.vertices, line.sigmas = before
                return "snap"
            self.lines = [held for held in self.lines if held is not line]
            break
        else:
            if not self.lines:
                return ""
            self.lines.pop()
        self.selected = None if self.selected is None or self.selected >= len(self.lines) else self.selected
        return "line"

    def snap_selected(self, image, settings: SnapSettings) -> tuple[int, int]:
        """Snap the selected line to the feature of ``image`` (raster path or array,
        :func:`core.measure.snapping.snap_lines`), undoable; (vertices refined, vertices)."""
        if self.selected is None:
            raise InputError("select an image line first (click it in the list), then snap it")
        line = self.lines[self.selected]
        v = np.array(line.vertices, dtype=float)
        sigma = line.sigmas if line.sigmas is not None else DEFAULT_SIGMA_PX
        result = snap_lines(image, ImageLines([line.line_id], "", [0, len(v)], v[:, 0], v[:, 1], sigma), settings)
        if result.refined.any():
            self.history.append((line, (line.vertices, line.sigmas)))
            line.vertices = list(zip(result.lines.col.tolist(), result.lines.row.tolist()))
            line.sigmas = result.lines.sigma_px.tolist()
        return int(result.refined.sum()), len(v)

    def delete_selected(self) -> bool:
        """Delete the selected line; False when none is selected."""
        if self.selected is None:
            return False
        del self.lines[self.selected]
        self.selected = None
        return True

    def select(self, index: int | None) -> None:
        if index is not None and not 0 <= index < len(self.lines):
            raise InputError(f"there is no line {index + 1} (there are {len(self.lines)})")
        self.selected = index

    def pair_selected(self, line_id: str) -> None:
        """Give the selected line the id of its ground line."""
        line_id = str(line_id).strip()
        if self.selected is None:
            raise InputError("select an image line first (click it in the list), then pick its ground line")
        if not line_id:
            raise InputError("the picked ground line has no id; choose the layer's id field")
        self.lines[self.selected].line_id = line_id

    def image_lines(self, camera: str, sigma_px: float = DEFAULT_SIGMA_PX, scene: str = "") -> ImageLines:
        """The finished lines as :class:`core.observations.lines.ImageLines` of ``camera`` (measured in
        the block scene named ``scene``; '' for none: one scene). InputError naming
        the lines (1-based, as listed) that are not paired, and when a line is still being
        drawn or there is none."""
        if self.current:
            raise InputError("a line is still being drawn: finish it (right click) or undo its vertices first")
        if not self.lines:
            raise InputError("no image line to save: digitise at least one")
        unpaired = [str(i + 1) for i, line in enumerate(self.lines) if not line.line_id]
        if unpaired:
            raise InputError(f"image line(s) {', '.join(unpaired)} are not paired with a ground line: select each "
                             "and pick its ground line on the map")
        sigmas = [np.full(len(line.vertices), sigma_px) if line.sigmas is None else np.array(line.sigmas)
                  for line in self.lines]
        return build_image_lines([line.line_id for line in self.lines],
                                 [np.array(line.vertices) for line in self.lines], camera, sigmas,
                                 source="digitised lines", scene=scene)

    def load(self, image: ImageLines) -> None:
        """Continue editing saved lines (replaces the lines held)."""
        self.lines = [DigitisedLine(list(zip(image.col[a:b].tolist(), image.row[a:b].tolist())), str(i),
                                    image.sigma_px[a:b].tolist())
                      for i, a, b in zip(image.line_id, image.start[:-1], image.start[1:])]
        self.current, self.selected, self.history = [], None, []


# --- ground lines --------------------------------------------------------------------------------
def nearest_line(parts: list[np.ndarray], x: float, y: float) -> tuple[int, float]:
    """(index of the part nearest to point (x, y), its distance) for polylines ``parts``
    [(n_i, 2)] in the point's frame (units of the frame). InputError without lines."""
    if not parts:
        raise InputError("the ground line layer holds no lines")
    a = np.concatenate([p[:-1, :2] for p in parts])
    b = np.concatenate([p[1:, :2] for p in parts])
    owner = np.repeat(np.arange(len(parts)), [max(len(p) - 1, 0) for p in parts])
    d = b - a
    dd = np.einsum("ni,ni->n", d, d)
    t = np.clip(np.einsum("ni,ni->n", np.array([x, y]) - a, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    dist = np.linalg.norm(np.array([x, y]) - a - t[:, None] * d, axis=1)
    k = int(np.argmin(dist))
    return int(owner[k]), float(dist[k])


def densify(part: np.ndarray, step_m: float) -> np.ndarray:
    """Vertices of a ground polyline (n, 2|3) lon, lat deg [, z] with points added along each
    segment, at most ``step_m`` m apart (interpolated linearly in lon, lat and z)."""
    lon, lat = part[:, 0], part[:, 1]
    dx = np.diff(lon) * M_PER_DEG * np.cos(np.radians(lat[:-1]))
    dy = np.diff(lat) * M_PER_DEG
    pieces = np.maximum(np.ceil(np.hypot(dx, dy) / step_m), 1).astype(int)
    # fractional vertex positions: segment k contributes k + j / pieces[k], j = 0 .. pieces[k] - 1
    seg = np.repeat(np.arange(pieces.size), pieces)
    frac = (np.arange(seg.size) - np.repeat(np.cumsum(pieces) - pieces, pieces)) / pieces[seg]
    at = np.r_[seg + frac, len(part) - 1]
    return np.stack([np.interp(at, np.arange(len(part)), part[:, k]) for k in range(part.shape[1])], axis=1)


@dataclass
class PredictedLine:
    """A ground line's image in one camera: line_id, col, row (n,) px (NaN where the model
    finds no image)."""
    line_id: str
    col: np.ndarray
    row: np.ndarray

    def runs(self) -> list[np.ndarray]:
        """The pieces (m, 2) of (col, row) between NaN gaps, each of two points or more."""
        ok = np.isfinite(self.col) & np.isfinite(self.row)
        edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(int), 0]))
        return [np.stack([self.col[a:b], self.row[a:b]], axis=1) for a, b in zip(edges[::2], edges[1::2])
                if b - a >= 2]


def predict_lines(scene, camera: int, ids, parts: list[np.ndarray], heights: Heights,
                  step_m: float = 20.0) -> list[PredictedLine]:
    """Ground lines predicted into ``camera``'s image by ``scene``: each part (n_i, 2|3) lon,
    lat deg [, z] densified to ``step_m`` m (a straight ground segment is not straight in a
    pushbroom image), heights as ``heights`` says (the parts' z, a DEM or a constant, each
    in its datum), then ground -> image. One :class:`PredictedLine` per part."""
    if not parts:
        return []
    dense = [densify(np.asarray(p, dtype=float), step_m) for p in parts]
    points = np.concatenate(dense)
    ids = np.asarray(ids, dtype=str)
    vid = np.repeat(ids, [len(p) for p in dense])
    z = points[:, 2] if points.shape[1] > 2 else None
    h = ellipsoidal_heights(points[:, 0], points[:, 1], heights, z, vid, "ground lines")
    col, row = scene.ground_to_image(geodetic_to_ecef(points[:, 0], points[:, 1], h), camera)
    bounds = np.cumsum([0] + [len(p) for p in dense])
    return [PredictedLine(str(i), col[a:b], row[a:b]) for i, a, b in zip(ids, bounds[:-1], bounds[1:])]
