"""Per-triangle measurements shared by the applications (plain arrays in, arrays out).

These take explicit ``points`` so they also measure moved vertices (a smoothing step) and
parameter-space positions (uv), not only the complex's own geometry.
"""

from __future__ import annotations

import numpy as np

from decrun.core.complex import _vertex_volumes

__all__ = ["embed3", "triangle_areas", "corner_angles"]


def embed3(points: np.ndarray) -> np.ndarray:
    """(N, 2 or 3) → (N, 3) float64, with z = 0 for planar input."""
    points = np.asarray(points, dtype=np.float64)
    if points.shape[1] == 3:
        return points
    return np.concatenate([points, np.zeros((points.shape[0], 3 - points.shape[1]))], axis=1)


def triangle_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unsigned areas ½|(p1−p0)×(p2−p0)|: points (n, 2|3), faces (m, 3) -> (m,)."""
    return _vertex_volumes(np.asarray(points, dtype=np.float64), np.asarray(faces))


def corner_angles(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Interior angles of every triangle corner, in radians.

    points (n, 2|3), faces (m, 3) -> (m, 3); entry ``[t, l]`` is the angle of triangle ``t``
    at its local vertex ``l``. Unsigned (in [0, π]); computed with ``atan2(|a×b|, a·b)``,
    which stays accurate for angles near 0 and π. A degenerate corner (zero-length edge)
    gets angle 0.
    """
    p = embed3(points)[np.asarray(faces)]  # (m, 3, 3)
    a = np.roll(p, -1, axis=1) - p  # edge to the next corner
    b = np.roll(p, 1, axis=1) - p  # edge to the previous corner
    cross = np.linalg.norm(np.cross(a, b), axis=2)
    dot = np.einsum("mkd,mkd->mk", a, b)
    return np.arctan2(cross, dot)
