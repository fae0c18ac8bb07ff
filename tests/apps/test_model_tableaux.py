"""The tableau integrators as ``app.integrator`` values (issue 47): gauss_legendre, radau_iia,
ssprk3 and ark_imex (h/integrators' Runge–Kutta steppers from Butcher tableaux) step a compiled
model through its ``Problem``, at their orders in time, and resume from a checkpoint's state bit
for bit; the registry and the config's choices list the same integrators."""

from __future__ import annotations

import numpy as np
import pytest

from decrun.apps.model import Integrator
from decrun.core.solvers import solver_factory
from decrun.methods.model.integrators import INTEGRATORS, SCHEMES, make_integrator
from decrun.methods.model.stepper import ModelStepper
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import prepare, run_experiment

#: the logistic reaction–diffusion of the issue's goal table, on the coarse sphere
LOGISTIC = ["app=heat", "mesh.subdiv=1", "app.t_end=1.6", "app.fields.u.initial=0.5 + 0.3*x*y",
            "app.equations=['dt(u) = 0.01*laplacian(u) + u*(1 - u)']", "+app.metrics.probe='inner(u, u)'",
            "app.stability_check=false", "figures=false", "progress=false"]
#: integrator → the least observed order the issue asks for
GOALS = {"gauss_legendre": 3.7, "radau_iia": 4.4, "ssprk3": 2.7, "ark_imex": 1.8}


def _probe(scheme: str, dt: float) -> float:
    overrides = [*LOGISTIC, f"app.integrator={scheme}", f"app.dt={dt}"]
    return run_experiment(compose_config(overrides)).result.metrics["probe"]


def test_the_registry_and_the_configs_choices_agree():
    assert list(SCHEMES) == list(INTEGRATORS) and sorted(Integrator.names()) == sorted(SCHEMES)
    for name in GOALS:
        assert SCHEMES[name].tableau is not None and SCHEMES[name].order >= GOALS[name]


@pytest.mark.parametrize("scheme", sorted(GOALS))
def test_a_tableau_integrator_converges_at_its_order_on_a_nonlinear_model(scheme):
    """Self-convergence against radau_iia at dt = 0.0125 (error below 1e-13): dt = 0.2, 0.1, 0.05
    give observed orders above the issue's goals (4 Gauss, 5 Radau IIA, 3 SSPRK3, 3 ARK3(2)4L)."""
    reference = _probe("radau_iia", 0.0125)
    errors = np.array([abs(_probe(scheme, dt) - reference) for dt in (0.2, 0.1, 0.05)])
    orders = np.log2(errors[:-1] / errors[1:])
    assert orders.min() >= GOALS[scheme], (errors, orders)


@pytest.mark.parametrize("scheme", sorted(GOALS))
def test_a_tableau_integrator_resumes_from_its_state_bit_for_bit(scheme):
    """Six steps in one go equal three steps, the stepper's state (what a checkpoint holds) put
    into a new stepper, and three more: bitwise, fields and counters."""
    run = prepare(compose_config([*LOGISTIC, f"app.integrator={scheme}", "app.dt=0.1"]))
    model = run.experiment.app.compiled(run.dec, solver_factory("auto"))

    def stepper():
        return ModelStepper(model, make_integrator(model, scheme, 0.1, solver_factory("auto")), 0.1)
    whole = stepper()
    for n in range(1, 7):
        assert whole.step(n) == ""
    first = stepper()
    for n in range(1, 4):
        first.step(n)
    saved = first.state_dict()
    second = stepper()
    second.load_state(saved)
    for n in range(4, 7):
        second.step(n)
    assert np.array_equal(second.state["u"], whole.state["u"]) and second.t == whole.t
    assert second.integrator.state_dict() == whole.integrator.state_dict()
