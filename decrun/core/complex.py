"""Simplicial complexes of any dimension (thesis §2.2–2.3).

A :class:`SimplicialComplex` is built from vertex positions and a list of top simplices
(triangles, tetrahedra, edges, ...). It stores every j-simplex list as **sorted** vertex
tuples in lexicographic order (§2.3.3), the parity of each top simplex relative to its
sorted tuple (the inversion count), and the boundary operators δ_j (Fig. 2.20) as sparse
matrices. Everything is vectorized: there is no Python loop over simplices.

Conventions (``shared/DESIGN.md``):

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

from itertools import combinations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from decrun.errors import (
    DegenerateSimplexError,
    DuplicateSimplexError,
    IndexOutOfRangeError,
    MeshError,
    NonFiniteCoordinateError,
    NonManifoldError,
    NonOrientableError,
    OrientationError,
    RepeatedVertexError,
    UnreferencedVertexError,
)

from decrun.core.cache import Cached
from decrun.core.simplex_arrays import (  # noqa: F401  (re-exported)
    FaceRows,
    group_rows,
    inversion_parity,
    simplex_volumes,
    sort_rows,
    unique_rows,
    vertex_volumes,
)

__all__ = ["SimplicialComplex", "unique_rows", "inversion_parity", "simplex_volumes"]

_MAX_LISTED = 8  # how many offending simplices an error message names


def _name(indices, what: str) -> str:
    """'face 3, 7 and 12 more' — the first offending indices for an error message."""
    indices = np.asarray(indices).ravel()
    shown = ", ".join(str(int(i)) for i in indices[:_MAX_LISTED])
    more = f" (and {indices.size - _MAX_LISTED} more)" if indices.size > _MAX_LISTED else ""
    return f"{_plural(what) if indices.size > 1 else what} {shown}{more}"


_SIMPLEX_NAMES = {0: "vertex", 1: "edge", 2: "triangle", 3: "tetrahedron"}
_PLURALS = {"vertex": "vertices", "tetrahedron": "tetrahedra"}


def _plural(name: str) -> str:
    return _PLURALS.get(name, name + "s")


def _simplex_name(j: int) -> str:
    return _SIMPLEX_NAMES.get(j, f"{j}-simplex")


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
        vertices,
        simplices,
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
        vertices = np.asarray(vertices, dtype=np.float64)
        simplices = np.asarray(simplices)
        if vertices.ndim != 2 or vertices.shape[0] == 0:
            raise MeshError(f"vertices must be a non-empty (n, d) array, got shape {vertices.shape}")
        if simplices.ndim != 2 or simplices.shape[0] == 0 or simplices.shape[1] < 2:
            raise MeshError(f"simplices must be a non-empty (m, k+1) array with k >= 1, got shape {simplices.shape}")
        if not np.issubdtype(simplices.dtype, np.integer):
            if not np.all(np.equal(np.mod(simplices, 1), 0)):
                raise MeshError("simplices must hold integer vertex indices")
        simplices = simplices.astype(np.int64)
        self.dim = simplices.shape[1] - 1
        if vertices.shape[1] < self.dim:
            raise MeshError(
                f"a {self.dim}-dimensional complex needs vertices in at least {self.dim} dimensions, "
                f"got {vertices.shape[1]}"
            )

        top_sorted = sort_rows(simplices)
        _check_indices(vertices, simplices, top_sorted, self.dim)
        bad = ~np.isfinite(vertices).all(axis=1)
        if bad.any():
            raise NonFiniteCoordinateError(f"{_name(np.flatnonzero(bad), 'vertex')} has NaN or infinite coordinates")
        self.original_vertex_index = np.arange(vertices.shape[0])
        used = np.zeros(vertices.shape[0], dtype=bool)
        used[simplices.ravel()] = True
        if not used.all():
            unused = np.flatnonzero(~used)
            if unreferenced == "error":
                raise UnreferencedVertexError(
                    f"{_name(unused, 'vertex')} {'is' if unused.size == 1 else 'are'} used by no "
                    f"{_simplex_name(self.dim)}", python_hint="pass unreferenced='drop' to remove them"
                )
            new_index = np.cumsum(used) - 1
            simplices = new_index[simplices]
            top_sorted = new_index[top_sorted]
            vertices = vertices[used]
            self.original_vertex_index = np.flatnonzero(used)

        self.vertices = vertices
        self.embedding_dim = vertices.shape[1]
        #: metadata of the mesh source (set by the runner: clean_vertices, noise_amplitude, hash, ...)
        self.meta: dict = {}
        n = self.dim

        # Top simplices: sorted rows (input order) + parity of the input tuple (§2.3.3).
        self._orientation = inversion_parity(simplices)
        self._lists: dict[int, np.ndarray] = {n: top_sorted, 0: np.arange(vertices.shape[0])[:, None]}

        # Every j-face of every top simplex, by local combinations of the sorted tuple.
        # _top_faces[j] : (m, C(n+1, j+1)) global indices of the j-faces of each top simplex,
        # columns in the order of combinations(range(n+1), j+1).
        m = top_sorted.shape[0]
        self._local = {j: list(combinations(range(n + 1), j + 1)) for j in range(n + 1)}
        self._top_faces = {n: np.arange(m)[:, None], 0: top_sorted}
        for j in range(1, n):
            cols = self._local[j]
            faces = FaceRows(top_sorted, cols)  # the (m·C, j+1) face tuples, built lazily
            unique, inverse, order, starts = group_rows(faces)
            self._lists[j] = unique
            self._top_faces[j] = inverse.reshape(m, len(cols))
            if j == n - 1:
                self._facet_groups = (order, starts)
        if n == 1:  # facets are the vertices themselves
            slots = top_sorted.ravel()
            order = np.argsort(slots, kind="stable")
            starts = np.append(np.flatnonzero(np.r_[True, slots[order][1:] != slots[order][:-1]]), slots.size)
            self._facet_groups = (order, starts)

        self._check_degenerate(degenerate_tol)
        self._check_facets(check_manifold)
        self._orient(orient)
        if check_manifold:
            self._check_vertex_stars()
        # the facet pairs serve validation only: do not hold on to them
        del self._pairs

    # ------------------------------------------------------------------ validation
    def _check_degenerate(self, tol: float) -> None:
        n = self.dim
        volumes = vertex_volumes(self.vertices, self._lists[n])
        bad = volumes <= tol * volumes.mean()
        if bad.any():
            raise DegenerateSimplexError(
                f"{_name(np.flatnonzero(bad), _simplex_name(n))} {'has' if bad.sum() == 1 else 'have'} zero volume "
                f"(below {tol:g} × the mean {_simplex_name(n)} volume {volumes.mean():.3g})"
            )
        self._top_volumes = volumes

    def _check_facets(self, check_manifold: bool) -> None:
        """Duplicates and (n-1)-faces in more than two top simplices; records facet pairs."""
        n = self.dim
        order, starts = self._facet_groups
        counts = np.diff(starts)
        over = np.flatnonzero(counts > 2)
        if over.size:
            self._check_duplicates()
            if check_manifold:
                facet_slots = order[np.concatenate([np.arange(starts[g], starts[g + 1]) for g in over[:3]])]
                owners = np.unique(facet_slots // (n + 1))
                tuples = self._lists[n - 1][over[:3]].tolist()
                raise NonManifoldError(
                    f"non-manifold: {_name(over, _simplex_name(n - 1))} (vertices {tuples}...) lie in more than two "
                    f"{_plural(_simplex_name(n))} (e.g. {_name(owners, _simplex_name(n))})"
                )
        interior = np.flatnonzero(counts == 2)
        first, second = order[starts[interior]], order[starts[interior] + 1]
        del self._facet_groups, order, starts, counts  # only needed to find the pairs
        index_type = np.int32 if first.size and max(first.max(), second.max()) < 2**31 - 1 else np.int64
        first, second = first.astype(index_type), second.astype(index_type)
        width = index_type(n + 1)
        self._pairs = (interior, first // width, second // width, first % width, second % width)
        # Two simplices sharing a facet are duplicates iff their vertices opposite it agree
        # (facet column c of combinations(range(n+1), n) omits sorted vertex n - c).
        top = self._lists[n]
        t0, t1, l0, l1 = self._pairs[1:]
        if np.any(top[t0, n - l0] == top[t1, n - l1]):
            self._check_duplicates()

    def _check_duplicates(self) -> None:
        n = self.dim
        _, inverse = unique_rows(self._lists[n])
        counts = np.bincount(inverse)
        dup = np.flatnonzero(counts[inverse] > 1)
        if dup.size:
            raise DuplicateSimplexError(f"{_name(dup, _simplex_name(n))} repeat the same vertices")

    def _facet_pairs(self):
        """Interior facets and the two top simplices sharing each (with their local positions)."""
        return self._pairs

    def _orient(self, mode: str) -> None:
        """Check (and optionally fix) consistent orientation by the δ_n column test (§2.3.4)."""
        n = self.dim
        m = self._lists[n].shape[0]
        facet, t0, t1, l0, l1 = self._facet_pairs()
        # Entry of δ_n for the facet in each simplex: (-1)^l * orientation. Consistent iff opposite.
        s0 = np.where(l0 % 2 == 0, 1, -1) * self._orientation[t0]
        s1 = np.where(l1 % 2 == 0, 1, -1) * self._orientation[t1]
        bad = s0 == s1
        if not bad.any():
            return
        # Signed graph 2-colouring on the doubled graph: node t (keep) and t+m (flip).
        same = ~bad  # already consistent: both keep or both flip
        rows = np.concatenate([t0[same], t0[same] + m, t0[bad], t0[bad] + m])
        cols = np.concatenate([t1[same], t1[same] + m, t1[bad] + m, t1[bad]])
        graph = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(2 * m, 2 * m))
        _, label = connected_components(graph, directed=False)
        contradiction = np.flatnonzero(label[:m] == label[m:])
        if contradiction.size:
            raise NonOrientableError(
                f"the mesh is not orientable (like a Möbius strip): no consistent orientation exists for "
                f"{_name(contradiction, _simplex_name(n))}"
            )
        if mode == "check":
            pairs = np.stack([t0[bad], t1[bad]], axis=1)[:_MAX_LISTED].tolist()
            raise OrientationError(
                f"inconsistent orientation: {int(bad.sum())} {_simplex_name(n - 1)}(s) are traversed in the same "
                f"direction by both neighbouring {_plural(_simplex_name(n))}, e.g. {_simplex_name(n)} pairs {pairs} "
                f"(§2.3.4)", python_hint="pass orient='fix' to re-orient each connected component"
            )
        # Choose per original component the coloring where most simplices keep their orientation.
        _, component = connected_components(
            sp.coo_matrix((np.ones(t0.size), (t0, t1)), shape=(m, m)), directed=False
        )
        root = np.full(component.max() + 1, m, dtype=np.int64)
        np.minimum.at(root, component, np.arange(m))
        keep = label[:m] == label[root[component]]  # same colour as the root keeping orientation
        keep_count = np.bincount(component, weights=keep, minlength=root.size)
        size = np.bincount(component, minlength=root.size)
        flip_component = keep_count < size / 2
        keep = keep ^ flip_component[component]
        self._orientation = np.where(keep, self._orientation, -self._orientation).astype(np.int8)

    def _check_vertex_stars(self) -> None:
        """Each vertex star must be one fan of top simplices glued along facets (Fig. 2.11–2.12).

        A vertex whose incident top simplices fall into more than one group connected across
        shared facets (a bowtie / wheel) has no ball or half-ball neighbourhood. For n = 2
        (with manifold edges) this test is exact; for n = 3 it finds pinched vertices but
        not every exotic link.
        """
        n = self.dim
        if n < 2:
            return
        fans = self._fans_per_vertex_surface() if n == 2 else self._fans_per_vertex_general()
        bad = np.flatnonzero(fans > 1)
        if bad.size:
            raise NonManifoldError(
                f"non-manifold {_name(bad, 'vertex')}: the {_plural(_simplex_name(n))} around "
                f"{'it' if bad.size == 1 else 'each'} form {int(fans[bad[0]])} separate fans, not one disk or "
                f"half-disk (a 'bowtie'/'wheel', Fig. 2.11)"
            )

    def _fans_per_vertex_surface(self) -> np.ndarray:
        """Number of triangle fans around each vertex of an oriented edge-manifold surface.

        Corner (t, i) steps to the corner of the same vertex in the triangle across the edge
        leaving it in t's orientation; fans are the orbits of this step (paths at border
        vertices, cycles inside). Orbits are counted by pointer jumping, O(m log valence).
        """
        top = self._lists[2]
        m = top.shape[0]
        _, t0, t1, l0, l1 = self._facet_pairs()
        # partner[3t + s]: the edge slot (3t' + s') across edge slot s of triangle t, or -1
        partner = np.full(3 * m, -1, dtype=np.int32)
        slot0 = (3 * t0 + l0).astype(np.int32)
        slot1 = (3 * t1 + l1).astype(np.int32)
        partner[slot0] = slot1
        partner[slot1] = slot0
        # Corner i of a sorted triangle leaves along the edge to its successor in the
        # triangle's orientation. Edge slots are (0,1)->0, (0,2)->1, (1,2)->2.
        positive = (self._orientation > 0)[:, None]
        leaving_slot = np.where(positive, np.array([0, 2, 1], dtype=np.int32), np.array([1, 0, 2], dtype=np.int32))
        smaller = np.where(positive, np.array([1, 1, 0], dtype=np.int32), np.array([1, 0, 0], dtype=np.int32))
        corner = np.arange(3 * m, dtype=np.int32)
        across = partner[(corner - corner % 3) + leaving_slot.ravel()]
        del partner, leaving_slot
        # position of our vertex in the triangle across: it is the smaller (or larger) vertex of the
        # shared edge there too; table[smaller][slot] gives that sorted position.
        position_table = np.array([1, 2, 2, 0, 0, 1], dtype=np.int32)  # larger: 1,2,2 ; smaller: 0,0,1
        moving = across >= 0
        following = np.where(
            moving, (across - across % 3) + position_table[3 * smaller.ravel() + across % 3], corner
        ).astype(np.int32)
        del across, smaller
        # a corner has a predecessor iff some other corner steps to it (path ends step to themselves)
        has_predecessor = np.zeros(3 * m, dtype=bool)
        has_predecessor[following[moving]] = True
        vertex = top.ravel()
        valence = np.bincount(vertex, minlength=self.vertices.shape[0])
        # label = smallest corner id seen along the orbit, or -1 once the orbit reaches a path end
        label = np.where(moving, corner, np.int32(-1))
        jump = following
        for _ in range(int(np.ceil(np.log2(max(int(valence.max()), 2))))):
            np.minimum(label, label[jump], out=label)
            jump = jump[jump]
        root = ~has_predecessor | (label == corner)
        return np.bincount(vertex[root], minlength=self.vertices.shape[0])

    def _fans_per_vertex_general(self) -> np.ndarray:
        """Fans per vertex for any n via connected components of the corner graph."""
        n = self.dim
        m = self._lists[n].shape[0]
        facet, t0, t1, l0, l1 = self._facet_pairs()
        tops = self._lists[n]
        facet_vertices = self._lists[n - 1][facet]
        rows, cols = [], []
        for a in range(n):
            v = facet_vertices[:, a]
            rows.append(t0 * (n + 1) + np.argmax(tops[t0] == v[:, None], axis=1))
            cols.append(t1 * (n + 1) + np.argmax(tops[t1] == v[:, None], axis=1))
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        graph = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(m * (n + 1), m * (n + 1)))
        _, label = connected_components(graph, directed=False)
        pairs = unique_rows(np.stack([tops.ravel(), label], axis=1))[0]
        return np.bincount(pairs[:, 0], minlength=self.vertices.shape[0])

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
        if not 1 <= j <= self.dim:
            raise IndexError(f"faces exist for dimensions 1..{self.dim}, not {j}")
        n = self.dim
        nj = self._lists[j].shape[0]
        alternating = np.array([1 if l % 2 == 0 else -1 for l in range(j + 1)], dtype=np.int8)
        if j == 1 and n > 1:
            faces = self._lists[1][:, ::-1]  # omit vertex 0 -> {v1} (+1), omit vertex 1 -> {v0} (-1)
            signs = np.broadcast_to(alternating, (nj, 2))
        elif j == n:
            # combinations(range(n+1), n) lists the facets omitting vertex n, n-1, ..., 0
            faces = self._top_faces[n - 1][:, ::-1]
            signs = alternating[None, :] * self._orientation[:, None]
        else:
            # A representative (top simplex, local combination) for every j-simplex.
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
            faces = self._top_faces[j - 1][owner[:, None], local_faces[slot]]
            signs = np.broadcast_to(alternating, (nj, j + 1))
        return faces, signs

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
            faces, signs = self._faces_and_signs(j)
            nj = faces.shape[0]
            index_type = np.int32 if max((j + 1) * nj, self._lists[j - 1].shape[0]) < 2**31 - 1 else np.int64
            return sp.csr_matrix(
                (signs.ravel().astype(np.float64), faces.ravel().astype(index_type),
                 np.arange(0, (j + 1) * nj + 1, j + 1, dtype=index_type)),
                shape=(nj, self._lists[j - 1].shape[0]),
            )

        return self.require(("incidence", j), compute)

    def boundary(self, j: int) -> sp.csr_matrix:
        """δ_j (Fig. 2.20): sparse (n_{j-1}, n_j) float64 with entries ±1 (§2.2.4).

        Column ``s`` is the border of the j-simplex ``s``: ``Σ_l (-1)^l {v_0..v̂_l..v_j}``
        (times its orientation for top simplices). ``boundary(j-1) @ boundary(j) == 0``.
        """
        return self.require(("boundary", j), lambda: self.incidence(j).T.tocsr())

    def find_simplices(self, tuples) -> np.ndarray:
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
        return int(sum((-1) ** j * self._lists[j].shape[0] for j in range(self.dim + 1)))

    def connected_components(self) -> tuple[int, np.ndarray]:
        """(number of components, (n_n,) component label of each top simplex) — via shared vertices."""

        def compute():
            n = self.dim
            m = self._lists[n].shape[0]
            nv = self.vertices.shape[0]
            rows = np.repeat(np.arange(m), n + 1)
            graph = sp.coo_matrix((np.ones(rows.size), (rows, self._lists[n].ravel() + m)), shape=(m + nv, m + nv))
            _, label = connected_components(graph, directed=False)
            # relabel so labels are 0..c-1 over top simplices
            _, top_label = np.unique(label[:m], return_inverse=True)
            return int(top_label.max()) + 1, top_label.astype(np.int64)

        return self.require("components", compute)

    def border_faces(self) -> tuple[np.ndarray, np.ndarray]:
        """Border (n-1)-simplices: ``δ_n · 1`` (§2.3.4).

        Returns
        -------
        index : (b,) int64 indices into ``simplices(n-1)``
        sign : (b,) int8 the induced orientation (+1: the sorted tuple is oriented as the border)
        """
        chain = np.asarray(self.boundary(self.dim).sum(axis=1)).ravel()
        index = np.flatnonzero(np.abs(chain) > 0.5)
        return index, np.sign(chain[index]).astype(np.int8)

    def border_vertices(self) -> np.ndarray:
        """(n0,) bool: vertices on the border."""
        mask = np.zeros(self.vertices.shape[0], dtype=bool)
        index, _ = self.border_faces()
        mask[self._lists[self.dim - 1][index].ravel()] = True
        return mask

    def border_complex(self) -> "SimplicialComplex | None":
        """The border as an oriented (n-1)-complex (vertices renumbered; see ``original_vertex_index``).

        Returns None for a closed complex.
        """
        index, sign = self.border_faces()
        if index.size == 0:
            return None
        faces = self._lists[self.dim - 1][index].copy()
        flip = sign < 0
        if faces.shape[1] >= 2:
            faces[flip, 0], faces[flip, 1] = faces[flip, 1], faces[flip, 0].copy()
        if faces.shape[1] == 1:
            raise MeshError("the border of a 1-complex is a set of points, not a complex")
        border = SimplicialComplex(self.vertices, faces, unreferenced="drop", check_manifold=False, orient="check")
        return border

    def border_loops(self) -> list[np.ndarray]:
        """Border components of a 2-manifold as ordered vertex cycles.

        Each loop follows the orientation the complex induces on its border (§2.2.4): for a
        counter-clockwise planar disk the outer loop runs counter-clockwise and holes run
        clockwise. Loops are sorted longest (in length) first.

        Returns
        -------
        list of (L,) int64 arrays; loop[i] -> loop[i+1] (cyclically) is a border edge.
        """
        if self.dim != 2:
            raise ValueError("border_loops() is defined for 2-manifolds (triangle meshes)")
        index, sign = self.border_faces()
        if index.size == 0:
            return []
        edges = self._lists[1][index]
        start = np.where(sign > 0, edges[:, 0], edges[:, 1])
        end = np.where(sign > 0, edges[:, 1], edges[:, 0])
        nv = self.vertices.shape[0]
        successor = np.full(nv, -1, dtype=np.int64)
        successor[start] = end
        # Walk all loops at once: each step moves every loop one vertex along its successor.
        graph = sp.coo_matrix((np.ones(start.size), (start, end)), shape=(nv, nv))
        _, label = connected_components(graph, directed=False)
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
            float(np.linalg.norm(self.vertices[np.roll(loop, -1)] - self.vertices[loop], axis=1).sum()) for loop in loops
        ]
        order = np.argsort(lengths_geom)[::-1]
        return [loops[i] for i in order]

    def betti_numbers(self) -> list[int]:
        """Betti numbers b_0..b_n over the reals.

        Exact for surfaces (b0 = components, b2 = closed components, b1 from χ), for
        tetrahedral meshes embedded in R³ (b2 = border surfaces − components, Alexander
        duality) and, for anything else, by dense rank computation (small complexes only).
        """
        n = self.dim
        count, label = self.connected_components()
        index, _ = self.border_faces()
        chi = self.euler_characteristic
        if n == 1:
            # a 1-manifold component is a loop (b1 = 1) or a path (b1 = 0)
            has_border = np.zeros(count, dtype=bool)
            vertex_degree = np.bincount(self._lists[1].ravel(), minlength=self.vertices.shape[0])
            ends = np.flatnonzero(vertex_degree == 1)
            if ends.size:
                edge_of_end = np.flatnonzero(np.isin(self._lists[1], ends).any(axis=1))
                has_border[label[edge_of_end]] = True
            closed = int((~has_border).sum())
            return [count, closed]
        if n == 2:
            has_border = np.zeros(count, dtype=bool)
            if index.size:
                is_border = np.zeros(self._lists[1].shape[0], dtype=bool)
                is_border[index] = True
                has_border[label[is_border[self._top_faces[1]].any(axis=1)]] = True
            b2 = int((~has_border).sum())
            return [count, count + b2 - chi, b2]
        if n == 3 and self.embedding_dim == 3:
            border = self.border_complex()
            if border is None:
                return self._betti_by_rank()
            border_components = border.connected_components()[0]
            b2 = border_components - count
            b1 = count + b2 - chi
            return [count, b1, b2, 0]
        return self._betti_by_rank()

    def _betti_by_rank(self) -> list[int]:
        sizes = [self._lists[j].shape[0] for j in range(self.dim + 1)]
        if max(sizes) > 4000:
            raise NotImplementedError(
                "betti_numbers(): dense rank computation is limited to complexes with at most 4000 simplices "
                "per dimension for this kind of complex"
            )
        ranks = [0] + [int(np.linalg.matrix_rank(self.boundary(j).toarray())) for j in range(1, self.dim + 1)] + [0]
        return [sizes[j] - ranks[j] - ranks[j + 1] for j in range(self.dim + 1)]

    def __repr__(self) -> str:
        counts = ", ".join(f"{self._lists[j].shape[0]} {_plural(_simplex_name(j))}" for j in range(self.dim + 1))
        return f"SimplicialComplex(dim={self.dim}, {counts})"


def _check_indices(vertices: np.ndarray, simplices: np.ndarray, s: np.ndarray, n: int) -> None:
    """Indices in range and no repeated vertex; ``s`` is ``simplices`` with sorted rows."""
    nv = vertices.shape[0]
    if s[:, 0].min() >= 0 and s[:, -1].max() < nv:
        out = None
    else:
        out = (simplices < 0) | (simplices >= nv)
    if out is not None:
        rows = np.flatnonzero(out.any(axis=1))
        raise IndexOutOfRangeError(
            f"{_name(rows, _simplex_name(n))} reference vertex indices outside 0..{nv - 1} "
            f"(e.g. {int(simplices[out][0])})"
        )
    repeated = np.flatnonzero((s[:, 1:] == s[:, :-1]).any(axis=1))
    if repeated.size:
        raise RepeatedVertexError(
            f"{_name(repeated, _simplex_name(n))} list the same vertex twice (e.g. {simplices[repeated[0]].tolist()})"
        )
