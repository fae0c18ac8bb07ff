"""Lloyd's iteration towards a spherical centroidal Voronoi tessellation (SCVT; Du, Gunzburger &
Ju 2003), keeping the triangulation's connectivity: the grid optimization MPAS applies to its
icosahedral meshes before running TRiSK (Ringler et al. 2010), here as a pure function of the
vertices and triangles of a sphere centred at the origin.

:func:`subdivide_sphere` splits every triangle into four at its edges' midpoints projected onto the
sphere (the icosphere's refinement): Lloyd-iterating level by level from the icosahedron reaches the
centroidal grid of a fine level in far fewer steps than from the plain icosphere, whose slowly
converging large-scale modes the coarse levels have already settled.

Each step moves every generator x_i to the radial projection of the centroid of its Voronoi cell,
the cell taken as the fan of flat triangles (x_i, c_T, c_T') over its edges, c_T the triangles'
circumcenters projected onto the sphere (the spherical Voronoi vertices).
"""

from __future__ import annotations

import numpy as np

from decrun.core.complex import SimplicialComplex
from decrun.core.trisk import sphere_radius

__all__ = ["lloyd_sphere", "subdivide_sphere"]


def _spherical_circumcenters(points: np.ndarray, radius: float) -> np.ndarray:
    """(m, 3) the circumcenters of the spherical triangles ``points`` (m, 3, 3): the normal of
    their plane, oriented to the triangle's side, at distance ``radius``."""
    normal = np.cross(points[:, 1] - points[:, 0], points[:, 2] - points[:, 0])
    normal *= np.sign(np.einsum("md,md->m", normal, points[:, 0]))[:, None]
    return radius * normal / np.linalg.norm(normal, axis=1, keepdims=True)


def lloyd_sphere(vertices: np.ndarray, triangles: np.ndarray, iterations: int,
                 tolerance: float = 0.0) -> tuple[np.ndarray, dict]:
    """Lloyd-iterate the vertices of a triangulated sphere (n, 3) with fixed ``triangles`` (m, 3).

    Stops after ``iterations`` steps or when the largest move is below ``tolerance`` times the radius.
    Returns (the moved vertices, exactly on the sphere of the input's radius; {"iterations": steps
    done, "last_move": the last step's largest move over the radius}). The caller checks the result
    is still Delaunay (:class:`decrun.core.trisk.TRiSK` refuses a mesh that is not).
    """
    radius = sphere_radius(vertices)
    K = SimplicialComplex(vertices, triangles, orient="fix")
    edges = K.simplices(1)
    # the two triangles of every edge (columns of d1ᵀ: each edge's row holds exactly two triangles)
    owners = K.incidence(2).T.tocsr()
    pair = owners.indices.reshape(-1, 2)
    x = np.array(vertices, dtype=np.float64)
    move = np.inf
    steps = 0
    while steps < iterations and not move < tolerance:
        steps += 1
        centre = _spherical_circumcenters(x[triangles], radius)
        c1, c2 = centre[pair[:, 0]], centre[pair[:, 1]]
        moment = np.zeros_like(x)
        area = np.zeros(x.shape[0])
        for end in (0, 1):  # the piece (x_i, c1, c2) of each of the edge's two cells
            xi = x[edges[:, end]]
            piece = 0.5 * np.linalg.norm(np.cross(c1 - xi, c2 - xi), axis=1)
            area += np.bincount(edges[:, end], weights=piece, minlength=x.shape[0])
            weighted = piece[:, None] * (xi + c1 + c2) / 3.0
            for axis in range(3):
                moment[:, axis] += np.bincount(edges[:, end], weights=weighted[:, axis], minlength=x.shape[0])
        centroid = moment / area[:, None]
        new = radius * centroid / np.linalg.norm(centroid, axis=1, keepdims=True)
        move = float(np.linalg.norm(new - x, axis=1).max() / radius)
        x = new
    return x, {"iterations": steps, "last_move": move}


def subdivide_sphere(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One 1-to-4 refinement of a triangulated sphere centred at the origin: (the vertices followed by
    one new vertex per edge, at the edge's midpoint projected onto the sphere; the 4m triangles
    (a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca), each oriented as its parent)."""
    radius = sphere_radius(vertices)
    sides = np.stack([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]], axis=1)  # (m, 3, 2)
    unique, inverse = np.unique(np.sort(sides.reshape(-1, 2), axis=1), axis=0, return_inverse=True)
    midpoint = vertices[unique[:, 0]] + vertices[unique[:, 1]]
    new = radius * midpoint / np.linalg.norm(midpoint, axis=1, keepdims=True)
    ab, bc, ca = (vertices.shape[0] + inverse.reshape(-1, 3)).T
    a, b, c = triangles.T
    refined = np.concatenate([np.column_stack(t) for t in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))])
    return np.concatenate([vertices, new]), refined
