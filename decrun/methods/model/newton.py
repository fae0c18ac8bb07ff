"""Newton's method for a nonlinear sparse system F(x) = 0, with the caller's exact Jacobian.

One iteration from x_k::

    J(x_k) Δ = −F(x_k)                       a sparse linear solve (``new_solver()``)
    x_{k+1} = x_k + λ Δ,   λ = 1, ½, ¼, …    the first λ with ‖F(x_k + λΔ)‖ ≤ (1 − 10⁻⁴ λ) ‖F(x_k)‖

(damped Newton with a backtracking line search on the Euclidean norm ‖F‖, Armijo's rule). Full
steps are taken as soon as they decrease ‖F‖, so near the root the iteration is Newton's own and
converges quadratically. It stops when

- ‖F(x_k)‖ ≤ atol + rtol ‖F(x_0)‖ (``stopped_by="residual"``), or
- a full Newton step with ‖Δ‖ ≤ ``step_tolerance`` was taken (``"step"``): near the root Newton's
  error after the step is O(‖Δ‖²), far below ‖Δ‖ (simplified Newton's, converging linearly with
  a contraction ≲ ½, is below ‖Δ‖). This is the test for a caller whose F cannot be
  evaluated to a relative accuracy ``rtol`` — a stiff operator times dt whose terms cancel near a
  steady state — and who knows the scale of x (a time stepper: the state's), or
- the Newton step is below round-off, ‖Δ‖ ≤ 8 ε ‖x_k‖ (``"round-off"``): no representable change of
  x lowers ‖F‖; or no damping decreases ‖F‖ (it is at the round-off of evaluating F) while the
  full step is tiny, ‖Δ‖ ≤ √ε ‖x_k‖, with J factorized at x_k: x_k + Δ is then the root to
  working precision (its error O(‖Δ‖²) ≤ ε).

``simplified=True`` is the simplified (chord) Newton method: J is factorized at x_0 and reused,
and refactorized at the current iterate only when a step with the old factorization contracts
‖F‖ by less than ½, or finds no decrease at all (linear convergence, fewer factorizations; one
factorization for a linear F).

Anything else — no decrease along the Newton direction, a singular Jacobian, a residual that is
not finite, ``max_iterations`` reached — is a :class:`NewtonDivergence`: one line naming the
equation (``where``), the last residual norm and the fix (``fix``: the override that helps).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp

from decrun.core.solvers.base import Solver
from decrun.errors import SolverError
from decrun.methods.model.language import ModelError

__all__ = ["NewtonResult", "NewtonDivergence", "newton"]

#: Armijo's sufficient decrease: ‖F(x + λΔ)‖ ≤ (1 − ARMIJO λ) ‖F(x)‖
ARMIJO = 1e-4
#: the smallest damping tried by the line search (λ = 1, ½, …, 2⁻¹⁶)
SMALLEST_DAMPING = 2.0 ** -16
#: simplified Newton refactorizes J when one step contracts ‖F‖ by less than this factor
CHORD_CONTRACTION = 0.5
#: a Newton step with ‖Δ‖ ≤ ROUND_OFF ‖x‖ cannot change x any more
ROUND_OFF = 8 * np.finfo(np.float64).eps
#: a full Newton step with ‖Δ‖ ≤ HALF_PRECISION ‖x‖ leaves an error O(‖Δ‖²), below round-off
HALF_PRECISION = np.sqrt(np.finfo(np.float64).eps)


@dataclass
class NewtonResult:
    """The root ``x`` (n,), the ``iterations`` taken and ‖F(x_k)‖ for k = 0..iterations
    (``residual_norms``); ``factorizations`` of the Jacobian, ``residual_evaluations`` and which
    test stopped the iteration (``stopped_by``: ``residual`` | ``step`` | ``round-off``)."""

    x: np.ndarray
    iterations: int
    residual_norms: list[float] = field(default_factory=list)
    factorizations: int = 0
    residual_evaluations: int = 0
    stopped_by: str = "residual"


class NewtonDivergence(ModelError):
    """Newton's method did not converge: one line naming the equation, the last residual norm
    and the fix. ``where``, ``fix`` and ``residual_norms`` are kept as attributes."""

    where: str = ""
    fix: str = ""
    residual_norms: list[float] = []

    @classmethod
    def of(cls, where: str, fix: str, reason: str, residual_norms: list[float]) -> "NewtonDivergence":
        """The error for equation ``where`` after ``residual_norms`` (‖F(x_0)‖, …, the last)."""
        last, iterations = residual_norms[-1], len(residual_norms) - 1
        error = cls(f"{where}: Newton's method did not converge: {reason} (last residual ‖F‖ = {last:.3e} after "
                    f"{iterations} iterations, initial {residual_norms[0]:.3e}); {fix}")
        error.where, error.fix, error.residual_norms = where, fix, list(residual_norms)
        return error


class _Linearization:
    """J factorized by a fresh solver at the iterate ``at``: the Newton direction Δ = −J(at)⁻¹ F.
    A :class:`NewtonDivergence` when J is singular or not finite."""

    def __init__(self, jacobian: Callable, new_solver: Callable):
        self.jacobian, self.new_solver = jacobian, new_solver
        self.solver: Solver | None = None
        self.at: np.ndarray | None = None
        self.factorizations = 0

    def direction(self, x: np.ndarray, F: np.ndarray, refactorize: bool, failure: Callable) -> np.ndarray:
        """−J⁻¹ F with J factorized at ``x`` when ``refactorize`` (or never yet); ``failure(reason)``
        is the error raised when the solve fails."""
        try:
            solver = self.solver
            if refactorize or solver is None:
                solver = self.solver = self.new_solver()
                solver.factorize(sp.csr_matrix(self.jacobian(x)))
                self.at = x
                self.factorizations += 1
            return -solver.solve(F)
        except SolverError as exc:
            raise failure(f"the linear solve with the Jacobian failed ({exc})") from exc


def _norm(F: np.ndarray) -> float:
    value = float(np.linalg.norm(F))
    return value if np.isfinite(value) else float("inf")


def _line_search(residual: Callable, x: np.ndarray, step: np.ndarray, norm: float, damped: bool):
    """(x + λΔ, F there, ‖F‖ there, evaluations) for the first λ = 1, ½, … with Armijo's
    decrease; λ = 1 unconditionally when not ``damped``; x_new is None when no λ decreases ‖F‖."""
    damping, evaluations = 1.0, 0
    while damping >= SMALLEST_DAMPING:
        trial = x + damping * step
        F = np.asarray(residual(trial), dtype=np.float64)
        evaluations += 1
        trial_norm = _norm(F)
        if not damped or trial_norm <= (1.0 - ARMIJO * damping) * norm:
            return trial, F, trial_norm, evaluations
        damping *= 0.5
    return None, None, norm, evaluations


def newton(residual: Callable[[np.ndarray], np.ndarray], jacobian: Callable[[np.ndarray], sp.csr_matrix],
           x0: np.ndarray, *, new_solver: Callable, where: str, fix: str, rtol: float = 1e-10, atol: float = 1e-12,
           max_iterations: int = 25, simplified: bool = False, line_search: bool = True,
           step_tolerance: float = 0.0) -> NewtonResult:
    """Solve F(x) = 0 from ``x0`` (n,) by damped Newton (module docstring).

    ``residual(x) -> (n,)`` is F, ``jacobian(x) -> csr (n, n)`` its exact derivative ∂F/∂x;
    ``new_solver()`` returns a fresh :mod:`decrun.core.solvers` solver (J is factorized every
    iteration, or once and reused when ``simplified``). ``line_search=False`` takes full steps
    (plain Newton); ``step_tolerance`` (in the units of x) stops after a step that small.
    Raises :class:`NewtonDivergence` naming ``where`` and ``fix``.
    """
    x = np.array(x0, dtype=np.float64)
    F = np.asarray(residual(x), dtype=np.float64)
    norms = [_norm(F)]
    result = NewtonResult(x=x, iterations=0, residual_norms=norms, residual_evaluations=1)

    def failure(reason: str) -> NewtonDivergence:
        return NewtonDivergence.of(where, fix, reason, norms)

    if not np.isfinite(norms[0]):
        raise failure("the residual at the initial guess is not finite")
    tolerance = atol + rtol * norms[0]
    linearization = _Linearization(jacobian, new_solver)
    refactorize = True
    while norms[-1] > tolerance:
        if len(norms) > max_iterations:
            raise failure(f"‖F‖ not below {tolerance:.3e} in {max_iterations} iterations")
        step = linearization.direction(x, F, refactorize, failure)
        size = _norm(step)
        if size <= ROUND_OFF * _norm(x):
            result.stopped_by = "round-off"
            break
        if size <= step_tolerance:  # the root is within ≈ ‖Δ‖ of x: the full step leaves O(‖Δ‖²)
            x_new, F_new, result.stopped_by = x + step, None, "step"
        else:
            x_new, F_new, norm, used = _line_search(residual, x, step, norms[-1], line_search)
            result.residual_evaluations += used
            if x_new is None and linearization.at is not x:
                refactorize = True  # simplified Newton: the old Jacobian's direction failed; refactorize here, retry
                continue
            if x_new is None and size > HALF_PRECISION * _norm(x):
                raise failure("no decrease of ‖F‖ along the Newton direction")
            if x_new is None:  # ‖F‖ is at the round-off of its evaluation: the full step's error is O(‖Δ‖²) ≤ ε
                x_new, result.stopped_by = x + step, "round-off"
            else:
                norms.append(norm)
        if F_new is None:  # a full step taken without the line search: its residual, for the record
            F_new = np.asarray(residual(x_new), dtype=np.float64)
            result.residual_evaluations += 1
            norms.append(_norm(F_new))
        x, F = x_new, F_new
        if not np.isfinite(norms[-1]):
            raise failure("the residual is not finite")
        if result.stopped_by != "residual":
            break
        refactorize = not simplified or norms[-1] > CHORD_CONTRACTION * norms[-2]
    result.x, result.iterations, result.factorizations = x, len(norms) - 1, linearization.factorizations
    return result
