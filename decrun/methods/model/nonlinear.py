"""``solve(lhs = rhs)`` with a left side nonlinear in its unknown: Newton's method on the
residual, with the exact sparse Jacobian of the derivative pass.

For the unknown u with free values u_F (the border values of ``fields.u.dirichlet`` stay fixed)

    F(u_F) = lhs(u) − rhs   at the free simplices,      J = ∂lhs/∂u restricted to them,

J from the registry's derivative rules (:mod:`decrun.methods.model.jacobian`: ``−Δu + u³`` gives
⋆0⁻¹ S + diag(3u²)), solved by the damped Newton of :mod:`decrun.methods.model.newton` from the
last solution (the field's initial value, or 0, the first time). The right side must not read
the unknown (it is evaluated once per solve). ``<u>_newton_iterations`` and the residual norms
of the last solve are kept for the run's metrics and series.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from decrun.methods.model.jacobian import derivative
from decrun.methods.model.language import Equation, ModelError, to_text

__all__ = ["NonlinearSolve", "compile_nonlinear_solve"]


@dataclass
class NonlinearSolve:
    """A compiled nonlinear ``solve``: :meth:`solve` gives the unknown's values at an env."""

    equation: Equation
    unknown: str
    residual_closure: Callable[[dict], Any]
    rhs_closure: Callable[[dict], Any]
    jacobian_closure: Callable[[dict], Any]
    size: int
    border: np.ndarray
    border_values: np.ndarray | None
    guess: np.ndarray
    new_solver: Callable | None
    fix: str
    iterations: list[int] = field(default_factory=list)
    residual_norms: list[float] = field(default_factory=list)

    @property
    def free(self) -> np.ndarray:
        return np.setdiff1d(np.arange(self.size), self.border)

    def bind(self, new_solver: Callable) -> None:
        self.new_solver = new_solver

    def solve(self, env: dict) -> np.ndarray:
        """The unknown's values at ``env`` (one Newton solve from the last solution)."""
        from decrun.methods.model.newton import newton

        if self.new_solver is None:  # a solve before bind (the app's checks at t = 0): the default solver, as LinearSystem
            from decrun.core.solvers import solver_factory

            self.new_solver = solver_factory(None)
        free, name = self.free, self.unknown
        local = dict(env)
        right = np.broadcast_to(np.asarray(self.rhs_closure(env), dtype=np.float64), (self.size,))[free]
        full = np.array(self.guess, dtype=np.float64)
        if self.border_values is not None:
            full[self.border] = self.border_values

        def with_free(x):
            values = full.copy()
            values[free] = x
            local[name] = values
            return local

        def residual(x):
            value = np.broadcast_to(np.asarray(self.residual_closure(with_free(x)), dtype=np.float64), (self.size,))
            return value[free] - right

        def jacobian(x):
            return self.jacobian_closure(with_free(x))[free][:, free]

        result = newton(residual, jacobian, full[free], new_solver=self.new_solver, where=self.equation.where,
                        fix=self.fix)
        full[free] = result.x
        self.guess = full
        self.iterations.append(int(result.iterations))
        self.residual_norms = [float(value) for value in result.residual_norms]
        return full.copy()


def compile_nonlinear_solve(equation: Equation, model, new_solver: Callable | None) -> NonlinearSolve:
    """The Newton solve of ``solve(lhs = rhs)`` for ``equation.target`` (module docstring); a
    right side that reads the unknown is refused, naming the term."""
    compiler, key = model.compiler, model.spec.key
    unknown, where = equation.target, equation.where
    if compiler.depends_on(equation.rhs, {unknown}):
        raise ModelError(f"{where}: the right side {to_text(equation.rhs)} reads the unknown {unknown}; move its terms "
                         "to the left side")
    compiler.varying.add(unknown)  # its value changes at every Newton iteration: nothing reading it is cached
    lhs = compiler.inline(equation.lhs)
    size = model.kinds[unknown].size(model.ops.K)
    border, values = model.fixed.get(unknown, (np.zeros(0, dtype=np.int64), None))
    spec = model.spec.fields[unknown]
    guess = np.zeros(size)
    if spec.initial is not None:
        from decrun.methods.model.initial import sample

        guess = sample(spec.initial, model.kinds[unknown], model.ops.dec, f"{key}.fields.{unknown}.initial",
                       constants=model.spec.constants, seed=model.spec.seed, name=unknown)
    fix = (f"start Newton nearer the solution with `{key}.fields.{unknown}.initial=<expression>` (now "
           f"{spec.initial if spec.initial is not None else 0!r})")
    return NonlinearSolve(equation, unknown, compiler.compile(lhs, where), compiler.compile(equation.rhs, where),
                          derivative(compiler, lhs, unknown, where), size, np.asarray(border, dtype=np.int64),
                          values, guess, new_solver, fix)
