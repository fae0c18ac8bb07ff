"""``solver=pardiso``: Intel MKL PARDISO via pypardiso, the thesis' solver (extra ``decrun[pardiso]``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from decrun.core.solvers.base import Solver
from decrun.errors import ConfigError, SolverError

__all__ = ["PardisoSolver"]


@dataclass
class PardisoSolver(Solver):
    """Analysis + numerical factorization once, forward/backward substitution per solve.
    ``matrix_type``: PARDISO mtype, 11 (real nonsymmetric) or 1 (real structurally symmetric)."""

    name = "pardiso"
    matrix_type: int = 11

    def __post_init__(self):
        super().__post_init__()
        try:
            import pypardiso
        except ImportError:
            raise SolverError("solver=pardiso needs the optional package pypardiso: install it with "
                              "`pip install -e '.[pardiso]'` in the decrun checkout (or `pip install pypardiso`), "
                              "or run with solver=direct") from None
        if self.matrix_type not in (11, 1):
            raise ConfigError(f"solver.matrix_type: only 11 (real nonsymmetric) and 1 (real structurally symmetric) "
                              f"are supported with full matrices, got {self.matrix_type}")
        self._pardiso = pypardiso.PyPardisoSolver(mtype=self.matrix_type)

    def _prepare(self, A) -> None:
        A = sp.csr_matrix(A)
        A.sort_indices()
        self._A = A
        try:
            self._pardiso.factorize(A)
        except Exception as exc:  # PyPardisoError
            raise SolverError(f"pardiso solver: cannot factorize the {A.shape} matrix: {exc}") from exc

    def _solve_block(self, b):
        """x for b (n,) or (n, m) by PARDISO's substitution (the base class checked b's rows
        and the empty system)."""
        try:
            x = self._pardiso.solve(self._A, b)
        except Exception as exc:
            raise SolverError(f"pardiso solver: solve failed: {exc}") from exc
        return np.asarray(x).reshape(b.shape)
