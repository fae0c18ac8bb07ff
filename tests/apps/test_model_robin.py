"""Robin borders ∂u/∂n + α u = value (issue 47, item 4; decrun/methods/model/robin.py) in the two
cases test_model_borders.py does not cover: α reading ``t`` (a moving coefficient: Newton in the
implicit integrators and in solves, at each stage's t), and a Galerkin ⋆0 (``operator=whitney``:
the Robin term ⋆0⁻¹ R u through the same inverse star as laplacian(u)), with Neumann under
``operator=whitney`` too — manufactured solutions and orders of convergence on triangles and
tetrahedra, and runs and refusals through the real ``decrun`` command."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from test_model_borders import DN, DN_LINEAR, DN_STEADY, POISSON, U_LINEAR, U_STEADY, F, U, _runs

from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment

#: α(t) = 2 + sin t > 0: the Robin coefficient moves in time
ALPHA_T = "(2 + sin(t))"
ROBIN_T = f"+app.fields.u.robin={{alpha: '{ALPHA_T}', value: '{DN} + {ALPHA_T}*{U}'}}"
ROBIN = f"+app.fields.u.robin={{alpha: 3, value: '{DN} + 3*{U}'}}"
NEUMANN = f"+app.fields.u.neumann='{DN}'"


def _orders(errors) -> np.ndarray:
    errors = np.asarray(errors)
    return np.log2(errors[:-1] / errors[1:])


def _heat(border: str, n: int, integrator: str, dt: float, *extra: str) -> dict:
    """dt(u) = Δu + f on the square [−½, ½]² with the border data of test_model_borders' exact u."""
    overrides = ["app=heat", "mesh=grid", f"mesh.nx={n}", f"mesh.ny={n}", "figures=false", "progress=false",
                 f"app.equations=['dt(u) = laplacian(u) + {F}']", "app.fields.u.initial='cos(pi*x)*cos(pi*y)'",
                 f"app.integrator={integrator}", f"app.dt={dt}", "app.t_end=0.2", "~app.require",
                 f"+app.metrics.u_error='norm(u - {U})/norm(1 + 0*x)'", border, *extra]
    return run_experiment(compose_config(overrides)).result.metrics


# ---------------------------------------------------------------------- α reading t
@pytest.mark.parametrize("integrator, dt", [("implicit_euler", 0.005), ("crank_nicolson", 0.01), ("rk4", 1e-4)])
def test_a_robin_coefficient_that_reads_t_converges_at_second_order(integrator, dt):
    """α(t) = 2 + sin t: the Robin term is a coefficient moving in time, explicit in rk4 and solved by
    Newton with its exact Jacobian diag(α(t)-weights) in the implicit schemes; the ⋆0-weighted L2
    error at t = 0.2 falls at order ≥ 1.8 (measured 2.2, 2.1 under crank_nicolson and rk4)."""
    errors = [_heat(ROBIN_T, n, integrator, dt)["u_error"] for n in (8, 16, 32)]
    orders = _orders(errors)
    assert orders.min() >= 1.8, (errors, orders)
    assert errors[-1] < 2e-3


#: a solve at every step: −Δp = (1 + t) f₀ with p = (1 + t) u₀ (u₀ test_model_borders' U_STEADY) and
#: ∂p/∂n + α(t) p = value(t), α = 2 + t; read by dt(w) = p, so w = (t + t²/2) u₀
P = f"((1 + t)*{U_STEADY})"
SOLVE_OVERRIDES = ["app=heat", "mesh=grid", "figures=false", "progress=false", "~app.require", "~app.fields.u",
                   "~app.metrics",
                   f"+app.fields.p={{form: 0, robin: {{alpha: '2 + t', value: '(1 + t)*{DN_STEADY} + (2 + t)*{P}'}}}}",
                   "+app.fields.w={form: 0, initial: 0}",
                   "app.equations=['solve(-laplacian(p) = (1 + t)*(2*pi**2*cos(pi*x)*cos(pi*y) - 2*x))', 'dt(w) = p']",
                   "app.integrator=crank_nicolson", "app.dt=0.05", "app.t_end=0.5",
                   f"+app.metrics={{p_error: 'norm(p - {P})/norm(1 + 0*x)'}}"]


def test_a_solve_reads_the_robin_coefficient_at_its_time():
    """The solve's α(t) p makes its left side's matrix S + R(t): a Newton solve (one iteration: it is
    linear) at each stage's t; p at t = 0.5 converges at order ≥ 1.8 (measured 2.2, 2.1)."""
    errors = []
    for n in (8, 16, 32):
        metrics = run_experiment(compose_config([*SOLVE_OVERRIDES, f"mesh.nx={n}", f"mesh.ny={n}"])).result.metrics
        assert metrics["p_newton_iterations"] == 1, metrics
        errors.append(metrics["p_error"])
    orders = _orders(errors)
    assert orders.min() >= 1.8, (errors, orders)


def test_a_coefficient_frozen_at_the_start_misses_the_answer():
    """The solve above with α frozen at α(0) = 2 (the value still that of α(t) = 2 + t) misses p(0.5)
    by far more than the discretization error: the moving α is read at each solve's t."""
    frozen = [item.replace("alpha: '2 + t'", "alpha: 2") for item in SOLVE_OVERRIDES]
    assert frozen != SOLVE_OVERRIDES
    mesh = ["mesh.nx=16", "mesh.ny=16"]
    moving = run_experiment(compose_config([*SOLVE_OVERRIDES, *mesh])).result.metrics["p_error"]
    assert run_experiment(compose_config([*frozen, *mesh])).result.metrics["p_error"] > 10 * moving


#: each integrator's distance (max over the vertices) from radau_iia at dt = 0.01, t = 0.2 on a 6 × 6
#: grid: its own time error (measured: α(t) 2.7e-4, 3.2e-3, 7.4e-3, 4e-6, 3.7e-6, 6.7e-5, 4.9e-7, 2.5e-9,
#: 6e-10; whitney 1e-3, 7e-3, 7e-3, 1.7e-5, 2.6e-9 — its explicit schemes are unstable at this dt)
AGREEMENT = {"alpha(t)": ([ROBIN_T], {"implicit_euler": 2e-3, "imex": 2e-2, "semi_implicit": 2e-2,
                                      "crank_nicolson": 3e-5, "ssprk3": 3e-5, "ark_imex": 1e-3, "rk4": 2e-6,
                                      "gauss_legendre": 1e-7, "bdf": 1e-6}),
             "whitney": ([ROBIN, "operator=whitney"], {"implicit_euler": 3e-3, "imex": 2e-2, "semi_implicit": 2e-2,
                                                        "crank_nicolson": 1e-4, "gauss_legendre": 1e-7})}


@pytest.mark.parametrize("case", list(AGREEMENT))
def test_the_integrators_give_the_same_robin_answer(case):
    """α(t) and the Galerkin Robin term in every integrator that steps them at dt = 0.01 agree with
    radau_iia (order 5) to their own time error; halving dt shrinks crank_nicolson's by ~4."""
    extra, tolerances = AGREEMENT[case]

    def field(integrator, dt=0.01):
        options = ["app.stability_check=false", "app.rtol=1e-9", "app.atol=1e-11", *extra[1:]]
        overrides = ["app=heat", "mesh=grid", "mesh.nx=6", "mesh.ny=6", "figures=false", "progress=false",
                     f"app.equations=['dt(u) = laplacian(u) + {F}']", "app.fields.u.initial='cos(pi*x)*cos(pi*y)'",
                     f"app.integrator={integrator}", f"app.dt={dt}", "app.t_end=0.2", "~app.require", extra[0],
                     *options]
        return np.asarray(run_experiment(compose_config(overrides)).result.fields["u"])

    reference = field("radau_iia")
    for integrator, tolerance in tolerances.items():
        distance = np.abs(field(integrator) - reference).max()
        assert distance < tolerance, (integrator, distance)
    ratio = np.abs(field("crank_nicolson") - reference).max() / np.abs(field("crank_nicolson", 0.005) - reference).max()
    assert ratio > 0.8 * 4, ratio


# ---------------------------------------------------------------------- a Galerkin ⋆0 (operator=whitney)
@pytest.mark.parametrize("border, integrator", [(ROBIN, "crank_nicolson"), (ROBIN, "implicit_euler"),
                                                (NEUMANN, "crank_nicolson")], ids=["robin-cn", "robin-ie", "neumann-cn"])
def test_a_flux_border_with_a_galerkin_mass_converges_at_second_order_on_triangles(border, integrator):
    """operator=whitney (⋆0 the P1 mass M): M u' = −(S + R) u + b + M f, R in the implicit block;
    L2 order ≥ 1.8 (measured 2.2, 2.1)."""
    errors = [_heat(border, n, integrator, 0.01, "operator=whitney")["u_error"] for n in (8, 16, 32)]
    orders = _orders(errors)
    assert orders.min() >= 1.8, (errors, orders)


def test_the_robin_term_with_a_galerkin_mass_is_one_linear_block():
    """The Robin term enters the linear block of laplacian(u): one weak block −(S + R) over the one
    mass M (no explicit term reads u; R = diag(∫_∂Ω α φ_i) = 3 diag(border_mass))."""
    from decrun import DEC, SimplicialComplex
    from decrun.methods.model import FieldSpec, ModelSpec, compile_model
    from decrun.methods.model.robin import border_mass
    from decrun.runner.mesh.sources.primitives import Grid

    mesh = Grid(nx=6, ny=6).make()
    dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces), star="whitney")
    spec = ModelSpec(fields={"u": FieldSpec(0, "x*y", robin={"alpha": 3, "value": 0})},
                     equations=["dt(u) = laplacian(u)"])
    model = compile_model(spec, dec, None)
    evolution = model.evolution
    assert evolution.reads_evolved("u") == []  # only the border load inv_star(b) is left explicit
    S = dec.d(0).T @ dec.star(1) @ dec.d(0)
    assert abs(evolution.mass["u"] - dec.star(0)).max() == 0
    assert abs(evolution.blocks[("u", "u")] + S + sp.diags(3 * border_mass(model.ops))).max() < 1e-12


#: u = (1 + t)(1 + 2x + 3y − z) on the box [0, 1]³: Δu = 0, u' = 1 + 2x + 3y − z
MOVING_LINEAR = f"((1 + t)*{U_LINEAR})"


def _box_heat(cells: int, border: str) -> float:
    overrides = ["app=heat", "mesh=box", f"mesh.cells={cells}", "operator=whitney", "figures=false", "progress=false",
                 "~app.require", f"app.equations=['dt(u) = laplacian(u) + {U_LINEAR}']",
                 f"app.fields.u.initial='{U_LINEAR}'", "app.integrator=crank_nicolson", "app.dt=0.05", "app.t_end=0.5",
                 f"+app.metrics.u_error='norm(u - {MOVING_LINEAR})/norm(1 + 0*x)'", border]
    return run_experiment(compose_config(overrides)).result.metrics["u_error"]


def test_neumann_with_a_galerkin_mass_on_tetrahedra_is_exact_for_linear_u():
    """With a Galerkin ⋆0 the border load is the P1 one, ∫_∂Ω g φ_i: the P1 stiffness of a linear u
    is exactly it (integration by parts), so a solve and an evolution of a linear u are exact."""
    solved = _solve_box(3, f"solve(u - laplacian(u) = {U_LINEAR})", f"+app.fields.u.neumann='{DN_LINEAR}'")
    assert solved < 1e-12
    assert _box_heat(3, f"+app.fields.u.neumann='(1 + t)*{DN_LINEAR}'") < 1e-12


def _solve_box(cells: int, equation: str, border: str) -> float:
    overrides = ["app=poisson", "mesh=box", f"mesh.cells={cells}", "operator=whitney", "figures=false",
                 "progress=false", "app.fields.u.dirichlet=null", "~app.metrics.l2_error_rel",
                 f"app.equations=['{equation}']", f"app.metrics.max_abs_error='norm(u - {U_LINEAR})/norm(1 + 0*x)'",
                 border]
    return run_experiment(compose_config(overrides)).result.metrics["max_abs_error"]


def test_robin_with_a_galerkin_mass_on_tetrahedra_converges_at_second_order():
    """solve(−Δu = 0) and dt(u) = Δu + u' with ∂u/∂n + 2u = value of a linear u on tetrahedra: R lumps
    ∫ α u φ_i, so not exact — order ≥ 1.8 (measured 1.95, 2.0 solved; 2.0, 2.0 evolved)."""
    solved = [_solve_box(cells, "solve(-laplacian(u) = 0)",
                         f"+app.fields.u.robin={{alpha: 2, value: '{DN_LINEAR} + 2*{U_LINEAR}'}}") for cells in (2, 4, 8)]
    assert _orders(solved).min() >= 1.8, (solved, _orders(solved))
    border = f"+app.fields.u.robin={{alpha: 2, value: '(1 + t)*{DN_LINEAR} + 2*{MOVING_LINEAR}'}}"
    evolved = [_box_heat(cells, border) for cells in (2, 4, 8)]
    assert _orders(evolved).min() >= 1.8, (evolved, _orders(evolved))


@pytest.mark.parametrize("border", ["robin", "neumann"])
def test_a_solve_with_a_flux_border_and_a_galerkin_mass_converges_on_triangles(border):
    """solve(−Δu = f) with Robin (α = 2) and solve(u − Δu = u + f) with Neumann under operator=whitney:
    L2 order ≥ 1.8."""
    lhs, rhs = ("-laplacian(u)", "") if border == "robin" else ("u - laplacian(u)", f" + {U_STEADY}")
    condition = (f"+app.fields.u.robin={{alpha: 2, value: '{DN_STEADY} + 2*{U_STEADY}'}}" if border == "robin" else
                 f"+app.fields.u.neumann='{DN_STEADY}'")
    errors = []
    for n in (8, 16, 32):
        overrides = ["app=poisson", f"mesh.nx={n}", f"mesh.ny={n}", "operator=whitney", "figures=false",
                     "progress=false", "app.fields.u.dirichlet=null", "~app.metrics.l2_error_rel", condition,
                     f"app.equations=['solve({lhs} = 2*pi**2*cos(pi*x)*cos(pi*y) - 2*x{rhs})']",
                     f"app.metrics.max_abs_error='norm(u - {U_STEADY})/norm(1 + 0*x)'"]
        errors.append(run_experiment(compose_config(overrides)).result.metrics["max_abs_error"])
    assert _orders(errors).min() >= 1.8, (errors, _orders(errors))


def test_border_mass_sums_to_the_border_measure():
    """Σ_i border_mass(1)_i = ∫_∂Ω 1: the square's perimeter 4 and the cube's surface 6."""
    for mesh in (["mesh=grid", "mesh.nx=5", "mesh.ny=5"], ["mesh=box", "mesh.cells=2"]):
        overrides = ["app=poisson", *mesh, "figures=false", "progress=false", "~app.metrics.l2_error_rel",
                     "app.metrics.max_abs_error='integral(border_mass(1 + 0*x))'"]
        total = run_experiment(compose_config(overrides)).result.metrics["max_abs_error"]
        assert abs(total - (4.0 if "mesh=grid" in mesh else 6.0)) < 1e-12, (mesh, total)


# ---------------------------------------------------------------------- through the command
HEAT = ["app=heat", "mesh=grid", "mesh.nx=16", "mesh.ny=16", f"app.equations=['dt(u) = laplacian(u) + {F}']",
        "app.fields.u.initial='cos(pi*x)*cos(pi*y)'", "app.dt=0.01", "app.t_end=0.2", "~app.require",
        f"+app.metrics.u_error='norm(u - {U})/norm(1 + 0*x)'"]


@pytest.mark.parametrize("case", ["alpha reads t", "whitney robin", "whitney neumann"])
def test_the_command_runs_each_case(case, tmp_path):
    """One run of each case through the real ``decrun`` command (n = 16): it runs, and meets the exact u."""
    extra = {"alpha reads t": [ROBIN_T, "app.integrator=implicit_euler"],
             "whitney robin": [ROBIN, "operator=whitney", "app.integrator=crank_nicolson"],
             "whitney neumann": [NEUMANN, "operator=whitney", "app.integrator=crank_nicolson"]}[case]
    metrics = _runs(tmp_path, *HEAT, *extra)
    assert metrics["stable"] is True and metrics["u_error"] < 2e-2, metrics  # measured 4e-3 – 1.4e-2


def test_an_alpha_that_reads_t_runs_through_the_command_where_it_was_refused(tmp_path):
    """test_model_borders once refused `app.fields.u.robin={alpha: t, value: 0}`: now solve(u − Δu = 1)
    with it runs (a Newton solve at t = 0, one iteration) and gives u = 1 (α(0) = 0: Neumann 0)."""
    metrics = _runs(tmp_path, *POISSON, "+app.fields.u.robin={alpha: t, value: 0}",
                    "app.metrics.max_abs_error='max(abs(u - 1))'", "~app.metrics.l2_error_rel")
    assert metrics["max_abs_error"] < 1e-12 and metrics["u_newton_iterations"] == 1, metrics
