"""Vectorized kernels on simplex arrays: row grouping, sorting, parity and volumes.

Plain arrays in, arrays out — the building blocks of :class:`decrun.core.complex.SimplicialComplex`
and of the Hodge stars. Shapes: a list of m simplices of dimension j is an ``(m, j+1)`` int64
array of vertex indices; corner coordinates are ``(m, j+1, d)`` float64.
"""

from __future__ import annotations

from itertools import combinations
from math import factorial

import numpy as np

from decrun.core import extension

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
    if rows.shape[0] and bits * rows.shape[1] <= 62 and (compiled := extension.kernels()) is not None:
        return compiled.group_packed(np.ascontiguousarray(rows.top, dtype=np.int64), rows.column_table(), bits)
    return group_rows_numpy(rows)


def group_rows_numpy(rows: "FaceRows"):
    """The numpy twin (and reference) of :func:`group_rows`' compiled kernel; same outputs: a
    stable lexicographic sort of the rows — one stable sort of each row packed into one int64
    key where its entries fit (``bits`` each), else ``np.lexsort`` — then the groups' starts."""
    if not isinstance(rows, FaceRows):
        rows = FaceRows(np.ascontiguousarray(rows, dtype=np.int64), None)
    bits = max(1, int(np.ceil(np.log2(rows.max() + 2))))
    table = rows.materialize()
    m, c = table.shape
    if bits * c <= 62:
        key = np.zeros(m, dtype=np.int64)
        for column in table.T:
            key <<= bits
            key |= column
        order = np.argsort(key, kind="stable")
    else:
        order = np.lexsort(table.T[::-1])
    sorted_rows = table[order]
    new = np.ones(m, dtype=bool)
    new[1:] = np.any(sorted_rows[1:] != sorted_rows[:-1], axis=1)
    starts = np.flatnonzero(new)
    inverse = np.empty(m, dtype=np.int64)
    inverse[order] = np.cumsum(new, dtype=np.int64) - 1
    return sorted_rows[new], inverse, order, np.append(starts, m)


class FaceRows:
    """The rows ``top[:, cols]`` flattened to (m·C, len(cols[0])) without building them,
    unless asked (the compiled grouping reads ``top`` and the column table)."""

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

    def materialize(self) -> np.ndarray:
        """(m·C, width) int64 rows: ``top[t, cols[s]]`` at row t·C + s."""
        if self.cols is None:
            return self.top
        return self.top[:, np.array(self.cols)].reshape(self.shape)


def sort_rows(rows: np.ndarray) -> np.ndarray:
    """Each row sorted (ascending)."""
    return np.sort(rows, axis=1)


def sorted_rows_and_parity(rows: np.ndarray, n_vertices: int = 0):
    """(sorted rows (m, c) int64, inversion parity (m,) int8, smallest entry, largest entry,
    whether a sorted row repeats an entry, used (n_vertices,) bool: which of 0..n_vertices-1 the
    rows hold): the compiled ``sorted_rows`` (:mod:`decrun.core.extension`) in one pass, or its numpy
    twins :func:`sort_rows` and :func:`inversion_parity`."""
    if (compiled := extension.kernels()) is not None:
        return compiled.sorted_rows(np.asarray(rows, dtype=np.int64), n_vertices)  # any layout: not copied
    rows = np.asarray(rows, dtype=np.int64)
    ordered = sort_rows(rows)
    repeated = bool((ordered[:, 1:] == ordered[:, :-1]).any())
    smallest, largest = int(ordered[:, 0].min()), int(ordered[:, -1].max())
    return ordered, inversion_parity(rows), smallest, largest, repeated, _used(ordered, smallest, largest, n_vertices)


def _used(ordered: np.ndarray, smallest: int, largest: int, n_vertices: int) -> np.ndarray:
    """(n_vertices,) bool: the entries of ``ordered`` within 0..n_vertices-1 (the numpy twin of
    the compiled ``sorted_rows``' last result)."""
    used = np.zeros(max(n_vertices, 0), dtype=bool)
    entries = ordered.ravel()
    if smallest < 0 or largest >= n_vertices:  # entries out of range (the input check names them)
        entries = entries[(entries >= 0) & (entries < n_vertices)]
    used[entries] = True
    return used


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

    Edges and triangles in 2-D/3-D take the compiled ``small_volumes``, whose
    twin is :func:`vertex_volumes_numpy`; the rest :func:`simplex_volumes`.
    """
    if simplices.shape[1] in (2, 3) and vertices.shape[1] in (2, 3):
        if (compiled := extension.kernels()) is not None:
            return compiled.small_volumes(np.asarray(vertices, dtype=np.float64),  # any layout: not copied
                                         np.ascontiguousarray(simplices, dtype=np.int64))
        return vertex_volumes_numpy(vertices, simplices)
    return simplex_volumes(vertices[simplices])


def vertex_volumes_numpy(vertices: np.ndarray, simplices: np.ndarray) -> np.ndarray:
    """The numpy twin of :func:`vertex_volumes` for edges and triangles in 2-D/3-D."""
    return _small_simplex_volumes([vertices[simplices[:, i]] for i in range(simplices.shape[1])])
