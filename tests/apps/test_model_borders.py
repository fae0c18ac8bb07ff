"""Borders in the model language (issue 47, item 4; decrun/methods/model/borders.py): Neumann
``fields.u.neumann``, Robin ``fields.u.robin`` and Dirichlet values that read ``t``, through the
config composition and runner of the real ``decrun`` command (manufactured solutions, orders of
convergence, exactness for linear u on tetrahedra, every integrator on one answer) and the
refusals through the ``decrun`` process itself (one line naming ``app.fields.<u>.<key>``; each
suggested override runs)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment

from cli_processes import decrun

#: u = cos(πx) cos(πy) cos t + t (x² + y) on the square [−½, ½]² (mesh=grid), with
#: f = ∂u/∂t − Δu and its outward normal derivative ∂u/∂n = n·∇u: n = (sign x, 0) on the sides
#: |x| = ½, (0, sign y) on |y| = ½ (the border quadrature points are never at a corner)
C = "cos(pi*x)*cos(pi*y)"
U = f"({C}*cos(t) + t*(x**2 + y))"
F = f"(-sin(t)*{C} + x**2 + y + 2*pi**2*cos(t)*{C} - 2*t)"
UX = "(-pi*sin(pi*x)*cos(pi*y)*cos(t) + 2*t*x)"
UY = "(-pi*cos(pi*x)*sin(pi*y)*cos(t) + t)"
NX = "(sign(x)*(sign(abs(x) - abs(y)) + 1)/2)"
NY = "(sign(y)*(sign(abs(y) - abs(x)) + 1)/2)"
DN = f"({NX}*{UX} + {NY}*{UY})"
ALPHA = 3

CONDITIONS = {"neumann": f"+app.fields.u.neumann='{DN}'",
              "robin": f"+app.fields.u.robin={{alpha: {ALPHA}, value: '{DN} + {ALPHA}*{U}'}}",
              "dirichlet": f"+app.fields.u.dirichlet='{U}'"}


def _heat(condition: str, n: int, integrator: str = "crank_nicolson", dt: float = 0.01, *extra: str):
    overrides = ["app=heat", "mesh=grid", f"mesh.nx={n}", f"mesh.ny={n}", "figures=false", "progress=false",
                 f"app.equations=['dt(u) = laplacian(u) + {F}']", f"app.fields.u.initial='{C}'",
                 f"app.integrator={integrator}", f"app.dt={dt}", "app.t_end=0.2", "~app.require",
                 f"+app.metrics.u_error='norm(u - {U})/norm(1 + 0*x)'", CONDITIONS[condition], *extra]
    return run_experiment(compose_config(overrides)).result


def _orders(errors) -> np.ndarray:
    errors = np.asarray(errors)
    return np.log2(errors[:-1] / errors[1:])


@pytest.mark.parametrize("condition", ["neumann", "robin", "dirichlet"])
def test_a_moving_border_converges_at_second_order_on_triangles(condition):
    """dt(u) = laplacian(u) + f with the border data of the exact u (moving in time), h halved twice:
    the ⋆0-weighted L2 error at t = 0.2 falls at order ≥ 1.8 (measured 2.1–2.3)."""
    errors = [_heat(condition, n).metrics["u_error"] for n in (8, 16, 32)]
    orders = _orders(errors)
    assert orders.min() >= 1.8, (errors, orders)
    assert errors[-1] < 5e-3


#: u = cos(πx) cos(πy) + x³/3 + y: −Δu = 2π² cos(πx) cos(πy) − 2x
U_STEADY = "(cos(pi*x)*cos(pi*y) + x**3/3 + y)"
DN_STEADY = f"({NX}*(-pi*sin(pi*x)*cos(pi*y) + x**2) + {NY}*(-pi*cos(pi*x)*sin(pi*y) + 1))"


@pytest.mark.parametrize("condition", ["robin", "neumann"])
def test_a_solve_with_a_flux_border_converges_at_second_order(condition):
    """solve(−Δu = f) with Robin (α = 2), and solve(u − Δu = u + f) with Neumann: L2 order ≥ 1.8."""
    lhs, rhs = ("-laplacian(u)", "") if condition == "robin" else ("u - laplacian(u)", f" + {U_STEADY}")
    border = (f"+app.fields.u.robin={{alpha: 2, value: '{DN_STEADY} + 2*{U_STEADY}'}}" if condition == "robin" else
              f"+app.fields.u.neumann='{DN_STEADY}'")
    errors = []
    for n in (8, 16, 32):
        overrides = ["app=poisson", f"mesh.nx={n}", f"mesh.ny={n}", "figures=false", "progress=false",
                     "app.fields.u.dirichlet=null", "~app.metrics.l2_error_rel", border,
                     f"app.equations=['solve({lhs} = 2*pi**2*cos(pi*x)*cos(pi*y) - 2*x{rhs})']",
                     f"app.metrics.max_abs_error='norm(u - {U_STEADY})/norm(1 + 0*x)'"]
        errors.append(run_experiment(compose_config(overrides)).result.metrics["max_abs_error"])
    orders = _orders(errors)
    assert orders.min() >= 1.8, (errors, orders)


#: the tetrahedral box [0, 1]³ (mesh=box): u linear, its outward normal derivative on each face
U_LINEAR = "(1 + 2*x + 3*y - z)"


def _normal(a: str, b: str, c: str) -> str:
    return f"(sign({a} - 0.5)*(sign(abs({a} - 0.5) - max(abs({b} - 0.5), abs({c} - 0.5))) + 1)/2)"


DN_LINEAR = f"(2*{_normal('x', 'y', 'z')} + 3*{_normal('y', 'z', 'x')} - {_normal('z', 'x', 'y')})"


def _box(cells: int, equation: str, *extra: str):
    overrides = ["app=poisson", "mesh=box", f"mesh.cells={cells}", "figures=false", "progress=false",
                 "app.fields.u.dirichlet=null", "~app.metrics.l2_error_rel", f"app.equations=['{equation}']",
                 f"app.metrics.max_abs_error='max(abs(u - {U_LINEAR}))'", f"+app.metrics.l2='norm(u - {U_LINEAR})'",
                 *extra]
    return run_experiment(compose_config(overrides)).result.metrics


def test_neumann_on_tetrahedra_is_exact_for_linear_u():
    """Green's identity in DEC is exact for linear u (S u = b): solve(u − Δu = u) with ∂u/∂n of a
    linear u gives u to round-off."""
    metrics = _box(3, f"solve(u - laplacian(u) = {U_LINEAR})", f"+app.fields.u.neumann='{DN_LINEAR}'")
    assert metrics["max_abs_error"] < 1e-12


def test_robin_on_tetrahedra_converges_at_second_order():
    """solve(−Δu = 0), ∂u/∂n + 2u = value of a linear u: R = diag(∫_Γi α) lumps ∫_Γi α u, so not
    exact — the ⋆0-weighted L2 error falls at order ≥ 1.8 (measured 2.2, 2.1)."""
    border = f"+app.fields.u.robin={{alpha: 2, value: '{DN_LINEAR} + 2*{U_LINEAR}'}}"
    errors = [_box(cells, "solve(-laplacian(u) = 0)", border)["l2"] for cells in (2, 4, 8)]
    orders = _orders(errors)
    assert orders.min() >= 1.8, (errors, orders)


@pytest.mark.parametrize("integrator", ["implicit_euler", "crank_nicolson", "radau_iia"])
def test_moving_dirichlet_on_tetrahedra_is_exact_for_linear_u(integrator):
    """u = (1 + t)(1 + 2x + 3y − z): Δu = 0 exactly in DEC inside, u linear in t: every step exact."""
    moving = f"((1 + t)*{U_LINEAR})"
    overrides = ["app=heat", "mesh=box", "mesh.cells=3", "figures=false", "progress=false", "~app.require",
                 f"app.equations=['dt(u) = laplacian(u) + {U_LINEAR}']", f"app.fields.u.initial='{U_LINEAR}'",
                 f"+app.fields.u.dirichlet='{moving}'", f"app.integrator={integrator}", "app.dt=0.05", "app.t_end=0.5",
                 f"+app.metrics.u_error='max(abs(u - {moving}))'"]
    assert run_experiment(compose_config(overrides)).result.metrics["u_error"] < 1e-12


@pytest.mark.parametrize("integrator", ["radau_iia", "crank_nicolson"])
def test_moving_dirichlet_with_a_galerkin_mass_takes_the_rate_of_the_border_values(integrator):
    """operator=whitney (⋆0 the P1 mass, not diagonal): u = (1 + t²)(1 + 2x + 3y) solves M u' = −S u
    + M f exactly only with −M_FD ∂g/∂t in the free rows; with it the run is exact (without it the
    error is 7e-3)."""
    linear = "(1 + 2*x + 3*y)"
    moving = f"((1 + t**2)*{linear})"
    overrides = ["app=heat", "mesh=grid", "mesh.nx=5", "mesh.ny=5", "operator=whitney", "figures=false",
                 "progress=false", "~app.require", f"app.equations=['dt(u) = laplacian(u) + 2*t*{linear}']",
                 f"app.fields.u.initial='{linear}'", f"+app.fields.u.dirichlet='{moving}'",
                 f"app.integrator={integrator}", "app.dt=0.01", "app.t_end=0.2",
                 f"+app.metrics.u_error='max(abs(u - {moving}))'"]
    assert run_experiment(compose_config(overrides)).result.metrics["u_error"] < 1e-12


#: each integrator's distance (max over the vertices) from radau_iia at dt = 0.01, t = 0.2 on a
#: 6 × 6 grid — the integrator's own error: O(dt) for the first-order ones, measured 2e-4 – 6e-3
TOLERANCE = {"explicit_euler": 2e-3, "implicit_euler": 2e-3, "imex": 2e-2, "semi_implicit": 2e-2,
             "crank_nicolson": 3e-5, "ssprk3": 3e-5, "ark_imex": 1e-3, "rk4": 2e-6, "gauss_legendre": 1e-7,
             "bdf": 1e-6, "radau": 1e-6, "rk45": 1e-6}


#: a few integrators by default (one per family), every one with -m slow
FEW = ("implicit_euler", "crank_nicolson", "rk4", "ark_imex", "bdf")


@pytest.mark.parametrize("condition, integrators", [
    pytest.param("dirichlet", FEW, id="dirichlet-few"), pytest.param("neumann", FEW, id="neumann-few"),
    pytest.param("dirichlet", tuple(TOLERANCE), id="dirichlet-all", marks=pytest.mark.slow),
    pytest.param("neumann", tuple(TOLERANCE), id="neumann-all", marks=pytest.mark.slow)])
def test_the_integrators_give_the_same_moving_border_answer(condition, integrators):
    """The moving Dirichlet and Neumann runs of the integrators agree with radau_iia (order 5) to
    each integrator's own time error; halving dt shrinks that distance by ~2^order."""
    def field(integrator, dt=0.01):
        result = _heat(condition, 6, integrator, dt, "app.stability_check=false", "app.rtol=1e-9", "app.atol=1e-11")
        return np.asarray(result.fields["u"])

    reference = field("radau_iia")
    for integrator in integrators:
        distance = np.abs(field(integrator) - reference).max()
        assert distance < TOLERANCE[integrator], (integrator, distance)
    for integrator, order in (("implicit_euler", 1), ("crank_nicolson", 2), ("ssprk3", 3)):
        if integrator in integrators:
            ratio = np.abs(field(integrator) - reference).max() / np.abs(field(integrator, 0.005) - reference).max()
            assert ratio > 0.8 * 2 ** order, (integrator, ratio)


def test_the_newton_cooling_model_matches_its_exact_mode():
    """conf/app/newton_cooling.yaml as shipped (Robin border, crank_nicolson): the slowest mode of
    the plate to 3e-3, and order 2 under refinement (measured 2.05, 1.99)."""
    errors = []
    for n in (9, 17, 33):
        metrics = run_experiment(compose_config(["app=newton_cooling", f"mesh.nx={n}", f"mesh.ny={n}", "figures=false",
                                                 "progress=false"])).result.metrics
        errors.append(metrics["l2_error_rel"])
    assert errors[0] < 3e-3
    assert _orders(errors).min() >= 1.9, errors


# ---------------------------------------------------------------------- refusals through the command
def _refused(tmp_path, *overrides: str) -> str:
    done = decrun(*overrides, "figures=false", "progress=false", cwd=tmp_path)
    lines = [line for line in done.stderr.strip().splitlines() if line.strip()]
    assert done.returncode != 0 and len(lines) == 1, done.stderr[-3000:]
    return lines[0]


def _runs(tmp_path, *overrides: str) -> dict:
    done = decrun(*overrides, "figures=false", "progress=false", "hydra.run.dir=fixed", cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads((tmp_path / "fixed" / "metrics.json").read_text())


POISSON = ["app=poisson", "mesh.nx=5", "mesh.ny=5", "app.fields.u.dirichlet=null",
           "app.equations=['solve(u - laplacian(u) = 1)']"]

REFUSALS = [
    pytest.param(["app=heat", "mesh.subdiv=1", "app.steps=1", "+app.fields.u.neumann=1"],
                 "error: app.fields.u.neumann: this mesh has no border", "app.fields.u.neumann=null", id="closed mesh"),
    pytest.param([*POISSON, "+app.fields.u.robin=1"], "error: app.fields.u.robin: Robin's",
                 "app.fields.u.robin={alpha: 1, value: 0}", id="wrong type"),
    pytest.param([*POISSON, "+app.fields.u.neumann='k2*x'"], "error: app.fields.u.neumann: unknown name 'k2'",
                 "+app.constants.k2=1", id="unknown name"),
    pytest.param([*POISSON, "+app.fields.u.neumann='log(x + 0.5)'"],
                 "error: app.fields.u.neumann: the border value log(x + 0.5) is not finite", "app.fields.u.neumann=0",
                 id="not finite"),
    pytest.param([*POISSON, "app.fields.u.dirichlet=0", "+app.fields.u.neumann=0"],
                 "error: app.fields.u: give one border condition", "app.fields.u.neumann=null", id="two conditions"),
    pytest.param([*POISSON, "app.equations=['solve(u - laplacian(u) - laplacian(v) = 1)']",
                  "+app.fields.v={form: 0, initial: 'x*y', neumann: 0}"],
                 "error: app.fields.v.neumann: v is neither evolved", "app.fields.v.neumann=null", id="not computed"),
    pytest.param([*POISSON, "+app.fields.u.robin={alpha: -40, value: 0}"],
                 "error: app.fields.u.robin.alpha: the Robin weights ∫_Γi α are negative at 16 border vertices",
                 "app.fields.u.robin.alpha=1", id="indefinite robin"),
    pytest.param([*POISSON, "app.equations=['solve(u = 1)']", "+app.fields.u.neumann=0"],
                 "error: app.fields.u.neumann: no equation reads laplacian(u)", "app.fields.u.neumann=null",
                 id="no laplacian"),
    pytest.param([*POISSON, "+app.fields.u.robin={alpha: '-40 + t', value: 0}"],
                 "error: app.fields.u.robin.alpha: the Robin weights ∫_Γi α are negative at 16 border vertices",
                 "app.fields.u.robin.alpha=1", id="indefinite alpha(t)"),
    pytest.param(["app=heat", "mesh=grid", "mesh.nx=10", "mesh.ny=10", "app.integrator=implicit_euler", "app.dt=0.005",
                  "app.t_end=0.05", "+app.fields.u.robin={alpha: '1 - 100*t', value: 0}"],
                 "error: app.fields.u.robin.alpha: the Robin weights ∫_Γi α are negative at t = 0.0",
                 "app.fields.u.robin.alpha=1", id="alpha(t) turns negative during the run"),
    pytest.param([*POISSON, "operator=whitney", "+app.fields.u.robin={alpha: -40, value: 0}"],
                 "error: app.fields.u.robin.alpha: the Robin weights ∫_Γi α are negative at 16 border vertices",
                 "app.fields.u.robin.alpha=1", id="indefinite whitney"),
    pytest.param([*POISSON, "operator=whitney", "+app.fields.u.robin={alpha: '1 + t', value: 0}"],
                 "error: app.fields.u.robin.alpha: α reading t makes the Robin term a moving coefficient",
                 "operator=circumcentric", id="alpha(t) whitney"),
]


@pytest.mark.parametrize("overrides, start, fix", REFUSALS)
def test_a_bad_border_is_one_line_naming_its_key_and_the_suggested_override_runs(overrides, start, fix, tmp_path):
    line = _refused(tmp_path, *overrides)
    assert line.startswith(start), line
    assert f"`{fix}`" in line, line
    _runs(tmp_path, *overrides, fix)


def test_a_border_key_the_yaml_does_not_list_names_its_own_key_and_the_plus_form_runs(tmp_path):
    """`app.fields.u.neumann=0` on a model whose YAML gives u no neumann (Hydra overrides only
    listed keys): one line naming app.fields.u.neumann (not app.neumann, not an unknown field) and
    the `+` form, which runs."""
    common = ["app=heat", "mesh=grid", "mesh.nx=5", "mesh.ny=5", "app.steps=2"]
    line = _refused(tmp_path, *common, "app.fields.u.neumann=0")
    assert line == ("error: app.fields.u.neumann: the field u of app=heat does not list neumann in its config; add it "
                    "with `+app.fields.u.neumann=0`"), line
    _runs(tmp_path, *common, "+app.fields.u.neumann=0")


def test_a_solve_reads_its_moving_border_values_at_the_time_of_the_solve():
    """solve(laplacian(p) = 0) with p = t x on the border (p = t x inside too: harmonic), read by
    dt(w) = 2*p: every stage's solve at its own t, so w = t² x exactly under crank_nicolson, and
    p at the end is t x to round-off (the term 2*p is not frozen at its first value)."""
    overrides = ["app=heat", "mesh=grid", "mesh.nx=5", "mesh.ny=5", "figures=false", "progress=false", "~app.require",
                 "~app.fields.u", "~app.metrics", "+app.fields.p={form: 0, dirichlet: 't*x'}",
                 "+app.fields.w={form: 0, initial: 0}", "app.equations=['solve(laplacian(p) = 0)', 'dt(w) = 2*p']",
                 "app.integrator=crank_nicolson", "app.dt=0.05", "app.t_end=0.5",
                 "+app.metrics={p_error: 'max(abs(p - t*x))', w_error: 'max(abs(w - t**2*x))'}"]
    metrics = run_experiment(compose_config(overrides)).result.metrics
    assert metrics["p_error"] < 1e-12 and metrics["w_error"] < 1e-12, metrics
