"""The Runge–Kutta steppers (decrun/methods/model/runge_kutta.py) on M y' = f(y, t).

Observed orders by self-convergence on the logistic reaction–diffusion problem
y' = ε M⁻¹(−S) y + y(1 − y), M = ⋆0, S = d0ᵀ ⋆1 d0 (circumcentric DEC on a 6 × 5 jittered lattice,
30 vertices, natural borders), ε = 0.05, t ∈ [0, 1], a smooth bump as initial value: the order is
log₂(‖y_dt − y_dt/2‖ / ‖y_dt/2 − y_dt/4‖) in the ⋆0 norm over dt = 1/4, 1/8, 1/16, 1/32
(two orders per method; measured 7 Dec 2026 by ``observed_orders`` below)::

    integrator          order   observed
    explicit_euler      1       1.05  1.02
    ssprk3              3       3.14  3.07
    rk4                 4       4.05  4.02
    implicit_euler      1       0.96  0.98
    implicit_midpoint   2       2.00  2.00
    crank_nicolson      2       2.00  2.00
    gauss_legendre      4       4.01  4.00
    radau_iia           5       5.00  5.00
    ars232              2       2.02  2.01
    ark_imex            3       3.05  3.02

The issue's goals (gauss_legendre ≥ 3.7, radau_iia ≥ 4.4, ssprk3 ≥ 2.7, ark_imex ≥ 1.8) are
asserted; every other tableau must show its order within 0.2. Against an exact, time-dependent
solution (Prothero–Robinson, λ = −1, dt = 1/2, 1/4, 1/8) every tableau shows its order within 0.3
(ark_imex 2.83, 2.91; the others within 0.2). Also: the mass matrix is honoured
(M = ⋆0 steps as M⁻¹ moved into f does; with a non-diagonal M each method keeps its order), a
linear problem is factorized once per dt, a checkpoint resumes bit for bit, and refusals are one
line.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
import scipy.sparse as sp

from decrun.complex import SimplicialComplex
from decrun.core.solvers import solver_factory
from decrun.core.solvers.direct import DirectSolver
from decrun.dec import DEC
from decrun.methods.model.language import ModelError
from decrun.methods.model.newton import NewtonDivergence
from decrun.methods.model.runge_kutta import (
    INTEGRATORS,
    AdditiveRungeKutta,
    ExplicitRungeKutta,
    ImplicitRungeKutta,
    Needs,
    tableau_entry,
)
from decrun.methods.model.tableaux import TABLEAUX, Tableau

from meshes_for_tests import jittered_lattice

#: the issue's goals of the observed order
GOALS = {"gauss_legendre": 3.7, "radau_iia": 4.4, "ssprk3": 2.7, "ark_imex": 1.8}
ENTRIES = {name: tableau_entry(tableau) for name, tableau in TABLEAUX.items()}


class Logistic:
    """M y' = −ε S y + M y(1 − y) (``mass`` M = ⋆0), or with M⁻¹ moved into f (``mass`` None), or
    with ⋆0 replaced by a non-diagonal SPD M = ⋆0 + δ S (``consistent``): L = −εS, g = M y(1 − y)."""

    def __init__(self, mass: str = "diagonal", epsilon: float = 0.05, reaction: float = 1.0):
        vertices, faces = jittered_lattice(6, 5)
        dec = DEC(SimplicialComplex(vertices, faces))
        S = (dec.d(0).T @ dec.star(1) @ dec.d(0)).tocsr()
        M = dec.star(0).tocsr() + (0.2 * 0.05 * S if mass == "consistent" else 0)
        self.size, self.reaction = S.shape[0], reaction
        self.weights = dec.star(0).diagonal()
        self.mass = None if mass == "none" else sp.csr_matrix(M)
        inverse = sp.diags(1 / dec.star(0).diagonal())
        self.linear = (-epsilon * S).tocsr() if mass != "none" else (-epsilon * inverse @ S).tocsr()
        self.stiff = self.linear
        x, y = vertices[:, 0] / vertices[:, 0].max(), vertices[:, 1] / vertices[:, 1].max()
        self.initial = 0.1 + 0.8 * np.exp(-4 * ((x - 0.3) ** 2 + (y - 0.5) ** 2))

    def _weighted(self, value):
        return value if self.mass is None else self.mass @ value

    def nonstiff(self, y, t):
        return self._weighted(self.reaction * y * (1 - y))

    def f(self, y, t):
        return self.linear @ y + self.nonstiff(y, t)

    def jacobian(self, y, t):
        slope = self.reaction * (1 - 2 * y)  # ∂/∂y of y(1 − y), times the mass: M diag(slope)
        reaction = sp.diags(slope) if self.mass is None else self.mass.multiply(slope[None, :])
        return (self.linear + reaction).tocsr()


class ProtheroRobinson:
    """M y' = M (λ (y − φ(t)) + φ'(t)), φ_k(t) = sin(t + θ_k), M = ⋆0: y = φ exactly from y(0) = φ(0);
    time-dependent, so a stage evaluated at the wrong time c_i dt shows (L = λM, g = M(φ' − λφ))."""

    def __init__(self, rate: float = -1.0):
        self.rate = rate
        self.weights = Logistic().weights
        self.size = len(self.weights)
        self.mass = sp.diags(self.weights, format="csr")
        self.stiff = (rate * self.mass).tocsr()
        self.phase = np.linspace(0.0, np.pi, self.size)
        self.initial = self.exact(0.0)

    def exact(self, t):
        return np.sin(t + self.phase)

    def nonstiff(self, y, t):
        return self.weights * (np.cos(t + self.phase) - self.rate * self.exact(t))

    def f(self, y, t):
        return self.stiff @ y + self.nonstiff(y, t)

    def jacobian(self, y, t):
        return self.stiff


def integrate(entry, problem, dt: float, steps: int, y=None, t0: float = 0.0, stepper=None):
    stepper = stepper or entry.factory(problem, dt, DirectSolver)
    y = problem.initial.copy() if y is None else y
    for n in range(steps):
        y = stepper.step(y, t0 + n * dt)
    return y, stepper


def observed_orders(entry, problem, halvings: int = 4, end: float = 1.0) -> np.ndarray:
    solutions = [integrate(entry, problem, end / 2 ** k, 2 ** k)[0] for k in range(2, 2 + halvings)]
    differences = [np.sqrt(problem.weights @ (a - b) ** 2) for a, b in zip(solutions[:-1], solutions[1:], strict=True)]
    return np.log2(np.array(differences[:-1]) / np.array(differences[1:]))


def test_the_registry_holds_the_issues_integrators_with_what_they_need():
    assert list(INTEGRATORS) == ["ssprk3", "gauss_legendre", "radau_iia", "ark_imex"]
    assert {name: (entry.needs, entry.order) for name, entry in INTEGRATORS.items()} == {
        "ssprk3": (Needs.explicit, 3), "gauss_legendre": (Needs.jacobian, 4), "radau_iia": (Needs.jacobian, 5),
        "ark_imex": (Needs.stiff_split, 3)}
    assert all(entry.tableau is TABLEAUX[name] and entry.name == name for name, entry in INTEGRATORS.items())
    stepper = INTEGRATORS["radau_iia"].factory(Logistic(), 0.1, DirectSolver)
    assert isinstance(stepper, ImplicitRungeKutta)


@pytest.mark.parametrize("name", list(TABLEAUX))
def test_the_observed_order_on_logistic_reaction_diffusion(name):
    orders = observed_orders(ENTRIES[name], Logistic())
    goal = GOALS.get(name, TABLEAUX[name].order - 0.2)
    assert np.all(orders >= goal), (name, orders)
    assert np.all(orders <= TABLEAUX[name].order + 0.3), (name, orders)  # not better than the tableau says


@lru_cache(maxsize=None)
def reference(mass: str) -> np.ndarray:
    """y(1) by radau_iia at dt = 1/64 (error ≈ 1e-13)."""
    return integrate(ENTRIES["radau_iia"], Logistic(mass), 1 / 64, 64)[0]


@pytest.mark.parametrize("name", list(TABLEAUX))
def test_the_order_against_an_exact_time_dependent_solution(name):
    """Prothero–Robinson (λ = −1): the error against y(1) = φ(1) falls at the tableau's order, which
    needs every stage at its own time t + c_i dt."""
    problem = ProtheroRobinson()
    errors = [np.sqrt(problem.weights @ (integrate(ENTRIES[name], problem, 1 / steps, steps)[0] -
                                         problem.exact(1.0)) ** 2) for steps in (2, 4, 8)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders >= TABLEAUX[name].order - 0.3), (errors, orders)


@pytest.mark.parametrize("name", list(TABLEAUX))
def test_the_mass_matrix_is_honoured(name):
    """M y' = f with M = ⋆0 and y' = M⁻¹ f (mass None) are the same problem: the same steps to
    round-off; with a non-diagonal M (factorized, never inverted) the method keeps its order."""
    entry = ENTRIES[name]
    with_mass, _ = integrate(entry, Logistic("diagonal"), 0.125, 8)
    without, _ = integrate(entry, Logistic("none"), 0.125, 8)
    np.testing.assert_allclose(with_mass, without, rtol=1e-12, atol=1e-13)
    consistent = Logistic("consistent")
    errors = [np.sqrt(consistent.weights @ (integrate(entry, consistent, 1 / steps, steps)[0] -
                                            reference("consistent")) ** 2) for steps in (4, 8)]
    assert np.log2(errors[0] / errors[1]) >= GOALS.get(name, TABLEAUX[name].order - 0.3), errors
    assert not np.allclose(reference("consistent"), reference("diagonal"), rtol=1e-4)  # M changed the answer


def test_a_linear_problem_is_factorized_once_per_time_step_size():
    """No reaction: f = −εS y is linear, so Newton's Jacobian I⊗M − dt A⊗J never changes: one
    factorization and one Newton iteration a step; the IMEX pair one factorization per γ."""
    problem = Logistic(reaction=0.0)
    y, stepper = integrate(INTEGRATORS["radau_iia"], problem, 0.05, 20)
    assert stepper.factorizations == 1 and stepper.newton_iterations == 20
    assert stepper.last_newton.iterations == 1
    assert abs(problem.weights @ y - problem.weights @ problem.initial) < 1e-13  # Σ⋆0 y is conserved
    _, imex = integrate(INTEGRATORS["ark_imex"], problem, 0.05, 20)
    assert [solver.factorizations for solver in imex.systems.values()] == [1]  # γ = 0.4358…: stages 2, 3, 4


@pytest.mark.parametrize("name", ["gauss_legendre", "radau_iia"])
def test_the_stage_jacobian_is_exact_newton_converges_quadratically(name):
    """∂R/∂Z = I⊗M − dt (A⊗I) blockdiag(J(Y_j)): block (i, j) is a_ij J(Y_j), J at the stage it
    differentiates; any other makes Newton's convergence linear. Reaction rate 5, dt = 1/4."""
    problem = Logistic(reaction=5.0)
    stepper = ENTRIES[name].factory(problem, 0.25, DirectSolver, rtol=1e-15)
    stepper.step(problem.initial, 0.0)
    r = np.array([norm for norm in stepper.last_newton.residual_norms if norm > 1e-14])
    orders = np.log(r[2:] / r[1:-1]) / np.log(r[1:-1] / r[:-2])
    assert len(orders) >= 2 and np.all(orders[1:] > 1.8), (r, orders)


def test_simplified_newton_reuses_the_jacobian_at_the_step_start_and_steps_the_same():
    """simplified=True factorizes I⊗M − dt A⊗J(yₙ) (the exact Jacobian at Z = 0) and keeps it while
    Newton contracts fast: fewer factorizations, the same steps to Newton's tolerance."""
    problem = Logistic()
    exact, full = integrate(INTEGRATORS["radau_iia"], problem, 0.125, 8)
    stepper = INTEGRATORS["radau_iia"].factory(problem, 0.125, DirectSolver, simplified=True)
    chord, stepper = integrate(None, problem, 0.125, 8, stepper=stepper)
    assert stepper.factorizations < full.factorizations == full.newton_iterations
    np.testing.assert_allclose(chord, exact, rtol=1e-10)


@pytest.mark.parametrize("name", ["implicit_euler", "crank_nicolson", "gauss_legendre", "radau_iia"])
def test_a_stiff_linear_problem_steps_to_its_steady_state(name):
    """ε = 10⁴, dt = 0.5: dt ε λ_max ≈ 10⁷. Near the steady state f's terms cancel, so its relative
    round-off is large; Newton's step test in the units of the state still stops (one iteration a
    step, one factorization). Σ⋆0 y is conserved; an L-stable method lands on the ⋆0 mean."""
    problem = Logistic(epsilon=1e4, reaction=0.0)
    y, stepper = integrate(ENTRIES[name], problem, 0.5, 6)
    mean = problem.weights @ problem.initial / problem.weights.sum()
    assert stepper.factorizations == 1 and stepper.newton_iterations <= 2 * 6
    total = problem.weights @ problem.initial
    assert abs(problem.weights @ y - total) < 1e-10 * total  # 1ᵀS = 0 to round-off, times dt ε = 5000
    if name in ("implicit_euler", "radau_iia"):
        assert np.max(abs(y - mean)) < 1e-10


@pytest.mark.parametrize("name", list(TABLEAUX))
def test_a_checkpoint_resumes_bit_for_bit(name):
    """N steps equal k steps, state_dict → load_state into a fresh stepper, N − k steps."""
    entry, problem, dt = ENTRIES[name], Logistic("consistent"), 0.1
    straight, first = integrate(entry, problem, dt, 8)
    middle, part = integrate(entry, problem, dt, 3)
    state = part.state_dict()
    assert all(type(value) is int for value in state.values())
    fresh = entry.factory(problem, dt, DirectSolver)
    fresh.load_state(state)
    resumed, fresh = integrate(entry, problem, dt, 5, y=middle, t0=3 * dt, stepper=fresh)
    assert np.array_equal(resumed, straight)
    assert fresh.state_dict() == first.state_dict()


def test_ark_imex_without_a_stiff_split_is_refused_and_the_named_integrator_runs():
    problem = Logistic()
    problem.stiff = None  # f stays −εS y + M y(1 − y); no split is declared
    with pytest.raises(ModelError) as info:
        INTEGRATORS["ark_imex"].factory(problem, 0.1, DirectSolver)
    assert str(info.value) == ("app.integrator=ark_imex needs the stiff linear part L of the equations (f = L y + g, "
                               "L constant) and this model has none; use app.integrator=radau_iia")
    y, _ = integrate(INTEGRATORS["radau_iia"], problem, 0.1, 3)
    assert np.all(np.isfinite(y))


class Square:
    """y' = y² componentwise: y(t) = 1/(1/y0 − t) blows up at t = 1/y0."""

    size, mass, stiff = 3, None, None
    initial = np.array([0.8, 0.5, 0.2])

    def f(self, y, t):
        return y ** 2

    def nonstiff(self, y, t):
        return y ** 2

    def jacobian(self, y, t):
        return sp.diags(2 * y, format="csr")


def test_stage_equations_without_a_solution_are_refused_and_half_the_step_solves_them():
    """One radau_iia step of dt = 1 from y0 = 0.8 (blow-up at 1.25) has no real stages; the fix the
    message names, dt = 0.5, steps to 1/(1/y0 − dt) within the method's error."""
    entry = INTEGRATORS["radau_iia"]
    with pytest.raises(NewtonDivergence) as info:
        entry.factory(Square(), 1.0, DirectSolver, where="app.equations[0]").step(Square.initial, 0.0)
    message = str(info.value)
    assert message.startswith("app.equations[0] (integrator=radau_iia, the step from t = 0): Newton's method did "
                              "not converge: ") and "\n" not in message
    assert message.endswith("; halve the time step (app.dt=0.5)")
    stepper = entry.factory(Square(), 0.5, DirectSolver, where="app.equations[0]")
    np.testing.assert_allclose(stepper.step(Square.initial, 0.0), 1 / (1 / Square.initial - 0.5), rtol=1e-5)
    assert stepper.last_newton.iterations <= 6


def test_a_step_that_blows_up_is_a_floating_point_error_naming_the_stage():
    """Explicit stages of a growth rate 20 with dt = 0.5 (dt·20 = 10) overflow: a blow-up for the
    caller (the model's stepper records it as unstable), never a NaN handed to a solver."""
    problem = Logistic("consistent", reaction=20.0)
    for name in ("ssprk3", "ark_imex"):
        with pytest.raises(FloatingPointError, match=rf"^integrator={name}: non-finite values in (stage \d|the "
                                                     r"update) of the step from t = \d"), np.errstate(all="ignore"):
            integrate(ENTRIES[name], problem, 0.5, 20)


def test_a_solver_for_symmetric_systems_only_is_refused_for_the_stage_system():
    """I⊗M − dt A⊗J is unsymmetric for s > 1 (A is): cg cannot solve it; one stage (implicit Euler,
    M − dt J symmetric for diffusion) can, and the named override solves the stages."""
    problem = Logistic()
    with pytest.raises(ModelError) as info:
        INTEGRATORS["radau_iia"].factory(problem, 0.1, solver_factory("cg"))
    assert str(info.value) == ("solver=cg: integrator=radau_iia solves the unsymmetric stage system I⊗M − dt A⊗J of "
                               "its 3 stages; use `solver=direct` (or `solver=iterative`, `solver=pardiso`)")
    by_direct, _ = integrate(None, problem, 0.1, 3,
                             stepper=INTEGRATORS["radau_iia"].factory(problem, 0.1, solver_factory("direct")))
    by_default, _ = integrate(INTEGRATORS["radau_iia"], problem, 0.1, 3)
    np.testing.assert_array_equal(by_direct, by_default)
    by_cg, _ = integrate(None, problem, 0.1, 3, stepper=ENTRIES["implicit_euler"].factory(problem, 0.1,
                                                                                         solver_factory("cg")))
    np.testing.assert_allclose(by_cg, integrate(ENTRIES["implicit_euler"], problem, 0.1, 3)[0], rtol=1e-6)


def test_the_families_refuse_a_tableau_of_another_family():
    problem = Logistic()
    with pytest.raises(ValueError, match="tableau radau_iia is not explicit"):
        ExplicitRungeKutta(TABLEAUX["radau_iia"], problem, 0.1, DirectSolver)
    with pytest.raises(ValueError, match="tableau ark_imex is an additive pair"):
        ImplicitRungeKutta(TABLEAUX["ark_imex"], problem, 0.1, DirectSolver)
    with pytest.raises(ValueError, match="tableau rk4 is not an additive pair"):
        AdditiveRungeKutta(TABLEAUX["rk4"], problem, 0.1, DirectSolver)
    singular = Tableau("singular", np.array([[0.0, 0.0], [0.5, 0.5]]), np.array([0.25, 0.75]), np.array([0.0, 1.0]),
                       order=1)
    with pytest.raises(ValueError, match="tableau singular: A is singular and bᵀ is not its last row"):
        ImplicitRungeKutta(singular, problem, 0.1, DirectSolver)
