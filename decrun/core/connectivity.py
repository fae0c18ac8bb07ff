"""Connectivity of simplex arrays: edge tables, edge owners, pieces, unused vertices.

Plain ``(m, 3)`` triangle (or ``(m, k+1)`` simplex) index arrays in, arrays out — the one
home of the helpers the mesh sources, post steps, hole cutters and methods share. A built
:class:`~decrun.core.complex.SimplicialComplex` has these tables already
(``simplices(1)``, ``top_face_indices(1)``, ``facet_indices(2)``); these serve arrays that
are not (yet) a complex.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["graph_components", "edge_table", "edge_owners", "component_labels", "largest_component", "drop_unreferenced", "simplex_pieces"]


def graph_components(graph: sp.spmatrix) -> tuple[int, np.ndarray]:
    """(count, (n,) int32 labels) of the connected components of the undirected graph whose
    adjacency is ``graph`` (n, n): scipy's ``connected_components``, imported on the first call —
    ``scipy.sparse.csgraph`` loads ``scipy.sparse.linalg`` and ``scipy.linalg`` (~0.1 s of CPU),
    which importing decrun and building a valid complex and its operators never need."""
    from scipy.sparse.csgraph import connected_components

    count, labels = connected_components(graph, directed=False)
    return int(count), labels


def edge_table(faces: np.ndarray, n_vertices: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The distinct edges of triangles and which edge each corner starts.

    Parameters
    ----------
    faces : (m, 3) int vertex indices
    n_vertices : number of vertices (default: ``faces.max() + 1``)

    Returns
    -------
    edges : (e, 2) int64 sorted vertex pairs in lexicographic order
    corner_edges : (m, 3) int64, entry ``[t, l]`` the index in ``edges`` of the edge from
        corner l to corner l+1 (mod 3) of triangle t
    """
    faces = np.asarray(faces, dtype=np.int64)
    n = int(faces.max()) + 1 if n_vertices is None else int(n_vertices)
    end = np.roll(faces, -1, axis=1)
    key = np.minimum(faces, end) * n + np.maximum(faces, end)
    unique_key, inverse = np.unique(key.ravel(), return_inverse=True)
    return np.column_stack([unique_key // n, unique_key % n]), inverse.reshape(faces.shape)


def edge_owners(face_edges: np.ndarray, n_edges: int) -> tuple[np.ndarray, np.ndarray]:
    """For every edge a triangle holding it: (owner (e,), slot (e,)) with
    ``face_edges[owner[i], slot[i]] == i`` — the last such triangle in order; -1 for an edge no
    triangle holds. ``face_edges`` (m, c) lists edge indices per triangle (e.g.
    ``K.facet_indices(2)`` or ``K.top_face_indices(1)``)."""
    face_edges = np.asarray(face_edges)
    m, c = face_edges.shape
    owner = np.full(n_edges, -1, dtype=np.int64)
    slot = np.full(n_edges, -1, dtype=np.int64)
    owner[face_edges.ravel()] = np.repeat(np.arange(m), c)
    slot[face_edges.ravel()] = np.tile(np.arange(c), m)
    return owner, slot


def component_labels(faces: np.ndarray, n_vertices: int | None = None, through: str = "edges") -> np.ndarray:
    """(m,) int: the piece of each top simplex (0 … pieces − 1), simplices joined across shared
    ``"edges"`` (triangles) or shared ``"vertices"`` (any dimension)."""
    faces = np.asarray(faces, dtype=np.int64)
    m = len(faces)
    if through == "edges":
        _, columns = edge_table(faces, n_vertices)
    elif through == "vertices":
        columns = faces
    else:
        raise ValueError(f"through must be 'edges' or 'vertices', not {through!r}")
    incidence = sp.csr_matrix((np.ones(columns.size), (np.repeat(np.arange(m), columns.shape[1]), columns.ravel())))
    return graph_components(incidence @ incidence.T)[1]


def largest_component(faces: np.ndarray, n_vertices: int | None = None, through: str = "edges") -> np.ndarray:
    """(m,) bool: the simplices of the largest piece (by simplex count; the first on a tie),
    :func:`component_labels`."""
    label = component_labels(faces, n_vertices, through)
    return label == np.argmax(np.bincount(label))


def drop_unreferenced(vertices: np.ndarray, simplices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices used by some simplex, simplices renumbered to them, (n,) bool mask of the
    kept input vertices). Order is kept: kept vertex i is ``vertices[np.flatnonzero(used)[i]]``."""
    simplices = np.asarray(simplices)
    used = np.zeros(len(vertices), dtype=bool)
    used[simplices.ravel()] = True
    renumber = np.cumsum(used) - 1
    return vertices[used], renumber[simplices], used


def simplex_pieces(top_label: np.ndarray, top_simplices: np.ndarray, simplices: np.ndarray,
                   n_vertices: int) -> np.ndarray:
    """(m_k,) int: the piece of each k-simplex, given the piece of each top simplex
    (``top_label`` (m,), e.g. ``SimplicialComplex.connected_components()[1]``, whose pieces
    join top simplices through shared vertices, so a k-simplex's vertices all lie in one
    piece). ``top_simplices`` (m, n+1), ``simplices`` (m_k, k+1) vertex indices."""
    vertex_label = np.full(int(n_vertices), -1, dtype=np.int64)
    vertex_label[np.asarray(top_simplices)] = np.asarray(top_label)[:, None]
    return vertex_label[np.asarray(simplices)[:, 0]]
