"""Topology of a simplicial complex: components, the border ∂M, Betti numbers (§2.3.4).

Functions of a built :class:`~decrun.core.complex.SimplicialComplex` ``K`` (the complex's
methods of the same names call them and cache what is costly). Words: *border* is the mesh's
∂M — the (n-1)-simplices in one top simplex only; *boundary* is the operator δ.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.core.connectivity import graph_components
from decrun.errors import MeshError, NonManifoldError

__all__ = ["euler_characteristic", "connected_components", "border_faces", "border_vertices", "border_simplices",
           "border_loops", "betti_numbers", "betti_by_rank"]


def euler_characteristic(K) -> int:
    """χ = Σ_j (-1)^j n_j."""
    return int(sum((-1) ** j * K.num_simplices(j) for j in range(K.dim + 1)))


def connected_components(K) -> tuple[int, np.ndarray]:
    """(number of components, (n_n,) component label 0..c-1 of each top simplex), via shared vertices."""
    n = K.dim
    top = K.simplices(n)
    m = top.shape[0]
    nv = K.vertices.shape[0]
    rows = np.repeat(np.arange(m), n + 1)
    graph = sp.coo_matrix((np.ones(rows.size), (rows, top.ravel() + m)), shape=(m + nv, m + nv))
    _, label = graph_components(graph)
    _, top_label = np.unique(label[:m], return_inverse=True)  # labels 0..c-1 over top simplices
    return int(top_label.max()) + 1, top_label.astype(np.int64)


def border_faces(K) -> tuple[np.ndarray, np.ndarray]:
    """Border (n-1)-simplices: ``δ_n · 1`` (§2.3.4).

    Returns
    -------
    index : (b,) int64 indices into ``simplices(n-1)``
    sign : (b,) int8 the induced orientation (+1: the sorted tuple is oriented as the border)
    """
    chain = np.asarray(K.boundary(K.dim).sum(axis=1)).ravel()
    index = np.flatnonzero(np.abs(chain) > 0.5)
    return index, np.sign(chain[index]).astype(np.int8)


def border_vertices(K) -> np.ndarray:
    """(n0,) bool: vertices on the border."""
    mask = np.zeros(K.vertices.shape[0], dtype=bool)
    index, _ = border_faces(K)
    mask[K.simplices(K.dim - 1)[index].ravel()] = True
    return mask


def border_simplices(K) -> np.ndarray | None:
    """(b, n) the border (n-1)-simplices in the orientation the complex induces on them, or
    None for a closed complex (the top simplices of :meth:`SimplicialComplex.border_complex`)."""
    index, sign = border_faces(K)
    if index.size == 0:
        return None
    faces = K.simplices(K.dim - 1)[index].copy()
    if faces.shape[1] == 1:
        raise MeshError("the border of a 1-complex is a set of points, not a complex")
    flip = sign < 0
    faces[flip, 0], faces[flip, 1] = faces[flip, 1], faces[flip, 0].copy()
    return faces


def border_loops(K) -> list[np.ndarray]:
    """Border components of a 2-manifold as ordered vertex cycles.

    Each loop follows the orientation the complex induces on its border (§2.2.4): for a
    counter-clockwise planar disk the outer loop runs counter-clockwise and holes run
    clockwise. Loops are sorted longest (in length) first.

    Returns
    -------
    list of (L,) int64 arrays; loop[i] -> loop[i+1] (cyclically) is a border edge.
    """
    if K.dim != 2:
        raise ValueError("border_loops() is defined for 2-manifolds (triangle meshes)")
    index, sign = border_faces(K)
    if index.size == 0:
        return []
    edges = K.simplices(1)[index]
    start = np.where(sign > 0, edges[:, 0], edges[:, 1])
    end = np.where(sign > 0, edges[:, 1], edges[:, 0])
    nv = K.vertices.shape[0]
    successor = np.full(nv, -1, dtype=np.int64)
    successor[start] = end
    # Walk all loops at once: each step moves every loop one vertex along its successor.
    graph = sp.coo_matrix((np.ones(start.size), (start, end)), shape=(nv, nv))
    _, label = graph_components(graph)
    border_label = label[start]
    components = np.unique(border_label)
    root_of = np.full(label.max() + 1, nv, dtype=np.int64)
    np.minimum.at(root_of, border_label, start)  # smallest vertex of each loop starts it
    root_vertices = root_of[components]
    lengths = np.bincount(border_label, minlength=label.max() + 1)[components]
    walk = np.empty((root_vertices.size, lengths.max()), dtype=np.int64)
    current = root_vertices
    for step in range(lengths.max()):
        walk[:, step] = current
        current = successor[current]
    loops = [walk[i, : lengths[i]] for i in range(root_vertices.size)]
    lengths_geom = [
        float(np.linalg.norm(K.vertices[np.roll(loop, -1)] - K.vertices[loop], axis=1).sum()) for loop in loops
    ]
    order = np.argsort(lengths_geom)[::-1]
    return [loops[i] for i in order]


def betti_numbers(K) -> list[int]:
    """Betti numbers b_0..b_n over the reals.

    Exact for surfaces (b0 = components, b2 = closed components, b1 from χ), for
    tetrahedral meshes embedded in R³ whose border is a closed 2-manifold (b2 = border
    surfaces − components, Alexander duality: each closed surface bounds one region of the
    complement) and, for anything else, by dense rank computation (:func:`betti_by_rank`,
    small complexes only). A border pinched along an edge or at a vertex (removed cells
    that touch there) breaks the surface count — two cavities meeting along an edge form
    one connected border but two regions — so it goes to the rank computation too.
    """
    n = K.dim
    count, label = K.connected_components()
    index, _ = border_faces(K)
    chi = euler_characteristic(K)
    if n == 1:
        # a 1-manifold component is a loop (b1 = 1) or a path (b1 = 0)
        edges = K.simplices(1)
        has_border = np.zeros(count, dtype=bool)
        vertex_degree = np.bincount(edges.ravel(), minlength=K.vertices.shape[0])
        ends = np.flatnonzero(vertex_degree == 1)
        if ends.size:
            edge_of_end = np.flatnonzero(np.isin(edges, ends).any(axis=1))
            has_border[label[edge_of_end]] = True
        closed = int((~has_border).sum())
        return [count, closed]
    if n == 2:
        has_border = np.zeros(count, dtype=bool)
        if index.size:
            is_border = np.zeros(K.num_simplices(1), dtype=bool)
            is_border[index] = True
            has_border[label[is_border[K.top_face_indices(1)].any(axis=1)]] = True
        b2 = int((~has_border).sum())
        return [count, count + b2 - chi, b2]
    if n == 3 and K.embedding_dim == 3:
        try:  # the surface count needs a closed 2-manifold border: one fan per vertex, two triangles per edge
            border = K.border_complex(check_manifold=True)
        except NonManifoldError as pinch:
            return betti_by_rank(K, f"its border surface is pinched ({pinch})")
        if border is None:
            return betti_by_rank(K, "it has no border")
        border_components = border.connected_components()[0]
        b2 = border_components - count
        b1 = count + b2 - chi
        return [count, b1, b2, 0]
    return betti_by_rank(K)


def betti_by_rank(K, why: str = "") -> list[int]:
    """Betti numbers b_j = n_j − rank δ_j − rank δ_{j+1} by dense ranks (≤ 4000 simplices per
    dimension); ``why`` says, in the error above that size, why the fast counts did not apply."""
    sizes = [K.num_simplices(j) for j in range(K.dim + 1)]
    if max(sizes) > 4000:
        raise NotImplementedError(
            "betti_numbers(): dense rank computation is limited to complexes with at most 4000 simplices "
            f"per dimension for this kind of complex{f' ({why})' if why else ''}; this one has {max(sizes)}"
        )
    ranks = [0] + [int(np.linalg.matrix_rank(K.boundary(j).toarray())) for j in range(1, K.dim + 1)] + [0]
    return [sizes[j] - ranks[j] - ranks[j + 1] for j in range(K.dim + 1)]
