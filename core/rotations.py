"""Rotation helpers. Quaternions are scalar first (w, x, y, z); matrices act on column
vectors (v_out = R @ v_in). Arrays are vectorised over leading axes: (..., 4) <-> (..., 3, 3).
"""
from __future__ import annotations

import numpy as np

ARCSEC = np.pi / 648000.0  # radians per arcsecond
ARCSEC_PER_RAD = 1.0 / ARCSEC  # arcseconds per radian


def quat_to_matrix(q) -> np.ndarray:
    """Unit-normalised quaternion(s) (..., 4), scalar first -> rotation matrices (..., 3, 3)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    r = np.empty(q.shape[:-1] + (3, 3))
    r[..., 0, 0] = 1 - 2 * (y * y + z * z)
    r[..., 0, 1] = 2 * (x * y - z * w)
    r[..., 0, 2] = 2 * (x * z + y * w)
    r[..., 1, 0] = 2 * (x * y + z * w)
    r[..., 1, 1] = 1 - 2 * (x * x + z * z)
    r[..., 1, 2] = 2 * (y * z - x * w)
    r[..., 2, 0] = 2 * (x * z - y * w)
    r[..., 2, 1] = 2 * (y * z + x * w)
    r[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def matrix_to_quat(r) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> quaternions (..., 4), scalar first, w >= 0."""
    r = np.asarray(r, dtype=float)
    tr = r[..., 0, 0] + r[..., 1, 1] + r[..., 2, 2]
    cand = np.stack([
        np.stack([1 + tr, r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]],
                 -1),
        np.stack([r[..., 2, 1] - r[..., 1, 2], 1 + 2 * r[..., 0, 0] - tr, r[..., 0, 1] + r[..., 1, 0],
                  r[..., 0, 2] + r[..., 2, 0]], -1),
        np.stack([r[..., 0, 2] - r[..., 2, 0], r[..., 0, 1] + r[..., 1, 0], 1 + 2 * r[..., 1, 1] - tr,
                  r[..., 1, 2] + r[..., 2, 1]], -1),
        np.stack([r[..., 1, 0] - r[..., 0, 1], r[..., 0, 2] + r[..., 2, 0], r[..., 1, 2] + r[..., 2, 1],
                  1 + 2 * r[..., 2, 2] - tr], -1),
    ], axis=-2)
    # The candidate built on the largest diagonal term is the numerically stable one.
    diag = np.stack([tr, r[..., 0, 0], r[..., 1, 1], r[..., 2, 2]], -1)
    best = np.take_along_axis(cand, np.argmax(diag, -1)[..., None, None], axis=-2)[..., 0, :]
    q = best / np.linalg.norm(best, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def rot_x(a) -> np.ndarray:
    """Active rotation by angle a (rad) about x, (..., 3, 3)."""
    return _axis_rotation(a, 0)


def rot_y(a) -> np.ndarray:
    """Active rotation by angle a (rad) about y, (..., 3, 3)."""
    return _axis_rotation(a, 1)


def rot_z(a) -> np.ndarray:
    """Active rotation by angle a (rad) about z, (..., 3, 3)."""
    return _axis_rotation(a, 2)


def _axis_rotation(a, axis: int) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.zeros(a.shape + (3, 3))
    r[..., axis, axis] = 1.0
    r[..., i, i] = c
    r[..., j, j] = c
    r[..., i, j] = -s
    r[..., j, i] = s
    return r


def rotation_from_angles(roll, pitch, yaw) -> np.ndarray:
    """R = Rz(yaw) @ Ry(pitch) @ Rx(roll); angles in radians, (..., 3, 3).

    Used for installation (boresight) angles and small attitude corrections: for small
    angles it is the identity plus the skew matrix of (roll, pitch, yaw).
    """
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def _rotation_elements(angles: np.ndarray) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """R = Rz(yaw) Ry(pitch) Rx(roll) (..., 3, 3) of (..., 3) angles written out element by
    element, and the angles' (cos, sin) of roll, pitch, yaw."""
    cr, sr = np.cos(angles[..., 0]), np.sin(angles[..., 0])
    cp, sp = np.cos(angles[..., 1]), np.sin(angles[..., 1])
    cy, sy = np.cos(angles[..., 2]), np.sin(angles[..., 2])
    r = np.empty(angles.shape[:-1] + (3, 3))
    r[..., 0, 0], r[..., 0, 1], r[..., 0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    r[..., 1, 0], r[..., 1, 1], r[..., 1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    r[..., 2, 0], r[..., 2, 1], r[..., 2, 2] = -sp, cp * sr, cp * cr
    return r, (cr, sr, cp, sp, cy, sy)


def rotation_matrices(angles) -> np.ndarray:
    """rotation_from_angles of (..., 3) angles (roll, pitch, yaw), element by element: the R of
    :func:`rotation_and_derivatives` (the same numbers) without its derivatives."""
    return _rotation_elements(np.asarray(angles, dtype=float))[0]


def rotation_and_derivatives(angles) -> tuple[np.ndarray, np.ndarray]:
    """rotation_from_angles of (..., 3) angles (roll, pitch, yaw) and its derivatives:
    (R (..., 3, 3), dR (..., 3, 3, 3)) with dR[..., k, :, :] = dR/d angle_k. Element by
    element (R = Rz(yaw) Ry(pitch) Rx(roll) written out): fast for millions of angles."""
    angles = np.asarray(angles, dtype=float)
    r, (cr, sr, cp, sp, cy, sy) = _rotation_elements(angles)
    d = np.zeros(angles.shape[:-1] + (3, 3, 3))
    # d/d roll
    d[..., 0, 0, 1], d[..., 0, 0, 2] = cy * sp * cr + sy * sr, -cy * sp * sr + sy * cr
    d[..., 0, 1, 1], d[..., 0, 1, 2] = sy * sp * cr - cy * sr, -sy * sp * sr - cy * cr
    d[..., 0, 2, 1], d[..., 0, 2, 2] = cp * cr, -cp * sr
    # d/d pitch
    d[..., 1, 0, 0], d[..., 1, 0, 1], d[..., 1, 0, 2] = -cy * sp, cy * cp * sr, cy * cp * cr
    d[..., 1, 1, 0], d[..., 1, 1, 1], d[..., 1, 1, 2] = -sy * sp, sy * cp * sr, sy * cp * cr
    d[..., 1, 2, 0], d[..., 1, 2, 1], d[..., 1, 2, 2] = -cp, -sp * sr, -sp * cr
    # d/d yaw
    d[..., 2, 0, 0], d[..., 2, 0, 1], d[..., 2, 0, 2] = -sy * cp, -sy * sp * sr - cy * cr, -sy * sp * cr + cy * sr
    d[..., 2, 1, 0], d[..., 2, 1, 1], d[..., 2, 1, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    return r, d
