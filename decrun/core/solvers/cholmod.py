"""``solver=cholmod``: sparse Cholesky (SuiteSparse CHOLMOD via the ``cholespy`` wheel), SPD only.

A = L Lᵀ once (supernodal, fill-reducing ordering), two triangular solves per right-hand
side. The matrix must be symmetric (checked: CHOLMOD reads one triangle only) and positive
definite (CHOLMOD reports otherwise; the error names ``solver=direct``).
"""

from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from decrun.core.solvers.base import Solver
from decrun.errors import SolverError

__all__ = ["CholmodSolver", "asymmetry", "quiet_stdout"]

SYMMETRY_TOL = 1e-12  # max |A − Aᵀ| relative to max |A| accepted as symmetric (round-off)


def asymmetry(A: sp.csr_matrix) -> float:
    """max |A − Aᵀ| / max |A| (0 for an exactly symmetric matrix)."""
    scale = float(np.abs(A.data).max()) if A.nnz else 0.0
    difference = A - A.T
    return float(np.abs(difference.data).max()) / scale if difference.nnz and scale > 0 else 0.0


@contextlib.contextmanager
def quiet_stdout():
    """Silence file descriptor 1 (CHOLMOD prints its 'not positive definite' warning there)."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as sink:
            os.dup2(sink.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


@dataclass
class CholmodSolver(Solver):
    """Cholesky factorization once in ``factorize``; each solve two triangular solves."""

    name = "cholmod"
    needs_spd = True

    def __post_init__(self):
        super().__post_init__()
        try:
            import cholespy  # noqa: F401
        except ImportError:
            raise SolverError("solver=cholmod needs the package cholespy: install it with `pip install cholespy`, "
                              "or run with solver=direct") from None

    def _prepare(self, A) -> None:
        self._factor = cholesky_factor(A, self.name)

    def _solve_block(self, b: np.ndarray) -> np.ndarray:
        return cholesky_solve(self._factor, np.ascontiguousarray(b))


def cholesky_factor(A: sp.csr_matrix, name: str):
    """The cholespy factor of the symmetric positive definite CSR matrix ``A``; SolverError
    (naming ``solver=direct``) when ``A`` is not symmetric or not positive definite."""
    import cholespy

    skew = asymmetry(A)
    if skew > SYMMETRY_TOL:
        raise SolverError(f"{name} solver: the {A.shape} matrix is not symmetric (max |A − Aᵀ| = {skew:.2g} × max |A|); "
                          "Cholesky needs a symmetric positive definite matrix: use solver=direct")
    A = sp.csr_matrix(A)
    A.sort_indices()
    try:
        with quiet_stdout():
            return cholespy.CholeskySolverD(A.shape[0], A.indptr.astype(np.int32), A.indices.astype(np.int32),
                                            np.ascontiguousarray(A.data), cholespy.MatrixType.CSR)
    except ValueError as exc:  # "Matrix is not positive definite!"
        raise SolverError(f"{name} solver: cannot factorize the {A.shape} matrix: {exc} "
                          "(Cholesky needs a positive definite matrix: use solver=direct)") from None


def cholesky_solve(factor, b: np.ndarray) -> np.ndarray:
    """x with A x = b for a cholespy ``factor`` of A; b (n,) or (n, m) C-contiguous float64."""
    x = np.empty_like(b)
    factor.solve(b, x)
    if not np.all(np.isfinite(x)):
        raise SolverError("cholmod solver: the solution is not finite (matrix numerically singular?)")
    return x
