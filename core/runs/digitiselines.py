"""The line dock's session without its widgets: the raw image opened (with its scene, or alone), the
image lines being digitised (:class:`core.measure.digitising.LineEditor`), the ground lines predicted
into the image, and every action on them, each returning the sentence the dock shows or raising a
PushbroomError whose message it shows instead.

Image coordinates are (col, row) GDAL px; ground lines are WGS84 lon, lat (deg) [, z].
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..errors import InputError
from ..measure.digitising import LineEditor, PredictedLine, nearest_line, predict_lines
from ..measure.snapping import SnapSettings
from ..measure.sources import ImageSource
from ..observations.lines import write_gpkg
from ..observations.tables import Heights
from .base import FilesInUse
from .docks import files_read

PREDICTION_STEP_M = 20.0  # ground spacing of predicted points: a few pixels of a 2-5 m GSD image
IMAGE_LINES = "image lines"  # how refusals of the save name its file
UNDONE = {"vertex": "Last vertex removed", "line": "Last line removed", "snap": "Snap undone", "": "Nothing to undo"}


@dataclass
class LineSession:
    """The raw image ``source`` shown (None: none yet) opened from file ``opened``, the ``editor`` and
    the ground lines ``predicted`` into the image."""
    editor: LineEditor = field(default_factory=LineEditor)
    source: ImageSource | None = None
    opened: str = ""
    predicted: list[PredictedLine] = field(default_factory=list)

    @property
    def scene(self):
        """The scene model (None: no image, or an image alone)."""
        return self.source.scene if self.source is not None else None

    @property
    def raw_image(self) -> str:
        """The raw image shown ('' for none): Snap reads its pixels."""
        return str(self.source.image) if self.source is not None else ""

    def open(self, opened: str, source: ImageSource) -> str:
        """Show the raw image ``source`` (opened from ``opened``): the prediction is cleared."""
        self.source, self.opened, self.predicted = source, str(opened), []
        return f"{source.image} shown" + (f", camera {source.camera_name} of {source.scene_path}"
                                          if source.scene_path else " without a scene")

    def scene_words(self) -> str:
        """The scene shown, in words."""
        if self.source is not None and self.source.scene_path:
            return f"{self.source.scene_path} ({self.source.camera_name})"
        return "none: the image alone (no prediction)" if self.source is not None else "none"

    # --- digitising -----------------------------------------------------------------------------------
    def finish(self) -> str:
        return f"Line {self.editor.finish() + 1} finished: press Pair, then click its ground line on the map"

    def undo(self) -> str:
        return UNDONE[self.editor.undo()]

    def delete(self) -> str:
        return "Line deleted" if self.editor.delete_selected() else "Select a line in the list first"

    def snap(self, settings: SnapSettings) -> str:
        """Snap the selected line to the raw image's feature across it (undoable)."""
        if not self.raw_image:
            raise InputError("Open the image first")
        refined, total = self.editor.snap_selected(self.raw_image, settings)
        return (f"{refined} of {total} vertices snapped (Undo restores them); the others found no clear feature and "
                "kept their place")

    def pair(self, ids: list[str], parts: list[np.ndarray], x: float, y: float) -> str:
        """Pair the selected line with the ground line (``ids``, ``parts`` [(n, 2|3)] in the frame of the
        click) nearest to the click at (x, y)."""
        index, _ = nearest_line(parts, x, y)
        self.editor.pair_selected(ids[index])
        return f"Line {self.editor.selected + 1} paired with ground line {ids[index]}"

    def bands(self) -> list[tuple[list, str]]:
        """What the dock draws, in order: (vertices [(col, row)] px, kind) of the predicted runs
        ('predicted'), the lines ('selected' or 'line') and the line being drawn ('drawing')."""
        bands = [(run.tolist(), "predicted") for line in self.predicted for run in line.runs()]
        bands += [(line.vertices, "selected" if i == self.editor.selected else "line")
                  for i, line in enumerate(self.editor.lines)]
        return bands + ([(self.editor.current, "drawing")] if self.editor.current else [])

    def selected_pixels(self) -> list[tuple[float, float]]:
        """The selected line's vertices (or those of the line being drawn): what the dock zooms to."""
        if self.editor.selected is not None:
            return list(self.editor.lines[self.editor.selected].vertices)
        return list(self.editor.current)

    def rows(self) -> list[str]:
        """The list's rows: each line's number, ground line id and vertex count."""
        return [f"{i + 1}: {line.line_id or 'not paired'} ({len(line.vertices)} vertices)"
                for i, line in enumerate(self.editor.lines)]

    # --- prediction and saving --------------------------------------------------------------------------
    def predict(self, ground: Callable[[], tuple[list[str], list[np.ndarray]]], heights: Heights, words: str) -> str:
        """The ground lines ``ground()`` gives (ids, parts [(n, 2|3)] lon, lat deg [, z]), as the scene
        model sees them in this camera (:func:`core.measure.digitising.predict_lines`), heights as
        ``heights`` say (``words``: where from)."""
        if self.scene is None:
            raise InputError("No scene: open the image with its scene file to see where the ground lines are")
        ids, parts = ground()
        self.predicted = predict_lines(self.scene, self.source.camera, ids, parts, heights, PREDICTION_STEP_M)
        shown = sum(bool(p.runs()) for p in self.predicted)
        return f"{shown} of {len(self.predicted)} ground lines predicted into the image, heights from {words}"

    def save(self, path: str, names: Callable[[list[str]], list[str]]) -> str:
        """Write the lines to layer ``image_lines`` of GeoPackage ``path`` (replaced whole, or not at all;
        never over a file the session reads), each naming its scene as ``names`` (scene files -> the
        names bundleadjust with SCENES gives them) names the scene file: the layer serves a block as it is."""
        scene_file = self.source.scene_path if self.source is not None else ""
        camera = self.source.camera_name if self.source is not None else ""
        if self.source is not None:
            FilesInUse(files_read(camera, self.opened, self.source)).check({IMAGE_LINES: [path]})
        scene = names([scene_file])[0] if scene_file else ""
        write_gpkg(path, image=self.editor.image_lines(camera, scene=scene))
        return f"{len(self.editor.lines)} image lines saved to {path}"
