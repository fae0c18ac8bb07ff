"""The :class:`Solver` interface: a dataclass of options with ``factorize`` / ``solve``."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.core.digest import Digest
from decrun.errors import SolverError

__all__ = ["Solver", "fingerprint", "norm_bound", "backward_error"]


def fingerprint(A: sp.csr_matrix) -> str:
    """sha256 of the shape, sparsity pattern and values of a CSR matrix (:mod:`decrun.core.digest`)."""
    h = Digest().text(repr(A.shape))
    for array in (A.indptr, A.indices, A.data):
        h.array(array, header=False)
    return h.hexdigest()


def norm_bound(A: sp.spmatrix) -> float:
    """√(‖A‖₁ ‖A‖∞) ≥ ‖A‖₂: the matrix norm of the backward error, without an SVD."""
    return float(np.sqrt(spla.norm(A, 1) * spla.norm(A, np.inf)))


def backward_error(residual: np.ndarray, x: np.ndarray, b: np.ndarray, norm_A: float) -> float:
    """‖r‖ / (‖A‖ ‖x‖ + ‖b‖) for r = b − A x: the normwise backward error of x (Rigal–Gaches),
    the smallest relative change of A and b that makes x exact; ``norm_A`` from :func:`norm_bound`."""
    scale = norm_A * float(np.linalg.norm(x)) + float(np.linalg.norm(b))
    return float(np.linalg.norm(residual)) / scale if scale > 0 else 0.0


@dataclass
class Solver:
    """Base of the solvers. Subclasses are dataclasses whose fields are their options.

    Class attributes: ``name`` (``solver=<name>``) and ``needs_spd`` (True when the method
    converges only for symmetric positive definite matrices).
    """

    name: ClassVar[str] = ""
    needs_spd: ClassVar[bool] = False

    def __post_init__(self):
        self._key: str | None = None
        self.shape: tuple[int, int] | None = None
        self.factorizations = 0  # how many times a matrix was actually prepared

    def fresh(self) -> "Solver":
        """A new, unfactorized solver with the same options."""
        return dataclasses.replace(self)

    def factorize(self, A) -> "Solver":
        """Prepare repeated solves with the square sparse matrix ``A`` (n, n).

        A no-op when ``A`` equals (values and pattern) the matrix prepared last. An empty
        system (n = 0: e.g. a problem whose every value is fixed by the border) is not
        handed to the method (CHOLMOD and pyamg refuse a 0×0 matrix): its solution is the
        empty array, for every solver.
        """
        A = sp.csr_matrix(A, dtype=np.float64)
        if A.shape[0] != A.shape[1]:
            raise SolverError(f"{self.name} solver: matrix must be square, got {A.shape}")
        A.sum_duplicates()
        if not np.isfinite(A.data).all():  # never hand NaN/inf to native code (SuperLU, PARDISO)
            bad = int((~np.isfinite(A.data)).sum())
            raise SolverError(f"{self.name} solver: the {A.shape} matrix has {bad} non-finite entries (NaN or inf): "
                              "the mesh or the operator variant produced them")
        key = fingerprint(A)
        if key == self._key:
            return self
        if A.shape[0]:
            self._prepare(A)
        self._key, self.shape = key, A.shape
        self.factorizations += 1
        return self

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve ``A x = b`` for ``b`` of shape (n,) or (n, m); returns x of b's shape."""
        if self._key is None:
            raise SolverError(f"{self.name} solver: solve() called before factorize()")
        b = np.asarray(b, dtype=np.float64)
        if b.shape[0] != self.shape[0]:
            raise SolverError(f"{self.name} solver: right-hand side has {b.shape[0]} rows, matrix {self.shape}")
        if self.shape[0] == 0:  # an empty system: nothing was prepared, nothing to solve
            return np.zeros(b.shape)
        return self._solve_block(b)

    def _solve_block(self, b: np.ndarray) -> np.ndarray:
        """x for b (n,) or (n, m) after the checks of :meth:`solve` (default: column by column)."""
        if b.ndim == 1:
            return self._solve_one(b)
        return np.column_stack([self._solve_one(b[:, j]) for j in range(b.shape[1])]).reshape(b.shape)

    def _prepare(self, A: sp.csr_matrix) -> None:
        raise NotImplementedError

    def _solve_one(self, b: np.ndarray) -> np.ndarray:
        raise NotImplementedError


def check_tolerance(tol: float, maxiter) -> None:
    """``solver.tol`` > 0 and ``solver.maxiter`` ≥ 1 or None (ConfigError otherwise)."""
    from decrun.errors import ConfigError

    if not tol > 0:
        raise ConfigError(f"solver.tol: must be > 0, got {tol}")
    if maxiter is not None and maxiter < 1:
        raise ConfigError(f"solver.maxiter: must be >= 1 or null, got {maxiter}")
