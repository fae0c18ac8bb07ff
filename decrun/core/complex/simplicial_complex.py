"""Simplicial complexes of any dimension (thesis §2.2–2.3).

A :class:`SimplicialComplex` is built from vertex positions and a list of top simplices
(triangles, tetrahedra, edges, ...). It stores every j-simplex list as **sorted** vertex
tuples in lexicographic order (§2.3.3), the parity of each top simplex relative to its
sorted tuple (the inversion count), and the boundary operators δ_j (Fig. 2.20) as sparse
matrices. Everything is vectorized: there is no Python loop over simplices.

Conventions:

* ``simplices(j)`` for ``j < n`` are sorted tuples in lexicographic order; ``simplices(n)``
  are the top simplices in *input order*, each row sorted, with ``orientation`` (±1)
  the parity of the consistently oriented input tuple relative to the sorted one.
* Words: *boundary* is the operator δ_j (§2.2.4); *border* is the mesh's ∂M — the
  (n-1)-simplices in one top simplex only (``border_faces``, ``border_vertices``,
  ``border_loops``, ``border_complex``; §2.3.4 calls it the border).
* ``boundary(j)`` is δ_j with shape ``(#(j-1)-simplices, #j-simplices)``; the entry of
  face ``l`` (the face omitting local vertex ``l`` of the sorted tuple) is ``(-1)**l``,
  times ``orientation`` for top simplices (§2.2.4, §2.3.3).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from decrun.core import extension
from decrun.core.cache import Cached
from decrun.core.complex import topology
from decrun.core.complex.checks import plural, simplex_name
from decrun.core.complex.construction import build
from decrun.core.simplex_arrays import unique_rows

__all__ = ["SimplicialComplex"]

# the compiled extension (when built) loads with this module, as a C++ library's bindings load when
# it is imported: the first complex built in a process does not pay for the extension's loading
extension.built()


def incidence_entries_numpy(faces: np.ndarray, signs: np.ndarray, index_type) -> tuple[np.ndarray, np.ndarray]:
    """(data, indices) of δ_jᵀ in CSR order from the (n_j, j+1) faces and signs (the numpy twin
    of the compiled ``incidence``)."""
    data = np.empty(faces.shape)
    indices = np.empty(faces.shape, dtype=index_type)  # holds every face index (the caller chose it)
    for l in range(faces.shape[1]):  # column by column: ``faces`` and ``signs`` are often strided views
        indices[:, l] = faces[:, l]
        data[:, l] = signs[:, l]
    return data.reshape(-1), indices.reshape(-1)


class SimplicialComplex(Cached):
    """An oriented simplicial complex built from top simplices (§2.2, §2.3.3).

    Parameters
    ----------
    vertices : (n0, d) array_like of float, d = 2 or 3 (any d >= dim works)
        Vertex positions.
    simplices : (m, k+1) array_like of int
        The top simplices (k = 1 curves, 2 triangle meshes, 3 tetrahedral meshes, any k).
    orient : {"check", "fix"}
        ``check`` (default) raises :class:`OrientationError` when neighbouring top simplices
        are inconsistently oriented (§2.3.4); ``fix`` re-orients each connected component
        consistently, keeping the orientation most of its simplices had.
        Non-orientable input raises :class:`NonOrientableError` either way.
    unreferenced : {"error", "drop"}
        What to do with vertices no simplex uses: raise (default) or drop them;
        ``original_vertex_index`` then maps new vertex indices to input ones.
    check_manifold : bool
        Check that every (k-1)-face lies in at most two top simplices and that the star of
        every vertex is a single (half-)ball fan (Fig. 2.11–2.12).
    degenerate_tol : float
        A top simplex is degenerate when its volume is below
        ``degenerate_tol * h**k`` with ``h`` the mean edge length.

    Raises
    ------
    MeshError subclasses naming the offending simplices or vertices.
    """

    def __init__(
        self,
        vertices: ArrayLike,
        simplices: ArrayLike,
        *,
        orient: str = "check",
        unreferenced: str = "error",
        check_manifold: bool = True,
        degenerate_tol: float = 1e-12,
    ):
        if orient not in ("check", "fix"):
            raise ValueError(f"orient must be 'check' or 'fix', not {orient!r}")
        if unreferenced not in ("error", "drop"):
            raise ValueError(f"unreferenced must be 'error' or 'drop', not {unreferenced!r}")
        built = build(vertices, simplices, orient=orient, unreferenced=unreferenced, check_manifold=check_manifold,
                      degenerate_tol=degenerate_tol)
        self.vertices = built.vertices
        #: (n0,) index of each vertex in the input (differs from arange when unreferenced="drop")
        self.original_vertex_index = built.original_vertex_index
        self.embedding_dim = built.vertices.shape[1]
        self.dim = len(built.faces.local) - 1
        #: metadata of the mesh source (set by the runner: clean_vertices, noise_amplitude, hash, ...)
        self.meta: dict = {}
        self._lists = built.faces.lists
        self._top_faces = built.faces.top_faces
        self._local = built.faces.local
        self._orientation = built.orientation
        self._top_volumes = built.top_volumes

    # ------------------------------------------------------------------ simplices
    @property
    def orientation(self) -> np.ndarray:
        """(n_n,) int8: parity (±1) of each consistently oriented top simplex vs its sorted tuple."""
        return self._orientation

    def simplices(self, j: int) -> np.ndarray:
        """(n_j, j+1) int64 vertex tuples of the j-simplices (sorted rows; see module doc)."""
        self._check_degree(j)
        return self._lists[j]

    def num_simplices(self, j: int) -> int:
        """Number of j-simplices."""
        self._check_degree(j)
        return self._lists[j].shape[0]

    def oriented_simplices(self) -> np.ndarray:
        """(n_n, n+1) top simplices in their consistent orientation (input order).

        The sorted tuple with its first two vertices swapped where ``orientation`` is -1.
        For triangle meshes these are the faces to use for normals and drawing.
        """
        top = self._lists[self.dim].copy()
        flip = self._orientation < 0
        top[flip, 0], top[flip, 1] = top[flip, 1], top[flip, 0].copy()
        return top

    def _check_degree(self, j: int) -> None:
        if not 0 <= j <= self.dim:
            raise IndexError(f"simplex dimension {j} outside 0..{self.dim}")

    def facet_indices(self, j: int) -> np.ndarray:
        """(n_j, j+1) int64: index of the (j-1)-face of each j-simplex omitting local vertex l."""
        return np.ascontiguousarray(self._faces_and_signs(j)[0], dtype=np.int64)

    def facet_signs(self, j: int) -> np.ndarray:
        """(n_j, j+1) int8: the δ_j entries ``(-1)**l`` (times ``orientation`` for j = n)."""
        return np.ascontiguousarray(self._faces_and_signs(j)[1], dtype=np.int8)

    def _faces_and_signs(self, j: int):
        faces = self._facet_table(j)
        alternating = np.array([1 if l % 2 == 0 else -1 for l in range(j + 1)], dtype=np.int8)
        if j == self.dim:
            signs = np.empty(faces.shape, dtype=np.int8)
            negated = -self._orientation
            for l in range(j + 1):  # column by column (a broadcast product is slower)
                signs[:, l] = self._orientation if l % 2 == 0 else negated
        else:
            signs = np.broadcast_to(alternating, faces.shape)
        return faces, signs

    def _facet_table(self, j: int) -> np.ndarray:
        """(n_j, j+1) index of the (j-1)-face omitting local vertex l (possibly a strided view)."""
        if not 1 <= j <= self.dim:
            raise IndexError(f"faces exist for dimensions 1..{self.dim}, not {j}")
        n = self.dim
        if j == 1 and n > 1:
            return self._lists[1][:, ::-1]  # omit vertex 0 -> {v1} (+1), omit vertex 1 -> {v0} (-1)
        if j == n:
            # combinations(range(n+1), n) lists the facets omitting vertex n, n-1, ..., 0
            return self._top_faces[n - 1][:, ::-1]
        # A representative (top simplex, local combination) for every j-simplex.
        nj = self._lists[j].shape[0]
        table = self._top_faces[j]
        owner = np.empty(nj, dtype=np.int64)
        slot = np.empty(nj, dtype=np.int64)
        flat = table.ravel()
        owner[flat] = np.repeat(np.arange(table.shape[0]), table.shape[1])
        slot[flat] = np.tile(np.arange(table.shape[1]), table.shape[0])
        sub_position = {c: i for i, c in enumerate(self._local[j - 1])}
        local_faces = np.array(
            [[sub_position[c[:l] + c[l + 1:]] for l in range(j + 1)] for c in self._local[j]], dtype=np.int64
        )  # (C(n+1, j+1), j+1)
        return self._top_faces[j - 1][owner[:, None], local_faces[slot]]

    def top_face_indices(self, j: int) -> np.ndarray:
        """(n_n, C(n+1, j+1)) int64: index into ``simplices(j)`` of every j-face of every top
        simplex; columns in the order of ``itertools.combinations(range(n+1), j+1)`` over the
        sorted top tuple (e.g. edge slots (0,1), (0,2), (1,2) of a triangle)."""
        self._check_degree(j)
        return self._top_faces[j]

    def edge_lengths(self) -> np.ndarray:
        """(n1,) lengths of the edges ``simplices(1)`` (model units), cached."""
        from decrun.core.geometry import edge_lengths

        return self.require("edge_lengths", lambda: edge_lengths(self.vertices, self.simplices(1)))

    @property
    def mean_edge_length(self) -> float:
        """Mean edge length h̄ (model units): the scale of noise, strokes and time steps."""
        return float(self.edge_lengths().mean())

    @property
    def top_volumes(self) -> np.ndarray:
        """(n_n,) unsigned volumes of the top simplices (areas of triangles, volumes of tets)."""
        return self._top_volumes

    def incidence(self, j: int) -> sp.csr_matrix:
        """δ_jᵀ: sparse (n_j, n_{j-1}) float64, row s holds the border of j-simplex s.

        This is the exterior derivative d_{j-1} of §4.5.1, built directly in CSR form
        (j+1 entries per row, no sorting).
        """

        def compute():
            nj = self._lists[j].shape[0]
            index_type = np.int32 if max((j + 1) * nj, self._lists[j - 1].shape[0]) < 2**31 - 1 else np.int64
            if (compiled := extension.kernels()) is not None:
                data, indices = np.empty(nj * (j + 1)), np.empty(nj * (j + 1), dtype=index_type)
                orientation = self._orientation if j == self.dim else self._orientation[:0]
                compiled.incidence(self._facet_table(j), orientation, data, indices)
            else:
                data, indices = incidence_entries_numpy(*self._faces_and_signs(j), index_type)
            return sp.csr_matrix((data, indices, np.arange(0, (j + 1) * nj + 1, j + 1, dtype=index_type)),
                                 shape=(nj, self._lists[j - 1].shape[0]))

        return self.require(("incidence", j), compute)

    def boundary(self, j: int) -> sp.csr_matrix:
        """δ_j (Fig. 2.20): sparse (n_{j-1}, n_j) float64 with entries ±1 (§2.2.4).

        Column ``s`` is the border of the j-simplex ``s``: ``Σ_l (-1)^l {v_0..v̂_l..v_j}``
        (times its orientation for top simplices). ``boundary(j-1) @ boundary(j) == 0``.
        """
        return self.require(("boundary", j), lambda: self.incidence(j).T.tocsr())

    def find_simplices(self, tuples: ArrayLike) -> np.ndarray:
        """Indices in ``simplices(j)`` of vertex tuples given in any vertex order; -1 if absent.

        Parameters
        ----------
        tuples : (p, j+1) int

        Returns
        -------
        (p,) int64
        """
        tuples = np.sort(np.atleast_2d(np.asarray(tuples, dtype=np.int64)), axis=1)
        j = tuples.shape[1] - 1
        self._check_degree(j)
        lists = self._lists[j]
        if j == self.dim:
            order = np.lexsort(lists.T[::-1])
            lists = lists[order]
        else:
            order = None
        both = np.concatenate([lists, tuples])
        _, inverse = unique_rows(both)
        key_of_list = inverse[: lists.shape[0]]
        lookup = np.full(inverse.max() + 1, -1, dtype=np.int64)
        lookup[key_of_list] = np.arange(lists.shape[0])
        found = lookup[inverse[lists.shape[0]:]]
        if order is not None:
            found = np.where(found >= 0, order[np.maximum(found, 0)], -1)
        return found

    # ------------------------------------------------------------------ topology
    @property
    def euler_characteristic(self) -> int:
        """χ = Σ_j (-1)^j n_j."""
        return topology.euler_characteristic(self)

    def connected_components(self) -> tuple[int, np.ndarray]:
        """(number of components, (n_n,) component label of each top simplex) — via shared vertices."""
        return self.require("components", lambda: topology.connected_components(self))

    def border_faces(self) -> tuple[np.ndarray, np.ndarray]:
        """Border (n-1)-simplices ``δ_n · 1`` (§2.3.4): (b,) indices into ``simplices(n-1)`` and
        (b,) int8 induced orientation (+1: the sorted tuple is oriented as the border)."""
        return topology.border_faces(self)

    def border_vertices(self) -> np.ndarray:
        """(n0,) bool: vertices on the border."""
        return topology.border_vertices(self)

    def border_complex(self, check_manifold: bool = False) -> "SimplicialComplex | None":
        """The border as an oriented (n-1)-complex (vertices renumbered; see ``original_vertex_index``).

        Returns None for a closed complex. With ``check_manifold`` a border that is not an
        (n-1)-manifold (pinched along a face or at a vertex) raises NonManifoldError.
        """
        faces = topology.border_simplices(self)
        if faces is None:
            return None
        return SimplicialComplex(self.vertices, faces, unreferenced="drop", check_manifold=check_manifold,
                                 orient="check")

    def border_loops(self) -> list[np.ndarray]:
        """Border components of a 2-manifold as ordered vertex cycles, longest first, each
        following the induced orientation (:func:`decrun.core.complex.topology.border_loops`)."""
        return topology.border_loops(self)

    def betti_numbers(self) -> list[int]:
        """Betti numbers b_0..b_n over the reals (:func:`decrun.core.complex.topology.betti_numbers`)."""
        return topology.betti_numbers(self)

    def __repr__(self) -> str:
        counts = ", ".join(f"{self._lists[j].shape[0]} {plural(simplex_name(j))}" for j in range(self.dim + 1))
        return f"SimplicialComplex(dim={self.dim}, {counts})"
