"""Vectorized kernels on simplex arrays: row grouping, sorting, parity and volumes.

Plain arrays in, arrays out — the building blocks of :class:`decrun.core.complex.SimplicialComplex`
and of the Hodge stars. Shapes: a list of m simplices of dimension j is an ``(m, j+1)`` int64
array of vertex indices; corner coordinates are ``(m, j+1, d)`` float64.
"""

from __future__ import annotations

from itertools import combinations
from math import factorial

import numpy as np

__all__ = ["unique_rows", "group_rows", "FaceRows", "sort_rows", "inversion_parity", "simplex_volumes", "vertex_volumes"]


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


def group_rows(rows: np.ndarray):
    """Group equal rows: (unique, inverse, order, starts).

    ``order`` is a stable lexicographic sort of the rows, ``starts`` the position in
    ``order`` where each group begins (plus a final ``m``), so the members of group g are
    ``order[starts[g]:starts[g+1]]`` in input order. One stable sort, everything else O(m).
    """
    if not isinstance(rows, FaceRows):
        rows = FaceRows(np.ascontiguousarray(rows, dtype=np.int64), None)
    m, c = rows.shape
    if m == 0:
        empty = np.zeros((0, c), dtype=np.int64)
        return empty, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(1, dtype=np.int64)
    bits = max(1, int(np.ceil(np.log2(rows.max() + 2))))
    if bits * c <= 62:
        # Pack each row into one int64 key (edges and triangles of meshes up to ~2M vertices).
        key = rows.packed(bits)
        order = np.argsort(key, kind="stable")
        sorted_key = key[order]
        del key
        new = np.empty(m, dtype=bool)
        new[0] = True
        np.not_equal(sorted_key[1:], sorted_key[:-1], out=new[1:])
        unique_key = sorted_key[new]
        del sorted_key
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
    group = np.cumsum(new, dtype=np.int64)
    group -= 1
    inverse = np.empty(m, dtype=np.int64)
    inverse[order] = group
    del group
    starts = np.append(np.flatnonzero(new), m)
    return unique, inverse, order, starts


class FaceRows:
    """The rows ``top[:, cols]`` flattened to (m·C, len(cols[0])) without building them,
    unless asked: packed integer keys are computed column by column."""

    def __init__(self, top: np.ndarray, cols):
        self.top, self.cols = top, cols
        width = top.shape[1] if cols is None else len(cols[0])
        count = top.shape[0] if cols is None else top.shape[0] * len(cols)
        self.shape = (count, width)

    def max(self) -> int:
        return int(self.top.max()) if self.top.size else 0

    def column(self, index: int) -> np.ndarray:
        """(m·C,) entries ``index`` of every row, in row order."""
        if self.cols is None:
            return self.top[:, index]
        return self.top[:, [c[index] for c in self.cols]].ravel()

    def packed(self, bits: int) -> np.ndarray:
        key = self.column(0).astype(np.int64)
        for col in range(1, self.shape[1]):
            key <<= bits
            key |= self.column(col)
        return key

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
    """Volumes of simplices given by vertex indices (fast path for edges and triangles)."""
    if simplices.shape[1] in (2, 3) and vertices.shape[1] in (2, 3):
        return _small_simplex_volumes(_CornerCoordinates(vertices, simplices))
    return simplex_volumes(vertices[simplices])


class _CornerCoordinates:
    """corners[i][:, axis] gathered one coordinate at a time (no (m, d) corner arrays)."""

    def __init__(self, vertices: np.ndarray, simplices: np.ndarray):
        self.columns = np.ascontiguousarray(vertices.T)  # (d, n0): contiguous per axis
        self.simplices = simplices

    def __len__(self) -> int:
        return self.simplices.shape[1]

    def __getitem__(self, i: int):
        return _CornerColumn(self.columns, self.simplices[:, i])


class _CornerColumn:
    def __init__(self, columns, index):
        self.columns, self.index = columns, index
        self.shape = (index.shape[0], columns.shape[0])

    def __getitem__(self, key):
        _, axis = key
        return self.columns[axis][self.index]
