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

from decrun.core.solvers.cholmod import SYMMETRY_TOL, asymmetry, cholesky_factor, cholesky_solve, installed_backends
from decrun.core.solvers.direct import DirectSolver
from decrun.errors import SolverError

__all__ = ["AutoSolver"]


@dataclass
class AutoSolver(DirectSolver):
    """CHOLMOD where it applies, else SuperLU with column ordering ``permc_spec`` (``solver=direct``'s)."""

    name = "auto"

    def __post_init__(self):
        super().__post_init__()
        self.method: str | None = None  # "cholmod" | "superlu" after factorize
        # a platform without any CHOLMOD binding: SuperLU for everything
        self._have_cholmod = bool(installed_backends())

    def _prepare(self, A) -> None:
        self._factor = None
        skew = asymmetry(A) if self._have_cholmod and (A.diagonal() > 0).all() else None
        if skew is not None and skew <= SYMMETRY_TOL:
            try:
                self._factor = cholesky_factor(A, self.name, skew=skew)  # measured once, here
                self.method = "cholmod"
                return
            except SolverError:  # symmetric but indefinite: LU below
                pass
        super()._prepare(A)
        self.method = "superlu"

    def _solve_block(self, b: np.ndarray) -> np.ndarray:
        if self._factor is not None:
            return cholesky_solve(self._factor, np.ascontiguousarray(b))
        return super()._solve_block(b)
