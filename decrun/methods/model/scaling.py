"""diag(f) · A and A · diag(f) for a sparse A, by scaling its stored values: the entries of the
sparse product without one (the lagged blocks, the derivative pass's chain rule and the Lie
derivative's Jacobians build them every step)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["scale_rows", "scale_columns"]


def scale_rows(matrix, factor) -> sp.csr_matrix:
    """(m, n) diag(factor) · matrix as a new CSR matrix (``factor`` (m,) or a number); ``matrix``
    is left untouched, and its pattern is kept (zeros of the product stay stored)."""
    out = sp.csr_matrix(matrix, dtype=np.float64, copy=True)
    out.data *= np.repeat(np.broadcast_to(factor, (out.shape[0],)), np.diff(out.indptr))
    return out


def scale_columns(matrix, factor) -> sp.csr_matrix:
    """(m, n) matrix · diag(factor) as a new CSR matrix (``factor`` (n,) or a number); ``matrix``
    is left untouched, and its pattern is kept."""
    out = sp.csr_matrix(matrix, dtype=np.float64, copy=True)
    out.data *= np.broadcast_to(factor, (out.shape[1],))[out.indices]
    return out
