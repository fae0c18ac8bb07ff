"""``solver=cg``: conjugate gradients with a Jacobi preconditioner (SPD matrices only)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
import scipy.sparse.linalg as spla

from decrun.core.choices import Choice
from decrun.core.solvers.base import Solver, check_tolerance
from decrun.errors import SolverError

__all__ = ["CGSolver"]


class Preconditioner(Choice):
    """``solver.preconditioner`` of cg: ``jacobi`` (the inverse diagonal) or ``none``."""

    jacobi = "jacobi"
    none = "none"


@dataclass
class CGSolver(Solver):
    """Conjugate gradients to the relative residual ``tol`` (``||b − A x|| ≤ tol ||b||``);
    ``factorize`` stores ``A`` and the inverse diagonal (``preconditioner: jacobi | none``)."""

    name = "cg"
    needs_spd = True
    tol: float = 1e-10
    maxiter: Optional[int] = None
    preconditioner: Preconditioner = Preconditioner.jacobi

    def __post_init__(self):
        super().__post_init__()
        check_tolerance(self.tol, self.maxiter)
        self.preconditioner = Preconditioner.of(self.preconditioner, "solver.preconditioner")
        self.iterations: list[int] = []

    def _prepare(self, A) -> None:
        self._A = A
        self._M = None
        if self.preconditioner == "jacobi":
            diagonal = A.diagonal()
            if np.any(diagonal <= 0):
                i = int(np.flatnonzero(diagonal <= 0)[0])
                raise SolverError(f"cg solver: Jacobi needs a positive diagonal; A[{i},{i}] = {diagonal[i]:.3g} "
                                  "(the matrix is not positive definite)")
            inverse = 1.0 / diagonal
            self._M = spla.LinearOperator(A.shape, matvec=lambda x: inverse * x.ravel(), dtype=np.float64)

    def _solve_one(self, b):
        count = [0]
        x, info = spla.cg(self._A, b, rtol=self.tol, atol=0.0, maxiter=self.maxiter, M=self._M,
                          callback=lambda _: count.__setitem__(0, count[0] + 1))
        self.iterations.append(count[0])
        if info != 0 or not np.all(np.isfinite(x)):
            residual = np.linalg.norm(b - self._A @ x) / max(np.linalg.norm(b), np.finfo(float).tiny)
            raise SolverError(f"cg solver: no convergence to tol={self.tol:g} after {count[0]} iterations "
                              f"(relative residual {residual:.3g}; is the matrix SPD?)")
        return x
