"""Values on a sphere mesh resampled on a regular longitude–latitude grid, the way the
shallow-water papers draw their maps (no matplotlib here: the figures are :mod:`.sphere`).

A grid point is the direction p = (cos θ cos λ, cos θ sin λ, sin θ) (λ longitude, θ latitude).
Its value is the linear interpolant of the triangle whose cone from the centre holds p:
with a, b, c the triangle's corners (outward oriented), Cramer's rule gives
p = μ_a a + μ_b b + μ_c c, μ_a = det(p, b, c)/det(a, b, c) …, and p lies in the cone when every
μ ≥ 0. The barycentric coordinates of the point where the ray through p pierces the
triangle's plane are λ = μ / Σμ, so the interpolant reproduces constants and every affine
function of the piercing point exactly, and a smooth field on the sphere to O(h²).

Values per vertex are interpolated on the mesh's own triangles; values per triangle (a dual
0-form, e.g. the relative vorticity) on the triangulation of the triangles' circumcentres
projected onto the sphere (their convex hull: the spherical Delaunay triangulation of the
dual vertices). The containing triangle is found among the nearest triangle centroids
(a k-d tree), all points at once; the few a quasi-uniform mesh leaves unfound are searched
again with more candidates, and finally among all triangles, in bounded blocks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, cKDTree

__all__ = ["SphereInterpolator", "lonlat_grid", "directions", "sphere_radius", "on_triangles", "regrid"]

#: relative tolerance of "the mesh is a sphere centred at the origin" (vertex radii and centre)
SPHERE_TOLERANCE = 1e-6


def sphere_radius(vertices: np.ndarray) -> float | None:
    """The radius of the sphere centred at the origin on which all ``vertices (n, 3)`` lie
    (to :data:`SPHERE_TOLERANCE` relative), or None when they do not."""
    vertices = np.asarray(vertices, dtype=np.float64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or not len(vertices):
        return None
    radii = np.linalg.norm(vertices, axis=1)
    radius = float(radii.mean())
    if not radius > 0 or np.abs(radii - radius).max() > SPHERE_TOLERANCE * radius:
        return None
    return radius


def lonlat_grid(latitudes=(-90.0, 90.0), center_longitude: float = 0.0,
                resolution: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """The grid's nodes in degrees: longitudes (nx,) from ``center_longitude`` − 180 to
    ``center_longitude`` + 180 and latitudes (ny,) over ``latitudes`` = (south, north), both
    ends included, spaced by at most ``resolution``."""
    south, north = (float(v) for v in latitudes)
    nx = int(np.ceil(360.0 / resolution)) + 1
    ny = max(2, int(np.ceil((north - south) / resolution)) + 1)
    return (np.linspace(center_longitude - 180.0, center_longitude + 180.0, nx), np.linspace(south, north, ny))


def directions(longitudes: np.ndarray, latitudes: np.ndarray) -> np.ndarray:
    """(ny, nx, 3) unit vectors of the grid nodes (degrees in, λ east of x, θ north)."""
    lon, lat = np.meshgrid(np.radians(longitudes), np.radians(latitudes))
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)


def _unit(points: np.ndarray) -> np.ndarray:
    return points / np.linalg.norm(points, axis=1, keepdims=True)


@dataclass
class Located:
    """Where each query direction fell: ``triangle (q,)`` (−1: in no triangle, e.g. a hole)
    and ``weights (q, 3)`` the barycentric coordinates λ (rows sum to 1; 0 where unfound)."""

    triangle: np.ndarray
    weights: np.ndarray


class SphereInterpolator:
    """Linear interpolation on the triangles ``(t, 3)`` over ``points (m, 3)`` on a sphere
    centred at the origin (module docstring); the triangles are reoriented outward."""

    #: candidates tried per query direction, then doubled on the unfound ones
    FIRST_CANDIDATES = 8
    #: queries × triangles per block of the final exhaustive search
    BLOCK = 400_000

    def __init__(self, points: np.ndarray, triangles: np.ndarray):
        self.points = _unit(np.asarray(points, dtype=np.float64))
        triangles = np.array(triangles, dtype=np.int64)
        a, b, c = (self.points[triangles[:, i]] for i in range(3))
        inward = np.einsum("ij,ij->i", a, np.cross(b, c)) < 0
        triangles[inward] = triangles[inward][:, [0, 2, 1]]
        self.triangles = triangles
        a, b, c = (self.points[triangles[:, i]] for i in range(3))
        #: (t, 3, 3) rows (b × c, c × a, a × b) / det(a, b, c): μ = duals @ p
        self.duals = np.stack([np.cross(b, c), np.cross(c, a), np.cross(a, b)], axis=1)
        self.duals /= np.einsum("ij,ij->i", a, self.duals[:, 0])[:, None, None]
        self.tree = cKDTree(_unit(self.points[triangles].sum(axis=1)))

    def _coordinates(self, p: np.ndarray, candidates: np.ndarray) -> np.ndarray:
        """μ (q, k, 3): Cramer's coordinates of the directions ``p (q, 3)`` in the candidate
        triangles ``(q, k)``."""
        return np.einsum("qkij,qj->qki", self.duals[candidates], p)

    def _pick(self, p, candidates, located: Located, rows: np.ndarray) -> np.ndarray:
        """Record, for the queries ``rows``, the first candidate whose cone holds them; returns
        the rows still unfound."""
        mu = self._coordinates(p, candidates)
        inside = (mu >= -1e-12).all(axis=-1) & (mu.sum(axis=-1) > 0)
        found = inside.any(axis=1)
        first = inside.argmax(axis=1)[found]
        hit = rows[found]
        located.triangle[hit] = candidates[found, first]
        chosen = mu[found, first]
        located.weights[hit] = chosen / chosen.sum(axis=1, keepdims=True)
        return rows[~found]

    def _search(self, p, rows, candidates_of, k: int, located: Located) -> np.ndarray:
        """:meth:`_pick` over ``rows`` in blocks of at most :data:`BLOCK` (query, candidate)
        pairs, the candidates ``candidates_of(block_rows) (b, k)``; returns the rows unfound."""
        block = max(1, self.BLOCK // k)
        left = [self._pick(p[part], candidates_of(part), located, part)
                for part in (rows[start:start + block] for start in range(0, rows.size, block))]
        return np.concatenate(left) if left else rows

    def locate(self, queries: np.ndarray) -> Located:
        """The triangle and barycentric coordinates of every direction ``queries (q, 3)``."""
        p = _unit(np.asarray(queries, dtype=np.float64).reshape(-1, 3))
        located = Located(np.full(len(p), -1, dtype=np.int64), np.zeros((len(p), 3)))
        rows = np.arange(len(p))
        count = len(self.triangles)
        k = min(self.FIRST_CANDIDATES, count)
        while rows.size and k < count:
            rows = self._search(p, rows, lambda part, k=k: self.tree.query(p[part], k=k)[1].reshape(part.size, k),
                                k, located)
            k = min(4 * k, count) if k < 64 else count
        if rows.size:  # exhaustive: a mesh with holes (those directions stay unfound), or a very uneven one
            everything = np.arange(count)
            self._search(p, rows, lambda part: np.broadcast_to(everything, (part.size, count)), count, located)
        return located

    def interpolate(self, values: np.ndarray, located: Located) -> np.ndarray:
        """(q,) the interpolated ``values (m,)`` at the located directions (NaN where unfound)."""
        values = np.asarray(values, dtype=np.float64)
        out = np.einsum("qi,qi->q", located.weights, values[self.triangles[np.maximum(located.triangle, 0)]])
        out[located.triangle < 0] = np.nan
        return out


def on_triangles(vertices: np.ndarray, triangles: np.ndarray) -> SphereInterpolator:
    """The interpolator of values per triangle: on the convex hull (spherical Delaunay
    triangulation) of the triangles' circumcentres projected onto the unit sphere."""
    from decrun.core.stars.circumcentric import circumcenter_barycentric

    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(triangles, dtype=np.int64)]
    centres = _unit(np.einsum("mc,mcd->md", circumcenter_barycentric(corners), corners))
    return SphereInterpolator(centres, ConvexHull(centres).simplices)


def regrid(vertices: np.ndarray, triangles: np.ndarray, values: np.ndarray, longitudes: np.ndarray,
           latitudes: np.ndarray) -> np.ndarray:
    """(ny, nx) ``values`` — one per vertex or one per triangle of the sphere mesh
    ``(vertices (n, 3), triangles (t, 3))`` — interpolated at the grid nodes (degrees)."""
    values = np.asarray(values, dtype=np.float64)
    if values.shape == (len(vertices),):
        interpolator = SphereInterpolator(vertices, triangles)
    elif values.shape == (len(triangles),):
        interpolator = on_triangles(vertices, triangles)
    else:
        raise ValueError(f"values must have one entry per vertex ({len(vertices)}) or per triangle "
                         f"({len(triangles)}), got shape {values.shape}")
    grid = directions(longitudes, latitudes)
    return interpolator.interpolate(values, interpolator.locate(grid.reshape(-1, 3))).reshape(grid.shape[:2])
