"""Moving Dirichlet values (``fields.<u>.dirichlet`` reading t) under the steppers that are not
Runge–Kutta tableaux (issue 47, item 4; decrun/methods/model/moving_steppers.py): ``symplectic``,
``semi_implicit`` with nonlinear terms, and SciPy's ``bdf``/``radau``/``rk45`` with a Galerkin
(Whitney) ⋆0 — once refused. Exactness on manufactured solutions linear in space on triangles and
tetrahedra, observed orders in time on manufactured solutions that are not, agreement with
radau_iia, and one run of each through the real ``decrun`` command."""

from __future__ import annotations

import json

import numpy as np
import pytest

from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment

from cli_processes import decrun

GRID = ["mesh=grid", "mesh.nx=5", "mesh.ny=5"]
BOX = ["mesh=box", "mesh.cells=2"]
MESHES = [pytest.param(GRID, id="triangles"), pytest.param(BOX, id="tetrahedra")]
QUIET = ["figures=false", "progress=false"]
#: linear in space: laplacian(L) = 0 at the inner vertices in DEC, and (S L)_I = 0 with Whitney's P1
L = "(1 + 2*x + 3*y - z)"


def _run(*overrides: str):
    return run_experiment(compose_config([*QUIET, *overrides])).result


def _cli(tmp_path, *overrides: str) -> dict:
    done = decrun(*overrides, *QUIET, "hydra.run.dir=fixed", cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads((tmp_path / "fixed" / "metrics.json").read_text())


def _time_orders(fields: list) -> np.ndarray:
    """log2 of the ratios of successive distances |u(dt) − u(dt/2)| (dt halved each time)."""
    distances = np.array([np.abs(a - b).max() for a, b in zip(fields[:-1], fields[1:], strict=True)])
    return np.log2(distances[:-1] / distances[1:])


def _orders(errors) -> np.ndarray:
    errors = np.asarray(errors)
    return np.log2(errors[:-1] / errors[1:])


# ---------------------------------------------------------------------- symplectic
#: u = (1 + t²) L, v = u_t = 2t L: u_tt = Δu + 2L with a constant acceleration, which
#: Störmer–Verlet integrates exactly
WAVE_EXACT = [f"app.fields.u.initial='{L}'", "app.fields.v.initial=0", f"+app.fields.u.dirichlet='(1 + t**2)*{L}'",
              f"+app.fields.v.dirichlet='2*t*{L}'", f"app.equations=['dt(u) = v', 'dt(v) = laplacian(u) + 2*{L}']",
              "app.integrator=symplectic", "app.dt=0.01", "app.t_end=0.2",
              f"+app.metrics={{u_error: 'max(abs(u - (1 + t**2)*{L}))', v_error: 'max(abs(v - 2*t*{L}))'}}"]


@pytest.mark.parametrize("operator", ["circumcentric", "whitney"])
@pytest.mark.parametrize("mesh", MESHES)
def test_symplectic_is_exact_for_a_wave_quadratic_in_time_and_linear_in_space(mesh, operator):
    """dt(u) = v, dt(v) = laplacian(u) + 2L with u = (1 + t²) L and v = 2t L on the border: every
    kick and drift reads the border values of its own time, so u and v are exact to round-off.
    Under Whitney dt(v) has the P1 mass M: its kicks take − M_IB (h(end) − h(start)), without
    which the error is 0.26 in v and 0.04 in u on the triangles (1.2 and 0.15 on the tetrahedra)."""
    metrics = _run("app=wave", *mesh, f"operator={operator}", "~app.metrics", *WAVE_EXACT).metrics
    assert metrics["u_error"] < 1e-12 and metrics["v_error"] < 1e-12, metrics


#: u = C cos t + t² (x² + y) on [−½, ½]², C = cos(πx) cos(πy): u_tt = Δu + f, v = u_t
C = "cos(pi*x)*cos(pi*y)"
U_WAVE = f"({C}*cos(t) + t**2*(x**2 + y))"
V_WAVE = f"(-{C}*sin(t) + 2*t*(x**2 + y))"
F_WAVE = f"(-{C}*cos(t) + 2*(x**2 + y) + 2*pi**2*cos(t)*{C} - 2*t**2)"


def _wave(operator: str, dt: float, n: int = 12):
    overrides = ["app=wave", "mesh=grid", f"mesh.nx={n}", f"mesh.ny={n}", f"operator={operator}", "~app.metrics",
                 f"app.fields.u.initial='{C}'", "app.fields.v.initial=0", f"+app.fields.u.dirichlet='{U_WAVE}'",
                 f"+app.fields.v.dirichlet='{V_WAVE}'", f"app.equations=['dt(u) = v', 'dt(v) = laplacian(u) + {F_WAVE}']",
                 "app.integrator=symplectic", f"app.dt={dt}", "app.t_end=0.4",
                 f"+app.metrics.u_error='norm(u - {U_WAVE})/norm(1 + 0*x)'"]
    result = _run(*overrides)
    return np.asarray(result.fields["u"]), result.metrics["u_error"]


@pytest.mark.parametrize("operator, steps", [("circumcentric", (0.04, 0.02, 0.01, 0.005)),
                                             ("whitney", (0.02, 0.01, 0.005, 0.0025))])
def test_symplectic_is_second_order_in_time_with_moving_border_values(operator, steps):
    """The manufactured wave with border values that move (t² (x² + y)) on a 13 × 13 grid, dt halved
    three times: the distances between successive runs fall at order ≥ 1.8 (measured 2.00–2.04),
    and every run is within the mesh's spatial error of the exact u."""
    runs = [_wave(operator, dt) for dt in steps]
    orders = _time_orders([u for u, _ in runs])
    assert orders.min() >= 1.8, orders
    assert max(error for _, error in runs) < (5e-3 if operator == "circumcentric" else 1.3e-2)


# ---------------------------------------------------------------------- semi_implicit
@pytest.mark.parametrize("operator", ["circumcentric", "whitney"])
@pytest.mark.parametrize("mesh", MESHES)
def test_semi_implicit_with_a_nonlinear_term_is_exact_for_u_linear_in_space_and_time(mesh, operator):
    """dt(u) = laplacian(u) + L + (u − E)², E = (1 + t) L the border values: the nonlinear term
    (lagged) vanishes at u = E, and implicit Euler is exact for u linear in t — with the border
    values at tⁿ⁺¹ in each solve and M_FD (g(tⁿ⁺¹) − g(tⁿ)) in its free rows (Whitney)."""
    moving = f"((1 + t)*{L})"
    metrics = _run("app=heat", *mesh, f"operator={operator}", "~app.require", f"app.fields.u.initial='{L}'",
                   f"app.equations=['dt(u) = laplacian(u) + {L} + (u - {moving})**2']",
                   f"+app.fields.u.dirichlet='{moving}'", "app.integrator=semi_implicit", "app.dt=0.01",
                   "app.t_end=0.2", f"+app.metrics.u_error='max(abs(u - {moving}))'").metrics
    assert metrics["u_error"] < 1e-12, metrics


#: u = (1 + t) C + t x with the diffusivity 1 + u²: u_t = ∇·((1 + u²)∇u) + f,
#: f = u_t − (1 + u²) Δu − 2u |∇u|²
U_NONLINEAR = f"((1 + t)*{C} + t*x)"
UX = "(-(1 + t)*pi*sin(pi*x)*cos(pi*y) + t)"
UY = "(-(1 + t)*pi*cos(pi*x)*sin(pi*y))"
F_NONLINEAR = f"({C} + x + 2*pi**2*(1 + t)*{C}*(1 + {U_NONLINEAR}**2) - 2*{U_NONLINEAR}*({UX}**2 + {UY}**2))"


def _nonlinear_diffusion(n: int, dt: float):
    overrides = ["app=heat", "mesh=grid", f"mesh.nx={n}", f"mesh.ny={n}", "~app.require", f"app.fields.u.initial='{C}'",
                 f"app.equations=['dt(u) = -codifferential(average(1 + u**2)*d(u)) + {F_NONLINEAR}']",
                 f"+app.fields.u.dirichlet='{U_NONLINEAR}'", "app.integrator=semi_implicit", f"app.dt={dt}",
                 "app.t_end=0.2", "app.stability_check=false",
                 f"+app.metrics.u_error='norm(u - {U_NONLINEAR})/norm(1 + 0*x)'"]
    result = _run(*overrides)
    return np.asarray(result.fields["u"]), result.metrics["u_error"]


def test_semi_implicit_is_first_order_in_time_on_a_manufactured_nonlinear_diffusion():
    """The lagged step on the nonlinear diffusion above with border values that move: dt halved
    three times on a 13 × 13 grid, successive distances fall at order 1 (measured 1.00, 1.00);
    refining dt with h² (8, 16, 32 cells a side) the error against the exact u falls at order ≥ 1.8
    in h (measured 2.04, 2.03): first order in time, second in space."""
    orders = _time_orders([_nonlinear_diffusion(12, dt)[0] for dt in (0.02, 0.01, 0.005, 0.0025)])
    assert np.all((orders > 0.9) & (orders < 1.2)), orders
    errors = [_nonlinear_diffusion(n, dt)[1] for n, dt in ((8, 0.02), (16, 0.005), (32, 0.00125))]
    assert _orders(errors).min() >= 1.8, errors


# ---------------------------------------------------------------------- bdf, radau, rk45 with a Galerkin mass
@pytest.mark.parametrize("integrator", ["bdf", "radau", "rk45"])
@pytest.mark.parametrize("mesh", MESHES)
def test_scipy_steppers_with_a_galerkin_mass_solve_the_condensed_system(mesh, integrator):
    """operator=whitney (⋆0 the P1 mass): u = (1 + t²) L solves M_FF u_F' = −(S u)_F + (M f)_F −
    M_FD ∂g/∂t with f = 2tL, and (u − u_exact)² makes the model nonlinear (bdf and radau then take
    M_L⁻¹ ∂f/∂y, the lumped mass, as with fixed borders): u to the tolerance asked."""
    moving = f"((1 + t**2)*{L})"
    metrics = _run("app=heat", *mesh, "operator=whitney", "~app.require", f"app.fields.u.initial='{L}'",
                   f"app.equations=['dt(u) = laplacian(u) + 2*t*{L} + (u - {moving})**2']",
                   f"+app.fields.u.dirichlet='{moving}'", f"app.integrator={integrator}", "app.dt=0.01",
                   "app.t_end=0.2", "app.rtol=1e-10", "app.atol=1e-12",
                   f"+app.metrics.u_error='max(abs(u - {moving}))'").metrics
    assert metrics["u_error"] < 1e-8, metrics


#: u = C cos t + t (x² + y): the moving border of tests/apps/test_model_borders.py
U_HEAT = f"({C}*cos(t) + t*(x**2 + y))"
F_HEAT = f"(-sin(t)*{C} + x**2 + y + 2*pi**2*cos(t)*{C} - 2*t)"


def test_scipy_steppers_with_a_galerkin_mass_agree_with_radau_iia():
    """The manufactured heat equation with moving border values under operator=whitney on a 7 × 7
    grid: bdf, radau and rk45 (rtol 1e-9) end within 1e-6 of radau_iia (order 5, dt = 0.01), and
    within the mesh's error of the exact u."""
    def run(integrator: str):
        result = _run("app=heat", "mesh=grid", "mesh.nx=6", "mesh.ny=6", "operator=whitney", "~app.require",
                      f"app.fields.u.initial='{C}'", f"app.equations=['dt(u) = laplacian(u) + {F_HEAT}']",
                      f"+app.fields.u.dirichlet='{U_HEAT}'", f"app.integrator={integrator}", "app.dt=0.01",
                      "app.t_end=0.2", "app.rtol=1e-9", "app.atol=1e-11", "app.stability_check=false",
                      f"+app.metrics.u_error='norm(u - {U_HEAT})/norm(1 + 0*x)'")
        return np.asarray(result.fields["u"]), result.metrics["u_error"]

    reference, error = run("radau_iia")
    assert error < 5e-2
    for integrator in ("bdf", "radau", "rk45"):
        u, _ = run(integrator)
        assert np.abs(u - reference).max() < 1e-6, integrator


# ---------------------------------------------------------------------- through the command
CLI = [
    pytest.param(["app=wave", *GRID, "~app.metrics", *WAVE_EXACT], 1e-12, id="symplectic"),
    pytest.param(["app=heat", *GRID, "~app.require", f"app.fields.u.initial='{L}'",
                  f"app.equations=['dt(u) = laplacian(u) + {L} + (u - (1 + t)*{L})**2']",
                  f"+app.fields.u.dirichlet='(1 + t)*{L}'", "app.integrator=semi_implicit", "app.dt=0.05",
                  "app.t_end=0.5", f"+app.metrics.u_error='max(abs(u - (1 + t)*{L}))'"], 1e-12, id="semi_implicit"),
    pytest.param(["app=heat", *GRID, "operator=whitney", "~app.require", f"app.fields.u.initial='{L}'",
                  f"app.equations=['dt(u) = laplacian(u) + 2*t*{L}']", f"+app.fields.u.dirichlet='(1 + t**2)*{L}'",
                  "app.integrator=bdf", "app.dt=0.05", "app.t_end=0.5", "app.rtol=1e-10", "app.atol=1e-12",
                  f"+app.metrics.u_error='max(abs(u - (1 + t**2)*{L}))'"], 1e-8, id="bdf-whitney"),
]


@pytest.mark.parametrize("overrides, tolerance", CLI)
def test_each_stepper_runs_moving_border_values_through_the_command(overrides, tolerance, tmp_path):
    """The once-refused cases run through ``decrun`` on manufactured solutions linear in space and
    write their answer: symplectic and semi_implicit (a nonlinear model) exact to round-off, bdf
    with Whitney's mass to the tolerance asked."""
    metrics = _cli(tmp_path, *overrides)
    assert metrics["status"] == "ok"
    assert metrics["u_error"] < tolerance, metrics
