"""Newton's method for ``solve(...)`` with a left side nonlinear in its unknown (issue 47): the
exact sparse Jacobian from the derivative pass, methods/model/newton.py's damped Newton, the
metric ``<u>_newton_iterations`` and the series ``<u>_newton_residuals``, and a one-line refusal
naming the equation and the override that fixes it (the test runs that override)."""

from __future__ import annotations

import json

import numpy as np

from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment

from cli_processes import decrun

#: −Δu + u³ = f on the unit square with u = sin(πx) cos(πy) + x² (app=poisson's exact solution
#: and border values): f = 2π² sin(πx) cos(πy) − 2 + u³
CUBIC = ("solve(-laplacian(u) + u**3 = 2*pi**2*sin(pi*x)*cos(pi*y) - 2 + (sin(pi*x)*cos(pi*y) + x**2)**3)")


def _run(n: int):
    overrides = ["app=poisson", f"mesh.nx={n}", f"mesh.ny={n}", f"app.equations=['{CUBIC}']", "figures=false",
                 "progress=false"]
    return run_experiment(compose_config(overrides)).result


def test_newton_solves_the_manufactured_cubic_problem_quadratically_with_spatial_order_two():
    """Three refinements (h halves): ≤ 8 Newton iterations each, quadratic convergence visible
    in the residual norms (‖F_{k+1}‖ ≤ C ‖F_k‖² with one C over the iterations, and the last
    contraction far beyond linear), and the max error against the exact u of order ≥ 1.8."""
    errors = []
    for n in (9, 17, 33):
        result = _run(n)
        iterations = result.metrics["u_newton_iterations"]
        norms = np.asarray(result.series["u_newton_residuals"])
        assert 1 <= iterations <= 8 and norms.size == iterations + 1
        assert norms[-1] <= 1e-10 * norms[0] + 1e-12 * 10
        ratios = norms[2:] / norms[1:-1] ** 2  # quadratic: bounded, not growing like 1/‖F_k‖
        assert ratios.max() <= 10 * ratios.min() and ratios.max() < 1e-2
        errors.append(result.metrics["max_abs_error"])
    orders = np.log2(np.asarray(errors[:-1]) / np.asarray(errors[1:]))
    assert orders.min() >= 1.8, (errors, orders)


def test_newton_non_convergence_is_one_line_naming_the_equation_and_the_fix(tmp_path):
    """u³ = 1 from the start u = 0 has the singular Jacobian 3u² = 0: refused in one line naming
    app.equations[0] and the override of a start; that override converges (u = 1)."""
    common = ["app=poisson", "mesh.nx=5", "mesh.ny=5", "app.equations=['solve(u**3 = 1)']", "app.fields.u.dirichlet=1",
              "app.metrics={}", "figures=false", "progress=false"]
    refused = decrun(*common, cwd=tmp_path)
    lines = [line for line in refused.stderr.strip().splitlines() if line.strip()]
    assert refused.returncode != 0 and len(lines) == 1, refused.stderr
    assert lines[0].startswith("error: app.equations[0]: Newton's method did not converge")
    assert "`app.fields.u.initial=<expression>`" in lines[0]
    fixed = decrun(*common, "+app.fields.u.initial=2", "hydra.run.dir=fixed", cwd=tmp_path)
    assert fixed.returncode == 0, fixed.stderr
    metrics = json.loads((tmp_path / "fixed" / "metrics.json").read_text())
    assert 1 <= metrics["u_newton_iterations"] <= 8


def test_a_nonlinear_solve_whose_right_side_reads_its_unknown_is_refused(tmp_path):
    done = decrun("app=poisson", "mesh.nx=5", "mesh.ny=5", "app.equations=['solve(u**3 = u + 1)']", "app.metrics={}",
                  "figures=false", cwd=tmp_path)
    lines = [line for line in done.stderr.strip().splitlines() if line.strip()]
    assert done.returncode != 0 and len(lines) == 1
    assert lines[0].startswith("error: app.equations[0]: the right side u + 1 reads the unknown u"), lines[0]
    assert lines[0].endswith("'solve(u ** 3 - u = 1)'"), lines[0]  # the rewrite to run instead


def _final(equations: list[str], scheme: str, dt: float, metric: str, extra=()) -> float:
    overrides = ["app=heat", "mesh.subdiv=1", f"app.integrator={scheme}", f"app.dt={dt}", "app.t_end=0.4",
                 f"app.equations={equations!r}", f"+app.metrics.probe='{metric}'", "app.stability_check=false",
                 "figures=false", "progress=false", *extra]
    return run_experiment(compose_config(overrides)).result.metrics["probe"]


def test_implicit_euler_and_crank_nicolson_step_nonlinear_models_by_newton_at_their_orders():
    """dt(u) = 0.01 Δu − 0.1 cosh(u) (refused by both before: 'not linear'): against rk4 at a
    small step, implicit Euler's error halves with dt (order 1) and Crank–Nicolson's quarters
    (order 2)."""
    equations = ["dt(u) = 0.01*laplacian(u) - 0.1*cosh(u)"]
    reference = _final(equations, "rk4", 0.005, "integral(u)")
    for scheme, order in (("implicit_euler", 1), ("crank_nicolson", 2)):
        errors = [abs(_final(equations, scheme, dt, "integral(u)") - reference) for dt in (0.04, 0.02, 0.01)]
        measured = np.log2(np.asarray(errors[:-1]) / np.asarray(errors[1:]))
        assert np.all(np.abs(measured - order) < 0.15), (scheme, errors, measured)


def test_crank_nicolson_takes_advection_by_a_fixed_field_at_second_order():
    """dt(u) = 0.01 Δu − lie(X, u) with the fixed X = d(x): linear with constant coefficients but
    not a linear operator of the table (refused before as 'not linear'); Crank–Nicolson by
    Newton (one iteration a step: the residual is linear) converges at order 2 in time."""
    equations = ["X = d(x)", "dt(u) = 0.01*laplacian(u) - lie(X, u)"]
    reference = _final(equations, "rk4", 0.002, "inner(u, u)")
    errors = [abs(_final(equations, "crank_nicolson", dt, "inner(u, u)") - reference) for dt in (0.02, 0.01, 0.005)]
    measured = np.log2(np.asarray(errors[:-1]) / np.asarray(errors[1:]))
    assert np.all(np.abs(measured - 2) < 0.15), (errors, measured)
