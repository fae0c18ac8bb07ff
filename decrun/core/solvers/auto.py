"""``solver=auto`` (the default): Cholesky (CHOLMOD) for SPD matrices, SuperLU for the rest.

Every system an application factorizes goes through one solver name. A symmetric matrix
with a positive diagonal is factorized by Cholesky (:mod:`decrun.core.solvers.cholmod`,
through the fastest CHOLMOD binding installed: scikit-sparse's supernodal factorization where
it is installed, else the cholespy wheel; ``benchmarks/bench_solvers.py``); an
unsymmetric one, or a symmetric one CHOLMOD finds indefinite, by SuperLU (``solver=direct``).
``method`` tells which one the last ``factorize`` used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.core.solvers.base import Solver
from decrun.core.solvers.cholmod import SYMMETRY_TOL, asymmetry, cholesky_factor, cholesky_solve, installed_backends
from decrun.errors import SolverError

__all__ = ["AutoSolver"]


@dataclass
class AutoSolver(Solver):
    """CHOLMOD where it applies, else SuperLU with column ordering ``permc_spec``."""

    name = "auto"
    permc_spec: str = "COLAMD"

    def __post_init__(self):
        super().__post_init__()
        self.method: str | None = None  # "cholmod" | "superlu" after factorize
        # a platform without any CHOLMOD binding: SuperLU for everything
        self._have_cholmod = bool(installed_backends())

    def _prepare(self, A) -> None:
        self._factor = self._lu = None
        if self._have_cholmod and (A.diagonal() > 0).all() and asymmetry(A) <= SYMMETRY_TOL:
            try:
                self._factor = cholesky_factor(A, self.name)
                self.method = "cholmod"
                return
            except SolverError:  # symmetric but indefinite: LU below
                pass
        try:
            self._lu = spla.splu(sp.csc_matrix(A), permc_spec=self.permc_spec)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SolverError(f"auto solver: cannot factorize the {A.shape} matrix: {exc}") from exc
        self.method = "superlu"

    def _solve_block(self, b: np.ndarray) -> np.ndarray:
        if self._factor is not None:
            return cholesky_solve(self._factor, np.ascontiguousarray(b))
        x = self._lu.solve(b)
        if not np.all(np.isfinite(x)):
            raise SolverError("auto solver: the solution is not finite (matrix numerically singular?)")
        return x
