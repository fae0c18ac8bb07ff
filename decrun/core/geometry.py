"""Geometry of simplicial meshes, measured from plain arrays (one home for every formula).

Functions take explicit ``points`` so they also measure moved vertices (a smoothing step)
and parameter-space positions (uv), not only a complex's own geometry; the complex caches
the ones it uses on its own vertices (``SimplicialComplex.require``).

Shapes: ``points (n, 2|3) float64``, ``faces (m, 3) int64`` (triangles), ``edges (e, 2)``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.core.connectivity import edge_table
from decrun.core.simplex_arrays import vertex_volumes

__all__ = [
    "PLANAR_TOLERANCE",
    "embed3",
    "edge_lengths",
    "mean_edge_length",
    "triangle_areas",
    "corner_angles",
    "corner_cotangents",
    "face_normals",
    "area_normals",
    "vertex_normals",
    "is_planar",
    "obtuse_triangle_count",
    "principal_frame",
]

#: relative tolerance of :func:`is_planar` (spread of z over the bounding-box diagonal)
PLANAR_TOLERANCE = 1e-12


def embed3(points: np.ndarray) -> np.ndarray:
    """(N, 2 or 3) → (N, 3) float64, with z = 0 for planar input."""
    points = np.asarray(points, dtype=np.float64)
    if points.shape[1] == 3:
        return points
    return np.concatenate([points, np.zeros((points.shape[0], 3 - points.shape[1]))], axis=1)


def edge_lengths(points: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Lengths |p_j − p_i| (model units) of the edges (e, 2) → (e,)."""
    return vertex_volumes(np.asarray(points, dtype=np.float64), np.asarray(edges))


def mean_edge_length(points: np.ndarray, faces: np.ndarray) -> float:
    """Mean length of the distinct edges of the triangles ``faces`` (model units)."""
    return float(edge_lengths(points, edge_table(faces)[0]).mean())


def triangle_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unsigned areas ½|(p1−p0)×(p2−p0)|: points (n, 2|3), faces (m, 3) -> (m,)."""
    return vertex_volumes(np.asarray(points, dtype=np.float64), np.asarray(faces))


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


def corner_cotangents(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """cot θ of every triangle corner: (m, 3), entry ``[t, l]`` at local vertex ``l``.

    cot θ = (a·b) / |a×b| for the two edges a, b leaving the corner — the weights of the
    cotangent formula ⋆1 = ½(cot α + cot β) (§4.5.5). Negative for obtuse corners.
    """
    p = embed3(points)[np.asarray(faces)]
    a = np.roll(p, -1, axis=1) - p
    b = np.roll(p, 1, axis=1) - p
    return np.einsum("mkd,mkd->mk", a, b) / np.linalg.norm(np.cross(a, b), axis=2)


def face_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m, 3) unit normals of the triangles (right-hand rule over the given vertex order):
    a planar mesh in the xy-plane oriented counter-clockwise gets +z. Pass
    ``K.oriented_simplices()`` for the consistent orientation of a complex."""
    normal = area_normals(points, faces)
    return normal / np.linalg.norm(normal, axis=1, keepdims=True)


def area_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m, 3) ``(p1 − p0) × (p2 − p0)``: normals of length 2·area (right-hand rule over the
    given vertex order; planar points get (0, 0, 2·signed area))."""
    x = embed3(points)
    f = np.asarray(faces)
    return np.cross(x[f[:, 1]] - x[f[:, 0]], x[f[:, 2]] - x[f[:, 0]])


def vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit vertex normals ``(n, 3)``: the area-weighted sum of the incident triangles' normals.

    Vertices whose weighted sum vanishes get the zero vector.
    """
    f = np.asarray(faces)
    face_normal = area_normals(points, f)  # length = 2 * area
    n, m = len(points), len(f)
    incidence = sp.csr_matrix((np.ones(3 * m), (f.ravel(), np.repeat(np.arange(m), 3))), shape=(n, m))
    normals = incidence @ face_normal
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)


def is_planar(points: np.ndarray, tol: float = PLANAR_TOLERANCE) -> bool:
    """True for 2-D points or 3-D points whose z spread is below ``tol`` × the bounding-box
    diagonal (the meshes decrun treats as planar domains in the xy-plane)."""
    points = np.asarray(points, dtype=np.float64)
    if points.shape[1] == 2:
        return True
    diagonal = float(np.linalg.norm(np.ptp(points, axis=0))) or 1.0
    return float(np.ptp(points[:, 2])) <= tol * diagonal


def obtuse_triangle_count(points: np.ndarray, faces: np.ndarray, tol_deg: float = 1e-9) -> int:
    """Number of triangles with an angle above 90° + ``tol_deg`` (points (n, 2|3), faces (m, 3)):
    the triangles whose circumcentric dual pieces are negative (§4.5.2, Fig. 4.17)."""
    return int((np.degrees(corner_angles(points, faces)).max(axis=1) > 90.0 + tol_deg).sum())


def principal_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """The frame a point set carries: ``(c, E, s, variances)``.

    c (3,) is the centroid; the rows e1, e2, e3 of E (3, 3) are the principal axes of the
    covariance Σ (x − c)(x − c)ᵀ / n, by decreasing variance (``variances`` (3,)); s is the
    RMS distance from c (model units; 0 when all points coincide). The sign of e1 and e2 is
    the one with a positive third moment Σ (e·(x − c))³ — an orientation the points
    themselves carry, so the frame moves with them; where that moment is zero to round-off
    (|mean u³| ≤ 1e-9, u = e·(x − c)/s: a symmetric point set) the largest component of e is
    made positive. e3 = e1 × e2 (right-handed). Planar points (n, 2) are taken in the z = 0
    plane. Where two variances are equal (a sphere, a cube) their axes are any orthonormal
    pair of that plane (whatever the eigensolver returns): the caller says so.
    """
    x = embed3(np.asarray(points, dtype=np.float64))
    c = x.mean(axis=0)
    r = x - c
    s = float(np.sqrt((r ** 2).sum(axis=1).mean()))
    values, vectors = np.linalg.eigh(r.T @ r / len(x))
    E = vectors[:, ::-1].T.copy()  # rows by decreasing variance
    third = ((r @ E[:2].T / (s if s > 0 else 1.0)) ** 3).mean(axis=0)
    largest = E[np.arange(2), np.argmax(np.abs(E[:2]), axis=1)]
    sign = np.where(np.abs(third) > 1e-9, np.sign(third), np.sign(largest))
    E[:2] *= sign[:, None]
    E[2] = np.cross(E[0], E[1])
    return c, E, s, values[::-1].copy()
