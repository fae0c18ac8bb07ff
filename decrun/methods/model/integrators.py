"""Time integrators of the model app: one step of ``dt(u) = F(u, t)`` for the evolved fields.

Each integrator is made once per run (:func:`make_integrator`; its matrices factorized once for
the run's ``dt``) and then steps a state — a dict ``field → array`` — from t to t + dt.
Implicit schemes work on the weak form: every evolution is split
(:meth:`decrun.methods.model.compiler.Compiler.split`) into blocks linear in the evolved fields,
``⋆_k⁻¹ A_uv`` with constant matrices, and the rest R; row u multiplied by its mass ``M_u = ⋆_k``
reads ``M_u u' = Σ_v A_uv v + M_u R_u`` (so a Galerkin ⋆ is never inverted, and the Laplacian's
system is the symmetric ``M + dt S`` of the thesis' implicit smoothing, §1.3).

==================  ==========================================================================
``explicit_euler``  u ← u + dt F(u, t)
``rk4``             the classical 4-stage Runge–Kutta
``implicit_euler``  (M − dt A) u⁺ = M u + dt M R(t⁺); when R reads the evolved fields, Newton's
                    method on M (u⁺ − u) = dt f(u⁺, t⁺) (:mod:`.implicit_newton`)
``crank_nicolson``  (M − dt/2 A) u⁺ = (M + dt/2 A) u + dt/2 M (R(t) + R(t⁺)); likewise
``imex``            (M − dt A) u⁺ = M u + dt M R(u, t): linear part implicit, the rest explicit
``semi_implicit``   (M − dt A(uⁿ)) u⁺ = M uⁿ + dt M R(uⁿ, t): lagged coefficients (Picard), A refactorized
                    every step — nonlinear diffusion ∇·(D(u)∇u) with D frozen at uⁿ
``symplectic``      Störmer–Verlet (kick–drift–kick) for pairs dt(q) = f(p), dt(p) = g(q)
``bdf``, ``radau``  SciPy's ``solve_ivp`` with the exact sparse Jacobian (a Galerkin mass: lumped)
``rk45``            SciPy's adaptive Runge–Kutta (no Jacobian)
==================  ==========================================================================

Fixed (Dirichlet) values stay at their border values in every scheme.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.adaptive_jacobian import exact_jacobian
from decrun.methods.model.compiler import NOT_LINEAR
from decrun.methods.model.implicit_check import check_implicit_matrix
from decrun.methods.model.implicit_newton import NewtonImplicit
from decrun.methods.model.jacobian import pattern as term_pattern
from decrun.methods.model.language import ModelError
from decrun.methods.model.lowering import Evolution
from decrun.methods.model.lumped_jacobian import lumped_jacobian_of_model
from decrun.methods.model.mixed import implicit_problem
from decrun.methods.model.problem import ModelProblem
from decrun.methods.model.runge_kutta import INTEGRATORS as RUNGE_KUTTA
from decrun.methods.model.runge_kutta import Needs
from decrun.methods.model.solve import LinearSystem

__all__ = ["INTEGRATORS", "SCHEMES", "Scheme", "ProblemStepper", "FROZEN", "make_integrator", "explicit_stability_limit", "jacobian_pattern", "Evolution"]

INTEGRATORS = ("explicit_euler", "rk4", "implicit_euler", "crank_nicolson", "imex", "symplectic", "bdf", "radau",
               "rk45", "semi_implicit", "ssprk3", "gauss_legendre", "radau_iia", "ark_imex")
#: the suffix of :func:`explicit_stability_limit`'s source when the limit is of frozen coefficients
FROZEN = " (coefficients frozen at t = 0)"
#: the stability interval on the negative real axis: |1 + z| ≤ 1 (Euler), RK4's ≈ −2.785
STABILITY_INTERVAL = {"explicit_euler": 2.0, "rk4": 2.785293563405282}


def _enforce(model, state: dict) -> dict:
    """The state with every fixed value set."""
    for name, (border, values) in model.fixed.items():
        if name in state:
            state[name] = np.array(state[name], dtype=np.float64)
            state[name][border] = values
    return state


class Explicit:
    """Explicit Euler or RK4 on F(u, t) evaluated in full."""

    def __init__(self, model, dt: float, scheme: str):
        self.model, self.dt, self.scheme = model, float(dt), scheme

    def _f(self, state, t):
        return self.model.derivative(self.model.environment(state, t))

    def step(self, state: dict, t: float) -> dict:
        dt, f = self.dt, self._f
        if self.scheme == "explicit_euler":
            k1 = f(state, t)
            return _enforce(self.model, {u: state[u] + dt * k1[u] for u in state})
        k1 = f(state, t)
        k2 = f({u: state[u] + 0.5 * dt * k1[u] for u in state}, t + 0.5 * dt)
        k3 = f({u: state[u] + 0.5 * dt * k2[u] for u in state}, t + 0.5 * dt)
        k4 = f({u: state[u] + dt * k3[u] for u in state}, t + dt)
        return _enforce(self.model, {u: state[u] + dt / 6.0 * (k1[u] + 2 * k2[u] + 2 * k3[u] + k4[u]) for u in state})

    def state_dict(self) -> dict:
        return {}

    def load_state(self, state: dict) -> None:
        pass


def _nonlinear(model) -> bool:
    """True when a term of an evolution that is not a constant linear block reads an evolved
    field: implicit Euler and Crank–Nicolson then take Newton's method each step
    (:class:`~decrun.methods.model.implicit_newton.NewtonImplicit`)."""
    evolution = model.evolution
    return any(evolution.reads_evolved(u) for u in evolution.names)


def check_integrator(model, scheme: str, dt: float) -> None:
    """The structural checks of integrator ``scheme`` on ``model`` — symplectic pairs, linear
    equations for implicit Euler and Crank–Nicolson, a Jacobian pattern for bdf/radau — without
    factorizing anything: raised when the model loads, before any work."""
    if scheme == "symplectic":
        Symplectic(model, dt)
    elif scheme in ("implicit_euler", "crank_nicolson") and _nonlinear(model):
        implicit_problem(model).check_jacobian()  # Newton's: every nonlinear term needs an exact Jacobian
    elif scheme in ("bdf", "radau") and exact_jacobian(model) is None:
        jacobian_pattern(model)
    elif SCHEMES[scheme].tableau is not None and SCHEMES[scheme].needs == "jacobian":
        implicit_problem(model).check_jacobian()  # the stages' Newton: every nonlinear term needs an exact Jacobian


class Implicit:
    """Implicit Euler, Crank–Nicolson or IMEX: one factorization of M − θ dt A for the run."""

    def __init__(self, model, dt: float, scheme: str, new_solver):
        self.model, self.dt, self.scheme = model, float(dt), scheme
        self.evolution = evolution = model.evolution  # implicit Euler, Crank–Nicolson: linear (else NewtonImplicit)
        theta = 0.5 if scheme == "crank_nicolson" else 1.0
        self.theta = theta
        check_implicit_matrix(model, evolution, theta, self.dt, scheme)  # singular or indefinite: say why, before
        fixed, self.fixed_values = evolution.fixed()
        self.fixed = fixed
        self.groups = _uncoupled_groups(model, evolution, theta * self.dt, new_solver)
        if self.groups is None:
            self.system = LinearSystem(evolution.matrix(theta * self.dt), new_solver, fixed)

    def step(self, state: dict, t: float) -> dict:
        model, evolution, dt = self.model, self.evolution, self.dt
        explicit = any(evolution.rest[u] for u in evolution.names)  # heat, mcf: no explicit term at all
        if self.scheme == "imex":
            env = model.environment(state, t) if explicit else None
            rhs = {u: evolution.apply_mass(u, state[u] + dt * evolution.rest_value(u, env) if evolution.rest[u]
                                           else state[u]) for u in evolution.names}
        elif self.scheme == "crank_nicolson":
            rhs = {u: evolution.apply_mass(u, state[u]) for u in evolution.names}
            applied = evolution.apply_blocks(state)
            later = model.environment(state, t + dt) if explicit else None  # R reads no evolved field: only t
            now = model.environment(state, t) if explicit else None
            for u in evolution.names:
                rhs[u] = rhs[u] + 0.5 * dt * applied[u]
                if evolution.rest[u]:
                    average = 0.5 * (evolution.rest_value(u, now) + evolution.rest_value(u, later))
                    rhs[u] = rhs[u] + dt * evolution.apply_mass(u, average)
        else:
            later = model.environment(state, t + dt) if explicit else None
            rhs = {u: evolution.apply_mass(u, state[u] + dt * evolution.rest_value(u, later) if evolution.rest[u]
                                           else state[u]) for u in evolution.names}
        if self.groups is not None:
            out = {}
            for names, system, fixed_values in self.groups:
                if len(names) == 1:
                    out[names[0]] = system.solve(rhs[names[0]], fixed_values[:, 0])
                    continue
                columns = system.solve(np.stack([rhs[u] for u in names], axis=1), fixed_values)
                out.update({u: columns[:, i] for i, u in enumerate(names)})
            return out
        vector = self.system.solve(evolution.stack(rhs), self.fixed_values)
        return evolution.unstack(vector)

    def state_dict(self) -> dict:
        return {}

    def load_state(self, state: dict) -> None:
        pass


def _uncoupled_groups(model, evolution: Evolution, alpha: float, new_solver):
    """When no evolved field's implicit part reads another (no block A_uv with u ≠ v): the
    system M − α A is block-diagonal, so each field's block is solved on its own — and fields
    with equal blocks and equal fixed rows (mcf's vx, vy, vz) share one factorization, their
    right sides solved as columns of one (n, m) block. Returns [(names, LinearSystem, fixed
    values (k, m))], or None for a coupled system (one factorization of the whole)."""
    from decrun.core.solvers.base import fingerprint

    if len(evolution.names) < 2 or any(u != v for u, v in evolution.blocks):
        return None
    groups: dict[tuple, list] = {}
    for u in evolution.names:
        block = evolution.blocks.get((u, u))
        matrix = sp.csr_matrix(evolution.mass[u] - alpha * block if block is not None else evolution.mass[u])
        border, values = model.fixed.get(u, (np.zeros(0, dtype=np.int64), np.zeros(0)))
        border = np.asarray(border, dtype=np.int64)
        key = (fingerprint(matrix), border.tobytes())
        if key not in groups:
            groups[key] = [[], LinearSystem(matrix, new_solver, border), []]
        groups[key][0].append(u)
        groups[key][2].append(np.asarray(values, dtype=np.float64))
    return [(names, system, np.stack(values, axis=1)) for names, system, values in groups.values()]


class SemiImplicit:
    """Linearly implicit Euler with lagged coefficients (a Picard step): every term of dt(u) is
    linearized by :meth:`~decrun.methods.model.compiler.Compiler.lagged` — the factors that read
    the evolved fields but are not linear in them frozen at uⁿ — into weak blocks A(uⁿ) over one
    mass M = ⋆_k; the terms with no linear unknown left stay explicit (R). Each step solves

        (M − dt A(uⁿ)) u⁺ = M uⁿ + dt M R(uⁿ, tⁿ)

    with a fresh factorization (the matrix changes every step). For nonlinear diffusion
    dt(h) = −δ(D(h) dh) this is (⋆0 + dt d0ᵀ ⋆1 diag(D(hⁿ)) d0) h⁺ = ⋆0 hⁿ: with ⋆1 ≥ 0 and D ≥ 0
    an M-matrix, so h⁺ ≥ 0 whenever hⁿ ≥ 0, at any dt (no stability limit; first order in
    time). ``factorizations`` counts the systems solved."""

    def __init__(self, model, dt: float, new_solver):
        self.model, self.dt, self.new_solver = model, float(dt), new_solver
        compiler = model.compiler
        self.names = list(model.evolved)
        unknowns = set(self.names)
        ops = model.ops
        self.sizes = {name: model.kinds[name].size(ops.K) for name in self.names}
        offsets = np.cumsum([0] + [self.sizes[name] for name in self.names])
        self.slices = {name: slice(offsets[i], offsets[i + 1]) for i, name in enumerate(self.names)}
        self.builders, self.rest, self.where = {}, {}, {}
        for equation in model.equations:
            if equation.kind != "evolution":
                continue
            u = equation.target
            self.where[u] = equation.where
            self.builders[u], self.rest[u] = [], []
            for sign, term in compiler.terms(equation.rhs):
                builder = compiler.lagged(term, unknowns)
                if builder is None or builder is NOT_LINEAR:
                    self.rest[u].append((sign, compiler.compile(term, equation.where)))
                else:
                    self.builders[u].append((sign, builder))
        self.fixed_indices, self.fixed_values = Evolution.fixed(self)
        self.factorizations = 0

    def _row(self, u: str, env: dict):
        """(M_u, {v: weak A_uv}) at ``env``."""
        ops = self.model.ops
        blocks = {}
        for sign, builder in self.builders[u]:
            for v, block in builder(env).items():
                block = block.scaled(sign)
                merged = block if v not in blocks else ops.add(blocks[v], block)
                if merged is None:
                    raise ModelError(f"{self.where[u]}: the terms of dt({u}) mix inverse stars; write them over one ⋆ "
                                     "or use an explicit integrator")
                blocks[v] = merged
        invs = {block.inv for block in blocks.values()} - {None}
        if len(invs) > 1:
            raise ModelError(f"{self.where[u]}: the linear terms of dt({u}) mix inverse stars {sorted(invs)}; write "
                             "them over one ⋆ or use an explicit integrator")
        if invs:
            M = ops.dec.star(invs.pop()).tocsr()
            weak = {v: block.A if block.inv is not None else M @ block.A for v, block in blocks.items()}
        else:
            M = sp.identity(self.sizes[u], format="csr")
            weak = {v: block.A for v, block in blocks.items()}
        return M, weak

    def step(self, state: dict, t: float) -> dict:
        model, dt = self.model, self.dt
        env = model.environment(state, t)
        rows, rhs = [], []
        for u in self.names:
            M, weak = self._row(u, env)
            rest = np.zeros(self.sizes[u])
            for sign, closure in self.rest[u]:
                rest = rest + sign * closure(env)
            rhs.append(M @ (state[u] + dt * rest))
            row = []
            for v in self.names:
                part = -dt * weak[v] if v in weak else None
                if u == v:
                    part = M if part is None else M + part
                row.append(part)
            rows.append(row)
        matrix = sp.bmat(rows, format="csr") if len(self.names) > 1 else sp.csr_matrix(rows[0][0])
        system = LinearSystem(matrix, self.new_solver, self.fixed_indices)
        vector = system.solve(np.concatenate(rhs), self.fixed_values)
        self.factorizations += 1
        return _enforce(model, {name: vector[self.slices[name]] for name in self.names})

    def state_dict(self) -> dict:
        return {"factorizations": self.factorizations}

    def load_state(self, state: dict) -> None:
        self.factorizations = int(state.get("factorizations", 0))


class Symplectic:
    """Störmer–Verlet for a pair of groups: dt(q) = f(p) and dt(p) = g(q) (kick p by dt/2,
    drift q by dt, kick p by dt/2). q is the group of the first evolution equation."""

    def __init__(self, model, dt: float):
        self.model, self.dt = model, float(dt)
        compiler = model.compiler
        reads = {}
        for equation in model.equations:
            if equation.kind == "evolution":
                reads[equation.target] = compiler.reads(equation.rhs) & set(model.evolved)
        group = {model.evolved[0]: 0}
        queue = [model.evolved[0]]
        while queue:
            u = queue.pop()
            neighbours = reads[u] | {v for v in model.evolved if u in reads[v]}
            for v in neighbours:
                if v not in group:
                    group[v] = 1 - group[u]
                    queue.append(v)
        for u in model.evolved:
            group.setdefault(u, 0)
        for u in model.evolved:
            clash = [v for v in reads[u] if group[v] == group[u]]
            if clash:
                equation = next(e for e in model.equations if e.kind == "evolution" and e.target == u)
                raise ModelError(f"{equation.where}: integrator=symplectic needs pairs dt(q) = f(p), dt(p) = g(q), but "
                                 f"dt({u}) reads {clash[0]}; use `app.integrator=rk4` or `app.integrator=crank_nicolson`")
        self.q = [u for u in model.evolved if group[u] == 0]
        self.p = [u for u in model.evolved if group[u] == 1]

    def step(self, state: dict, t: float) -> dict:
        model, dt = self.model, self.dt
        state = dict(state)
        kick = model.derivative(model.environment(state, t), self.p)
        for u in self.p:
            state[u] = state[u] + 0.5 * dt * kick[u]
        drift = model.derivative(model.environment(state, t + 0.5 * dt), self.q)
        for u in self.q:
            state[u] = state[u] + dt * drift[u]
        kick = model.derivative(model.environment(state, t + dt), self.p)
        for u in self.p:
            state[u] = state[u] + 0.5 * dt * kick[u]
        return _enforce(model, state)

    def state_dict(self) -> dict:
        return {}

    def load_state(self, state: dict) -> None:
        pass


class SolveIVP:
    """SciPy's ``solve_ivp`` (BDF, Radau or RK45) over one span [t, t + dt] at a time, restarted
    every span from the last accepted step size ``h`` (kept in the state, so a resumed run repeats
    the same steps); ``accepted`` counts the solver's accepted steps, ``evaluations`` the right
    side's. ``jac``: SciPy's Jacobian (a matrix or ``jac(t, y)``) or None; ``sparsity``: its
    ``jac_sparsity`` (finite differences on that pattern) when there is no ``jac``."""

    def __init__(self, scheme: str, rtol: float, atol: float, jac=None, sparsity=None):
        self.scheme, self.rtol, self.atol, self.jac, self.sparsity = scheme, float(rtol), float(atol), jac, sparsity
        self.h = float("nan")
        self.accepted = 0
        self.evaluations = 0

    def advance(self, fun: Callable, y: np.ndarray, t: float, dt: float) -> np.ndarray:
        """(n,) y' = fun(t, y) integrated from y at t to t + dt."""
        from scipy.integrate import solve_ivp

        def counted(time, v):
            self.evaluations += 1
            return fun(time, v)

        options: dict = {"rtol": self.rtol, "atol": self.atol}
        if np.isfinite(self.h) and self.h > 0:  # within the span as SciPy computes it: (t + dt) - t can be < dt
            options["first_step"] = min(self.h, (t + dt) - t)
        if self.jac is not None:
            options["jac"] = self.jac
        elif self.sparsity is not None:
            options["jac_sparsity"] = self.sparsity
        method = {"bdf": "BDF", "radau": "Radau", "rk45": "RK45"}[self.scheme]
        solution = solve_ivp(counted, (t, t + dt), y, method=method, **options)
        if not solution.success:
            raise FloatingPointError(f"solve_ivp ({method}) failed at t = {t:g}: {solution.message}")
        self.accepted += len(solution.t) - 1
        if len(solution.t) > 1:
            self.h = float(solution.t[-1] - solution.t[-2])
        return solution.y[:, -1].copy()

    def state_dict(self) -> dict:
        return {"h": self.h, "accepted": self.accepted, "evaluations": self.evaluations}

    def load_state(self, state: dict) -> None:
        self.h, self.accepted = float(state["h"]), int(state["accepted"])
        self.evaluations = int(state["evaluations"])


class Adaptive:
    """:class:`SolveIVP` stepping the model's state from t to t + dt (``accepted_steps`` counts the
    solver's accepted steps), with the most exact Jacobian the model gives: the constant M⁻¹A of a
    linear model, the derivative pass's, M_L⁻¹ ∂f/∂y for a Galerkin mass, else finite differences
    on the equations' sparsity pattern."""

    def __init__(self, model, dt: float, scheme: str, rtol: float, atol: float):
        self.model, self.dt, self.scheme = model, float(dt), scheme
        self.evolution = model.evolution
        self.exact = exact_jacobian(model) if scheme in ("bdf", "radau") else None  # the derivative pass's
        self.exact = self.exact or (lumped_jacobian_of_model(model) if scheme in ("bdf", "radau") else None)  # Galerkin M
        self.pattern = jacobian_pattern(model) if scheme in ("bdf", "radau") and self.exact is None else None
        self.jacobian = _exact_jacobian(self.evolution) if scheme in ("bdf", "radau") else None
        # a linear model: ∂F/∂u is the constant M⁻¹A, exactly
        self.ivp = SolveIVP(scheme, rtol, atol, self.jacobian if self.jacobian is not None else self.exact,
                            self.pattern)

    def step(self, state: dict, t: float) -> dict:
        evolution, model = self.evolution, self.model

        def fun(time, y):
            return evolution.stack(model.derivative(model.environment(evolution.unstack(y), time)))

        y = self.ivp.advance(fun, evolution.stack(state), t, self.dt)
        return _enforce(model, evolution.unstack(y))

    def state_dict(self) -> dict:
        return self.ivp.state_dict()

    def load_state(self, state: dict) -> None:
        self.ivp.load_state(state)


def _exact_jacobian(evolution: Evolution) -> sp.csr_matrix | None:
    """M⁻¹A over the stacked fields when every evolution is linear (no explicit term reads an
    evolved field) and every row mass is diagonal; None otherwise (finite differences on the
    sparsity pattern then)."""
    if any(evolution.reads_evolved(u) for u in evolution.names):
        return None
    inverse = {}
    for u in evolution.names:
        M = evolution.mass[u]
        diagonal = M.diagonal()
        if (M - sp.diags(diagonal)).nnz or np.any(diagonal == 0):
            return None
        inverse[u] = sp.diags(1.0 / diagonal)
    rows = [[(inverse[u] @ evolution.blocks[(u, v)]).tocsr() if (u, v) in evolution.blocks else None
             for v in evolution.names] for u in evolution.names]
    for i, u in enumerate(evolution.names):
        if all(block is None for block in rows[i]):
            rows[i][i] = sp.csr_matrix((evolution.sizes[u], evolution.sizes[u]))
    return sp.bmat(rows, format="csc")


class ProblemStepper:
    """A stepper of the Runge–Kutta family (:mod:`decrun.methods.model.runge_kutta`: y ↦ y⁺ over
    the model's :class:`~decrun.methods.model.problem.ModelProblem`) stepping the model's state
    (field → values, border values included); its state is the stepper's (checkpoints)."""

    def __init__(self, problem: ModelProblem, stepper):
        self.problem, self.stepper = problem, stepper

    def step(self, state: dict, t: float) -> dict:
        return self.problem.state(self.stepper.step(self.problem.free_values(state), t))

    def state_dict(self) -> dict:
        return self.stepper.state_dict()

    def load_state(self, state: dict) -> None:
        self.stepper.load_state(state)


def _make_tableau(entry):
    """The maker of a tableau integrator of the Runge–Kutta registry: its stepper over the
    model's Problem (the exact Jacobian checked first when it needs one)."""
    def make(model, dt: float, new_solver, rtol: float, atol: float):
        problem = implicit_problem(model) if entry.needs == Needs.jacobian else model.problem
        options: dict = {}
        if entry.needs == Needs.jacobian:
            problem.check_jacobian()
            options = {"where": f"app.integrator={entry.name}", "fix": f"take smaller steps: `app.dt={dt / 4:.6g}`"}
        elif entry.needs == Needs.stiff_split:
            options = {"key": "app.integrator"}
        return ProblemStepper(problem, entry.factory(problem, float(dt), new_solver, **options))
    return make


def _make_legacy(model, scheme: str, dt: float, new_solver, rtol: float, atol: float):
    if scheme in ("explicit_euler", "rk4"):
        return Explicit(model, dt, scheme)
    if scheme in ("implicit_euler", "crank_nicolson") and _nonlinear(model):
        return NewtonImplicit(model, dt, scheme, new_solver)
    if scheme in ("implicit_euler", "crank_nicolson", "imex"):
        return Implicit(model, dt, scheme, new_solver)
    if scheme == "symplectic":
        return Symplectic(model, dt)
    if scheme in ("bdf", "radau", "rk45"):
        return Adaptive(model, dt, scheme, rtol, atol)
    return SemiImplicit(model, dt, new_solver)


@dataclass(frozen=True)
class Scheme:
    """One integrator of ``app.integrator``: its ``name``, what it ``needs`` of the model
    (``explicit``: only f; ``jacobian``: the exact Jacobian of its nonlinear terms;
    ``stiff_split``: the constant linear part), its ``order`` in time, and
    ``make(model, dt, new_solver, rtol, atol) -> stepper`` (``step(state, t)``, ``state_dict``,
    ``load_state``); ``tableau``: its Butcher tableau, for a Runge–Kutta method given as data."""

    name: str
    needs: str
    order: int
    make: Callable
    tableau: object = None


#: every integrator by name, one entry each: the schemes written here, then the tableaux of
#: :data:`decrun.methods.model.runge_kutta.INTEGRATORS` (a new tableau there is a new integrator)
SCHEMES: dict[str, Scheme] = {
    name: Scheme(name, needs, order, lambda model, dt, new_solver, rtol, atol, name=name:
                 _make_legacy(model, name, dt, new_solver, rtol, atol))
    for name, needs, order in (("explicit_euler", "explicit", 1), ("rk4", "explicit", 4),
                               ("implicit_euler", "jacobian", 1), ("crank_nicolson", "jacobian", 2),
                               ("imex", "stiff_split", 1), ("symplectic", "explicit", 2), ("bdf", "jacobian", 5),
                               ("radau", "jacobian", 5), ("rk45", "explicit", 5), ("semi_implicit", "explicit", 1))}
SCHEMES.update({name: Scheme(name, str(entry.needs), entry.order, _make_tableau(entry), entry.tableau)
                for name, entry in RUNGE_KUTTA.items()})


def make_integrator(model, scheme: str, dt: float, new_solver, rtol: float = 1e-6, atol: float = 1e-9):
    """The integrator ``scheme`` (one of :data:`SCHEMES`) for ``model`` at step ``dt``."""
    entry = SCHEMES.get(scheme)
    if entry is not None:
        return entry.make(model, float(dt), new_solver, rtol, atol)
    raise ModelError(f"app.integrator: unknown integrator {scheme!r}; choose one of {' | '.join(INTEGRATORS)}")


def explicit_stability_limit(model, scheme: str, state: dict | None = None) -> tuple[float, str]:
    """(dt_max, the equation it comes from) for explicit Euler and RK4: s/λ_max with s the scheme's
    stability interval and λ_max the largest eigenvalue of −A_uu φ = λ M_u φ over the evolved
    fields whose linear block is symmetric and negative semi-definite (diffusion); (inf, "")
    when no such block exists.

    With ``state`` (the initial values), a model whose linear part gives no limit — a nonlinear
    diffusion such as dt(h) = −δ(D(h) dh) has no constant block — is linearized with its
    coefficients frozen at ``state`` (:meth:`~decrun.methods.model.compiler.Compiler.lagged`,
    A = −d0ᵀ ⋆1 diag(D(h0)) d0 there) and the same bound is taken of that matrix: the limit of
    the frozen-coefficient problem at the start (the source is then ``u`` + :data:`FROZEN`).
    That is a necessary bound, not a sufficient one: the linearization of a flux
    |∇h|^{p−1}∇h has p times the frozen coefficient along ∇h, and the coefficients change
    during the run (the Halfar dome, p = 3: explicit Euler at 0.54 of this limit diverges at
    1 km, at 0.27 it runs). A model with a constant diffusion block is checked as before."""
    from decrun.methods.mean_curvature_flow import largest_eigenvalue

    if scheme not in STABILITY_INTERVAL:
        return float("inf"), ""
    evolution = model.evolution
    best, source = float("inf"), ""
    for u in evolution.names:
        A = evolution.blocks.get((u, u))
        if A is None or A.nnz == 0:
            continue
        limit = _diffusion_limit(A, evolution.mass[u], scheme, largest_eigenvalue)
        if limit < best:
            best, source = limit, u
    if np.isfinite(best) or state is None:
        return best, source
    frozen = SemiImplicit(model, 1.0, None)
    env = model.environment({name: np.asarray(state[name], dtype=np.float64) for name in frozen.names}, 0.0)
    for u in frozen.names:
        if not frozen.builders[u]:
            continue
        M, weak = frozen._row(u, env)
        A = weak.get(u)
        if A is None or A.nnz == 0:
            continue
        limit = _diffusion_limit(A, M, scheme, largest_eigenvalue)
        if limit < best:
            best, source = limit, u + FROZEN
    return best, source


def _diffusion_limit(A, M, scheme: str, largest_eigenvalue) -> float:
    """s/λ_max(−A, M) for a symmetric negative semi-definite A (inf otherwise)."""
    A = sp.csr_matrix(A)
    scale = abs(A).max()
    if scale == 0 or abs(A - A.T).max() > 1e-12 * scale or np.any(A.diagonal() > 1e-12 * scale):
        return float("inf")
    diagonal = M.diagonal()
    if (M - sp.diags(diagonal)).nnz == 0 and np.all(diagonal > 0):
        lam = largest_eigenvalue(-A, diagonal)
    elif (M - sp.diags(diagonal)).nnz == 0:
        return float("inf")  # a non-positive ⋆: no generalized eigenproblem
    else:
        lam = largest_eigenvalue(-A, M)
    if np.isfinite(lam) and lam > 0:
        return STABILITY_INTERVAL[scheme] / lam
    return float("inf")


def jacobian_pattern(model) -> sp.csr_matrix:
    """The sparsity of ∂F/∂u over the stacked evolved fields: the linear blocks' structure and,
    for each other term, the structure of its exact Jacobian (:func:`decrun.methods.model.jacobian.pattern`:
    the derivative rules read on structures). A term without an exact sparse Jacobian is refused."""
    evolution = model.evolution
    compiler = model.compiler
    names = set(evolution.names)
    rows = []
    for u in evolution.names:
        row = {v: None for v in evolution.names}
        equation = next(e for e in model.equations if e.kind == "evolution" and e.target == u)
        for (uu, v), A in evolution.blocks.items():
            if uu == u:
                row[v] = _structure(A) if row[v] is None else row[v] + _structure(A)
        for _sign, term in evolution.rest_trees[u]:
            for v in compiler.reads(term) & names:
                part = term_pattern(compiler, term, v, equation.where)
                row[v] = part if row[v] is None else row[v] + part
        rows.append([None if row[v] is None else row[v] for v in evolution.names])
    for i, u in enumerate(evolution.names):  # bmat needs a block in every row and column
        if all(block is None for block in rows[i]):
            rows[i][i] = sp.csr_matrix((evolution.sizes[u], evolution.sizes[u]))
    pattern = sp.bmat(rows, format="csr")
    pattern.data[:] = 1.0
    return pattern


def _structure(A) -> sp.csr_matrix:
    A = sp.csr_matrix(A, copy=True)
    A.data = np.ones_like(A.data)
    return A
