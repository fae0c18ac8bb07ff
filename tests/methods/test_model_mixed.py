"""The Galerkin (Whitney) 1-form Laplacian in implicit integrators (methods/model/mixed.py):
``dt(w) = laplacian(w)`` under operator=whitney as M y' = L y in its mixed form, y = (w, p = δw).

On a closed sphere (no harmonic 1-forms) the discrete flow is the generalized eigenproblem
⋆1Δ1 φ = λ M1 φ with ⋆1Δ1 = B ⋆0⁻¹ Bᵀ + C dense; an eigenmode's amplitude after N steps is
R(−λ dt)^N exactly, R the scheme's stability function — so the steppers run the dense ODE, not an
approximation of it — and Crank–Nicolson's error on smooth data falls at order 2."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from test_model_operators import dec_of

from decrun.core.solvers import solver_factory
from decrun.methods.model import FieldSpec, ModelError, ModelSpec, compile_model
from decrun.methods.model.integrators import check_integrator, make_integrator
from decrun.methods.model.mixed import MixedProblem, implicit_problem

#: stability functions R(z) of the schemes (z = −λ dt)
STABILITY = {
    "implicit_euler": lambda z: 1 / (1 - z),
    "crank_nicolson": lambda z: (1 + z / 2) / (1 - z / 2),
    "gauss_legendre": lambda z: (1 + z / 2 + z ** 2 / 12) / (1 - z / 2 + z ** 2 / 12),
    "radau_iia": lambda z: (1 + 2 * z / 5 + z ** 2 / 20) / (1 - 3 * z / 5 + 3 * z ** 2 / 20 - z ** 3 / 60),
}


def _model(equation="dt(w) = laplacian(w)"):
    dec = dec_of("sphere", "whitney")
    spec = ModelSpec(fields={"w": FieldSpec(1, 0.0)}, equations=[equation], dt=0.01)
    return dec, compile_model(spec, dec, solver_factory("auto"))


def _spectrum(dec):
    """(λ ascending, M1-orthonormal φ) of B ⋆0⁻¹ Bᵀ + C against M1 (dense)."""
    M0, M1, M2 = (dec.star(k).toarray() for k in range(3))
    d0, d1 = dec.d(0).toarray(), dec.d(1).toarray()
    B = M1 @ d0
    stiffness = B @ np.linalg.solve(M0, B.T) + d1.T @ M2 @ d1
    return scipy.linalg.eigh(stiffness, M1)


def _run(model, scheme, w0, dt, steps):
    stepper = make_integrator(model, scheme, dt, solver_factory("auto"))
    state, t = {"w": w0.copy()}, 0.0
    for _ in range(steps):
        state = stepper.step(state, t)
        t += dt
    return state["w"]


def test_the_mixed_form_is_the_galerkin_laplacian():
    """f(y) at consistent p equals ⋆1 · laplacian(w) as the explicit evaluator computes it (with
    ⋆0⁻¹ a factorized solve), and L is sparse."""
    dec, model = _model()
    problem = implicit_problem(model)
    assert isinstance(problem, MixedProblem)
    w = np.random.default_rng(0).standard_normal(dec.K.num_simplices(1))
    y = problem.free_values({"w": w})
    explicit = model.derivative(model.environment({"w": w}, 0.0))["w"]
    n1 = w.size
    np.testing.assert_allclose(problem.f(y, 0.0)[:n1], dec.star(1) @ explicit, atol=1e-10 * np.abs(dec.star(1) @ explicit).max())
    np.testing.assert_allclose(problem.f(y, 0.0)[n1:], 0.0, atol=1e-12 * np.abs(w).max())
    assert problem.stiff.nnz < 0.05 * problem.size ** 2


@pytest.mark.parametrize("scheme", sorted(STABILITY))
def test_the_lowest_mode_decays_by_the_schemes_stability_function(scheme):
    """φ₁ (the smallest eigenvalue λ₁ > 0: the sphere has no harmonic 1-forms) after N steps is
    R(−λ₁ dt)^N φ₁ to 1e-9, and within the scheme's error of e^{−λ₁ T} φ₁."""
    dec, model = _model()
    eigenvalues, vectors = _spectrum(dec)
    assert eigenvalues[0] > 1e-6 * eigenvalues[-1]
    lam, phi = eigenvalues[0], vectors[:, 0]
    dt, steps = 0.2 / lam, 10
    w = _run(model, scheme, phi, dt, steps)
    amplitude = STABILITY[scheme](-lam * dt) ** steps
    np.testing.assert_allclose(w, amplitude * phi, atol=1e-9 * np.abs(phi).max())
    assert abs(amplitude - np.exp(-lam * dt * steps)) < {"implicit_euler": 0.05}.get(scheme, 2e-3)


def test_crank_nicolson_converges_at_order_2():
    """Smooth data (the 6 lowest modes) to T = 0.5/λ₁ against the exact e^{−tΔ} of the dense
    problem: the error falls by ≈ 4 per halving of dt."""
    dec, model = _model()
    eigenvalues, vectors = _spectrum(dec)
    w0 = vectors[:, :6] @ np.linspace(1.0, 0.5, 6)
    T = 0.5 / eigenvalues[0]
    exact = vectors[:, :6] @ (np.linspace(1.0, 0.5, 6) * np.exp(-eigenvalues[:6] * T))
    errors = [np.abs(_run(model, "crank_nicolson", w0, T / steps, steps) - exact).max() for steps in (8, 16, 32)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.9), orders


def test_bdf_is_refused_in_one_line_naming_what_runs_it():
    _, model = _model("dt(w) = 0.5*laplacian(w)")
    with pytest.raises(ModelError, match="app.integrator=radau_iia") as caught:
        check_integrator(model, "bdf", 0.01)
    assert "\n" not in str(caught.value) and str(caught.value).startswith("app.equations[0]: 0.5 * laplacian(w)")
    check_integrator(model, "radau_iia", 0.01)  # what the message names runs


def test_a_nonlinear_term_beside_the_galerkin_laplacian_has_its_exact_jacobian():
    """dt(w) = laplacian(w) − w³ (value by value on edges): the mixed problem's Jacobian L + M ∂R/∂y
    equals central differences of its f, and radau_iia steps it (Newton converges)."""
    dec, model = _model("dt(w) = laplacian(w) - w**3")
    problem = implicit_problem(model)
    assert isinstance(problem, MixedProblem)
    rng = np.random.default_rng(1)
    y = problem.free_values({"w": rng.standard_normal(dec.K.num_simplices(1))})
    direction = rng.standard_normal(problem.size)
    eps = 1e-6
    numeric = (problem.f(y + eps * direction, 0.0) - problem.f(y - eps * direction, 0.0)) / (2 * eps)
    assert np.abs(problem.jacobian(y, 0.0) @ direction - numeric).max() <= 1e-6 * np.abs(numeric).max()
    w = _run(model, "radau_iia", problem.state(y)["w"], 0.01, 3)
    assert np.all(np.isfinite(w)) and np.abs(w).max() < np.abs(problem.state(y)["w"]).max()
