"""Reaction–diffusion models of the model app (conf/app/gray_scott.yaml, brusselator.yaml,
cahn_hilliard.yaml): each against the same scheme written by hand in numpy, or against its
linear theory (MODELS.md, "Reaction–diffusion")."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.core.solvers import solver_factory
from decrun.methods.model.integrators import make_integrator
from decrun.runner.config import compose_config
from decrun.runner.run import prepare, run_experiment


def prepared(overrides):
    """(app, dec, compiled model, integrator) of ``decrun <overrides>``, nothing run yet."""
    run = prepare(compose_config(list(overrides) + ["figures=false"]))
    app, dec = run.experiment.app, run.dec
    model = app.compiled(dec, solver_factory("direct"))
    integrator = make_integrator(model, str(app.integrator), app.dt, solver_factory("direct"))
    return app, dec, model, integrator


def metrics(overrides):
    return run_experiment(compose_config(list(overrides) + ["figures=false"])).result.metrics


def mass_and_stiffness(dec):
    """M = ⋆0 (diagonal) and S = d0ᵀ ⋆1 d0 (the cotan stiffness), straight from DEC."""
    m = np.asarray(dec.star(0).diagonal(), dtype=np.float64)
    S = (dec.d(0).T @ dec.star(1) @ dec.d(0)).tocsc()
    return m, S


def steps(model, integrator, count):
    state = {u: np.array(model.initial_values[u], dtype=np.float64) for u in model.evolved}
    for n in range(count):
        state = integrator.step(state, n * integrator.dt)
    return state


# ---------------------------------------------------------------------------- Gray–Scott
def test_gray_scott_equals_the_hand_written_imex_step():
    """100 IMEX Euler steps of the model equal the same scheme written with M = ⋆0 and
    S = d0ᵀ⋆1d0: every linear term implicit, the rest explicit, one factorization each."""
    app, dec, model, integrator = prepared(["app=gray_scott"])
    c = app.constants
    Du, Dv, F, k, dt = c["Du"], c["Dv"], c["F"], c["k"], app.dt
    m, S = mass_and_stiffness(dec)
    M = sp.diags(m)
    solve_u = spla.factorized((M + dt * (Du * S + F * M)).tocsc())
    solve_v = spla.factorized((M + dt * (Dv * S + (F + k) * M)).tocsc())
    u = np.array(model.initial_values["u"])
    v = np.array(model.initial_values["v"])
    for _ in range(100):
        uvv = u * v * v
        u, v = solve_u(m * u + dt * m * (F - uvv)), solve_v(m * v + dt * m * uvv)
    state = steps(model, integrator, 100)
    assert np.abs(state["u"] - u).max() <= 1e-12 * np.abs(u).max()
    assert np.abs(state["v"] - v).max() <= 1e-12 * max(np.abs(v).max(), 1e-300)
    assert np.abs(v).max() > 0.1  # the comparison is not of two zero fields


def test_gray_scott_default_grows_a_pattern_and_a_stable_pair_stays_uniform():
    """The default (spots) pair forms a pattern (v_std > 0.02); at (F, k) = (0.06, 0.075)
    (beyond the spot region) the seed dies and the uniform (u, v) = (1, 0) remains."""
    spots = metrics(["app=gray_scott", "app.steps=1500"])
    assert spots["stable"] and spots["v_std"] > 0.02 and spots["pattern"] == 1.0
    uniform = metrics(["app=gray_scott", "app.steps=1500", "app.constants.F=0.06", "app.constants.k=0.075"])
    assert uniform["stable"] and uniform["v_std"] < 1e-6 and uniform["pattern"] == 0.0
    assert abs(uniform["u_min"] - 1) < 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("experiment, F, k, formed", [
    ("gray_scott_pearson", 0.035, 0.065, True), ("gray_scott_pearson", 0.04, 0.06, True),
    ("gray_scott_pearson", 0.06, 0.075, False), ("gray_scott_sphere", 0.035, 0.065, True),
    ("gray_scott_sphere", 0.04, 0.06, True), ("gray_scott_sphere", 0.06, 0.075, False)])
def test_gray_scott_pearson_regimes_on_the_square_and_the_sphere(experiment, F, k, formed):
    result = metrics([f"+experiment={experiment}", f"app.constants.F={F}", f"app.constants.k={k}"])
    assert result["stable"] and (result["v_std"] > 0.02) == formed and result["pattern"] == float(formed)
