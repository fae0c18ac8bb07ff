"""The circumcentric (Voronoi) Hodge star of the thesis (§4.5.2–4.5.5), any dimension.

⋆_k = |⋆σ| / |σ| with **signed** circumcentric dual volumes |⋆σ|, so the dual cell piece of
an obtuse simplex (circumcenter outside, Fig. 4.17) counts negatively and Σ ⋆0 is the total
volume exactly. On triangles ⋆1 is the cot formula ½(cot α + cot β) and ⋆0 the Voronoi area
(§4.5.5). ⋆1 is negative on non-Delaunay edges and zero on the diagonals of right-angled
grid cells (then ⋆1⁻¹ does not exist). Dual cells of border simplices are truncated at the
border (the natural, Neumann, boundary condition of the Laplacians).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations, permutations
from math import factorial

import numpy as np

from decrun.core import extension
from decrun.core.simplex_arrays import simplex_volumes
from decrun.core.stars import HodgeStar

__all__ = ["Circumcentric", "circumcenter_barycentric", "circumcentric_dual_volumes", "triangle_dual_volumes",
           "triangle_dual_volumes_numpy"]


def circumcenter_barycentric(points: np.ndarray) -> np.ndarray:
    """Barycentric coordinates of the circumcenters of simplices.

    The circumcenter of ``p_0..p_j`` is the point of their affine hull equidistant from all
    corners (§4.5.5 gives the triangle case). With ``E = [p_1-p_0, ..., p_j-p_0]`` it is
    ``p_0 + E μ`` where ``(EᵀE) μ = ½ diag(EᵀE)``.

    Parameters
    ----------
    points : (m, j+1, d) corner coordinates

    Returns
    -------
    (m, j+1) barycentric coordinates λ (rows sum to 1; negative entries mean the
    circumcenter lies outside, on the far side of the opposite face).
    """
    m, c, _ = points.shape
    if c == 1:
        return np.ones((m, 1))
    if c == 2:
        return np.full((m, 2), 0.5)
    edges = points[:, 1:, :] - points[:, :1, :]
    gram = np.einsum("mai,mbi->mab", edges, edges)
    rhs = 0.5 * np.einsum("maa->ma", gram)
    mu = np.linalg.solve(gram, rhs[..., None])[..., 0]
    return np.concatenate([1.0 - mu.sum(axis=1, keepdims=True), mu], axis=1)


def circumcentric_dual_volumes(K) -> dict[int, np.ndarray]:
    """{k: (n_k,) signed (n−k)-volumes |⋆σ| of the circumcentric dual cells} for k = 0..n.

    Computed exactly as a sum over the flags σ = S_k ⊂ S_{k+1} ⊂ … ⊂ S_n of every incident
    top simplex: the dual cell piece is the orthoscheme on the circumcenters c(S_k), …,
    c(S_n), whose edges are mutually orthogonal, so its volume is Π_j h_j / (n−k)! with h_j
    the *signed* distance of c(S_{j+1}) from aff(S_j), positive towards the vertex
    S_{j+1} \\ S_j. Obtuse simplices thus contribute negatively. Triangles use the closed
    cot forms of :func:`triangle_dual_volumes`.
    """
    if K.dim == 2:
        return triangle_dual_volumes(K)
    n = K.dim
    top = K.simplices(n)
    points = K.vertices[top]  # (m, n+1, d)
    m = top.shape[0]
    subsets = {j: list(combinations(range(n + 1), j + 1)) for j in range(n + 1)}
    volume = {}
    lam = {}
    for j in range(n + 1):
        for S in subsets[j]:
            corner = points[:, list(S), :]
            volume[S] = simplex_volumes(corner)
            lam[S] = circumcenter_barycentric(corner)

    def height(S, T):
        """Signed distance of c(T) from aff(S) inside aff(T), T = S ∪ {q}."""
        q = next(v for v in T if v not in S)
        j = len(S) - 1
        return lam[T][:, T.index(q)] * (j + 1) * volume[T] / volume[S]

    heights = {}
    result = {n: np.ones(K.num_simplices(n))}
    full = tuple(range(n + 1))
    for k in range(n):
        accumulated = np.zeros((m, len(subsets[k])))
        for slot, S in enumerate(subsets[k]):
            rest = [v for v in full if v not in S]
            total = np.zeros(m)
            for order in permutations(rest):
                product = np.ones(m)
                chain = S
                for q in order:
                    nxt = tuple(sorted(chain + (q,)))
                    key = (chain, nxt)
                    if key not in heights:
                        heights[key] = height(chain, nxt)
                    product = product * heights[key]
                    chain = nxt
                total += product
            accumulated[:, slot] = total / factorial(n - k)
        result[k] = np.bincount(
            K.top_face_indices(k).ravel(), weights=accumulated.ravel(), minlength=K.num_simplices(k)
        )
    return result


def triangle_dual_volumes(K) -> dict[int, np.ndarray]:
    """Closed forms of the flag sums for triangles (§4.5.5, Fig. 4.19).

    In a triangle with angle θ_i at corner i, the dual edge piece of the opposite edge
    is ½ cot θ_i |e_i| and corner i gets (|e_ij|² cot θ_k + |e_ik|² cot θ_j) / 8 of
    Voronoi area — signed, so obtuse triangles are exact. The compiled
    ``triangle_dual`` (:mod:`decrun.core.extension`); :func:`triangle_dual_volumes_numpy` is its twin.
    """
    compiled = extension.kernels()
    if compiled is None:
        return triangle_dual_volumes_numpy(K)
    top = K.simplices(2)
    dual0, dual1, lengths = compiled.triangle_dual(np.asarray(K.vertices, dtype=np.float64), top,
                                                  K.top_volumes, K.top_face_indices(1), K.num_simplices(1),
                                                  K.num_simplices(0))
    if K.embedding_dim in (2, 3):  # where K.edge_lengths() has these bits (vertex_volumes' loops)
        K.require("edge_lengths", lambda: lengths)  # ⋆1's divisor, found on the way
    return {0: dual0, 1: dual1, 2: np.ones(top.shape[0])}


def triangle_dual_volumes_numpy(K) -> dict[int, np.ndarray]:
    """The numpy twin (and tested reference) of :func:`triangle_dual_volumes`."""
    top = K.simplices(2)
    area = K.top_volumes
    # edge vectors opposite each sorted corner: e0 = p2 - p1, e1 = p0 - p2, e2 = p1 - p0,
    # one contiguous coordinate at a time, accumulated in place (few (m,) temporaries)
    m = top.shape[0]
    sq = np.zeros((3, m))  # sq[i] = |e_i|²
    dots = np.zeros((3, m))  # dots[i] = e_j · e_k for the two edges meeting at corner i
    edge = np.empty((3, m))
    columns = np.ascontiguousarray(K.vertices.T)
    for axis in range(K.embedding_dim):
        x = columns[axis]
        x0, x1, x2 = x[top[:, 0]], x[top[:, 1]], x[top[:, 2]]
        np.subtract(x2, x1, out=edge[0])
        np.subtract(x0, x2, out=edge[1])
        np.subtract(x1, x0, out=edge[2])
        del x0, x1, x2
        sq += edge * edge
        dots[0] += edge[1] * edge[2]
        dots[1] += edge[2] * edge[0]
        dots[2] += edge[0] * edge[1]
    del edge
    cot = dots  # cot θ_i = -(e_j · e_k) / (2A), computed in place
    cot *= -0.5 / area
    # dual edge piece ½ cot θ_i |e_i|; edge slots (0,1), (0,2), (1,2) are opposite corners 2, 1, 0
    dual_edge = np.empty((m, 3))  # in slot order, written column by column (no strided temporaries)
    for slot in range(3):
        np.sqrt(sq[2 - slot], out=dual_edge[:, slot])
        dual_edge[:, slot] *= 0.5 * cot[2 - slot]
    dual1 = np.bincount(K.top_face_indices(1).ravel(), weights=dual_edge.ravel(), minlength=K.num_simplices(1))
    del dual_edge
    weighted = sq * cot  # |e_i|² cot θ_i
    del sq, cot
    corner_area = np.empty((m, 3))
    np.add(weighted[2], weighted[1], out=corner_area[:, 0])
    np.add(weighted[0], weighted[2], out=corner_area[:, 1])
    np.add(weighted[1], weighted[0], out=corner_area[:, 2])
    del weighted
    corner_area *= 0.125
    dual0 = np.bincount(top.ravel(), weights=corner_area.ravel(), minlength=K.num_simplices(0))
    return {0: dual0, 1: dual1, 2: np.ones(top.shape[0])}


@dataclass
class Circumcentric(HodgeStar):
    """The thesis' circumcentric dual (``operator=circumcentric``, the default)."""

    name = "circumcentric"

    def diagonal(self, dec, k: int) -> np.ndarray:
        """⋆_k = |⋆σ| / |σ| (§4.5.4), (n_k,). A vertex's volume is 1 and a top simplex's dual is a
        point (volume 1): ⋆0 is a copy of the dual volumes and ⋆n the reciprocals of the volumes
        (the bits of the divisions, without their arrays of ones)."""
        if k == 0:
            return dec.dual_volumes(0).copy()
        if k == dec.n:
            return 1.0 / dec.primal_volumes(k)
        return dec.dual_volumes(k) / dec.primal_volumes(k)
