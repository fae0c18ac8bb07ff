"""A step's environment (decrun.methods.model.environment): the definitions only metrics and
records read (Halfar's exact solution and error) are deferred until read — and then equal, bit
for bit, to the complete environment's values; the step reads none of them."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from decrun.core.solvers import solver_factory
from decrun.methods.model.environment import Environment, deferred_names
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import prepare


@lru_cache(maxsize=None)
def halfar():
    """The shipped Halfar model (conf/app/halfar.yaml) compiled on its default 4 km grid."""
    run = prepare(compose_config(["app=halfar", "figures=false", "progress=false", "app.stability_check=false"]))
    return run.experiment.app.compiled(run.dec, solver_factory("auto"))


def state(model) -> dict:
    return {name: np.asarray(model.initial_values[name], dtype=np.float64) for name in model.evolved}


def test_the_definitions_only_metrics_read_are_deferred():
    model = halfar()
    assert deferred_names(model) == {"t0", "s", "H_exact", "ice", "H_error"}  # the exact solution and the error
    env = model.environment(state(model), 5.0)
    assert isinstance(env, Environment)
    assert {"grad2", "D", "Gamma"} <= set(env) and not set(env) & deferred_names(model)


def test_a_deferred_definition_read_is_the_complete_environments_value():
    model = halfar()
    complete = model.environment(state(model), 5.0, complete=True)
    assert deferred_names(model) <= set(complete)
    lazy = model.environment(state(model), 5.0)
    np.testing.assert_array_equal(lazy["H_error"], complete["H_error"])  # computes t0, s, H_exact, ice, H_error
    assert deferred_names(model) <= set(lazy)
    for name in complete:
        np.testing.assert_array_equal(lazy[name], complete[name])
    with pytest.raises(KeyError, match="nothing_defines_this"):
        lazy["nothing_defines_this"]


def test_the_evolution_reads_no_deferred_definition():
    """dt(H) (the evolution's right side, explicit integrators' stage) and the semi-implicit
    step's lagged matrix read the step's environment without computing a deferred name."""
    from decrun.methods.model.integrators import make_integrator

    model = halfar()
    env = model.environment(state(model), 0.0)
    rate = model.derivative(env)["H"]
    assert np.isfinite(rate).all() and np.abs(rate).max() > 0
    integrator = make_integrator(model, "semi_implicit", 1.0, solver_factory("auto"))
    M, blocks = integrator._row("H", env)
    assert blocks["H"].nnz > 0
    assert not set(env) & deferred_names(model)
