"""Sparse linear solvers behind one interface: ``factorize(A)`` once, ``solve(b)`` many.

>>> solver = make_solver("direct")
>>> solver.factorize(A)        # A: (n, n) scipy.sparse
>>> x = solver.solve(b)        # b: (n,) or (n, m)
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.errors import ConfigError, SolverError


class Solver:
    """Interface: ``factorize(A)`` stores what repeated solves with ``A`` need."""

    name = "base"

    def factorize(self, A) -> "Solver":
        raise NotImplementedError

    def solve(self, b: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class DirectSolver(Solver):
    """scipy SuperLU: one LU factorization of ``A`` reused by every ``solve``."""

    name = "direct"

    def __init__(self, permc_spec: str = "COLAMD"):
        self.permc_spec = permc_spec
        self._lu = None

    def factorize(self, A) -> "DirectSolver":
        A = sp.csc_matrix(A, dtype=np.float64)
        try:
            self._lu = spla.splu(A, permc_spec=self.permc_spec)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SolverError(f"direct solver: cannot factorize the {A.shape} matrix: {exc}") from exc
        return self

    def solve(self, b: np.ndarray) -> np.ndarray:
        if self._lu is None:
            raise SolverError("solve() called before factorize()")
        b = np.asarray(b, dtype=np.float64)
        return self._lu.solve(b)


SOLVERS = {"direct": DirectSolver}


def make_solver(name: str = "direct", **options) -> Solver:
    """Return a solver by name (``direct`` | ``cg`` | ``amg`` | ``pardiso``)."""
    try:
        cls = SOLVERS[name]
    except KeyError:
        raise ConfigError(f"solver.name: unknown solver {name!r}; choose one of {sorted(SOLVERS)}") from None
    return cls(**options)
