"""Newton's method (decrun/methods/model/newton.py): quadratic convergence on the DEC system of
−Δu + u³ = f (manufactured, Dirichlet) with second-order spatial accuracy, the line search rescuing
arctan(x) = 0 where plain Newton overshoots and diverges, the simplified (chord) variant, and every
non-convergence refused in one line naming the equation, the last residual and the fix."""

from __future__ import annotations

import re

import numpy as np
import pytest
import scipy.sparse as sp

from decrun.complex import SimplicialComplex
from decrun.core.primitives import grid_triangles
from decrun.core.solvers.direct import DirectSolver
from decrun.dec import DEC
from decrun.methods.model.language import ModelError
from decrun.methods.model.newton import NewtonDivergence, NewtonResult, newton

WHERE = "app.equations[0]"
FIX = "use app.newton.max_iterations=50"
#: the manufactured solution u* = A sin(πx) sin(πy) on the unit square: large enough that u³ matters
AMPLITUDE = 3.0


def cubic_problem(cells: int):
    """−Δu + u³ = f on the unit square's DEC grid, u = u* on the border, condensed to the interior
    vertices I: F(u_I) = S_II u_I + S_IB u*_B + M_I (u_I³ − f_I) with S = d0ᵀ ⋆1 d0, M = ⋆0;
    returns (F, J, exact u*_I, ⋆0 on I)."""
    vertices, faces = grid_triangles(cells)
    dec = DEC(SimplicialComplex(vertices, faces))
    x, y = vertices[:, 0], vertices[:, 1]
    exact = AMPLITUDE * np.sin(np.pi * x) * np.sin(np.pi * y)
    f = 2 * np.pi ** 2 * exact + exact ** 3
    S = (dec.d(0).T @ dec.star(1) @ dec.d(0)).tocsr()
    mass = dec.star(0).diagonal()
    interior = ~dec.K.border_vertices()
    S_II, S_IB = S[interior][:, interior], S[interior][:, ~interior]
    m, load = mass[interior], mass[interior] * f[interior] - S_IB @ exact[~interior]

    def residual(u):
        return S_II @ u + m * u ** 3 - load

    def jacobian(u):
        return (S_II + sp.diags(3 * m * u ** 2)).tocsr()

    return residual, jacobian, exact[interior], m


def observed_orders(norms):
    """q_k = log(r_{k+1}/r_k) / log(r_k/r_{k−1}): 2 for quadratic convergence."""
    r = np.asarray(norms)
    return np.log(r[2:] / r[1:-1]) / np.log(r[1:-1] / r[:-2])


def test_newton_converges_quadratically_on_the_cubic_poisson_problem_with_spatial_order_two():
    errors = []
    for cells in (8, 16, 32):
        residual, jacobian, exact, mass = cubic_problem(cells)
        result = newton(residual, jacobian, np.zeros_like(exact), new_solver=DirectSolver, where=WHERE, fix=FIX)
        assert isinstance(result, NewtonResult)
        assert result.iterations <= 8 and result.factorizations == result.iterations
        assert len(result.residual_norms) == result.iterations + 1
        assert result.residual_norms[-1] <= 1e-12 + 1e-10 * result.residual_norms[0]
        assert np.linalg.norm(residual(result.x)) == pytest.approx(result.residual_norms[-1], rel=1e-12)
        # quadratic: the last orders above round-off are ≈ 2 (r_{k+1} ≈ C r_k²)
        above_round_off = [r for r in result.residual_norms if r > 1e-13 * result.residual_norms[0]]
        assert max(observed_orders(above_round_off)[-2:]) > 1.8
        errors.append(np.sqrt(np.sum(mass * (result.x - exact) ** 2)))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.9), orders


def test_a_linear_system_takes_one_newton_step():
    A = sp.diags([-1.0, 4.0, -1.0], [-1, 0, 1], shape=(30, 30), format="csr")
    b = np.linspace(1.0, 2.0, 30)
    result = newton(lambda x: A @ x - b, lambda x: A, np.zeros(30), new_solver=DirectSolver, where=WHERE, fix=FIX)
    assert result.iterations == 1
    np.testing.assert_allclose(A @ result.x, b, rtol=1e-14)


def arctan_problem():
    """F(x) = arctan(x) = 0 componentwise from x0 ∈ [1.45, 2]: plain Newton's steps
    x − (1 + x²) arctan(x) overshoot the root 0 further each time (|x0| > 1.3917)."""
    return (np.arctan, lambda x: sp.diags(1.0 / (1.0 + x ** 2), format="csr"), np.linspace(1.45, 2.0, 12))


def test_the_line_search_rescues_newton_where_full_steps_overshoot():
    residual, jacobian, x0 = arctan_problem()
    with pytest.raises(NewtonDivergence), np.errstate(over="ignore"):
        newton(residual, jacobian, x0, new_solver=DirectSolver, where=WHERE, fix=FIX, line_search=False)
    result = newton(residual, jacobian, x0, new_solver=DirectSolver, where=WHERE, fix=FIX)
    assert np.max(np.abs(result.x)) < 1e-12
    assert result.iterations <= 12
    assert np.all(np.diff(result.residual_norms) < 0)  # ‖F‖ decreases every iteration
    assert result.residual_evaluations > result.iterations + 1  # some steps were damped


def test_simplified_newton_reuses_the_factorization_and_reaches_the_same_root():
    residual, jacobian, exact, _ = cubic_problem(16)
    full = newton(residual, jacobian, np.zeros_like(exact), new_solver=DirectSolver, where=WHERE, fix=FIX)
    chord = newton(residual, jacobian, np.zeros_like(exact), new_solver=DirectSolver, where=WHERE, fix=FIX,
                   simplified=True, max_iterations=60)
    assert chord.factorizations < chord.iterations
    assert chord.residual_norms[-1] <= 1e-12 + 1e-10 * chord.residual_norms[0]
    np.testing.assert_allclose(chord.x, full.x, rtol=1e-8, atol=1e-10)


def message_pattern(reason: str) -> str:
    number = r"(\d\.\d{3}e[+-]\d\d|inf)"
    return (rf"^{re.escape(WHERE)}: Newton's method did not converge: {reason} \(last residual ‖F‖ = {number} "
            rf"after \d+ iterations, initial {number}\); {re.escape(FIX)}$")


def test_non_convergence_is_one_line_naming_the_equation_the_residual_and_the_fix():
    residual, jacobian, exact, _ = cubic_problem(8)
    with pytest.raises(NewtonDivergence) as info:
        newton(residual, jacobian, np.zeros_like(exact), new_solver=DirectSolver, where=WHERE, fix=FIX,
               max_iterations=2)
    error = info.value
    assert isinstance(error, ModelError) and "\n" not in str(error)
    assert re.match(message_pattern(r"‖F‖ not below \S+ in 2 iterations"), str(error)), str(error)
    assert error.where == WHERE and error.fix == FIX and len(error.residual_norms) == 3
    assert f"{error.residual_norms[-1]:.3e}" in str(error)


def test_a_system_without_a_root_is_refused():
    """x² + 1 = 0 has no real root: ‖F‖ cannot go below 1, the line search finds no decrease."""
    with pytest.raises(NewtonDivergence) as info:
        newton(lambda x: x ** 2 + 1, lambda x: sp.diags(2 * x, format="csr"), np.full(5, 0.7),
               new_solver=DirectSolver, where=WHERE, fix=FIX)
    assert re.match(message_pattern(r"(no decrease of ‖F‖ along the Newton direction|the linear solve with the "
                                    r"Jacobian failed \(.*\)|‖F‖ not below \S+ in 25 iterations)"), str(info.value))
    assert info.value.residual_norms[-1] >= np.sqrt(5) * (1 - 1e-12)


def test_a_singular_jacobian_and_a_non_finite_residual_are_refused():
    with pytest.raises(NewtonDivergence, match=r"the linear solve with the Jacobian failed \(direct solver: "):
        newton(lambda x: x - 1, lambda x: sp.csr_matrix((3, 3)), np.zeros(3), new_solver=DirectSolver,
               where=WHERE, fix=FIX)
    with pytest.raises(NewtonDivergence, match=message_pattern("the residual at the initial guess is not finite")), \
            np.errstate(invalid="ignore"):
        newton(np.log, lambda x: sp.diags(1 / x, format="csr"), -np.ones(3), new_solver=DirectSolver,
               where=WHERE, fix=FIX)


def test_a_tolerance_below_round_off_stops_at_the_root_to_working_precision():
    """rtol = atol = 0 cannot be met in floating point: Newton stops when its step can no longer
    change x (or the full step is below √ε with no decrease of ‖F‖ left) — converged, not refused."""
    residual, jacobian, exact, _ = cubic_problem(16)
    reference = newton(residual, jacobian, np.zeros_like(exact), new_solver=DirectSolver, where=WHERE, fix=FIX)
    exactly = newton(residual, jacobian, np.zeros_like(exact), new_solver=DirectSolver, where=WHERE, fix=FIX,
                     rtol=0.0, atol=0.0)
    assert exactly.iterations <= reference.iterations + 2
    np.testing.assert_allclose(exactly.x, reference.x, rtol=1e-13, atol=1e-14)
    assert exactly.residual_norms[-1] < 1e-13 * exactly.residual_norms[0]


def test_a_step_tolerance_stops_after_a_small_newton_step_with_an_error_of_its_square():
    residual, jacobian, exact, _ = cubic_problem(16)
    reference = newton(residual, jacobian, np.zeros_like(exact), new_solver=DirectSolver, where=WHERE, fix=FIX)
    result = newton(residual, jacobian, np.zeros_like(exact), new_solver=DirectSolver, where=WHERE, fix=FIX,
                    rtol=0.0, atol=0.0, step_tolerance=1e-2)
    assert result.stopped_by == "step" and reference.stopped_by == "residual"
    assert result.iterations < reference.iterations
    assert np.linalg.norm(result.x - reference.x) < 1e-2 ** 2  # the last step ‖Δ‖ ≤ 1e-2 leaves O(‖Δ‖²)
