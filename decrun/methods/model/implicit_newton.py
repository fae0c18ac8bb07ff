"""Implicit Euler and Crank–Nicolson on a nonlinear model: one Newton solve per step.

Over the compiled model's ``Problem`` (:class:`~decrun.methods.model.problem.ModelProblem`:
M y' = f(y, t) on the free unknowns, the exact sparse Jacobian from the derivative pass), a step
from yⁿ at t to y⁺ at t + dt is the root of

    implicit Euler:   G(y) = M (y − yⁿ) − dt f(y, t + dt)
    Crank–Nicolson:   G(y) = M (y − yⁿ) − dt/2 (f(y, t + dt) + f(yⁿ, t))

with ∂G/∂y = M − θ dt ∂f/∂y (θ = 1, ½), found by the damped Newton of
:mod:`decrun.methods.model.newton` from yⁿ. A model whose every term is linear with constant
coefficients keeps the one factorization of :class:`~decrun.methods.model.integrators.Implicit`;
this stepper takes the others — reactions u v², cosh(u), advection lie(X, u) by a field X that
changes, … — which those schemes refused before.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.mixed import implicit_problem

__all__ = ["NewtonImplicit"]


class NewtonImplicit:
    """``scheme`` (``implicit_euler`` | ``crank_nicolson``) with Newton's method each step."""

    def __init__(self, model, dt: float, scheme: str, new_solver):
        self.model, self.dt, self.scheme, self.new_solver = model, float(dt), scheme, new_solver
        self.problem = problem = implicit_problem(model)  # the mixed form of a Galerkin Laplacian too
        problem.check_jacobian()  # a term without an exact Jacobian is refused now, not at the first step
        self.theta = 0.5 if scheme == "crank_nicolson" else 1.0
        self.mass = problem.mass if problem.mass is not None else sp.identity(problem.size, format="csr")
        self.iterations = 0
        self.steps = 0

    def step(self, state: dict, t: float) -> dict:
        from decrun.methods.model.newton import newton

        problem, dt, theta, M = self.problem, self.dt, self.theta, self.mass
        y0 = problem.free_values(state)
        constant = M @ y0
        if theta < 1.0:
            constant = constant + (1.0 - theta) * dt * problem.f(y0, t)
        later = t + dt

        def residual(y):
            return M @ y - theta * dt * problem.f(y, later) - constant

        def jacobian(y):
            return (M - theta * dt * problem.jacobian(y, later)).tocsr()

        scale = max(float(np.abs(y0).max()) if y0.size else 0.0, 1.0)
        result = newton(residual, jacobian, y0, new_solver=self.new_solver,
                        where=f"app.integrator={self.scheme} (the step from t = {t:.6g})",
                        fix=f"take smaller steps: `app.dt={dt / 4:.6g}`", atol=1e-12 * scale,
                        step_tolerance=1e-13 * scale)
        self.iterations += int(result.iterations)
        self.steps += 1
        return problem.state(result.x)

    def state_dict(self) -> dict:
        return {"newton_iterations": self.iterations, "newton_steps": self.steps}

    def load_state(self, state: dict) -> None:
        self.iterations = int(state.get("newton_iterations", 0))
        self.steps = int(state.get("newton_steps", 0))
