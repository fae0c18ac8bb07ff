"""BDF and Radau get the exact sparse Jacobian from the derivative rules (diagonal masses) or else
the sparse Jacobian pattern of the equations — nonzeros exactly where the operators and the
value-by-value terms put them, never a dense n × n Jacobian — and an adaptive run records the
steps its solver accepted."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from decrun.core.solvers import solver_factory
from decrun.methods.model.integrators import jacobian_pattern, make_integrator
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import prepare, run_experiment


def prepared(overrides):
    run = prepare(compose_config(list(overrides) + ["figures=false"]))
    app, dec = run.experiment.app, run.dec
    model = app.compiled(dec, solver_factory("auto"))
    return app, dec, model, make_integrator(model, str(app.integrator), app.dt, solver_factory("auto"))


@pytest.mark.parametrize("scheme", ["bdf", "radau"])
def test_the_jacobian_pattern_is_the_operators_nonzeros(scheme):
    """Gray–Scott under operator=whitney (a Galerkin ⋆0: M⁻¹ is dense, so no exact sparse ∂F/∂u):
    ∂(Du Δu − u v² + F(1 − u))/∂(u, v) and ∂(Dv Δv + u v² − (F + k) v)/∂(u, v) have the
    P1 stiffness S's pattern in the diagonal blocks (its stored entries: the vertex adjacency and
    the diagonal) and the identity's off the diagonal (u v² couples u and v value by value) —
    compared entry by entry, and far from dense."""
    app, dec, model, integrator = prepared(["app=gray_scott", f"app.integrator={scheme}", "operator=whitney"])
    assert integrator.pattern is None  # its derivative rules give the lumped Jacobian instead (test below)
    pattern = _structure(jacobian_pattern(model))  # the pattern a term without them would use
    S = model.evolution.blocks[("u", "u")]  # the weak Laplacian block: the P1 stiffness, stored entries
    n = S.shape[0]
    diagonal = _structure(_structure(S) + sp.identity(n))
    identity = sp.identity(n)
    expected = _structure(sp.bmat([[diagonal, identity], [identity, diagonal]], format="csr"))
    assert pattern.shape == (2 * n, 2 * n)
    difference = (pattern - expected).tocsr()
    difference.eliminate_zeros()
    assert difference.nnz == 0
    assert pattern.nnz == expected.nnz < 0.05 * (2 * n) ** 2


def _structure(A) -> sp.csr_matrix:
    """A's stored entries as ones (explicit zeros included)."""
    A = sp.csr_matrix(A, copy=True)
    A.sum_duplicates()
    A.data[:] = 1.0
    return A


@pytest.mark.parametrize("scheme", ["bdf", "radau"])
def test_a_nonlinear_model_hands_bdf_the_exact_jacobian_of_its_derivative_rules(scheme):
    """Gray–Scott (diagonal ⋆0): ∂F/∂(u, v) = M⁻¹A + ∂R/∂(u, v) from the derivative pass, sparse
    within the operators' pattern, equal to central differences of F, with the border-free rows."""
    app, dec, model, integrator = prepared(["app=gray_scott", f"app.integrator={scheme}"])
    assert integrator.jacobian is None and integrator.pattern is None and integrator.exact is not None
    evolution = model.evolution
    y = evolution.stack(model.initial_values)
    J = integrator.exact(0.0, y)
    n = J.shape[0] // 2
    assert sp.issparse(J) and J.nnz < 0.05 * J.shape[0] ** 2

    def F(y):
        return evolution.stack(model.derivative(model.environment(evolution.unstack(y), 0.0)))
    w = np.random.default_rng(0).standard_normal(y.size)
    eps = 1e-6
    numeric = (F(y + eps * w) - F(y - eps * w)) / (2 * eps)
    assert np.abs(J @ w - numeric).max() <= 1e-6 * np.abs(numeric).max()
    assert n == dec.K.num_simplices(0)


def test_a_linear_model_hands_bdf_its_exact_sparse_jacobian():
    """Heat: ∂F/∂u is the constant M⁻¹A = −⋆0⁻¹ S (k = 1), handed to BDF exactly (sparse)."""
    app, dec, model, integrator = prepared(["app=heat", "app.integrator=bdf", "mesh.subdiv=2"])
    m = np.asarray(dec.star(0).diagonal())
    S = dec.d(0).T @ dec.star(1) @ dec.d(0)
    assert sp.issparse(integrator.jacobian)
    difference = integrator.jacobian - (-app.constants["k"] * sp.diags(1.0 / m) @ S)
    assert abs(difference).max() <= 1e-12 * abs(integrator.jacobian).max()


@pytest.mark.parametrize("scheme", ["bdf", "radau", "rk45"])
def test_an_adaptive_run_records_its_accepted_steps(scheme):
    """accepted_steps (the solver's accepted steps over the run, at least one per output step)
    and rhs_evaluations are metrics of the run; a fixed-step run has neither."""
    base = ["app=heat", "mesh.subdiv=2", "app.dt=0.02", "app.t_end=0.1", "figures=false"]
    metrics = run_experiment(compose_config(base + [f"app.integrator={scheme}"])).result.metrics
    assert metrics["steps_done"] == 5
    assert isinstance(metrics["accepted_steps"], int) and metrics["accepted_steps"] >= 5
    assert metrics["rhs_evaluations"] >= metrics["accepted_steps"]
    fixed = run_experiment(compose_config(base + ["app.integrator=crank_nicolson"])).result.metrics
    assert "accepted_steps" not in fixed and "rhs_evaluations" not in fixed


@pytest.mark.parametrize("scheme", ["bdf", "radau"])
def test_a_galerkin_mass_hands_bdf_its_lumped_mass_times_the_exact_jacobian(scheme):
    """operator=whitney (⋆0 the P1 mass M, M⁻¹ dense), fixed border values, a nonlinear term:
    the Jacobian is M_L⁻¹ ∂f/∂y at the free rows (M_L = diag of M_FF's row sums, all > 0; ∂f/∂y
    equal to central differences of the weak right side f) and 0 at the fixed rows."""
    app, dec, model, integrator = prepared(["app=heat", "mesh=grid", "mesh.nx=4", "mesh.ny=4", "operator=whitney",
                                            "~app.require", "app.fields.u.initial='1 + x*y'",
                                            "app.equations=['dt(u) = laplacian(u) - u**2']",
                                            "+app.fields.u.dirichlet='1 + x*y'", f"app.integrator={scheme}"])
    assert integrator.pattern is None and integrator.jacobian is None
    problem = model.problem
    assert problem.mass is not None and problem.fixed_index.size > 0
    row_sums = np.asarray(problem.mass.sum(axis=1)).ravel()
    assert row_sums.min() > 0
    x = model.evolution.stack(model.initial_values)
    J = integrator.exact(0.0, x)
    assert sp.issparse(J) and J.shape == (problem.total, problem.total)
    assert abs(J[problem.fixed_index]).max() == 0.0
    w = np.zeros(problem.total)
    w[problem.free] = np.random.default_rng(1).standard_normal(problem.size)
    y, eps = x[problem.free], 1e-6
    numeric = (problem.f(y + eps * w[problem.free], 0.0) - problem.f(y - eps * w[problem.free], 0.0)) / (2 * eps)
    assert np.abs((J @ w)[problem.free] - numeric / row_sums).max() <= 1e-6 * np.abs(numeric / row_sums).max()


#: the manufactured heat equation with moving border values of tests/apps/test_model_moving_steppers.py
C = "cos(pi*x)*cos(pi*y)"
U_HEAT = f"({C}*cos(t) + t*(x**2 + y))"
F_HEAT = f"(-sin(t)*{C} + x**2 + y + 2*pi**2*cos(t)*{C} - 2*t)"


def test_the_lumped_jacobian_saves_bdf_and_radau_steps_on_a_galerkin_mass():
    """The manufactured heat with moving border values under operator=whitney on an 11 × 11 grid
    (rtol 1e-9): bdf and radau end within 1e-7 of radau_iia, in fewer than 1,000 and 500 accepted
    steps (measured 442 and 230 with M_L⁻¹ ∂f/∂y; 9,295 and 12,047 with finite differences on
    the equations' pattern)."""
    def run(integrator: str):
        result = run_experiment(compose_config([
            "figures=false", "progress=false", "app=heat", "mesh=grid", "mesh.nx=10", "mesh.ny=10",
            "operator=whitney", "~app.require", f"app.fields.u.initial='{C}'",
            f"app.equations=['dt(u) = laplacian(u) + {F_HEAT}']", f"+app.fields.u.dirichlet='{U_HEAT}'",
            f"app.integrator={integrator}", "app.dt=0.01", "app.t_end=0.2", "app.rtol=1e-9", "app.atol=1e-11",
            "app.stability_check=false"])).result
        return np.asarray(result.fields["u"]), result.metrics.get("accepted_steps")

    reference, _ = run("radau_iia")
    for integrator, bound in (("bdf", 1000), ("radau", 500)):
        u, steps = run(integrator)
        assert np.abs(u - reference).max() < 1e-7, integrator
        assert steps < bound, (integrator, steps)
