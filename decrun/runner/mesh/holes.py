"""Cut holes into a triangle mesh: remove the faces whose centroids fall in balls or boxes.

This makes the thesis' test subjects (Fig. 5.7: a half sphere with eyes, a smile and 'ears';
Fig. 5.8: a sphere with a T-shaped hole) out of generated spheres. After the cut the result
is made a manifold with border again, so :class:`decrun.core.complex.SimplicialComplex` accepts it:

1. faces whose centroid lies in any ball ``[cx, cy, cz, r]`` or axis-aligned box
   ``[xmin, ymin, zmin, xmax, ymax, zmax]`` are removed (2-D meshes: ``[cx, cy, r]`` and
   ``[xmin, ymin, xmax, ymax]``);
2. a vertex where two holes touch (more than two border edges meet — a pinch) loses all its
   faces, repeated until no pinch is left (the holes grow by one ring there);
3. only the largest edge-connected piece is kept (unless ``keep_all_pieces``) and unreferenced
   vertices are dropped.

Pure numpy/scipy. The ``holes`` post step (:func:`decrun.runner.mesh.post.holes`) uses it
with ``mesh.hole_cut=whole_triangles``; its default cut, ``split``, is
:func:`decrun.runner.mesh.cut.cut_holes` (triangles split along the region borders, smooth
holes), so this module is kept for reproducing the earlier sawtooth-border experiments.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from decrun.core.connectivity import drop_unreferenced, edge_table, largest_component
from decrun.errors import ConfigError, MeshError

__all__ = ["faces_in_regions", "cut_holes"]


def faces_in_regions(vertices: np.ndarray, faces: np.ndarray, balls: Sequence = (), boxes: Sequence = ()) -> np.ndarray:
    """(m,) bool: faces whose centroid lies in one of the ``balls`` or ``boxes`` (closed sets)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    d = vertices.shape[1]
    centroid = vertices[np.asarray(faces)].mean(axis=1)
    inside = np.zeros(len(centroid), dtype=bool)
    for k, ball in enumerate(balls):
        ball = np.asarray(list(ball), dtype=np.float64)
        if ball.shape != (d + 1,) or ball[-1] <= 0:
            raise ConfigError(f"mesh.hole_balls[{k}]: need [center ({d} numbers), radius > 0], got {ball.tolist()}")
        inside |= np.linalg.norm(centroid - ball[:d], axis=1) <= ball[d]
    for k, box in enumerate(boxes):
        box = np.asarray(list(box), dtype=np.float64)
        if box.shape != (2 * d,) or np.any(box[:d] > box[d:]):
            raise ConfigError(f"mesh.hole_boxes[{k}]: need [min corner ({d}), max corner ({d})] with min <= max, got {box.tolist()}")
        inside |= np.all((centroid >= box[:d]) & (centroid <= box[d:]), axis=1)
    return inside


def _pinched_vertices(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Vertices with more than two border edges (two holes meet there)."""
    edges, corner_edges = edge_table(faces, n_vertices)
    count = np.bincount(corner_edges.ravel(), minlength=len(edges))
    border = edges[count == 1]
    degree = np.bincount(border.ravel(), minlength=n_vertices)
    return np.flatnonzero(degree > 2)


def cut_holes(vertices: np.ndarray, faces: np.ndarray, balls: Sequence = (), boxes: Sequence = (),
              max_repairs: int = 50, keep_all_pieces: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Remove faces in ``balls``/``boxes``, repair pinches, keep the largest piece (every
    piece with ``keep_all_pieces``: the ``holes`` post step keeps, counts and logs itself).

    vertices (n, d), faces (m, 3) -> (vertices (n', d), faces (m', 3), kept_vertex_index (n',)),
    ``kept_vertex_index`` mapping new vertex numbers to the input ones. Raises
    :class:`MeshError` when nothing is left.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    keep = ~faces_in_regions(vertices, faces, balls, boxes)
    kept = faces[keep]
    for _ in range(max_repairs):
        if len(kept) == 0:
            break
        pinched = _pinched_vertices(kept, len(vertices))
        if pinched.size == 0:
            break
        kept = kept[~np.isin(kept, pinched).any(axis=1)]
    if len(kept) == 0:
        raise MeshError("mesh.hole_balls/hole_boxes: the holes remove every face of the mesh")
    if not keep_all_pieces:
        kept = kept[largest_component(kept, len(vertices))]
    kept_vertices, kept, used = drop_unreferenced(vertices, kept)
    return kept_vertices, kept, np.flatnonzero(used)
