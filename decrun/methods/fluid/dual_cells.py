"""Explicit circumcentric dual cells for the vorticity fluid (thesis §7.2.3, ETK07).

Every vertex owns one polygon. Its corners ("dual points") are, in counter-clockwise
fan order around the vertex normal, the circumcenters of its triangles; the cell of a
border vertex is closed by the midpoints of its two border edges and the vertex itself
(Fig. 7.12-style truncation at the border). Dual points are numbered globally:

    0 .. m-1                     circumcenters (one per triangle, the dual vertices)
    m .. m+nbe-1                 midpoints of the border edges
    m+nbe .. m+nbe+nbv-1         the border vertices

Cells are stored as padded integer arrays; no Python loop runs over vertices or faces.
On obtuse triangles the circumcenter leaves its triangle and the cell turns inside out
(§7.3): :func:`decrun.core.geometry.obtuse_triangle_count` measures that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from decrun.core import geometry
from decrun.core.dec import DEC
from decrun.core.geometry import embed3
from decrun.errors import TopologyError

__all__ = ["DualCells", "build_dual_cells", "face_normals", "vertex_normals"]


def _normalize(vectors: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(vectors, axis=-1, keepdims=True)
    return vectors / np.where(length > 0, length, 1.0)


def face_normals(dec: DEC) -> np.ndarray:
    """(m, 3) unit normals of the consistently oriented triangles (right-hand rule).

    A planar mesh whose triangles run counter-clockwise in the xy-plane gets +z.
    """
    return geometry.face_normals(dec.K.vertices, dec.K.oriented_simplices())


def vertex_normals(dec: DEC, relative_tol: float = 1e-8) -> np.ndarray:
    """(n0, 3) unit flattening normals per vertex (thesis §7.2.3, Fig. 7.8).

    The mean-curvature normal of Meyer, Desbrun, Schröder, Barr 2003: the direction of
    ``Δ0 x = ⋆0⁻¹ d0ᵀ ⋆1 d0 x`` (decrun's PSD Laplacian applied to the coordinates, = 2H n),
    oriented like the area-weighted face normal. Falls back to the area-weighted face normal
    where the curvature normal vanishes (flat regions, ``|Δ0 x|·sqrt(⋆0) < relative_tol``),
    at border vertices (where Δ0 x holds the border term) and where it deviates by more than
    60° from the face normal (saddles with noise).
    """
    K = dec.K
    x = embed3(K.vertices)
    f = K.oriented_simplices()
    area_normal = np.cross(x[f[:, 1]] - x[f[:, 0]], x[f[:, 2]] - x[f[:, 0]])  # 2·area·n
    face_average = np.zeros_like(x)
    for corner in range(3):
        np.add.at(face_average, f[:, corner], area_normal)
    face_average = _normalize(face_average)
    curvature = dec.laplacian(0) @ x
    size = np.linalg.norm(curvature, axis=1)
    curvature_unit = _normalize(curvature)
    cosine = np.einsum("nd,nd->n", curvature_unit, face_average)
    use = (size * np.sqrt(np.abs(dec.star_diagonal(0))) > relative_tol) & (np.abs(cosine) > 0.5)
    use &= ~K.border_vertices()
    return np.where(use[:, None], np.sign(cosine)[:, None] * curvature_unit, face_average)


@dataclass
class DualCells:
    """The explicit dual cells of a triangle mesh (all arrays indexed as documented).

    Attributes
    ----------
    points : (P, 3) positions of the dual points (circumcenters, border midpoints, border vertices)
    n_circumcenters : m, the number of triangles (dual points 0..m-1 are their circumcenters)
    point_vertex : (P,) for fixed border points the border vertex they belong to
        (a midpoint: its edge's smaller vertex), -1 for circumcenters
    corners : (n0, K) dual point ids of each cell polygon, counter-clockwise about the
        vertex normal, padded with the cell's first corner (so a cyclic sum over all K
        columns closes the polygon)
    count : (n0,) number of corners of each cell
    interpolation_corners : (n0, Ki) the corners used by the WSHD07 interpolation: as
        ``corners`` without coincident neighbours (right triangles share a circumcenter)
        and without a reflex border vertex (its velocity is the wall velocity anyway;
        dropping it keeps the cell convex); padded with -1
    interpolation_count : (n0,)
    border_vertex : (n0,) bool
    border_edges : (nbe,) edge ids of the border edges, in midpoint order
    vertex_normal : (n0, 3) flattening normals (:func:`vertex_normals`)
    face_normal : (m, 3)
    """

    points: np.ndarray
    n_circumcenters: int
    point_vertex: np.ndarray
    corners: np.ndarray
    count: np.ndarray
    interpolation_corners: np.ndarray
    interpolation_count: np.ndarray
    border_vertex: np.ndarray
    border_edges: np.ndarray
    vertex_normal: np.ndarray
    face_normal: np.ndarray


def _compact(table: np.ndarray, keep: np.ndarray, fill: int) -> tuple[np.ndarray, np.ndarray]:
    """Move the kept entries of each row to the front (stable), pad with ``fill``."""
    order = np.argsort(~keep, axis=1, kind="stable")
    packed = np.take_along_axis(table, order, axis=1)
    count = keep.sum(axis=1)
    packed[np.arange(packed.shape[1])[None, :] >= count[:, None]] = fill
    width = max(int(count.max()), 1)
    return packed[:, :width], count


def build_dual_cells(dec: DEC, duplicate_tol: float = 1e-9) -> DualCells:
    """Build the explicit circumcentric dual cells of ``dec.K`` (a manifold triangle mesh).

    Fan order: in the oriented triangle (v, b, c) the next triangle counter-clockwise
    about v is the one across edge {v, c}; the fan of a border vertex starts at the
    triangle whose edge {v, b} is a border edge. The walk runs max-valence rounds over
    all vertices at once.

    Parameters
    ----------
    dec : DEC on a triangle mesh (vertices (n0, 2) planar or (n0, 3) surface)
    duplicate_tol : corners closer than this times the mean edge length are merged
        (for the interpolation cells only)

    Returns
    -------
    DualCells
    """
    K = dec.K
    if K.dim != 2:
        raise TopologyError(f"the fluid solver needs a triangle mesh (a 2-complex), got a {K.dim}-complex")
    n0, m = K.num_simplices(0), K.num_simplices(2)
    x = embed3(K.vertices)
    f = K.oriented_simplices()
    corner_vertex = f.ravel()
    local = np.tile(np.arange(3), m)
    triangle_of = np.repeat(np.arange(m), 3)
    after = f[triangle_of, (local + 1) % 3]
    before = f[triangle_of, (local + 2) % 3]
    out_key = corner_vertex * n0 + after  # outgoing half-edge v -> b of each corner
    order = np.argsort(out_key)
    sorted_keys = out_key[order]
    want = corner_vertex * n0 + before  # the next corner around v leaves along v -> c
    position = np.clip(np.searchsorted(sorted_keys, want), 0, sorted_keys.size - 1)
    successor = np.where(sorted_keys[position] == want, order[position], -1)
    has_predecessor = np.zeros(3 * m, dtype=bool)
    has_predecessor[successor[successor >= 0]] = True

    valence = np.bincount(corner_vertex, minlength=n0)
    start = np.full(n0, 3 * m, dtype=np.int64)
    np.minimum.at(start, corner_vertex, np.arange(3 * m))
    border_start = ~has_predecessor
    start[corner_vertex[border_start]] = np.flatnonzero(border_start)
    border_vertex = np.zeros(n0, dtype=bool)
    border_vertex[corner_vertex[border_start]] = True

    width = int(valence.max())
    walk = np.full((n0, width), -1, dtype=np.int64)
    current = start.copy()
    for step in range(width):  # a fixed small number of rounds (the max valence)
        walk[:, step] = current
        alive = current >= 0
        current = np.where(alive, successor[np.maximum(current, 0)], -1)
        # a cyclic fan returns to its start: stop there
        current[current == start] = -1
    fan_length = (walk >= 0).sum(axis=1)
    if np.any(fan_length != valence):
        bad = np.flatnonzero(fan_length != valence)
        raise TopologyError(f"vertices {bad[:8].tolist()} do not have a single triangle fan (non-manifold?)")

    # border edges, their midpoints and the border vertices as dual points
    edges = K.simplices(1)
    edge_key = edges[:, 0] * n0 + edges[:, 1]

    def edge_id(a, b):
        return np.searchsorted(edge_key, np.minimum(a, b) * n0 + np.maximum(a, b))

    border_edges, _ = K.border_faces()
    border_edges = np.asarray(border_edges, dtype=np.int64)
    midpoint_of_edge = np.full(edges.shape[0], -1, dtype=np.int64)
    midpoint_of_edge[border_edges] = m + np.arange(border_edges.size)
    border_ids = np.flatnonzero(border_vertex)
    vertex_point = np.full(n0, -1, dtype=np.int64)
    vertex_point[border_ids] = m + border_edges.size + np.arange(border_ids.size)

    triangle_walk = np.where(walk >= 0, walk // 3, -1)
    corners = np.full((n0, width + 3), -1, dtype=np.int64)
    interior = ~border_vertex
    corners[interior, :width] = triangle_walk[interior]
    b = border_ids
    corners[b, 1:width + 1] = triangle_walk[b]
    first_corner = start[b]
    last_corner = walk[b, valence[b] - 1]
    corners[b, 0] = midpoint_of_edge[edge_id(b, after[first_corner])]
    corners[b, valence[b] + 1] = midpoint_of_edge[edge_id(b, before[last_corner])]
    corners[b, valence[b] + 2] = vertex_point[b]
    count = np.where(border_vertex, valence + 3, valence)
    if np.any(corners[b, 0] < 0) or np.any(corners[b, valence[b] + 1] < 0):
        raise TopologyError("a border fan does not start and end at border edges")

    points = np.concatenate([
        embed3(dec.circumcenters()),
        0.5 * (x[edges[border_edges, 0]] + x[edges[border_edges, 1]]),
        x[border_ids],
    ])
    point_vertex = np.concatenate([np.full(m, -1), edges[border_edges, 0], border_ids]).astype(np.int64)
    vertex_normal = vertex_normals(dec)

    slot = np.arange(corners.shape[1])[None, :]
    valid = slot < count[:, None]
    corners = np.where(valid, corners, corners[:, :1])
    corners = corners[:, : int(count.max())]
    valid = valid[:, : corners.shape[1]]

    # interpolation cells: merge coincident neighbours, drop reflex border vertices
    mean_edge = float(np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1).mean())
    position_of = points[corners]  # (n0, K, 3)
    previous = np.where(slot[:, : corners.shape[1]] == 0, count[:, None] - 1, slot[:, : corners.shape[1]] - 1)
    previous_point = np.take_along_axis(position_of, previous[..., None], axis=1)
    keep = valid & (np.linalg.norm(position_of - previous_point, axis=2) > duplicate_tol * mean_edge)
    keep[:, 0] |= valid[:, 0] & ~keep.any(axis=1)
    is_vertex_corner = corners >= m + border_edges.size
    nxt = np.where(slot[:, : corners.shape[1]] + 1 >= count[:, None], 0, slot[:, : corners.shape[1]] + 1)
    next_point = np.take_along_axis(position_of, nxt[..., None], axis=1)
    turn = np.einsum("nkd,nd->nk", np.cross(position_of - previous_point, next_point - position_of), vertex_normal)
    convex = turn > 1e-9 * mean_edge**2
    keep &= ~(is_vertex_corner & ~convex)
    interpolation_corners, interpolation_count = _compact(np.where(valid, corners, -1), keep, -1)
    return DualCells(
        points=points,
        n_circumcenters=m,
        point_vertex=point_vertex,
        corners=corners,
        count=count,
        interpolation_corners=interpolation_corners,
        interpolation_count=interpolation_count,
        border_vertex=border_vertex,
        border_edges=border_edges,
        vertex_normal=vertex_normal,
        face_normal=face_normals(dec),
    )
