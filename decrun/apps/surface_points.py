"""Checks of points given in a config against the mesh (shared by the apps that take points:
``app=vector_field`` sources and sinks, ``app=fluid`` stirring strokes)."""

from __future__ import annotations

import numpy as np

from decrun.core.geometry import embed3
from decrun.errors import ConfigError, format_point
from decrun.methods.vector_design import nearest_faces

__all__ = ["check_points_on_surface"]


def check_points_on_surface(K, points, key: str, tolerance: float) -> None:
    """ConfigError naming ``key`` (``app.sources[0].point``) unless every point (P, d) has
    the mesh's embedding dimension d and lies within ``tolerance`` × h̄ (h̄ the mean edge
    length) of the surface. The distance is to the point's projection onto the nearest of
    the candidate faces of :func:`nearest_faces` (exact near the surface, an upper bound
    far from it). Points are snapped (to a vertex, a face) only within this tolerance."""
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    if points.shape[1] != K.embedding_dim:
        raise ConfigError(f"{key}: a point needs {K.embedding_dim} coordinates (the mesh's embedding dimension), "
                          f"got {points[0].tolist()}")
    _, projected = nearest_faces(K, points)
    distance = np.linalg.norm(embed3(points) - projected, axis=1)
    h = float(K.mean_edge_length)
    far = np.flatnonzero(distance > tolerance * h)
    if far.size:
        i = int(far[0])
        where = f"{key}[{i}]" if len(points) > 1 else key
        needed = float(np.ceil(distance[i] / h * 10) / 10 + 0.1)
        raise ConfigError(
            f"{where}: {points[i].tolist()} lies {distance[i]:.3g} from the surface (nearest surface point "
            f"{format_point(projected[i])}), more than app.point_tolerance={tolerance:g} mean edge lengths "
            f"(h̄ = {h:.3g}); move the point onto the mesh, or accept the snap with app.point_tolerance={needed:g}")
