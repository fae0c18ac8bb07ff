"""``solver=amg``: pyamg algebraic multigrid preconditioning a Krylov method (extra ``decrun[amg]``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from decrun.core.choices import Choice
from decrun.core.solvers.base import Solver, backward_error, check_tolerance, norm_bound
from decrun.errors import SolverError

__all__ = ["AMGSolver"]

#: numpy's global seed while pyamg builds a hierarchy (its setup draws random start vectors)
SETUP_SEED = 0


class AMGMethod(Choice):
    """``solver.method`` of amg: pyamg's hierarchy builders."""

    smoothed_aggregation = "smoothed_aggregation"
    ruge_stuben = "ruge_stuben"


class Accelerator(Choice):
    """``solver.accel`` of amg: the Krylov method preconditioned by a V-cycle (``none``: V-cycles alone)."""

    cg = "cg"
    gmres = "gmres"
    bicgstab = "bicgstab"
    none = "none"


@dataclass
class AMGSolver(Solver):
    """The multigrid hierarchy is built once in ``factorize``; each solve runs ``accel``
    (cg by default) preconditioned by one V-cycle to relative tolerance ``tol``; a solve that
    does not get there is accepted when its normwise backward error ‖b − A x‖ / (‖A‖ ‖x‖ + ‖b‖)
    is below ``tol`` (else SolverError): a shifted singular system
    (:class:`decrun.core.solvers.SingularSolve`'s refinement rounds) whose right-hand side has
    a component along the kernel has a solution ~ 1/shift larger than b, and a residual
    relative to ‖b‖ alone that no iteration reaches (such a solve failed after 500 iterations;
    the refinement around it checks the true residual). The hierarchy is built under
    :data:`SETUP_SEED` (numpy's global random state, which pyamg's setup draws from, is restored after):
    a run's solves do not depend on what drew random numbers before it."""

    name = "amg"
    needs_spd = True
    tol: float = 1e-10
    maxiter: Optional[int] = None
    method: AMGMethod = AMGMethod.smoothed_aggregation
    accel: Accelerator = Accelerator.cg

    def __post_init__(self):
        super().__post_init__()
        try:
            import pyamg  # noqa: F401
        except ImportError:
            raise SolverError("solver=amg needs the optional package pyamg: install it with "
                              "`pip install -e '.[amg]'` in the decrun checkout (or `pip install pyamg`), "
                              "or run with solver=direct") from None
        check_tolerance(self.tol, self.maxiter)
        self.method = AMGMethod.of(self.method, "solver.method")
        self.accel = Accelerator.of(self.accel, "solver.accel")

    def _prepare(self, A) -> None:
        import warnings

        import pyamg

        build = {"smoothed_aggregation": pyamg.smoothed_aggregation_solver,
                 "ruge_stuben": pyamg.ruge_stuben_solver}[self.method]
        self._A = A
        self._norm_A = norm_bound(A)
        # pyamg's setup estimates spectral radii (the prolongation smoother's weight) by Arnoldi
        # from np.random's global state: the same hierarchy for the same A only under a fixed
        # seed, set here and the caller's random state given back
        state = np.random.get_state()
        np.random.seed(SETUP_SEED)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # pyamg warns "Indefinite preconditioner": make it our error
            try:
                self._ml = build(A)
            except Warning as exc:
                raise SolverError(f"amg solver: {exc} (the matrix is not positive definite)") from None
            finally:
                np.random.set_state(state)

    def _solve_one(self, b):
        import warnings

        accel = None if self.accel == Accelerator.none else str(self.accel)  # pyamg takes the plain name
        residuals: list[float] = []
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                x = self._ml.solve(b, tol=self.tol, maxiter=self.maxiter or 500, accel=accel, residuals=residuals)
            except Warning as exc:
                raise SolverError(f"amg solver: {exc} (the matrix is not positive definite)") from None
        x = np.asarray(x, dtype=np.float64).reshape(b.shape)
        r = b - self._A @ x
        relative = float(np.linalg.norm(r)) / max(float(np.linalg.norm(b)), np.finfo(float).tiny)
        error = backward_error(r, x, b, self._norm_A)
        if not np.all(np.isfinite(x)) or (relative > 10 * self.tol and error > self.tol):
            raise SolverError(f"amg solver: no convergence to tol={self.tol:g} after {len(residuals)} "
                              f"iterations (relative residual {relative:.3g}, backward error {error:.3g})")
        return x
