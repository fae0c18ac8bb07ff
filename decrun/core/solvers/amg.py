"""``solver=amg``: pyamg algebraic multigrid preconditioning a Krylov method (extra ``decrun[amg]``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from decrun.core.solvers.base import Solver, check_tolerance
from decrun.errors import ConfigError, SolverError

__all__ = ["AMGSolver"]

_METHODS = ("smoothed_aggregation", "ruge_stuben")
_ACCELERATORS = ("cg", "gmres", "bicgstab", "none")


@dataclass
class AMGSolver(Solver):
    """The multigrid hierarchy is built once in ``factorize``; each solve runs ``accel``
    (cg by default) preconditioned by one V-cycle to relative tolerance ``tol``."""

    name = "amg"
    needs_spd = True
    tol: float = 1e-10
    maxiter: Optional[int] = None
    method: str = "smoothed_aggregation"
    accel: str = "cg"

    def __post_init__(self):
        super().__post_init__()
        try:
            import pyamg  # noqa: F401
        except ImportError:
            raise SolverError("solver=amg needs the optional package pyamg: install it with "
                              "`pip install -e '.[amg]'` in the decrun checkout (or `pip install pyamg`), "
                              "or run with solver=direct") from None
        check_tolerance(self.tol, self.maxiter)
        if self.method not in _METHODS:
            raise ConfigError(f"solver.method: choose one of {list(_METHODS)}, got {self.method!r}")
        if self.accel not in _ACCELERATORS:
            raise ConfigError(f"solver.accel: choose one of {list(_ACCELERATORS)}, got {self.accel!r}")

    def _prepare(self, A) -> None:
        import warnings

        import pyamg

        build = {"smoothed_aggregation": pyamg.smoothed_aggregation_solver,
                 "ruge_stuben": pyamg.ruge_stuben_solver}[self.method]
        self._A = A
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # pyamg warns "Indefinite preconditioner": make it our error
            try:
                self._ml = build(A)
            except Warning as exc:
                raise SolverError(f"amg solver: {exc} (the matrix is not positive definite)") from None

    def _solve_one(self, b):
        import warnings

        accel = None if self.accel == "none" else self.accel
        residuals: list[float] = []
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                x = self._ml.solve(b, tol=self.tol, maxiter=self.maxiter or 500, accel=accel, residuals=residuals)
            except Warning as exc:
                raise SolverError(f"amg solver: {exc} (the matrix is not positive definite)") from None
        norm_b = max(np.linalg.norm(b), np.finfo(float).tiny)
        residual = np.linalg.norm(b - self._A @ x) / norm_b
        if not np.all(np.isfinite(x)) or residual > 10 * self.tol:
            raise SolverError(f"amg solver: no convergence to tol={self.tol:g} after {len(residuals)} iterations "
                              f"(relative residual {residual:.3g})")
        return x
