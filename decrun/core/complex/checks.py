"""The checks a :class:`~decrun.core.complex.SimplicialComplex` runs while it is built.

Plain functions of arrays, run in the order of
:func:`decrun.core.complex.construction.build`: the input arrays (indices in range, no
repeated vertex, finite coordinates, every vertex used), degenerate top simplices,
(n-1)-faces in more than two top simplices and duplicates, consistent orientation
(§2.3.4) and the vertex stars (Fig. 2.11–2.12). Each raises a :class:`decrun.errors.MeshError`
subclass that names the offending simplices; nothing is repaired silently (``orient="fix"``
and ``unreferenced="drop"`` are the caller's explicit choices).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from decrun.core import extension
from decrun.core.connectivity import graph_components
from decrun.core.simplex_arrays import (
    FaceRows,
    group_rows,
    sorted_rows_and_parity,
    unique_rows,
    vertex_volumes,
)
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

__all__ = ["FacetPairs", "group_facets", "fan_roots_and_consistency", "checked_input", "check_degenerate", "facet_pairs", "orient", "check_vertex_stars",
           "fans_per_vertex", "facet_pairs_numpy", "inconsistent_facets", "fans_per_vertex_general", "simplex_name", "plural",
           "name_indices"]

MAX_LISTED = 8  # how many offending simplices an error message names
_SIMPLEX_NAMES = {0: "vertex", 1: "edge", 2: "triangle", 3: "tetrahedron"}
_PLURALS = {"vertex": "vertices", "tetrahedron": "tetrahedra"}


def name_indices(indices, what: str) -> str:
    """'triangles 3, 7 (and 12 more)' — the first offending indices for an error message."""
    indices = np.asarray(indices).ravel()
    shown = ", ".join(str(int(i)) for i in indices[:MAX_LISTED])
    more = f" (and {indices.size - MAX_LISTED} more)" if indices.size > MAX_LISTED else ""
    return f"{plural(what) if indices.size > 1 else what} {shown}{more}"


def plural(name: str) -> str:
    """'vertex' → 'vertices', 'edge' → 'edges'."""
    return _PLURALS.get(name, name + "s")


def simplex_name(j: int) -> str:
    """'vertex', 'edge', 'triangle', 'tetrahedron' or 'j-simplex'."""
    return _SIMPLEX_NAMES.get(j, f"{j}-simplex")


# ---------------------------------------------------------------- input arrays
def checked_input(vertices, simplices, unreferenced: str):
    """Validated arrays: (vertices (n0, d) float64, the (m, n+1) int64 simplices with sorted
    rows (input order), the parity (m,) int8 of each input row vs its sorted one,
    original_vertex_index (n0,)). Unused vertices raise, or are dropped
    (``unreferenced="drop"``) with indices renumbered."""
    vertices = np.asarray(vertices, dtype=np.float64)
    simplices = np.asarray(simplices)
    if vertices.ndim != 2 or vertices.shape[0] == 0:
        raise MeshError(f"vertices must be a non-empty (n, d) array, got shape {vertices.shape}")
    if simplices.ndim != 2 or simplices.shape[0] == 0 or simplices.shape[1] < 2:
        raise MeshError(f"simplices must be a non-empty (m, k+1) array with k >= 1, got shape {simplices.shape}")
    if not np.issubdtype(simplices.dtype, np.integer):
        if not np.all(np.equal(np.mod(simplices, 1), 0)):
            raise MeshError("simplices must hold integer vertex indices")
    simplices = simplices.astype(np.int64, copy=False)  # read only: sorted into new rows below
    n = simplices.shape[1] - 1
    if vertices.shape[1] < n:
        raise MeshError(f"a {n}-dimensional complex needs vertices in at least {n} dimensions, "
                        f"got {vertices.shape[1]}")
    top_sorted, parity, smallest, largest, repeated, used = sorted_rows_and_parity(simplices, vertices.shape[0])
    if smallest < 0 or largest >= vertices.shape[0] or repeated:
        _check_indices(vertices.shape[0], simplices, top_sorted, n)
    if not np.isfinite(vertices).all():  # one pass over the coordinates; the rows only to name them
        bad = ~np.isfinite(vertices).all(axis=1)
        raise NonFiniteCoordinateError(f"{name_indices(np.flatnonzero(bad), 'vertex')} has NaN or infinite coordinates")
    original = np.arange(vertices.shape[0])
    if not used.all():  # ``used``: marked while the rows were sorted
        unused = np.flatnonzero(~used)
        if unreferenced == "error":
            raise UnreferencedVertexError(
                f"{name_indices(unused, 'vertex')} {'is' if unused.size == 1 else 'are'} used by no "
                f"{simplex_name(n)}", python_hint="pass unreferenced='drop' to remove them"
            )
        new_index = np.cumsum(used) - 1
        top_sorted = new_index[top_sorted]  # monotone: rows stay sorted, parities unchanged
        vertices, original = vertices[used], np.flatnonzero(used)
    return vertices, top_sorted, parity, original


def _check_indices(nv: int, simplices: np.ndarray, s: np.ndarray, n: int) -> None:
    """Indices in range and no repeated vertex; ``s`` is ``simplices`` with sorted rows."""
    if not (s[:, 0].min() >= 0 and s[:, -1].max() < nv):
        out = (simplices < 0) | (simplices >= nv)
        rows = np.flatnonzero(out.any(axis=1))
        raise IndexOutOfRangeError(
            f"{name_indices(rows, simplex_name(n))} reference vertex indices outside 0..{nv - 1} "
            f"(e.g. {int(simplices[out][0])})"
        )
    repeated = np.flatnonzero((s[:, 1:] == s[:, :-1]).any(axis=1))
    if repeated.size:
        raise RepeatedVertexError(
            f"{name_indices(repeated, simplex_name(n))} list the same vertex twice "
            f"(e.g. {simplices[repeated[0]].tolist()})"
        )


# ---------------------------------------------------------------- top simplices
def check_degenerate(vertices: np.ndarray, top: np.ndarray, tol: float) -> np.ndarray:
    """(m,) unsigned volumes of the top simplices; raises when one is below ``tol`` × the mean."""
    n = top.shape[1] - 1
    volumes = vertex_volumes(vertices, top)
    if volumes.min() <= tol * volumes.mean():  # a reduction; the mask only to name the offenders
        bad = volumes <= tol * volumes.mean()
        raise DegenerateSimplexError(
            f"{name_indices(np.flatnonzero(bad), simplex_name(n))} {'has' if bad.sum() == 1 else 'have'} zero volume "
            f"(below {tol:g} × the mean {simplex_name(n)} volume {volumes.mean():.3g})"
        )
    return volumes


class FacetPairs(NamedTuple):
    """The interior (n-1)-faces and the two top simplices sharing each: ``facet`` indices into
    ``simplices(n-1)``; ``first``/``second`` the top simplices (input order of the pair);
    ``first_slot``/``second_slot`` the facet's column in their rows of ``top_face_indices(n-1)``
    (column c omits sorted vertex n - c)."""

    facet: np.ndarray
    first: np.ndarray
    second: np.ndarray
    first_slot: np.ndarray
    second_slot: np.ndarray


def _pair_index_type(top: np.ndarray):
    """The integer type of the pairs' simplices and slots: int32 where every facet slot fits."""
    return np.int32 if top.shape[0] < 2**31 // top.shape[1] - 1 else np.int64


def _compiled_pairs(pairs: tuple) -> FacetPairs:
    if not pairs[1].size:  # no interior facet: int64, as the numpy twin's
        pairs = (pairs[0], *(a.astype(np.int64) for a in pairs[1:]))
    return FacetPairs(*pairs)


def group_facets(top: np.ndarray, local, n_vertices: int) -> tuple[tuple, tuple[FacetPairs, bool] | None]:
    """The (n-1)-face slots ``top[t, local[s]]`` of the (m, n+1) sorted top simplices grouped
    (:func:`decrun.core.simplex_arrays.group_rows`: unique, inverse, order, starts) and, where the
    compiled ``facet_groups`` runs, the facet pairs with their duplicate suspicion
    (:func:`facet_pairs`' ``found``) from the same call; else ``None`` for them (the grouping alone).
    ``top``'s entries are vertex indices below ``n_vertices`` (the checked input): the packed keys'
    width follows from it, without a pass over ``top`` for its largest entry."""
    rows = FaceRows(top, local)
    bits = max(1, int(np.ceil(np.log2(max(n_vertices - 1, 0) + 2))))
    if rows.shape[0] and bits * rows.shape[1] <= 62 and (compiled := extension.kernels()) is not None:
        groups, pairs, suspect = compiled.facet_groups(np.ascontiguousarray(top, dtype=np.int64), rows.column_table(),
                                                      bits, np.zeros(0, _pair_index_type(top)))
        return groups, (_compiled_pairs(pairs), suspect)
    return group_rows(rows), None


def facet_pairs(order: np.ndarray, starts: np.ndarray, top: np.ndarray, facets: np.ndarray,
                check_manifold: bool, found: tuple[FacetPairs, bool] | None = None) -> FacetPairs:
    """The facet pairs from the facet groups (``order``/``starts`` of the grouped facet slots
    ``(n+1)·t + c``); raises on duplicate top simplices and, with ``check_manifold``, on facets
    in more than two top simplices. ``found``: the pairs and duplicate suspicion
    :func:`group_facets` already computed from these groups."""
    n = top.shape[1] - 1
    if found is not None:
        pairs, suspect = found
    elif (compiled := extension.kernels()) is not None:
        pairs, suspect = compiled.facet_pairs(order, starts, np.ascontiguousarray(top), np.zeros(0, _pair_index_type(top)))
        pairs = _compiled_pairs(pairs)
    else:
        pairs, suspect = facet_pairs_numpy(order, starts, top)
    # The facets in more than two simplices, without a pass over the groups: with p pairs, g groups
    # and s slots, s - g - p is the sum of (size - 1) over the groups of three or more, zero iff none.
    if order.shape[0] - (starts.shape[0] - 1) - pairs.first.shape[0] > 0:
        over = np.flatnonzero(np.diff(starts) > 2)
        _check_duplicates(top)
        if check_manifold:
            facet_slots = order[np.concatenate([np.arange(starts[g], starts[g + 1]) for g in over[:3]])]
            owners = np.unique(facet_slots // (n + 1))
            tuples = facets[over[:3]].tolist()
            raise NonManifoldError(
                f"non-manifold: {name_indices(over, simplex_name(n - 1))} (vertices {tuples}...) lie in more than two "
                f"{plural(simplex_name(n))} (e.g. {name_indices(owners, simplex_name(n))})"
            )
    if suspect:
        _check_duplicates(top)
    return pairs


def facet_pairs_numpy(order: np.ndarray, starts: np.ndarray, top: np.ndarray) -> tuple[FacetPairs, bool]:
    """The numpy twin of the compiled ``facet_pairs``: (pairs of the facets in exactly two top
    simplices, whether two of them have the same vertex opposite a shared facet — duplicates)."""
    n = top.shape[1] - 1
    width = n + 1
    interior = np.flatnonzero(np.diff(starts) == 2)
    at = starts[interior]
    index_type = np.int32 if interior.size and top.shape[0] < 2**31 // width - 1 else np.int64  # as the kernel's
    first, second = order[at].astype(index_type), order[at + 1].astype(index_type)
    first_slot, second_slot = first % width, second % width
    # Two simplices sharing a facet are duplicates iff their vertices opposite it agree: facet
    # column c of combinations(range(n+1), n) omits sorted vertex n - c, which is entry
    # (n+1)·t + n - c = slot + n - 2c of the flattened rows.
    flat = top.ravel()
    opposite_first = first + n
    opposite_first -= 2 * first_slot
    opposite_second = second + n
    opposite_second -= 2 * second_slot
    suspect = bool(np.any(flat[opposite_first] == flat[opposite_second]))
    pairs = FacetPairs(interior, first // width, second // width, first_slot, second_slot)
    return pairs, suspect


def _check_duplicates(top: np.ndarray) -> None:
    n = top.shape[1] - 1
    _, inverse = unique_rows(top)
    counts = np.bincount(inverse)
    dup = np.flatnonzero(counts[inverse] > 1)
    if dup.size:
        raise DuplicateSimplexError(f"{name_indices(dup, simplex_name(n))} repeat the same vertices")


def orient(pairs: FacetPairs, parity: np.ndarray, mode: str, n: int, consistent: bool | None = None) -> np.ndarray:
    """(m,) int8 consistent orientation of the n-dimensional top simplices, by the δ_n column
    test (§2.3.4).

    ``parity`` is the orientation of the input tuples; ``mode="check"`` returns it when it is
    consistent and raises :class:`OrientationError` otherwise; ``"fix"`` re-orients each
    connected component, keeping the orientation most of its simplices had. Non-orientable
    input raises :class:`NonOrientableError` either way. ``consistent``: the answer of
    :func:`fan_roots_and_consistency` for these pairs and ``parity``, when it was asked.
    """
    _, t0, t1, l0, l1 = pairs
    m = parity.shape[0]
    if consistent is None and (compiled := extension.kernels()) is not None:
        consistent = compiled.consistent(t0, t1, l0, l1, parity)
    if consistent:
        return parity
    bad = inconsistent_facets(pairs, parity)
    if not bad.any():
        return parity
    # Signed graph 2-colouring on the doubled graph: node t (keep) and t+m (flip).
    same = ~bad  # already consistent: both keep or both flip
    rows = np.concatenate([t0[same], t0[same] + m, t0[bad], t0[bad] + m])
    cols = np.concatenate([t1[same], t1[same] + m, t1[bad] + m, t1[bad]])
    graph = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(2 * m, 2 * m))
    _, label = graph_components(graph)
    contradiction = np.flatnonzero(label[:m] == label[m:])
    if contradiction.size:
        raise NonOrientableError(
            f"the mesh is not orientable (like a Möbius strip): no consistent orientation exists for "
            f"{name_indices(contradiction, simplex_name(n))}"
        )
    if mode == "check":
        listed = np.stack([t0[bad], t1[bad]], axis=1)[:MAX_LISTED].tolist()
        raise OrientationError(
            f"inconsistent orientation: {int(bad.sum())} {simplex_name(n - 1)}(s) are traversed in the same "
            f"direction by both neighbouring {plural(simplex_name(n))}, e.g. {simplex_name(n)} pairs {listed} "
            f"(§2.3.4)", python_hint="pass orient='fix' to re-orient each connected component"
        )
    # Choose per original component the coloring where most simplices keep their orientation.
    _, component = graph_components(sp.coo_matrix((np.ones(t0.size), (t0, t1)), shape=(m, m)))
    root = np.full(component.max() + 1, m, dtype=np.int64)
    np.minimum.at(root, component, np.arange(m))
    keep = label[:m] == label[root[component]]  # same colour as the root keeping orientation
    keep_count = np.bincount(component, weights=keep, minlength=root.size)
    size = np.bincount(component, minlength=root.size)
    flip_component = keep_count < size / 2
    keep = keep ^ flip_component[component]
    return np.where(keep, parity, -parity).astype(np.int8)


def inconsistent_facets(pairs: FacetPairs, parity: np.ndarray) -> np.ndarray:
    """(p,) bool: the interior facets both of whose top simplices induce the same orientation
    on them (the numpy twin of the compiled ``consistent``)."""
    _, t0, t1, l0, l1 = pairs
    # Entry of δ_n for the facet in each simplex: (-1)^l * orientation. Consistent iff opposite:
    # (-1)^l0 p0 == (-1)^l1 p1 exactly when p0 == p1 and l0 + l1 is even, or p0 != p1 and it is odd.
    odd = np.bitwise_xor(l0, l1)
    odd &= 1
    same = parity[t0] == parity[t1]
    return same != odd.astype(bool)




# ---------------------------------------------------------------- vertex stars
def fan_roots_and_consistency(top: np.ndarray, pairs: FacetPairs, parity: np.ndarray) -> tuple[int, bool] | None:
    """(the fans around all vertices together, whether ``parity`` orients the pairs consistently)
    from one call of the compiled ``fan_roots`` — what :func:`check_vertex_stars` and
    :func:`orient` ask of the facet pairs — or None where it does not run (they ask the numpy twins)."""
    compiled = extension.kernels()
    if compiled is None:
        return None
    roots, consistent = compiled.fan_roots(np.ascontiguousarray(top), pairs.first, pairs.second, pairs.first_slot,
                                          pairs.second_slot, parity)
    return int(roots), bool(consistent)


def check_vertex_stars(top: np.ndarray, facets: np.ndarray, orientation: np.ndarray, pairs: FacetPairs,
                       n_vertices: int, roots: int | None = None) -> None:
    """Each vertex star must be one fan of top simplices glued along facets (Fig. 2.11–2.12).

    A vertex whose incident top simplices fall into more than one group connected across
    shared facets (a bowtie / wheel) has no ball or half-ball neighbourhood. For n = 2
    (with manifold edges) this test is exact; for n = 3 it finds pinched vertices but
    not every exotic link. Runs after :func:`orient` (the orientation is consistent), on the
    checked input: every vertex below ``n_vertices`` is used. ``roots``: the fans around all
    vertices together, when :func:`fan_roots_and_consistency` counted them.
    """
    n = top.shape[1] - 1
    if n < 2:
        return
    if roots is None:
        found = fan_roots_and_consistency(top, pairs, orientation)
        roots = None if found is None else found[0]
    if roots == n_vertices:
        return  # every vertex is used (the checked input) and has a fan: as many fans as vertices is one each
    fans = fans_per_vertex(top, facets, pairs, n_vertices)
    bad = np.flatnonzero(fans > 1)
    if bad.size:
        raise NonManifoldError(
            f"non-manifold {name_indices(bad, 'vertex')}: the {plural(simplex_name(n))} around "
            f"{'it' if bad.size == 1 else 'each'} form {int(fans[bad[0]])} separate fans, not one disk or "
            f"half-disk (a 'bowtie'/'wheel', Fig. 2.11)"
        )


def fans_per_vertex(top, facets, pairs: FacetPairs, n_vertices: int) -> np.ndarray:
    """(n0,) int64 number of fans (top simplices connected across shared facets) around each
    vertex: the compiled ``fans``, or its numpy twin :func:`fans_per_vertex_general` (no extension,
    or ``DECRUN_NUMBA=0``)."""
    if (compiled := extension.kernels()) is not None:
        return compiled.fans(np.ascontiguousarray(top), pairs.first, pairs.second, pairs.first_slot,
                            pairs.second_slot, n_vertices)
    return fans_per_vertex_general(top, facets, pairs, n_vertices)


def fans_per_vertex_general(top, facets, pairs: FacetPairs, n_vertices: int) -> np.ndarray:
    """Fans per vertex for any n via connected components of the corner graph."""
    m, width = top.shape
    n = width - 1
    facet, t0, t1, _, _ = pairs
    facet_vertices = facets[facet]
    rows, cols = [], []
    for a in range(n):
        v = facet_vertices[:, a]
        rows.append(t0 * width + np.argmax(top[t0] == v[:, None], axis=1))
        cols.append(t1 * width + np.argmax(top[t1] == v[:, None], axis=1))
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    graph = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(m * width, m * width))
    count, label = graph_components(graph)
    fans = np.unique(top.ravel() * np.int64(count) + label)  # the distinct (vertex, fan) pairs
    return np.bincount(fans // count, minlength=n_vertices)
