"""Runge–Kutta steppers of M y' = f(y, t) from their tableaux, one generic stepper per family.

The compiled model presents its evolution as a :class:`Problem` over one stacked vector y (n,)
(borders condensed out); a :class:`~decrun.methods.model.tableaux.Tableau` says the method.

- :class:`ExplicitRungeKutta` (explicit A; needs only f)::

      M K_i = f(y + dt Σ_{j<i} a_ij K_j, t + c_i dt),   y⁺ = y + dt Σ_i b_i K_i

  M is factorized once (a diagonal M is divided by, the identity skipped).
- :class:`ImplicitRungeKutta` (any A: Gauss, Radau IIA, implicit Euler, Crank–Nicolson; needs the
  exact Jacobian J = ∂f/∂y): the s·n stage equations in the stage derivatives K (s, n)::

      G_i(K) = M K_i − f(Y_i, t + c_i dt) = 0,   Y_i = y + dt Σ_j a_ij K_j

  solved by :func:`~decrun.methods.model.newton.newton` from K = 0 with the exact Jacobian
  ∂G/∂K = I⊗M − dt blockdiag(J(Y_1), …, J(Y_s)) (A⊗I) (= I⊗M − dt A⊗J for a linear f). One
  solver serves every step: a matrix equal to the last one it factorized is not factorized
  again, so a linear problem factorizes I⊗M − dt A⊗J once per dt.
- :class:`AdditiveRungeKutta` (an IMEX pair; needs the split f = L y + g, L constant): stage by
  stage, L implicit and g explicit::

      (M − dt a_ii L) Y_i = M y + dt Σ_{j<i} (â_ij g(Y_j, t + c_j dt) + a_ij L Y_j)
      M y⁺ = M y + dt Σ_i (b̂_i g(Y_i, t + c_i dt) + b_i L Y_i)

  (â, b̂ the explicit tableau), one factorization of M − dt γ L per distinct diagonal γ, made
  once and reused by every step.

Each is made as ``make(problem, dt, new_solver)`` and has ``step(y, t) -> y⁺``, ``state_dict()``
and ``load_state(state)``: the state holds the counters (the steps read nothing else), so a run
resumed from a checkpoint repeats the uninterrupted run's steps bit for bit. :data:`INTEGRATORS`
registers them by name (:class:`IntegratorEntry`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Any, Callable, Protocol

import numpy as np
import scipy.sparse as sp

from decrun.core.choices import Choice
from decrun.methods.model.language import ModelError
from decrun.methods.model.newton import NewtonResult, newton
from decrun.methods.model.tableaux import ARK_IMEX, GAUSS_LEGENDRE, RADAU_IIA, SSPRK3, Tableau

__all__ = ["Problem", "Stepper", "Needs", "IntegratorEntry", "INTEGRATORS", "MassMatrix", "ExplicitRungeKutta",
           "ImplicitRungeKutta", "AdditiveRungeKutta", "tableau_entry"]


class Problem(Protocol):
    """M y' = f(y, t) over y (n,): ``mass`` M (n, n) SPD or None (the identity), ``stiff`` L (n, n)
    the part of f linear with constant coefficients (f = L y + g(y, t)) or None."""

    size: int
    mass: sp.csr_matrix | None
    stiff: sp.csr_matrix | None

    def f(self, y: np.ndarray, t: float) -> np.ndarray:
        """The whole right side f(y, t), (n,)."""

    def jacobian(self, y: np.ndarray, t: float) -> sp.csr_matrix:
        """The exact ∂f/∂y at (y, t), csr (n, n)."""

    def nonstiff(self, y: np.ndarray, t: float) -> np.ndarray:
        """g(y, t) = f(y, t) − L y, (n,)."""


class Stepper(Protocol):
    """One step of fixed length dt, and the state a later step reads."""

    def step(self, y: np.ndarray, t: float) -> np.ndarray:
        """y(t + dt) from y(t), (n,)."""

    def state_dict(self) -> dict[str, Any]:
        """Everything a later step reads (counters), as Python scalars."""

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore a :meth:`state_dict`."""


class Needs(Choice):
    """What an integrator needs from the :class:`Problem`: only f, its exact Jacobian, or the
    split f = L y + g."""

    explicit = "explicit"
    jacobian = "jacobian"
    stiff_split = "stiff_split"


@dataclass(frozen=True)
class IntegratorEntry:
    """An integrator by ``name``: ``factory(problem, dt, new_solver) -> Stepper``, what it ``needs``
    from the problem, its ``order`` and its ``tableau`` (None for one that is not a Runge–Kutta method)."""

    name: str
    factory: Callable[..., Stepper]
    needs: Needs
    order: int
    tableau: Tableau | None = None


class MassMatrix:
    """M (n, n) or the identity (None): products M v and solves M⁻¹ v for v (n,) or (n, m); a
    diagonal M is divided by, any other is factorized once by ``new_solver()``."""

    def __init__(self, mass: sp.spmatrix | None, size: int, new_solver: Callable):
        self.matrix = sp.identity(size, format="csr") if mass is None else sp.csr_matrix(mass)
        self.identity = mass is None
        diagonal = self.matrix.diagonal()
        if (self.matrix - sp.diags(diagonal)).count_nonzero() == 0:
            self._solve: Callable[[np.ndarray], np.ndarray] = \
                lambda v: v / (diagonal if v.ndim == 1 else diagonal[:, None])
        else:
            solver = new_solver()
            solver.factorize(self.matrix)
            self._solve = solver.solve

    def apply(self, v: np.ndarray) -> np.ndarray:
        """M v."""
        return v if self.identity else self.matrix @ v

    def solve(self, v: np.ndarray) -> np.ndarray:
        """M⁻¹ v."""
        return v if self.identity else self._solve(v)


class _Counters:
    """The steps' counters, the whole state of a Runge–Kutta stepper."""

    counters: tuple[str, ...] = ("rhs_evaluations",)

    def state_dict(self) -> dict[str, Any]:
        """The counters (the steps read nothing else)."""
        return {name: int(getattr(self, name)) for name in self.counters}

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore a :meth:`state_dict`."""
        for name in self.counters:
            setattr(self, name, int(state[name]))


class ExplicitRungeKutta(_Counters):
    """An explicit tableau on M y' = f(y, t) (module docstring)."""

    def __init__(self, tableau: Tableau, problem: Problem, dt: float, new_solver: Callable):
        if not tableau.explicit:
            raise ValueError(f"tableau {tableau.name} is not explicit")
        self.tableau, self.problem, self.dt = tableau, problem, float(dt)
        self.mass = MassMatrix(problem.mass, problem.size, new_solver)
        self.rhs_evaluations = 0

    def step(self, y: np.ndarray, t: float) -> np.ndarray:
        """y⁺ = y + dt Σ b_i K_i, M K_i = f(Y_i, t + c_i dt), (n,)."""
        A, b, c, dt = self.tableau.A, self.tableau.b, self.tableau.c, self.dt
        K = np.zeros((self.tableau.stages, len(y)))
        for i in range(self.tableau.stages):
            stage = y + dt * (A[i, :i] @ K[:i]) if i else y
            K[i] = self.mass.solve(self.problem.f(stage, t + c[i] * dt))
        self.rhs_evaluations += self.tableau.stages
        return y + dt * (b @ K)


class ImplicitRungeKutta(_Counters):
    """A fully implicit tableau on M y' = f(y, t): the stage equations by Newton (module docstring).

    ``where`` names the equations in a :class:`~decrun.methods.model.newton.NewtonDivergence`
    and ``fix`` the override that helps (default: halve ``app.dt``); ``rtol``, ``atol`` and
    ``max_iterations`` are Newton's; ``simplified`` reuses one Jacobian factorization while
    Newton contracts fast (:func:`~decrun.methods.model.newton.newton`)."""

    counters = ("rhs_evaluations", "newton_iterations")

    def __init__(self, tableau: Tableau, problem: Problem, dt: float, new_solver: Callable, *,
                 where: str = "app.equations", fix: str | None = None, rtol: float = 1e-12, atol: float = 0.0,
                 max_iterations: int = 25, simplified: bool = False):
        if tableau.additive:
            raise ValueError(f"tableau {tableau.name} is an additive pair: use AdditiveRungeKutta")
        self.tableau, self.problem, self.dt = tableau, problem, float(dt)
        s, n = tableau.stages, problem.size
        mass = sp.identity(n, format="csr") if problem.mass is None else sp.csr_matrix(problem.mass)
        self.stage_mass = sp.kron(sp.identity(s), mass, format="csr")  # I⊗M
        self.coupling = sp.kron(sp.csr_matrix(tableau.A), sp.identity(n), format="csr")  # A⊗I
        self.solver = new_solver()  # reused: an unchanged matrix is not factorized again
        self.where = where
        self.fix = fix if fix is not None else f"halve the time step (app.dt={self.dt / 2:g})"
        self.newton = partial(newton, rtol=rtol, atol=atol, max_iterations=max_iterations, simplified=simplified)
        self.rhs_evaluations = self.newton_iterations = 0
        self.last_newton: NewtonResult | None = None

    @property
    def factorizations(self) -> int:
        """The Jacobians factorized by this process (a linear problem's: one)."""
        return self.solver.factorizations

    def _stages(self, y: np.ndarray, K: np.ndarray) -> np.ndarray:
        """Y = y + dt A K, (s, n) from K (s·n,)."""
        return y[None, :] + self.dt * (self.tableau.A @ K.reshape(self.tableau.stages, -1))

    def step(self, y: np.ndarray, t: float) -> np.ndarray:
        """y⁺ = y + dt Σ b_i K_i with the stage equations G(K) = 0 solved by Newton, (n,)."""
        s, n, dt, c = self.tableau.stages, len(y), self.dt, self.tableau.c
        times = t + c * dt

        def residual(K: np.ndarray) -> np.ndarray:
            Y = self._stages(y, K)
            self.rhs_evaluations += s
            forces = np.concatenate([self.problem.f(Y[i], times[i]) for i in range(s)])
            return self.stage_mass @ K - forces

        def jacobian(K: np.ndarray) -> sp.csr_matrix:
            Y = self._stages(y, K)
            blocks = sp.block_diag([self.problem.jacobian(Y[i], times[i]) for i in range(s)], format="csr")
            return (self.stage_mass - dt * (blocks @ self.coupling)).tocsr()

        result = self.newton(residual, jacobian, np.zeros(s * n), new_solver=lambda: self.solver, where=self.where,
                             fix=self.fix)
        self.last_newton = result
        self.newton_iterations += result.iterations
        return y + dt * (self.tableau.b @ result.x.reshape(s, n))


class AdditiveRungeKutta(_Counters):
    """An IMEX pair on M y' = L y + g(y, t): L implicit, g explicit (module docstring)."""

    def __init__(self, tableau: Tableau, problem: Problem, dt: float, new_solver: Callable, *,
                 key: str = "app.integrator"):
        if not (tableau.additive and tableau.diagonally_implicit):
            raise ValueError(f"tableau {tableau.name} is not an additive pair with a diagonally implicit part")
        if problem.stiff is None:
            raise ModelError(f"{key}={tableau.name} needs the stiff linear part L of the equations (f = L y + g, "
                             f"L constant) and this model has none; use {key}=radau_iia")
        self.tableau, self.problem, self.dt = tableau, problem, float(dt)
        self.explicit_A, self.explicit_b = np.asarray(tableau.explicit_A), np.asarray(tableau.explicit_b)
        self.mass = MassMatrix(problem.mass, problem.size, new_solver)
        self.stiff = sp.csr_matrix(problem.stiff)
        self.systems: dict[float, Any] = {}
        for gamma in sorted(set(np.diag(tableau.A)) - {0.0}):
            solver = new_solver()
            solver.factorize(self.mass.matrix - self.dt * gamma * self.stiff)
            self.systems[gamma] = solver
        self.rhs_evaluations = 0

    def _solve(self, gamma: float, rhs: np.ndarray) -> np.ndarray:
        """(M − dt γ L)⁻¹ rhs."""
        return self.mass.solve(rhs) if gamma == 0.0 else self.systems[gamma].solve(rhs)

    def step(self, y: np.ndarray, t: float) -> np.ndarray:
        """y⁺ from the stages Y_i, (n,)."""
        tableau, dt = self.tableau, self.dt
        implicit, explicit, c = tableau.A, self.explicit_A, tableau.c
        s = tableau.stages
        explicit_forces, linear_forces = np.zeros((s, len(y))), np.zeros((s, len(y)))
        mass_y = self.mass.apply(y)
        for i in range(s):
            if i == 0 and implicit[0, 0] == 0.0:
                stage = y
            else:
                rhs = mass_y + dt * (explicit[i, :i] @ explicit_forces[:i] + implicit[i, :i] @ linear_forces[:i])
                stage = self._solve(float(implicit[i, i]), rhs)
            explicit_forces[i] = self.problem.nonstiff(stage, t + c[i] * dt)
            linear_forces[i] = self.stiff @ stage
        self.rhs_evaluations += s
        return self.mass.solve(mass_y + dt * (self.explicit_b @ explicit_forces + tableau.b @ linear_forces))


def tableau_entry(tableau: Tableau) -> IntegratorEntry:
    """The registry entry of a tableau: its family's stepper (explicit, additive or implicit)."""
    if tableau.explicit:
        return IntegratorEntry(tableau.name, partial(ExplicitRungeKutta, tableau), Needs.explicit, tableau.order,
                               tableau)
    if tableau.additive:
        return IntegratorEntry(tableau.name, partial(AdditiveRungeKutta, tableau), Needs.stiff_split, tableau.order,
                               tableau)
    return IntegratorEntry(tableau.name, partial(ImplicitRungeKutta, tableau), Needs.jacobian, tableau.order, tableau)


#: the Runge–Kutta integrators by name (the compiler adds the others to the same table)
INTEGRATORS: dict[str, IntegratorEntry] = {
    tableau.name: tableau_entry(tableau) for tableau in (SSPRK3, GAUSS_LEGENDRE, RADAU_IIA, ARK_IMEX)}
