"""The steppers of moving Dirichlet values g(t) that are not Runge–Kutta tableaux (issue #47,
item 4): Störmer–Verlet, the lagged-coefficient semi-implicit Euler and SciPy's ``solve_ivp``,
each on the system condensed at the border values, M_FF y' = f_F(y, t) − M_FD ∂g/∂t
(:class:`~decrun.methods.model.borders.MovingProblem`; F the free values, D the border ones).

``symplectic``
    :class:`MovingSymplectic`: kick p by dt/2 at t, drift q by dt at t + dt/2, kick p by dt/2 at
    t + dt (the groups of :class:`~decrun.methods.model.integrators.Symplectic`). After each
    substep a moving field's border values are set to g at the time that substep reaches (q's
    at t + dt after the drift; p's at t + dt/2, then t + dt), so every evaluation reads the
    border values of its own time. A row whose mass is not diagonal (Whitney's ⋆0) takes the
    coupling − M_FD ∂g/∂t over the substep as − M_FD (g(end) − g(start)), its exact integral:
    M_FF Δy_F + M_FD Δg = τ W_F, the condensed M Δu = τ W. The border terms only shift each
    kick and drift, so the map of the free values stays a composition of shears (symplectic);
    second order in time.
``semi_implicit``
    :class:`MovingSemiImplicit`: (M − dt A(uⁿ)) u⁺ = M uⁿ + dt M R(uⁿ, tⁿ) with u⁺ = g(tⁿ⁺¹) on
    the border and uⁿ = g(tⁿ) there: the free rows hold M_FD (g(tⁿ⁺¹) − g(tⁿ)), implicit Euler's
    − dt M_FD ∂g/∂t. First order in time.
``bdf``, ``radau``, ``rk45``
    :class:`MovingSciPy`: y' = M_FF⁻¹ (f_F(y, t) − M_FD ∂g/∂t), M_FF divided by when diagonal and
    factorized once (``new_solver``) otherwise. The Jacobian as the fixed-border path
    (:class:`~decrun.methods.model.integrators.Adaptive`) takes it: the exact sparse M_FF⁻¹ ∂f/∂y
    for a diagonal mass whose terms all have derivative rules; for a Galerkin mass (M_FF⁻¹ dense,
    never formed) M_L⁻¹ ∂f/∂y with the lumped M_FF
    (:func:`~decrun.methods.model.lumped_jacobian.lumped_jacobian`); else finite differences on the
    sparsity pattern of the equations (:func:`~decrun.methods.model.integrators.jacobian_pattern`,
    restricted to the free values).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.adaptive_jacobian import exact_jacobian
from decrun.methods.model.integrators import SemiImplicit, SolveIVP, Symplectic, jacobian_pattern
from decrun.methods.model.lumped_jacobian import lumped_jacobian
from decrun.methods.model.runge_kutta import MassMatrix

__all__ = ["MovingSymplectic", "MovingSemiImplicit", "MovingSciPy"]


def _diagonal(M) -> bool:
    return (M - sp.diags(M.diagonal())).count_nonzero() == 0


class MovingSymplectic:
    """Störmer–Verlet for pairs dt(q) = f(p), dt(p) = g(q) whose fields may have border values
    g(t) (module docstring). ``expressions``: field → its moving border expression (a
    :class:`~decrun.methods.model.borders.BorderExpression`); ``new_solver()`` factorizes M_II of
    each moving field whose row mass is not diagonal, once."""

    def __init__(self, model, dt: float, expressions: dict, new_solver: Callable):
        pairs = Symplectic(model, dt)  # the groups q, p (and the refusal of a model that is not pairs)
        self.model, self.dt, self.q, self.p = model, float(dt), pairs.q, pairs.p
        points = model.ops.K.vertices
        #: field → (border indices, border points, expression)
        self.moving = {u: (model.fixed[u][0], points[model.fixed[u][0]], g) for u, g in expressions.items()}
        #: field → (interior indices, M_IB, solve with M_II) where the row mass is not diagonal
        self.coupling = {}
        for u, (border, _, _) in self.moving.items():
            M = sp.csr_matrix(model.evolution.mass[u])
            if _diagonal(M):
                continue
            inner = np.setdiff1d(np.arange(M.shape[0]), border)
            solver = new_solver()
            solver.factorize(M[inner][:, inner].tocsc())
            self.coupling[u] = (inner, M[inner][:, border].tocsr(), solver.solve)

    def _advance(self, state: dict, names: list, at: float, start: float, end: float) -> None:
        """``names`` from ``start`` to ``end`` with their derivative at time ``at`` (in place)."""
        model = self.model
        derivative = model.derivative(model.environment(state, at), names)
        for u in names:
            value = state[u] + (end - start) * derivative[u]
            if u in self.moving:
                border, points, g = self.moving[u]
                after = g.at(points, end)
                if u in self.coupling:
                    inner, coupling, solve = self.coupling[u]
                    value[inner] -= solve(coupling @ (after - g.at(points, start)))
                value[border] = after
            state[u] = value

    def step(self, state: dict, t: float) -> dict:
        """One kick–drift–kick step from t to t + dt."""
        dt, state = self.dt, dict(state)
        self._advance(state, self.p, t, t, t + 0.5 * dt)
        self._advance(state, self.q, t + 0.5 * dt, t, t + dt)
        self._advance(state, self.p, t + dt, t + 0.5 * dt, t + dt)
        for u, (border, values) in self.model.fixed.items():
            if u in state and u not in self.moving:
                state[u][border] = values
        return state

    def state_dict(self) -> dict:
        return {}

    def load_state(self, state: dict) -> None:
        pass


class MovingSemiImplicit(SemiImplicit):
    """:class:`~decrun.methods.model.integrators.SemiImplicit` with the border values of
    ``problem`` (a :class:`~decrun.methods.model.borders.MovingProblem`) at tⁿ⁺¹ in each step's
    solve and in the state it returns (module docstring)."""

    def __init__(self, model, dt: float, new_solver: Callable, problem):
        super().__init__(model, dt, new_solver)
        self.problem = problem

    def step(self, state: dict, t: float) -> dict:
        """uⁿ (border values g(t)) → u⁺ (border values g(t + dt))."""
        self.fixed_values = self.problem.values(t + self.dt)
        out = super().step(state, t)
        evolution = self.problem.evolution
        stacked = evolution.stack(out)
        stacked[self.problem.fixed_index] = self.fixed_values
        return evolution.unstack(stacked)


class MovingSciPy:
    """:class:`~decrun.methods.model.integrators.SolveIVP` (BDF, Radau, RK45) stepping the free
    values y by ``dt`` on y' = M_FF⁻¹ f(y, t) of a :class:`~decrun.methods.model.borders.MovingProblem`
    (module docstring); its counters and last step are the state."""

    def __init__(self, model, problem, scheme: str, dt: float, rtol: float, atol: float, new_solver: Callable):
        self.problem, self.dt = problem, float(dt)
        self.mass = MassMatrix(problem.mass, problem.size, new_solver)
        diagonal = problem.mass is None or _diagonal(problem.mass)
        self.inverse = None if problem.mass is None or not diagonal else 1.0 / problem.mass.diagonal()
        #: jac(t, y) for solve_ivp, or None (the pattern, or no Jacobian)
        self.exact: Callable[[float, np.ndarray], sp.csc_matrix] | None = None
        self.pattern = None
        if scheme in ("bdf", "radau"):
            if diagonal and exact_jacobian(model) is not None:
                self.exact = self._jacobian
            elif (lumped := lumped_jacobian(problem)) is not None:  # a Galerkin mass: M_L⁻¹ ∂f/∂y
                self.exact = lumped
            else:
                free = problem.free
                self.pattern = jacobian_pattern(model)[free][:, free].tocsr()
        self.ivp = SolveIVP(scheme, rtol, atol, self.exact, self.pattern)

    def _jacobian(self, time: float, y: np.ndarray) -> sp.csc_matrix:
        J = self.problem.jacobian(y, time)
        return sp.csc_matrix(J if self.inverse is None else sp.diags(self.inverse) @ J)

    def step(self, y: np.ndarray, t: float) -> np.ndarray:
        """The free values y at t → at t + dt (SciPy's own steps in between)."""
        return self.ivp.advance(lambda time, v: self.mass.solve(self.problem.f(v, time)), y, t, self.dt)

    def state_dict(self) -> dict:
        return self.ivp.state_dict()

    def load_state(self, state: dict) -> None:
        self.ivp.load_state(state)
