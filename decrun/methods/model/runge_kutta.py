"""Runge–Kutta steppers of M y' = f(y, t) from their tableaux, one generic stepper per family.

The compiled model presents its evolution as a :class:`Problem` over one stacked vector y (n,)
(borders condensed out); a :class:`~decrun.methods.model.tableaux.Tableau` says the method.

- :class:`ExplicitRungeKutta` (explicit A; needs only f)::

      M K_i = f(y + dt Σ_{j<i} a_ij K_j, t + c_i dt),   y⁺ = y + dt Σ_i b_i K_i

  M is factorized once (a diagonal M is divided by, the identity skipped).
- :class:`ImplicitRungeKutta` (any A stiffly accurate or invertible: Gauss, Radau IIA, implicit
  Euler, Crank–Nicolson; needs the exact Jacobian J = ∂f/∂y): the s·n stage equations in the
  stage increments Z_i = Y_i − y (s, n)::

      R(Z) = (I⊗M) Z − dt (A⊗I) F(y + Z) = 0,   F_i = f(Y_i, t + c_i dt)
      y⁺ = y + Σ_i d_i Z_i,   dᵀ = bᵀA⁻¹   (y⁺ = Y_s when bᵀ is the last row of A)

  solved by :func:`~decrun.methods.model.newton.newton` from Z = 0 with the exact Jacobian
  ∂R/∂Z = I⊗M − dt (A⊗I) blockdiag(J(Y_1), …, J(Y_s)) (= I⊗M − dt A⊗J for a linear f). The
  increments are in the units of the state, so Newton's step test reads ‖ΔZ‖ against ‖y‖: it
  holds near a steady state, where f's terms cancel and its relative round-off is large, and
  y⁺ of a stiffly accurate method is a stage value, never dt·f of one. One solver serves every
  step: a matrix equal to the last one it factorized is not factorized again, so a linear
  problem factorizes I⊗M − dt A⊗J once per dt.
- :class:`AdditiveRungeKutta` (an IMEX pair; needs the split f = L y + g, L constant): stage by
  stage, L implicit (A, b: a_ij, b_i) and g explicit (explicit_A, explicit_b: e_ij, e_i)::

      (M − dt a_ii L) Y_i = M y + dt Σ_{j<i} (e_ij g(Y_j, t + c_j dt) + a_ij L Y_j)
      M y⁺ = M y + dt Σ_i (e_i g(Y_i, t + c_i dt) + b_i L Y_i)

  one factorization of M − dt γ L per distinct diagonal γ = a_ii, made once and reused by
  every step.

Each is made as ``make(problem, dt, new_solver)`` and has ``step(y, t) -> y⁺``, ``state_dict()``
and ``load_state(state)``: the state holds the counters (the steps read nothing else), so a run
resumed from a checkpoint repeats the uninterrupted run's steps bit for bit. A step whose
explicit stages blow up (NaN, ±inf) raises :class:`FloatingPointError` naming the stage and t (a
blow-up, for the caller to record); stage equations that Newton cannot solve raise a
:class:`~decrun.methods.model.newton.NewtonDivergence`. :data:`INTEGRATORS` registers the
steppers by name (:class:`IntegratorEntry`).
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
    """M y' = f(y, t) over y (n,): ``mass`` M (n, n) symmetric positive semi-definite or None (the
    identity) — SPD for an ODE; singular only on algebraic rows (0 = L y + g, a DAE of index 1:
    :class:`~decrun.methods.model.mixed.MixedProblem`), which the steppers that solve with M − a dt J
    alone take and the others refuse; ``stiff`` L (n, n) the part of f linear with constant
    coefficients (f = L y + g(y, t)) or None."""

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
    """One step of fixed length dt, and the state a later step reads (an integrator's: the model's
    :class:`decrun.methods.stepping.Stepper` wraps it)."""

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
    """An integrator by ``name``: ``factory(problem, dt, new_solver, **options) -> Stepper``, what it
    ``needs`` from the problem, its ``order`` and its ``tableau`` (None for one that is not a
    Runge–Kutta method). The options by family: ``needs=jacobian`` (:class:`ImplicitRungeKutta`)
    ``where``, ``fix``, ``rtol``, ``max_iterations``, ``simplified``; ``needs=stiff_split``
    (:class:`AdditiveRungeKutta`) ``key``; ``needs=explicit`` none."""

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
            K[i] = self.mass.solve(_finite(self.problem.f(stage, t + c[i] * dt), self.tableau, i, t))
        self.rhs_evaluations += self.tableau.stages
        return y + dt * (b @ K)


class ImplicitRungeKutta(_Counters):
    """A fully implicit tableau on M y' = f(y, t): the stage equations by Newton (module docstring).

    ``where`` names the equations in a :class:`~decrun.methods.model.newton.NewtonDivergence`
    and ``fix`` the override that helps (default: halve ``app.dt``); ``rtol`` is Newton's
    tolerance relative to the first residual and, on its steps, to the state (‖ΔZ‖ ≤ rtol √s ‖y‖);
    ``max_iterations`` is Newton's; ``simplified`` reuses one Jacobian factorization while Newton
    contracts fast (:func:`~decrun.methods.model.newton.newton`). The tableau must be stiffly
    accurate (bᵀ the last row of A) or have an invertible A."""

    counters = ("rhs_evaluations", "newton_iterations")

    def __init__(self, tableau: Tableau, problem: Problem, dt: float, new_solver: Callable, *,
                 where: str = "app.equations", fix: str | None = None, rtol: float = 1e-12,
                 max_iterations: int = 25, simplified: bool = False):
        if tableau.additive:
            raise ValueError(f"tableau {tableau.name} is an additive pair: use AdditiveRungeKutta")
        self.tableau, self.problem, self.dt = tableau, problem, float(dt)
        self.output = _output_weights(tableau)
        s, n = tableau.stages, problem.size
        mass = sp.identity(n, format="csr") if problem.mass is None else sp.csr_matrix(problem.mass)
        self.stage_mass = sp.kron(sp.identity(s), mass, format="csr")  # I⊗M
        self.coupling = sp.kron(sp.csr_matrix(tableau.A), sp.identity(n), format="csr")  # A⊗I
        self.solver = new_solver()  # reused: an unchanged matrix is not factorized again
        if s > 1 and getattr(self.solver, "needs_spd", False):
            raise ModelError(f"solver={self.solver.name}: integrator={tableau.name} solves the unsymmetric stage "
                             f"system I⊗M − dt A⊗J of its {s} stages; use `solver=direct` (or `solver=iterative`, "
                             "`solver=pardiso`)")
        self.where = where
        self.fix = fix if fix is not None else f"halve the time step (app.dt={self.dt / 2:g})"
        self.rtol = rtol
        self.newton = partial(newton, rtol=rtol, atol=0.0, max_iterations=max_iterations, simplified=simplified)
        self.rhs_evaluations = self.newton_iterations = 0
        self.last_newton: NewtonResult | None = None

    @property
    def factorizations(self) -> int:
        """The Jacobians factorized by this process (a linear problem's: one)."""
        return self.solver.factorizations

    def step(self, y: np.ndarray, t: float) -> np.ndarray:
        """y⁺ = y + Σ d_i Z_i with the stage equations R(Z) = 0 solved by Newton from Z = 0, (n,)."""
        s, n, dt = self.tableau.stages, len(y), self.dt
        times = t + self.tableau.c * dt

        def residual(Z: np.ndarray) -> np.ndarray:
            Y = y[None, :] + Z.reshape(s, n)
            self.rhs_evaluations += s
            forces = np.concatenate([self.problem.f(Y[i], times[i]) for i in range(s)])
            return self.stage_mass @ Z - dt * (self.coupling @ forces)

        def jacobian(Z: np.ndarray) -> sp.csr_matrix:
            Y = y[None, :] + Z.reshape(s, n)
            blocks = sp.block_diag([self.problem.jacobian(Y[i], times[i]) for i in range(s)], format="csr")
            return (self.stage_mass - dt * (self.coupling @ blocks)).tocsr()

        where = f"{self.where} (integrator={self.tableau.name}, the step from t = {t:g})"
        result = self.newton(residual, jacobian, np.zeros(s * n), new_solver=lambda: self.solver, where=where,
                             fix=self.fix, step_tolerance=self.rtol * np.sqrt(s) * float(np.linalg.norm(y)))
        self.last_newton = result
        self.newton_iterations += result.iterations
        return y + self.output @ result.x.reshape(s, n)


def _output_weights(tableau: Tableau) -> np.ndarray:
    """d (s,) with y⁺ = y + Σ d_i Z_i: dᵀ = bᵀA⁻¹, which is e_s for a stiffly accurate tableau
    (bᵀ the last row of A: y⁺ is the last stage, exactly)."""
    if np.array_equal(tableau.b, tableau.A[-1]):
        return np.eye(tableau.stages)[-1]
    try:
        return np.linalg.solve(tableau.A.T, tableau.b)
    except np.linalg.LinAlgError as exc:
        raise ValueError(f"tableau {tableau.name}: A is singular and bᵀ is not its last row: the step cannot be "
                         "written in the stage increments") from exc


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
                stage = self._solve(float(implicit[i, i]), _finite(rhs, tableau, i, t))
            explicit_forces[i] = self.problem.nonstiff(stage, t + c[i] * dt)
            linear_forces[i] = self.stiff @ stage
        self.rhs_evaluations += s
        update = mass_y + dt * (self.explicit_b @ explicit_forces + tableau.b @ linear_forces)
        return self.mass.solve(_finite(update, tableau, s, t))


def _finite(values: np.ndarray, tableau: Tableau, stage: int, t: float) -> np.ndarray:
    """``values``, or a FloatingPointError (the step blew up: the stepper's caller records where)
    before a solver is handed a NaN or ±inf."""
    if not np.all(np.isfinite(values)):
        what = f"stage {stage + 1}" if stage < tableau.stages else "the update"
        raise FloatingPointError(f"integrator={tableau.name}: non-finite values in {what} of the step from t = {t:g}")
    return values


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
