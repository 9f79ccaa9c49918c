"""Automatic tie points: raw images matched with each other through their scene models, the
cameras of one scene (:func:`match_tiepoints`) or images of several scenes of a block, other
passes, dates or sensors (:func:`match_block_tiepoints`).

Each other image is resampled into the base image's geometry through its own scene model on the
DEM (the common ground geometry, so view angles do not defeat the correlation) and matched with
the grid of the base image like a reference orthoimage (:func:`core.measure.matching.match_grid`:
the same coarse and fine passes, sub-pixel peaks and rejections). Normalised cross-correlation is
blind to gain and offset, so images of other dates and sensors match as long as the ground looks
alike (clouds and changed land cover are rejected as 'low correlation'). A grid point matched in
k other images is one tie point observed k + 1 times: its base observation is the grid point
itself, the others the matched positions mapped back to it through the local map base -> image.
``search`` (m) bounds the images' relative error (their models' errors together).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from osgeo import gdal

from ..errors import InputError
from ..model.sensor import SceneModel
from ..observations.tiepoints import TieTable
from ..rasters import open_input_raster
from .matching import (NO_DEM_HEIGHT, REASONS, GridMatch, MatchSettings, ground_sample_distance, match_grid,
                       reason_text)
from .reference import ImageReference
from .surface import filled_surface

log = logging.getLogger(__name__)

OUTSIDE_OTHER = "outside the other camera's image"  # REASONS[3] for tie points


@dataclass(frozen=True)
class View:
    """One raw image of a block: the name of its scene ('' within one scene), the scene model,
    the camera's index in it and the image file."""
    scene_name: str
    scene: SceneModel
    camera: int
    image: Path

    @property
    def camera_name(self) -> str:
        return self.scene.cameras[self.camera].name

    @property
    def label(self) -> str:
        """'<scene>/<camera>' in a block, the camera's name within one scene."""
        return f"{self.scene_name}/{self.camera_name}" if self.scene_name else self.camera_name


def match_tiepoints(scene: SceneModel, images: dict, dem, settings: MatchSettings = MatchSettings(search=300.0),
                    base: int = 0, progress: Callable[[float, str | None], None] | None = None,
                    is_cancelled: Callable[[], bool] | None = None) -> tuple[TieTable, dict]:
    """Tie points between camera ``base`` of ``scene`` and every other camera of ``images``
    ({camera index: raw image path}), see the module docstring. Returns the table (scene column
    empty) and {camera name: rejected counts by reason} (REASONS, 'outside the reference' named
    OUTSIDE_OTHER). InputError when no grid point matches in any camera, with the counts."""
    if base not in images or len(images) < 2:
        raise InputError("tie points need the base camera's image and at least one other camera's")
    order = sorted(images)
    views = [View("", scene, k, Path(images[k])) for k in order]
    return match_views(views, dem, settings, order.index(base), progress, is_cancelled)


def match_block_tiepoints(views: list[View], dem, settings: MatchSettings = MatchSettings(search=1000.0),
                          base: int = 0, progress: Callable[[float, str | None], None] | None = None,
                          is_cancelled: Callable[[], bool] | None = None) -> tuple[TieTable, dict]:
    """Tie points between image ``views[base]`` and each other image of a block of scenes (see
    the module docstring); the table's scene column names each observation's scene. Returns it
    and {'<scene>/<camera>': rejected counts by reason}. InputError naming the views for a view
    listed twice, an image given for two views, fewer than two scenes, or no match at all (and
    'do not overlap' when no grid point of the base image falls in another image)."""
    refuse_shared_images(views)
    if not 0 <= base < len(views):
        raise InputError(f"the base image {base} is not one of the {len(views)} given", parameter="base")
    filled = filled_surface(views[base].scene, views[base].camera, dem)    # a DSM's holes must not part the scenes
    apart = [v.label for k, v in enumerate(views) if k != base and not overlapping(views[base], v, filled)]
    if apart:
        raise InputError(f"{', '.join(apart)} do{'es' * (len(apart) == 1)} not overlap {views[base].label}: no "
                         f"point of its image, on the DEM through its onboard model, falls in "
                         f"{'theirs' if len(apart) > 1 else 'its image'}; leave out scenes of other ground",
                         parameter="scenes")
    return match_views(views, dem, settings, base, progress, is_cancelled)


def refuse_shared_images(views: list[View]) -> None:
    """InputError naming the views for a view listed twice, an image file given for two views, or
    fewer than two scenes: a block's views are images of two or more scenes, each its own."""
    labels = [v.label for v in views]
    twice = sorted({k for k in labels if labels.count(k) > 1})
    if twice:
        raise InputError(f"{', '.join(twice)} listed twice: give each scene's camera once", parameter="scenes")
    paths = [str(Path(v.image).resolve()) for v in views]
    shared = sorted({p for p in paths if paths.count(p) > 1})
    if shared:
        raise InputError(f"the image {shared[0]} is given for "
                         f"{' and '.join(v.label for v, p in zip(views, paths) if p == shared[0])}: each scene "
                         "needs its own image", parameter="images")
    if len({v.scene_name for v in views}) < 2:
        raise InputError("tie points between scenes need images of at least two scenes", parameter="scenes")


OVERLAP_GRID = 7  # points per side of the base image tried for an overlap
IDENTICAL_CORRELATION = 0.99  # two raw images of one size correlating this well pixel for pixel are one image
IDENTICAL_SIDE = 512          # px: the images compared block-averaged to about this size


def refuse_identical_images(base: View, others: list[View]) -> None:
    """InputError (parameter 'images') when another view's image shows the base image's pixels: same
    size and a correlation of at least IDENTICAL_CORRELATION pixel for pixel (a copy, or the same
    image in another format). Two scenes never record the same pixels (noise alone differs), but a
    copy correlates with itself through two different models at every place where the models'
    difference is smooth, and the ties it gives contradict the models by the relief parallax
    between them (measured: a median 13.5 px, at most 24 px, from where the other model puts them)."""
    size = (base.scene.cameras[base.camera].cols, base.scene.cameras[base.camera].rows)
    same = [v for v in others if (v.scene.cameras[v.camera].cols, v.scene.cameras[v.camera].rows) == size]
    if not same:
        return
    first = _thumbnail(base.image, size)
    for v in same:
        rho = _correlation(first, _thumbnail(v.image, size))
        if rho >= IDENTICAL_CORRELATION:
            raise InputError(f"the images of {base.label} ({base.image}) and {v.label} ({v.image}) show the same "
                             f"pixels (correlation {rho:.4f} pixel for pixel): one image given for two "
                             f"{'scenes' if base.scene_name else 'cameras'}? Each needs its own image",
                             parameter="images")


def _thumbnail(path, size: tuple[int, int]) -> np.ndarray:
    """Band 1 of the raster ``path`` (cols, rows = ``size``) block-averaged to about IDENTICAL_SIDE px."""
    step = max(1, max(size) // IDENTICAL_SIDE)
    ds = open_input_raster(path)   # held while its band is read: a band outliving its dataset crashes GDAL
    a = ds.GetRasterBand(1).ReadAsArray(buf_xsize=max(size[0] // step, 1), buf_ysize=max(size[1] // step, 1),
                                        resample_alg=gdal.GRIORA_Average).astype(np.float64)
    ds = None
    return a


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    energy = math.sqrt(float((a * a).sum() * (b * b).sum()))
    return float((a * b).sum()) / energy if energy > 0 else 0.0


def overlapping(base: View, other: View, dem) -> bool:
    """Whether a point of an OVERLAP_GRID x OVERLAP_GRID grid over ``base``'s image, on ``dem``
    through its model, falls in ``other``'s image through its model (the onboard models' errors,
    tens of metres, do not decide an overlap of kilometres)."""
    cam = base.scene.cameras[base.camera]
    col, row = (v.ravel() for v in np.meshgrid(np.linspace(0.5, cam.cols - 0.5, OVERLAP_GRID),
                                               np.linspace(0.5, cam.rows - 0.5, OVERLAP_GRID)))
    ground = base.scene.image_to_ground_dem(col, row, dem, base.camera)
    ground = ground[np.isfinite(ground).all(axis=1)]
    if not ground.size:
        return False
    c, r = other.scene.ground_to_image(ground, other.camera)
    return bool(np.any(other.scene.cameras[other.camera].in_image(c, r)))


def log_match(pair: str, m, surface) -> None:
    """Log the grid points of ``m`` (:class:`core.measure.matching.GridMatch` of the images ``pair``)
    that the DEM gives no height under (off its extent or on its holes), and how many of them matched."""
    if m.in_hole.any():
        log.info("%s: %s: those were matched at the estimated height %.1f m (%d matched; where the terrain is "
                 "steep their windows, rectified at that height, match less accurately)", pair,
                 surface.missing(m.ground, "grid points"), surface.estimate, int(((m.reasons < 0) & m.in_hole).sum()))


def match_in_view(base: View, other: View, surface, gsd: float, settings: MatchSettings,
                  report: Callable[[float, str | None], None], cancelled: Callable[[], bool]) -> tuple[GridMatch, dict]:
    """Match ``base``'s grid in ``other``'s image (resampled into base's geometry on ``surface``, a
    FilledSurface under base's image, at ``gsd`` m). Returns the GridMatch and its rejected counts
    {reason: grid points} (REASONS, 'outside the reference' named OUTSIDE_OTHER; the points the DEM
    has no height under are matched at the estimated height, so not a reason here)."""
    ref = ImageReference(other.scene, other.camera, other.image, gsd)
    m = match_grid(base.scene, base.camera, base.image, ref, surface, gsd, settings, report, cancelled)
    log_match(f"{base.label}-{other.label}", m, surface)
    return m, {OUTSIDE_OTHER if r == REASONS[3] else r: c for r, c in m.rejected().items() if r != NO_DEM_HEIGHT}


def match_views(views: list[View], dem, settings: MatchSettings, base: int,
                progress: Callable[[float, str | None], None] | None = None,
                is_cancelled: Callable[[], bool] | None = None) -> tuple[TieTable, dict]:
    """Match ``views[base]``'s grid in every other view (see :func:`match_block_tiepoints`)."""
    settings.validate()
    report = progress or (lambda fraction, message=None: None)
    cancelled = is_cancelled or (lambda: False)
    b = views[base]
    others = [v for k, v in enumerate(views) if k != base]
    refuse_identical_images(b, others)
    surface = filled_surface(b.scene, b.camera, dem)
    gsd = float(b.scene.info.get("gsd_m") or ground_sample_distance(b.scene, b.camera, surface))
    observations, rejected, outside = [], {}, []
    for n, v in enumerate(others):
        m, counts = match_in_view(b, v, surface, gsd, settings,
                                  lambda f, msg=None, n=n: report((n + f) / len(others), msg), cancelled)
        ok = m.reasons < 0
        rejected[v.label] = counts
        if counts[OUTSIDE_OTHER] == m.col.size:
            outside.append(v.label)
        ids = np.char.add("T", (np.nonzero(ok)[0] + 1).astype(str))
        observations.append((ids, b.camera_name, m.col[ok], m.row[ok], m.out["sigma"][ok], b.scene_name))
        observations.append((ids, v.camera_name, m.out["ref_col"][ok], m.out["ref_row"][ok], m.out["sigma"][ok],
                             v.scene_name))
    if not any(o[0].size for o in observations):
        apart = f" ({', '.join(outside)} do{'es' * (len(outside) == 1)} not overlap {b.label})" if outside else ""
        raise InputError(f"no tie point matched between {b.label} and the others{apart}: "
                         + "; ".join(f"{name}: {reason_text(r)}" for name, r in rejected.items())
                         + ". Lower the quality threshold, enlarge the window or the search range, or check that "
                           "the images are the scenes'")
    ids, cams, col, row, sigma, scenes = (np.concatenate([np.broadcast_to(o[i], o[0].shape) for o in observations])
                                          for i in range(6))
    # the base observation of a point matched in several images once
    key = np.char.add(np.char.add(np.char.add(ids, "|"), np.char.add(scenes, "|")), cams)
    _, first = np.unique(key, return_index=True)
    keep = np.sort(first)
    return TieTable(ids[keep], cams[keep], col[keep], row[keep], sigma[keep], scenes[keep]), rejected
