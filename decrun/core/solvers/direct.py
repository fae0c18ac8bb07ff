"""``solver=direct``: scipy SuperLU, one LU factorization reused by every solve (the default)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.core.solvers.base import Solver
from decrun.errors import SolverError

__all__ = ["DirectSolver"]


@dataclass
class DirectSolver(Solver):
    """scipy SuperLU with column ordering ``permc_spec`` (COLAMD, MMD_AT_PLUS_A, NATURAL, ...)."""

    name = "direct"
    permc_spec: str = "COLAMD"

    def _prepare(self, A) -> None:
        try:
            self._lu = spla.splu(sp.csc_matrix(A), permc_spec=self.permc_spec)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SolverError(f"{self.name} solver: cannot factorize the {A.shape} matrix: {exc}") from exc

    def _solve_block(self, b: np.ndarray) -> np.ndarray:
        x = self._lu.solve(b)
        if not np.all(np.isfinite(x)):
            raise SolverError(f"{self.name} solver: the solution is not finite (matrix numerically singular?)")
        return x
