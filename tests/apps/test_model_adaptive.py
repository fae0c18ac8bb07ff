"""BDF and Radau get the sparse Jacobian pattern of the equations — nonzeros exactly where the
operators and the value-by-value terms put them, never a dense n × n Jacobian — and an
adaptive run records the steps its solver accepted."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from decrun.core.solvers import solver_factory
from decrun.methods.model.integrators import make_integrator
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import prepare, run_experiment


def prepared(overrides):
    run = prepare(compose_config(list(overrides) + ["figures=false"]))
    app, dec = run.experiment.app, run.dec
    model = app.compiled(dec, solver_factory("auto"))
    return app, dec, model, make_integrator(model, str(app.integrator), app.dt, solver_factory("auto"))


@pytest.mark.parametrize("scheme", ["bdf", "radau"])
def test_the_jacobian_pattern_is_the_operators_nonzeros(scheme):
    """Gray–Scott: ∂(Du Δu − u v² + F(1 − u))/∂(u, v) and ∂(Dv Δv + u v² − (F + k) v)/∂(u, v)
    have the stiffness S = d0ᵀ⋆1d0's pattern in the diagonal blocks (its stored entries: the
    vertex adjacency and the diagonal) and the identity's off the diagonal (u v² couples u
    and v value by value) — compared entry by entry, and far from dense."""
    app, dec, model, integrator = prepared(["app=gray_scott", f"app.integrator={scheme}"])
    assert integrator.jacobian is None  # nonlinear: finite differences on the pattern
    pattern = sp.csr_matrix(integrator.pattern)
    S = sp.csr_matrix(dec.d(0).T @ dec.star(1) @ dec.d(0))
    n = S.shape[0]
    diagonal = (abs(S) + sp.identity(n)).astype(bool).astype(np.float64)
    identity = sp.identity(n)
    expected = sp.bmat([[diagonal, identity], [identity, diagonal]], format="csr").astype(bool)
    assert pattern.shape == (2 * n, 2 * n)
    assert (pattern.astype(bool) != expected).nnz == 0
    assert pattern.nnz == expected.nnz < 0.05 * (2 * n) ** 2


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
