"""``solver=iterative``: a Krylov method chosen to fit the matrix, with a preconditioner.

``method: auto`` inspects the matrix in ``factorize``:

=============================================  ===========================================
matrix                                         method (preconditioner)
=============================================  ===========================================
symmetric, positive diagonal                   CG (Jacobi); GMRES (ILU), then MINRES
                                               (Jacobi), if CG stalls — an indefinite matrix
                                               (negative cot weights)
symmetric, a zero or negative diagonal entry   GMRES (ILU), then MINRES (Jacobi on |diag|,
                                               when no |diagonal| entry is below 1e-8 × the
                                               largest) or BiCGSTAB (ILU): saddle points,
                                               negative ⋆ entries
unsymmetric                                    GMRES (incomplete LU); BiCGSTAB (ILU) if
                                               GMRES stalls
=============================================  ===========================================

MINRES needs a symmetric positive definite preconditioner, hence Jacobi on |diag|; GMRES and
BiCGSTAB take the incomplete LU (``scipy.sparse.linalg.spilu``, built on first use and
shared by both; a solve that needs more than ``ILU_SLOW`` iterations with it makes the next
solves use one with a 1000× smaller drop tolerance, down to a complete LU). MINRES +
Jacobi converged on the indefinite systems, but slowly: 1,400 iterations per solve of the
coexact system of ``app=hodge mesh=torus mesh.noise=0.05 operator=circumcentric`` (85 s of
solves against 0.55 s direct), where GMRES + ILU takes a few.

A method with a fallback gets a budget of ``max(200, 10 √n)`` iterations per solve (all
refinement rounds together): past it the solve fails over to the next method, which then
leads every later solve with this matrix (measured before: MINRES ran 19,998 iterations on
a circumcentric bunny before GMRES finished in 6). Every solve is followed by iterative
refinement on the true residual until the normwise backward error ``‖b − A x‖ / (‖A‖ ‖x‖ +
‖b‖) ≤ tol`` (Krylov methods stop on an estimate), and a solve that does not get there with
any method raises :class:`SolverError` naming the methods and their errors.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.core.choices import Choice
from decrun.core.solvers.base import Solver, backward_error, check_tolerance, norm_bound
from decrun.errors import ConfigError, SolverError

__all__ = ["KrylovSolver", "KrylovMethod", "KrylovPreconditioner", "choose_method"]

class KrylovMethod(Choice):
    """``solver.method`` of iterative: ``auto`` (chosen to fit the matrix, :func:`choose_method`)
    or one Krylov method."""

    auto = "auto"
    cg = "cg"
    minres = "minres"
    gmres = "gmres"
    bicgstab = "bicgstab"


class KrylovPreconditioner(Choice):
    """``solver.preconditioner`` of iterative: ``auto`` (Jacobi for cg/minres, ILU for
    gmres/bicgstab), ``jacobi``, ``ilu`` or ``none``."""

    auto = "auto"
    jacobi = "jacobi"
    ilu = "ilu"
    none = "none"


def is_symmetric(A: sp.csr_matrix, rtol: float = 1e-12) -> bool:
    """max |A − Aᵀ| ≤ rtol · max |A| (a sparse, exact-pattern check)."""
    scale = float(np.abs(A.data).max()) if A.nnz else 0.0
    difference = (A - A.T).tocsr()
    return difference.nnz == 0 or float(np.abs(difference.data).max()) <= rtol * scale


def choose_method(A: sp.csr_matrix) -> list[tuple[str, str]]:
    """The (method, preconditioner) pairs ``method: auto`` tries on ``A``, first choice first."""
    diagonal = A.diagonal()
    if is_symmetric(A):
        if np.all(diagonal > 0):
            return [("cg", "jacobi"), ("gmres", "ilu"), ("minres", "jacobi")]
        magnitude = np.abs(diagonal)
        if magnitude.min() > 1e-8 * magnitude.max():  # Jacobi on |diag| means something
            return [("gmres", "ilu"), ("minres", "jacobi")]
        return [("gmres", "ilu"), ("bicgstab", "ilu")]
    return [("gmres", "ilu"), ("bicgstab", "ilu")]


# An incomplete LU with which a solve needs more than ILU_SLOW iterations (x = M b counts one)
# is rebuilt ILU_TIGHTEN × tighter for the next solves (and the same solve is retried with it
# once the budget ran out): on the shifted singular coexact system of ``app=hodge mesh=torus
# mesh.noise=0.05 operator=circumcentric`` GMRES took 43 iterations per solve with drop_tol
# 1e-5, 2 with 1e-8, and x = M b alone meets tol with drop_tol 0; eigsh's shift-invert runs
# 510 solves there, so a rebuild pays.
ILU_SLOW = 3
ILU_TIGHTEN = 1e3


def iteration_budget(n: int) -> int:
    """Iterations a method with a fallback may spend on one solve of an (n, n) system:
    max(200, 10 √n) — CG + Jacobi on the apps' SPD Laplacians needs ~2.5 √n (measured: 177
    on n = 512 per refined solve), a stalling method would run to maxiter."""
    return max(200, int(10 * np.sqrt(n)))


@dataclass
class KrylovSolver(Solver):
    """Krylov iterations to the relative residual ``tol``; ``method`` auto | cg | minres |
    gmres | bicgstab, ``preconditioner`` auto | jacobi | ilu | none (auto: Jacobi for
    cg/minres — on |diag| for minres, 1 where the diagonal is 0 — ILU for gmres/bicgstab), ``restart`` of GMRES, ``ilu_drop_tol`` /
    ``ilu_fill_factor`` of the incomplete LU, ``refinements`` rounds on the true residual.
    ``methods_used`` / ``iterations`` record what each solve ran."""

    name = "iterative"
    tol: float = 1e-14
    maxiter: Optional[int] = None
    method: KrylovMethod = KrylovMethod.auto
    preconditioner: KrylovPreconditioner = KrylovPreconditioner.auto
    restart: int = 50
    ilu_drop_tol: float = 1e-5
    ilu_fill_factor: float = 20.0
    refinements: int = 5

    def __post_init__(self):
        super().__post_init__()
        check_tolerance(self.tol, self.maxiter)
        self.method = KrylovMethod.of(self.method, "solver.method")  # also for Python callers (strings)
        self.preconditioner = KrylovPreconditioner.of(self.preconditioner, "solver.preconditioner")
        if self.preconditioner == "ilu" and self.method in ("cg", "minres"):
            raise ConfigError(f"solver.preconditioner=ilu: solver.method={self.method} needs a symmetric positive "
                              "definite preconditioner; use `solver.preconditioner=jacobi`")
        if self.restart < 1 or self.refinements < 0:
            raise ConfigError(f"solver.restart must be >= 1 and solver.refinements >= 0, got "
                              f"{self.restart} and {self.refinements}")
        self.iterations: list[int] = []
        self.methods_used: list[str] = []
        self.ilu_drop_tols_used: list[float] = []  # the tightened drop tolerances, in order

    # ------------------------------------------------------------------ preparation
    def _prepare(self, A) -> None:
        self._A = A
        self._norm_A = norm_bound(A)
        if self.method == "auto":
            plan = choose_method(A)
        else:
            default = "ilu" if self.method in ("gmres", "bicgstab") else "jacobi"
            plan = [(str(self.method), default)]
        if self.preconditioner != "auto":
            plan = [(method, str(self.preconditioner)) for method, _ in plan]
        self._plan = list(plan)
        self._built: dict = {}  # key → preconditioner, built on first use (one ILU for gmres and bicgstab)
        self._drop_tol = self.ilu_drop_tol  # tightened by _tighten_ilu when the ILU is too coarse

    def _preconditioner_for(self, method: str, kind: str):
        key = ("ilu", self._drop_tol) if kind == "ilu" and method not in ("cg", "minres") else (method, kind)
        if key not in self._built:
            self._built[key] = self._preconditioner(self._A, method, kind)
        return self._built[key]

    def _tighten_ilu(self) -> bool:
        """The next incomplete LU drops ILU_TIGHTEN × fewer entries (below 1e-12: none, a complete
        LU within ``ilu_fill_factor``); False when it already drops none."""
        if self._drop_tol == 0.0:
            return False
        self._built.pop(("ilu", self._drop_tol), None)
        self._drop_tol = self._drop_tol / ILU_TIGHTEN if self._drop_tol / ILU_TIGHTEN >= 1e-12 else 0.0
        self.ilu_drop_tols_used.append(self._drop_tol)
        return True

    def _preconditioner(self, A, method: str, kind: str):
        if kind == "none":
            return None
        if kind == "jacobi":
            diagonal = np.abs(A.diagonal()) if method == "minres" else A.diagonal()
            inverse = np.divide(1.0, diagonal, out=np.ones_like(diagonal), where=diagonal != 0)  # 1 on a zero diagonal
            return spla.LinearOperator(A.shape, matvec=lambda x: inverse * x.ravel(), dtype=np.float64)
        if method in ("cg", "minres"):  # method=auto on a symmetric matrix with preconditioner=ilu
            raise ConfigError(f"solver.preconditioner=ilu: {method} (chosen for this symmetric matrix) needs a "
                              "symmetric positive definite preconditioner; use `solver.preconditioner=jacobi`")
        try:
            ilu = spla.spilu(sp.csc_matrix(A), drop_tol=self._drop_tol, fill_factor=self.ilu_fill_factor)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SolverError(f"iterative solver: incomplete LU of the {A.shape} matrix failed ({exc}); "
                              "use `solver=direct`") from None
        return spla.LinearOperator(A.shape, matvec=ilu.solve, dtype=np.float64)

    # ------------------------------------------------------------------ solves
    def _krylov(self, method: str, M, b: np.ndarray, atol: float, count: list, good_enough=None,
                maxiter: int | None = None) -> np.ndarray:
        """One Krylov run on A x = b from x = 0, to ‖b − A x‖ ≤ atol (the method's estimate).

        GMRES runs one restart cycle at a time and stops early once ``good_enough(x)``: on a
        shifted singular system the attainable residual is ~ u ‖A‖ ‖x‖, far above an atol set
        from ‖b‖ alone, and without the check every cycle up to maxiter would run (measured:
        4,755 iterations where 6 had reached the backward error)."""
        callback = lambda _: count.__setitem__(0, count[0] + 1)  # noqa: E731
        maxiter = maxiter or self.maxiter or max(1000, 2 * b.size)
        if method == "cg":
            x, _ = spla.cg(self._A, b, rtol=0.0, atol=atol, maxiter=maxiter, M=M, callback=callback)
        elif method == "minres":  # no atol: its rtol is relative to ‖b‖
            x, _ = spla.minres(self._A, b, rtol=atol / float(np.linalg.norm(b)), maxiter=maxiter, M=M,
                               callback=callback)
        elif method == "gmres":
            x = np.zeros_like(b)
            for _ in range(max(1, maxiter // self.restart)):
                x, info = spla.gmres(self._A, b, x0=x, rtol=0.0, atol=atol, restart=self.restart, maxiter=1, M=M,
                                     callback=callback, callback_type="pr_norm")
                if info == 0 or (good_enough is not None and good_enough(x)):
                    break
        else:
            x, _ = spla.bicgstab(self._A, b, rtol=0.0, atol=atol, maxiter=maxiter, M=M, callback=callback)
        return x

    def _solve_one(self, b):
        """Krylov runs with iterative refinement until the normwise backward error
        ‖b − A x‖ / (‖A‖ ‖x‖ + ‖b‖) ≤ tol (Rigal–Gaches; ‖A‖ ≤ √(‖A‖₁ ‖A‖∞) bounds the 2-norm):
        the accuracy a backward-stable direct solve reaches, so a tolerance near round-off is
        met on ill-conditioned (shifted singular) systems too."""
        norm_b = float(np.linalg.norm(b))
        if norm_b == 0.0:
            self.iterations.append(0)
            self.methods_used.append("none")
            return np.zeros_like(b)
        tried = []
        for index, (method, kind) in enumerate(list(self._plan)):
            last = index == len(self._plan) - 1
            while True:
                x, error, count = self._attempt(method, kind, b, norm_b, last, tried)
                if x is not None or kind != "ilu" or not self._tighten_ilu():
                    break  # solved, or nothing to tighten: the next method
            if x is None:
                continue
            self.iterations.append(count)
            self.methods_used.append(method)
            if kind == "ilu" and count > ILU_SLOW:  # slow with this ILU: the next solves get a tighter one
                self._tighten_ilu()
            if index:  # the methods before it failed: this one leads the next solves
                self._plan.insert(0, self._plan.pop(index))
            return x
        raise SolverError(f"iterative solver: no convergence to tol={self.tol:g} ({'; '.join(tried)}); "
                          "use `solver=direct`")

    def _attempt(self, method: str, kind: str, b: np.ndarray, norm_b: float, last: bool, tried: list):
        """One method's Krylov runs with refinement on ``b``: (x, backward error, iterations),
        x None when it did not reach ``tol`` (the reason appended to ``tried``)."""
        try:
            M = self._preconditioner_for(method, kind)
        except SolverError as exc:  # an incomplete LU that fails: the next method, if any
            if last:
                raise
            tried.append(f"{method}: {exc}")
            return None, np.inf, 0
        # a method with a fallback gets a budget; the last one runs to maxiter
        budget = None if last else min(self.maxiter or np.inf, iteration_budget(b.size))
        count = [0]
        x = np.zeros_like(b)
        residual, error = b, np.inf
        if kind == "ilu":  # x = M b first: once the ILU is tight it alone meets tol (one apply, no Krylov run)
            x, count[0] = M.matvec(b), 1
            residual = b - self._A @ x
            error = backward_error(residual, x, b, self._norm_A)
            if error <= self.tol and np.all(np.isfinite(x)):
                return x, error, count[0]
            if not np.isfinite(error) or error >= 1.0:  # no better than x = 0
                x, residual, error = np.zeros_like(b), b, np.inf
        for _ in range(self.refinements + 1):
            if budget is not None and count[0] >= budget:
                break
            scale = self._norm_A * float(np.linalg.norm(x)) + norm_b
            # each round reduces the residual at least 100-fold (else a refinement round
            # whose residual already meets tol · scale would return x = 0 and stall)
            target = min(self.tol * scale, 0.01 * float(np.linalg.norm(residual)))
            def good_enough(dx, start=x):  # the whole solve's backward error, not this round's
                candidate = start + dx
                return backward_error(b - self._A @ candidate, candidate, b, self._norm_A) <= self.tol

            # a breakdown (a singular or inconsistent system) divides by zero inside the Krylov
            # method: its non-finite x is refused below, not printed as a numpy warning
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                x = x + self._krylov(method, M, residual, target, count, good_enough=good_enough,
                                     maxiter=None if budget is None else int(budget - count[0]))
            residual = b - self._A @ x
            previous, error = error, backward_error(residual, x, b, self._norm_A)
            if not np.isfinite(error) or error <= self.tol or error > 0.9 * previous:
                break  # converged, diverged or no longer improving
        if np.isfinite(error) and error <= self.tol and np.all(np.isfinite(x)):
            return x, error, count[0]
        tried.append(f"{method}: backward error {error:.3g} after {count[0]} iterations")
        return None, error, count[0]
