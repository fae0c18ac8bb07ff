"""The metrics every model run reports besides the declared ones."""

from __future__ import annotations

from typing import Any

import numpy as np

from decrun.methods.model.finite import nonfinite_definitions

__all__ = ["model_metrics", "metric_values"]


def metric_values(model, env: dict) -> dict[str, float]:
    """Each declared metric's value at ``env``, one by one: a metric whose evaluation fails is nan
    — its error kept in ``model.metric_errors`` (name → one line) for the run's warnings — so
    that it never loses the run's result nor the other metrics. Numbers follow IEEE 754 (1/0 is
    inf), without numpy's warnings: a non-finite metric is reported by name at the end."""
    values, errors = {}, {}
    for name, closure in model.metrics.items():
        try:
            with np.errstate(all="ignore"):
                values[name] = float(closure(env))
        except Exception as error:  # noqa: BLE001 - reported by name, the run goes on
            values[name] = float("nan")
            errors[name] = f"{type(error).__name__}: {str(error).splitlines()[0] if str(error) else ''}"
    model.metric_errors = errors
    return values


def model_metrics(model, env: dict, report=None, *, integrator=None, dt: float, integrator_name: str,
                  stability_limit: float | None = None) -> dict[str, Any]:
    """The declared metrics at the end (``env``) and their names (``headline_metrics``, which a
    sweep table shows by default), then: ``stable`` (no step blew up, every
    declared metric is finite and so is every definition's value), ``unstable_reason``/``diverged_at_step`` (only when not),
    the driver's ``steps_done``, ``solve_seconds``, ``steps_per_second``, ``step_seconds_max``,
    ``resumed_from_step`` (time-dependent models), ``t_final``, ``dt``, ``integrator``,
    ``dt_stability_limit`` and ``dt_over_stability_limit`` (explicit integrators with a
    diffusion block), ``accepted_steps`` and ``rhs_evaluations`` (adaptive integrators), ``factorizations``
    (semi_implicit: one per step), ``<unknown>_newton_iterations`` per nonlinear solve (its last
    solve's), and per
    singular solve ``<unknown>_kernel_pieces``, ``<unknown>_rhs_mean_removed`` (the part of
    the right side along the kernel that was removed, relative) and ``<unknown>_rhs_mean`` (the
    mean that was subtracted, in the right side's units)."""
    with np.errstate(all="ignore"):
        declared = model.metric_values(env)
    metrics: dict[str, Any] = dict(declared)
    if declared:  # the sweep table shows these by default (decrun.runner.sweep.tables.HEADLINE_COLUMN)
        metrics["headline_metrics"] = ",".join(declared)
    nonfinite = [name for name, value in declared.items() if not np.isfinite(value)]
    stable = True
    if report is not None:
        metrics.update(report.metrics())
        stable = report.stable
        metrics["t_final"] = float(env.get("t", 0.0))
        metrics["dt"] = float(dt)
        metrics["integrator"] = integrator_name
    if nonfinite and stable:
        stable = False
        metrics["unstable_reason"] = f"non-finite metric {nonfinite[0]}"
    definitions = nonfinite_definitions(model, env)  # v = 1/x with a vertex at x = 0 is no answer
    if definitions and stable:
        stable = False
        metrics["unstable_reason"] = f"non-finite definition {next(iter(definitions))}"
    metrics["stable"] = bool(stable)
    if stability_limit is not None and np.isfinite(stability_limit):
        metrics["dt_stability_limit"] = float(stability_limit)
        metrics["dt_over_stability_limit"] = float(dt / stability_limit)
    state = integrator.state_dict() if integrator is not None else {}
    if "accepted" in state:
        metrics["accepted_steps"] = int(state["accepted"])
        metrics["rhs_evaluations"] = int(state["evaluations"])
    if "factorizations" in state:
        metrics["factorizations"] = int(state["factorizations"])
    for what, item in model.order:  # nonlinear solves: Newton's iterations of the last solve
        if what == "newton" and item.iterations:
            metrics[f"{item.unknown}_newton_iterations"] = int(item.iterations[-1])
    for name, kernel in model.solve_reports().items():
        metrics[f"{name}_kernel_pieces"] = int(kernel.pieces)
        metrics[f"{name}_rhs_mean_removed"] = float(kernel.removed)
        metrics[f"{name}_rhs_mean"] = float(kernel.mean)
    return metrics
