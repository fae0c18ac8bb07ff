"""Newton's Jacobian J = L + M ∂R/∂y assembled into a sparsity pattern made once.

For a model whose explicit terms R are value by value in the evolved fields (reactions u v²,
u − u³, cosh(u): the derivative pass gives each block ∂R_u/∂v as an array d_uv, the diagonal
matrix diag(d_uv)) and whose row masses M_u are diagonal (⋆0, the circumcentric ⋆k), J has a
fixed pattern: L's, plus the diagonal of every block (u, v) that a term couples. That pattern —
restricted to the free values, as a canonical CSR structure, with the place of each of L's
values and of each block's diagonal in it — is made once (:class:`PatternAssembly`); a Jacobian
is then one copy of L's values and one scatter-add of M_u d_uv per block, O(nnz) with no sparse
arithmetic, no format conversion and no fancy-indexed restriction. A term whose derivative is a
sparse matrix (through ♯, a linear operator of a nonlinear term) takes the general assembly of
:class:`~decrun.methods.model.problem.ModelProblem` instead.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["PatternAssembly", "as_matrix"]


def as_matrix(D, rows: int, cols: int) -> sp.csr_matrix:
    """A derivative as the derivative pass gives it (None, an array: a diagonal, or a sparse
    matrix) as a (rows, cols) CSR matrix."""
    if D is None:
        return sp.csr_matrix((rows, cols))
    if sp.issparse(D):
        return sp.csr_matrix(D)
    return sp.diags(np.broadcast_to(np.asarray(D, dtype=np.float64), (cols,))).tocsr()


class PatternAssembly:
    """The pattern of J over the free values (module docstring) for the diagonal blocks ``blocks``
    [(u, v)]: ``stiff`` L (size, size) on the free values, ``slices`` each field's place in the
    stacked vector of ``total`` values, ``free`` the free places, ``mass`` (total,) the diagonal
    row masses."""

    def __init__(self, stiff: sp.csr_matrix, blocks: list[tuple[str, str]], slices: dict, free: np.ndarray,
                 total: int, mass: np.ndarray):
        size = stiff.shape[0]
        self.size = size
        free_index = np.full(total, -1, dtype=np.int64)
        free_index[free] = np.arange(size)
        L = sp.coo_matrix(stiff)
        rows, cols = [L.row.astype(np.int64)], [L.col.astype(np.int64)]
        places = {}
        for u, v in blocks:
            count = slices[u].stop - slices[u].start
            full_rows = slices[u].start + np.arange(count)
            r, c = free_index[full_rows], free_index[slices[v].start + np.arange(count)]
            keep = (r >= 0) & (c >= 0)
            places[(u, v)] = (keep, r[keep], c[keep], mass[full_rows][keep])
            rows.append(r[keep])
            cols.append(c[keep])
        row, col = np.concatenate(rows), np.concatenate(cols)
        pattern = sp.csr_matrix((np.ones(row.size), (row, col)), shape=(size, size))
        pattern.sum_duplicates()
        pattern.sort_indices()
        self.indptr, self.indices = pattern.indptr, pattern.indices
        for array in (self.indptr, self.indices):  # shared by every Jacobian made: never changed in place
            array.flags.writeable = False
        keys = np.repeat(np.arange(size, dtype=np.int64), np.diff(self.indptr)) * size + self.indices
        self.values = np.zeros(keys.size)
        self.values[np.searchsorted(keys, L.row.astype(np.int64) * size + L.col)] = L.data
        #: (u, v) → (which of the block's values are free, their places in the pattern, M_u there)
        self.blocks = {key: (None if keep.all() else keep, np.searchsorted(keys, r * size + c), weight)
                       for key, (keep, r, c, weight) in places.items()}

    def assemble(self, diagonals: dict) -> sp.csr_matrix:
        """J (size, size) from ``diagonals`` {(u, v): d_uv (n_u,) or a number}: L + M diag(d_uv) in
        each block, in the pattern made once: its values are its own, its structure (indices,
        indptr) is the pattern's, read-only."""
        data = self.values.copy()
        for key, d in diagonals.items():
            keep, slots, weight = self.blocks[key]
            value = np.broadcast_to(np.asarray(d, dtype=np.float64), weight.shape if keep is None else keep.shape)
            data[slots] += weight * (value if keep is None else value[keep])
        matrix = sp.csr_matrix((data, self.indices, self.indptr), shape=(self.size, self.size), copy=False)
        matrix.has_sorted_indices = True
        return matrix
