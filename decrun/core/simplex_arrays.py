"""Vectorized kernels on simplex arrays: row grouping, sorting, parity and volumes.

Plain arrays in, arrays out — the building blocks of :class:`decrun.core.complex.SimplicialComplex`
and of the Hodge stars. Shapes: a list of m simplices of dimension j is an ``(m, j+1)`` int64
array of vertex indices; corner coordinates are ``(m, j+1, d)`` float64.
"""

from __future__ import annotations

from itertools import combinations
from math import factorial

import numpy as np

from decrun.core import jit

__all__ = ["unique_rows", "group_rows", "group_rows_numpy", "FaceRows", "sort_rows", "inversion_parity", "simplex_volumes", "vertex_volumes",
           "vertex_volumes_numpy",
           "sorted_rows_and_parity"]


def unique_rows(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lexicographically sorted unique rows of an integer array and the inverse map.

    Parameters
    ----------
    rows : (m, c) int64

    Returns
    -------
    unique : (u, c) int64, rows sorted lexicographically (column 0 most significant)
    inverse : (m,) int64 with ``unique[inverse] == rows``
    """
    unique, inverse, _, _ = group_rows(rows)
    return unique, inverse


def group_rows(rows: "np.ndarray | FaceRows"):
    """Group equal rows: (unique, inverse, order, starts).

    ``order`` is a stable lexicographic sort of the rows, ``starts`` the position in
    ``order`` where each group begins (plus a final ``m``), so the members of group g are
    ``order[starts[g]:starts[g+1]]`` in input order. One stable sort, everything else O(m).
    """
    if not isinstance(rows, FaceRows):
        rows = FaceRows(np.ascontiguousarray(rows, dtype=np.int64), None)
    bits = max(1, int(np.ceil(np.log2(rows.max() + 2))))
    if rows.shape[0] and bits * rows.shape[1] <= 62 and _group_packed_kernel.runs(rows.shape[0]):
        return _group_packed_kernel(np.ascontiguousarray(rows.top, dtype=np.int64), rows.column_table(), bits)
    return group_rows_numpy(rows)


def group_rows_numpy(rows: "FaceRows"):
    """The numpy twin (and reference) of :func:`group_rows`' compiled kernel; same outputs."""
    if not isinstance(rows, FaceRows):
        rows = FaceRows(np.ascontiguousarray(rows, dtype=np.int64), None)
    m, c = rows.shape
    if m == 0:
        empty = np.zeros((0, c), dtype=np.int64)
        return empty, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(1, dtype=np.int64)
    bits = max(1, int(np.ceil(np.log2(rows.max() + 2))))
    if bits * c <= 62:
        # Pack each row into one int64 key (edges and triangles of meshes up to ~2M vertices).
        position_bits = max(1, (m - 1).bit_length())
        if bits * c + position_bits <= 63:
            # The row's position in the low bits makes every key distinct: sorting the keys by
            # value (no indirection) gives the stable order, read back from the low bits.
            key = rows.packed(bits, position_bits)
            key.sort(kind="stable")
            order = key & ((1 << position_bits) - 1)
            key >>= position_bits
        else:
            key = rows.packed(bits)
            order = np.argsort(key, kind="stable")
            key = key[order]
        new = np.empty(m, dtype=bool)
        new[0] = True
        np.not_equal(key[1:], key[:-1], out=new[1:])
        starts = np.flatnonzero(new)
        unique_key = key[starts]
        del key
        unique = np.empty((unique_key.size, c), dtype=np.int64)
        mask = (1 << bits) - 1
        for col in range(c - 1, -1, -1):
            np.bitwise_and(unique_key, mask, out=unique[:, col])
            unique_key >>= bits
    else:
        rows = rows.materialize()
        order = np.lexsort(rows.T[::-1])
        sorted_rows = rows[order]
        new = np.empty(m, dtype=bool)
        new[0] = True
        new[1:] = np.any(sorted_rows[1:] != sorted_rows[:-1], axis=1)
        unique = sorted_rows[new]
        del sorted_rows
        starts = np.flatnonzero(new)
    group = np.cumsum(new, dtype=np.int64)
    group -= 1
    inverse = np.empty(m, dtype=np.int64)
    inverse[order] = group
    del group
    return unique, inverse, order, np.append(starts, m)


_SMALL_BUCKET = 32  # buckets up to this size are insertion-sorted, larger ones merge-sorted


@jit.njit
def _group_packed_kernel(top, columns, bits):
    """Compiled twin of :func:`group_rows_numpy` for rows ``top[t, columns[s]]`` (t major).

    The rows' packed keys are ordered by a stable counting sort on the leading entry (a
    vertex index, bounded by the vertex count) and a stable sort of each bucket by the
    key: the same ``order`` as numpy's stable argsort, in O(rows) for meshes.
    """
    m = top.shape[0]
    slots, width = columns.shape
    total = m * slots
    key = np.empty(total, np.int64)
    largest = 0
    for t in range(m):
        for s in range(slots):
            k = np.int64(0)
            for q in range(width):
                k = (k << bits) | top[t, columns[s, q]]
            key[t * slots + s] = k
            lead = top[t, columns[s, 0]]
            if lead > largest:
                largest = lead
    shift = bits * (width - 1)
    count = np.zeros(largest + 2, np.int64)
    for i in range(total):
        count[(key[i] >> shift) + 1] += 1
    for v in range(largest + 1):
        count[v + 1] += count[v]
    position = count[:-1].copy()
    order = np.empty(total, np.int64)
    sorted_key = np.empty(total, np.int64)  # keys in ``order``: the bucket sorts read them contiguously
    for i in range(total):
        lead = key[i] >> shift
        order[position[lead]] = i
        sorted_key[position[lead]] = key[i]
        position[lead] += 1
    for v in range(largest + 1):
        low, high = count[v], count[v + 1]
        if high - low <= 1:
            continue
        if high - low <= _SMALL_BUCKET:
            for a in range(low + 1, high):  # stable insertion sort by key
                item = order[a]
                item_key = sorted_key[a]
                b = a - 1
                while b >= low and sorted_key[b] > item_key:
                    order[b + 1] = order[b]
                    sorted_key[b + 1] = sorted_key[b]
                    b -= 1
                order[b + 1] = item
                sorted_key[b + 1] = item_key
        else:
            rank = np.argsort(sorted_key[low:high], kind="mergesort")
            bucket = order[low:high][rank]
            bucket_key = sorted_key[low:high][rank]
            order[low:high] = bucket
            sorted_key[low:high] = bucket_key
    groups = 0
    for a in range(total):
        if a == 0 or sorted_key[a] != sorted_key[a - 1]:
            groups += 1
    unique = np.empty((groups, width), np.int64)
    inverse = np.empty(total, np.int64)
    starts = np.empty(groups + 1, np.int64)
    g = -1
    mask = (np.int64(1) << bits) - 1
    for a in range(total):
        k = sorted_key[a]
        if a == 0 or k != sorted_key[a - 1]:
            g += 1
            starts[g] = a
            packed = k
            for q in range(width - 1, -1, -1):
                unique[g, q] = packed & mask
                packed >>= bits
        inverse[order[a]] = g
    starts[groups] = total
    return unique, inverse, order, starts


@jit.njit
def _facet_pairs_kernel(order, starts, top, index_like):
    """One pass over the facet groups (``order``/``starts`` of the grouped facet slots
    ``(n+1)·t + c`` of the (m, n+1) sorted ``top``): the pairs of
    :func:`decrun.core.complex.checks.facet_pairs_numpy` (the facets in exactly two top simplices,
    int64; their simplices and slots of ``index_like``'s type) and the duplicate suspicion (two of
    them with the same vertex opposite their shared facet)."""
    width = top.shape[1]
    n = width - 1
    groups = starts.shape[0] - 1
    count = 0
    for g in range(groups):
        if starts[g + 1] - starts[g] == 2:
            count += 1
    interior = np.empty(count, np.int64)
    first = np.empty(count, index_like.dtype)
    second = np.empty(count, index_like.dtype)
    first_slot = np.empty(count, index_like.dtype)
    second_slot = np.empty(count, index_like.dtype)
    suspect = False
    p = 0
    for g in range(groups):
        if starts[g + 1] - starts[g] != 2:
            continue
        a, b = order[starts[g]], order[starts[g] + 1]
        interior[p] = g
        first[p], first_slot[p] = a // width, a % width
        second[p], second_slot[p] = b // width, b % width
        if top[first[p], n - first_slot[p]] == top[second[p], n - second_slot[p]]:
            suspect = True
        p += 1
    return (interior, first, second, first_slot, second_slot), suspect


@jit.njit
def _facet_groups_kernel(top, columns, bits, index_like):
    """:func:`_group_packed_kernel` on the facet slots, then :func:`_facet_pairs_kernel` on its
    groups: ((unique, inverse, order, starts), pairs, suspect).
    One call, so that the extension's twin can do both in one counting sort."""
    unique, inverse, order, starts = _group_kernel_for_facets(top, columns, bits)
    pairs, suspect = _pairs_for_groups(order, starts, top, index_like)
    return (unique, inverse, order, starts), pairs, suspect


# the names _facet_groups_kernel calls: numba swaps them for the dispatchers when it compiles it,
# while the kernels' own names stay lazy kernels (the callers above and in complex.checks ask them)
_group_kernel_for_facets = _group_packed_kernel
_pairs_for_groups = _facet_pairs_kernel


class FaceRows:
    """The rows ``top[:, cols]`` flattened to (m·C, len(cols[0])) without building them,
    unless asked: packed integer keys are computed column by column."""

    def __init__(self, top: np.ndarray, cols):
        self.top, self.cols = top, cols
        width = top.shape[1] if cols is None else len(cols[0])
        count = top.shape[0] if cols is None else top.shape[0] * len(cols)
        self.shape = (count, width)

    def column_table(self) -> np.ndarray:
        """(C, width) int64 local columns of the rows (one row of ``0..width-1`` for plain rows)."""
        if self.cols is None:
            return np.arange(self.shape[1], dtype=np.int64)[None, :]
        return np.array(self.cols, dtype=np.int64)

    def max(self) -> int:
        return int(self.top.max()) if self.top.size else 0

    def column(self, index: int) -> np.ndarray:
        """(m·C,) entries ``index`` of every row, in row order."""
        if self.cols is None:
            return self.top[:, index]
        return self.top[:, [c[index] for c in self.cols]].ravel()

    def packed(self, bits: int, position_bits: int = 0) -> np.ndarray:
        """(m·C,) int64 keys: each row's entries, ``bits`` bits each (the first most significant),
        then, with ``position_bits``, the row's position ``0..m·C-1`` in the lowest bits."""
        count, width = self.shape
        cols = [tuple(range(width))] if self.cols is None else self.cols
        key = np.empty((self.top.shape[0], len(cols)), dtype=np.int64)  # row t·C + s is key[t, s]
        for s, local in enumerate(cols):
            out = key[:, s]
            np.copyto(out, self.top[:, local[0]])
            for q in local[1:]:
                out <<= bits
                out |= self.top[:, q]
            if position_bits:
                out <<= position_bits
                out |= np.arange(s, count, len(cols), dtype=np.int64)
        return key.reshape(count)

    def materialize(self) -> np.ndarray:
        if self.cols is None:
            return self.top
        return self.top[:, np.array(self.cols)].reshape(self.shape)


def sort_rows(rows: np.ndarray) -> np.ndarray:
    """Sort each (short) row; a min/max network for triangles, np.sort otherwise."""
    if rows.shape[1] == 3:
        a, b, c = rows[:, 0], rows[:, 1], rows[:, 2]
        low = np.minimum(np.minimum(a, b), c)
        high = np.maximum(np.maximum(a, b), c)
        return np.stack([low, a + b + c - low - high, high], axis=1)
    return np.sort(rows, axis=1)


def sorted_rows_and_parity(rows: np.ndarray, n_vertices: int = 0):
    """(sorted rows (m, c) int64, inversion parity (m,) int8, smallest entry, largest entry,
    whether a sorted row repeats an entry, used (n_vertices,) bool: which of 0..n_vertices-1 the
    rows hold) in one pass: the compiled :func:`_sorted_rows_kernel`, or its numpy twins
    :func:`sort_rows` and :func:`inversion_parity`."""
    if _sorted_rows_kernel.runs(rows.shape[0]):
        return _sorted_rows_kernel(np.asarray(rows, dtype=np.int64), n_vertices)  # any layout: not copied
    rows = np.asarray(rows, dtype=np.int64)
    if rows.shape[1] == 3 and rows.shape[0]:  # triangles: a min/max network on the three columns
        a, b, c = rows[:, 0], rows[:, 1], rows[:, 2]
        low, high = np.minimum(a, b), np.maximum(a, b)
        middle = np.minimum(high, c)
        np.maximum(high, c, out=high)
        np.maximum(low, middle, out=middle)
        np.minimum(low, c, out=low)
        repeated = bool(np.any(low == middle) or np.any(middle == high))
        inversions = (a > b).view(np.int8) + (a > c).view(np.int8)
        inversions += (b > c).view(np.int8)
        inversions &= 1
        parity = 1 - 2 * inversions  # int8: +1 even, -1 odd
        ordered = np.stack([low, middle, high], axis=1)
        smallest, largest = int(low.min()), int(high.max())
        return ordered, parity, smallest, largest, repeated, _used(ordered, smallest, largest, n_vertices)
    ordered = sort_rows(rows)
    repeated = bool((ordered[:, 1:] == ordered[:, :-1]).any())
    smallest, largest = int(ordered[:, 0].min()), int(ordered[:, -1].max())
    return ordered, inversion_parity(rows), smallest, largest, repeated, _used(ordered, smallest, largest, n_vertices)


def _used(ordered: np.ndarray, smallest: int, largest: int, n_vertices: int) -> np.ndarray:
    """(n_vertices,) bool: the entries of ``ordered`` within 0..n_vertices-1 (the numpy twin of
    :func:`_sorted_rows_kernel`'s last result)."""
    used = np.zeros(max(n_vertices, 0), dtype=bool)
    entries = ordered.ravel()
    if smallest < 0 or largest >= n_vertices:  # entries out of range (the input check names them)
        entries = entries[(entries >= 0) & (entries < n_vertices)]
    used[entries] = True
    return used


@jit.njit
def _sorted_rows_kernel(rows, n_vertices):
    """Insertion sort of each row; its shift count is the row's inversion count (§2.3.3); and
    which of the vertices 0..n_vertices-1 the rows hold, marked as the sorted entries are written."""
    m, c = rows.shape
    ordered = np.empty((m, c), np.int64)
    parity = np.empty(m, np.int8)
    used = np.zeros(max(n_vertices, 0), np.bool_)
    smallest = rows[0, 0]
    largest = rows[0, 0]
    repeated = False
    for t in range(m):
        shifts = 0
        for a in range(c):
            value = rows[t, a]
            b = a - 1
            while b >= 0 and ordered[t, b] > value:
                ordered[t, b + 1] = ordered[t, b]
                b -= 1
                shifts += 1
            ordered[t, b + 1] = value
        parity[t] = 1 if shifts % 2 == 0 else -1
        if ordered[t, 0] < smallest:
            smallest = ordered[t, 0]
        if ordered[t, c - 1] > largest:
            largest = ordered[t, c - 1]
        for a in range(1, c):
            if ordered[t, a] == ordered[t, a - 1]:
                repeated = True
        for a in range(c):
            if 0 <= ordered[t, a] < n_vertices:
                used[ordered[t, a]] = True
    return ordered, parity, smallest, largest, repeated, used


def inversion_parity(tuples: np.ndarray) -> np.ndarray:
    """(-1)**(number of inversions) of each row (§2.3.3, the inversion table).

    Parameters
    ----------
    tuples : (m, c) integer array

    Returns
    -------
    (m,) int8, +1 for an even permutation of the sorted row, -1 for an odd one.
    """
    tuples = np.asarray(tuples)
    c = tuples.shape[1]
    inversions = np.zeros(tuples.shape[0], dtype=np.int64)
    for a, b in combinations(range(c), 2):
        inversions += tuples[:, a] > tuples[:, b]
    return np.where(inversions % 2 == 0, 1, -1).astype(np.int8)


def simplex_volumes(points: np.ndarray) -> np.ndarray:
    """Unsigned j-dimensional volumes of simplices given by their corner points.

    Parameters
    ----------
    points : (m, j+1, d) corner coordinates

    Returns
    -------
    (m,) volumes ``sqrt(det(EᵀE)) / j!`` with ``E = [p1-p0, ..., pj-p0]`` (Gram determinant);
    1 for j = 0.
    """
    j = points.shape[1] - 1
    if j == 0:
        return np.ones(points.shape[0])
    if j in (1, 2) and points.shape[2] in (2, 3):
        return _small_simplex_volumes([points[:, i, :] for i in range(j + 1)])
    edges = points[:, 1:, :] - points[:, :1, :]
    if j == 1:
        return np.linalg.norm(edges[:, 0], axis=1)
    if j == 2 and points.shape[2] == 3:
        return 0.5 * np.linalg.norm(np.cross(edges[:, 0], edges[:, 1]), axis=1)
    if j == points.shape[2]:
        return np.abs(np.linalg.det(edges)) / factorial(j)
    gram = np.einsum("mai,mbi->mab", edges, edges)
    return np.sqrt(np.clip(np.linalg.det(gram), 0.0, None)) / factorial(j)


def _small_simplex_volumes(corners: list) -> np.ndarray:
    """Lengths of segments / areas of triangles from corner arrays (m, d), d = 2 or 3."""
    d = corners[0].shape[1]
    if len(corners) == 2:
        total = 0.0
        for axis in range(d):
            diff = corners[1][:, axis] - corners[0][:, axis]
            total = total + diff * diff
        return np.sqrt(total)
    u = [corners[1][:, axis] - corners[0][:, axis] for axis in range(d)]
    v = [corners[2][:, axis] - corners[0][:, axis] for axis in range(d)]
    if d == 2:
        return 0.5 * np.abs(u[0] * v[1] - u[1] * v[0])
    total = np.zeros(u[0].shape[0])
    for a, b in ((1, 2), (2, 0), (0, 1)):  # the components of u × v, squared and summed
        component = u[a] * v[b]
        component -= u[b] * v[a]
        component *= component
        total += component
    np.sqrt(total, out=total)
    total *= 0.5
    return total


def vertex_volumes(vertices: np.ndarray, simplices: np.ndarray) -> np.ndarray:
    """(m,) volumes of the simplices (m, j+1) of vertex indices into ``vertices`` (n0, d).

    Edges and triangles in 2-D/3-D take the compiled :func:`_small_volumes_kernel`, whose
    twin is :func:`vertex_volumes_numpy`; the rest :func:`simplex_volumes`.
    """
    if simplices.shape[1] in (2, 3) and vertices.shape[1] in (2, 3):
        if _small_volumes_kernel.runs(simplices.shape[0]):
            return _small_volumes_kernel(np.asarray(vertices, dtype=np.float64),  # any layout: not copied
                                         np.ascontiguousarray(simplices, dtype=np.int64))
        return vertex_volumes_numpy(vertices, simplices)
    return simplex_volumes(vertices[simplices])


def vertex_volumes_numpy(vertices: np.ndarray, simplices: np.ndarray) -> np.ndarray:
    """The numpy twin of :func:`vertex_volumes` for edges and triangles in 2-D/3-D."""
    return _small_simplex_volumes(_CornerCoordinates(vertices, simplices))


@jit.njit
def _small_volumes_kernel(points, simplices):
    """Lengths of edges / areas of triangles with the arithmetic of :func:`_small_simplex_volumes`
    in the same order (bit-for-bit equal): ``points`` (n0, d) coordinates in any layout (C order keeps
    a vertex's in one cache line for the simplices' random gathers), ``simplices`` (m, 2|3)."""
    m, corners = simplices.shape
    d = points.shape[1]
    out = np.empty(m)
    for t in range(m):
        p = simplices[t, 0]
        q = simplices[t, 1]
        if corners == 2:
            total = 0.0
            for axis in range(d):
                diff = points[q, axis] - points[p, axis]
                total = total + diff * diff
            out[t] = np.sqrt(total)
            continue
        r = simplices[t, 2]
        if d == 2:
            u0, u1 = points[q, 0] - points[p, 0], points[q, 1] - points[p, 1]
            v0, v1 = points[r, 0] - points[p, 0], points[r, 1] - points[p, 1]
            out[t] = 0.5 * abs(u0 * v1 - u1 * v0)
            continue
        u0, u1, u2 = points[q, 0] - points[p, 0], points[q, 1] - points[p, 1], points[q, 2] - points[p, 2]
        v0, v1, v2 = points[r, 0] - points[p, 0], points[r, 1] - points[p, 1], points[r, 2] - points[p, 2]
        total = 0.0
        component = u1 * v2 - u2 * v1
        total += component * component
        component = u2 * v0 - u0 * v2
        total += component * component
        component = u0 * v1 - u1 * v0
        total += component * component
        out[t] = np.sqrt(total) * 0.5
    return out


class _CornerCoordinates:
    """corners[i][:, axis] gathered one coordinate at a time (no (m, d) corner arrays)."""

    def __init__(self, vertices: np.ndarray, simplices: np.ndarray):
        self.columns = np.ascontiguousarray(vertices.T)  # (d, n0): contiguous per axis
        self.corners = [np.ascontiguousarray(simplices[:, i]) for i in range(simplices.shape[1])]  # read d times each

    def __len__(self) -> int:
        return len(self.corners)

    def __getitem__(self, i: int):
        return _CornerColumn(self.columns, self.corners[i])


class _CornerColumn:
    def __init__(self, columns, index):
        self.columns, self.index = columns, index
        self.shape = (index.shape[0], columns.shape[0])

    def __getitem__(self, key):
        _, axis = key
        return self.columns[axis][self.index]
