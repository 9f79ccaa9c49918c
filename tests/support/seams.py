"""Round-trip checks that allow for seam duplicates.

Staggered CCD chips that are misaligned (as the true camera of a simulated scene is) image a
strip of ground a few pixels wide twice, once on each side of a seam: ground -> image may then
return the other chip's pixel, which sees the same ground point just as well. A round trip is
correct when it returns the same pixel, or, next to a seam, a pixel that sees the same ground.
"""
import numpy as np

SEAM_ZONE_PX = 10.0


def seam_distance(camera, col) -> np.ndarray:
    """Distance (px) from image columns to the nearest chip boundary of a camera."""
    bounds = np.array([c.col_offset for c in camera.chips[1:]] or [np.inf])
    return np.min(np.abs(np.asarray(col)[:, None] - bounds[None, :]), axis=1)


def round_trip_errors(scene, dem, col, row, col2, row2, camera: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(error (n,) px, duplicate (n,) bool): the image distance between (col, row) and the
    round-trip result (col2, row2), except for seam duplicates, where it is the ground distance
    (in px of the camera's GSD) between what the two pixels see on the DEM."""
    err = np.hypot(np.asarray(col2) - col, np.asarray(row2) - row)
    duplicate = (err > 1e-3) & (seam_distance(scene.cameras[camera], col) < SEAM_ZONE_PX)
    if duplicate.any():
        a = scene.image_to_ground_dem(col[duplicate], row[duplicate], dem, camera)
        b = scene.image_to_ground_dem(col2[duplicate], row2[duplicate], dem, camera)
        err[duplicate] = np.linalg.norm(a - b, axis=1) / scene.info["gsd_m"]
    return err, duplicate
