"""Dirichlet values that read ``t`` in Newton and block-system solves (issue 47, item 4;
decrun/methods/model/moving_solves.py): manufactured solutions whose border values move, solved at
several t on triangles and tetrahedra (exact border values, spatial order of the ⋆0-weighted L2
error, Newton's iteration count, one factorization of a block system), and solves inside an
evolution through the real ``decrun`` command (every step's solve at its own t)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from decrun import DEC, SimplicialComplex
from decrun.core.solvers import solver_factory
from decrun.methods.model import FieldSpec, ModelSpec, compile_model
from decrun.runner.mesh.sources.primitives import Grid
from decrun.runner.mesh.sources.volumes import Box

from cli_processes import decrun

#: the times each static model is evaluated at (its solves read g(t) there)
TIMES = (0.0, 0.5, 1.3)

#: u(x, t) with Δu, as the language's text and as numpy: on the square [−½, ½]² (mesh=grid) and
#: the box [0, 1]³ (mesh=box); neither is zero on the border, and both move with t
EXACT = {
    "triangles": ("(cos(t)*sin(pi*x)*cos(pi*y) + t*x**2)", "(-2*pi**2*cos(t)*sin(pi*x)*cos(pi*y) + 2*t)",
                  lambda x, y, z, t: np.cos(t) * np.sin(np.pi * x) * np.cos(np.pi * y) + t * x ** 2),
    "tetrahedra": ("(cos(t)*sin(pi*x)*sin(pi*y)*sin(pi*z) + t*x*y)",
                   "(-3*pi**2*cos(t)*sin(pi*x)*sin(pi*y)*sin(pi*z))",
                   lambda x, y, z, t: np.cos(t) * np.sin(np.pi * x) * np.sin(np.pi * y) * np.sin(np.pi * z) + t * x * y),
}
#: a static linear partner of u in the block system (harmonic: DEC's Laplacian of it is zero inside)
V = "(1 + x + 2*y - z)"


def _v(x, y, z, t):
    return 1 + x + 2 * y - z


def _dec(mesh: str, level: int) -> DEC:
    """Three refinements (h halved): the grid of 9², 17², 33² vertices, the box of 2³, 4³, 8³ cells."""
    if mesh == "triangles":
        n = 8 * 2 ** level + 1
        source = Grid(nx=n, ny=n).make()
    else:
        source = Box(cells=2 * 2 ** level).make()
    return DEC(SimplicialComplex(source.vertices, source.faces))


def _exact(dec: DEC, function, t: float) -> np.ndarray:
    points = np.zeros((dec.K.num_simplices(0), 3))
    points[:, :dec.K.vertices.shape[1]] = dec.K.vertices
    return function(*points.T, t)


def _l2(dec: DEC, error: np.ndarray) -> float:
    """The ⋆0-weighted L2 norm of a 0-form over the domain's measure."""
    star0 = dec.star(0).diagonal()
    return float(np.sqrt(np.sum(star0 * error ** 2) / np.sum(star0)))


def _orders(errors) -> np.ndarray:
    errors = np.asarray(errors)
    return np.log2(errors[:-1] / errors[1:])


@pytest.mark.parametrize("mesh", ["triangles", "tetrahedra"])
def test_a_newton_solve_takes_its_moving_border_values_at_each_t_with_spatial_order_two(mesh):
    """solve(−Δu + u³ = f(x, t)) with u = g(x, t) on the border, the model evaluated at t = 0, 0.5,
    1.3: every solve ≤ 8 Newton iterations, u on the border g(t) to round-off, and the ⋆0-weighted
    L2 error against the exact u of order ≥ 1.8 at every t over three refinements (measured 2.0)."""
    u_text, laplacian, exact = EXACT[mesh]
    spec = ModelSpec(fields={"u": FieldSpec(0, None, u_text)},
                     equations=[f"solve(-laplacian(u) + u**3 = -{laplacian} + {u_text}**3)"])
    errors = np.zeros((3, len(TIMES)))
    for level in range(3):
        dec = _dec(mesh, level)
        model = compile_model(spec, dec, solver_factory("direct"))
        (what, newton), = model.order
        assert what == "newton"
        border = model.fixed["u"][0]  # the border vertices
        for i, t in enumerate(TIMES):
            u = model.environment({}, t)["u"]
            exact_u = _exact(dec, exact, t)
            assert np.abs(u[border] - exact_u[border]).max() <= 1e-14
            errors[level, i] = _l2(dec, u - exact_u)
        assert 1 <= max(newton.iterations) <= 8, newton.iterations
    orders = _orders(errors)
    assert orders.min() >= 1.8, (errors, orders)


@pytest.mark.parametrize("mesh", ["triangles", "tetrahedra"])
def test_a_block_system_takes_moving_border_values_with_its_matrix_factorized_once(mesh):
    """solve(−Δu + v = f1, −Δv − u = f2) with u = g(x, t) moving on the border and v = 1 + x + 2y − z
    fixed there: one block matrix, factorized at the first solve and never again, its condensed
    right side b_F − A_FD g(t) at each t; the border values are g(t) and v's, and the L2 errors of u
    and v fall at order ≥ 1.8 at every t (measured 2.0)."""
    u_text, laplacian, exact = EXACT[mesh]
    spec = ModelSpec(fields={"u": FieldSpec(0, None, u_text), "v": FieldSpec(0, None, V)},
                     equations=[f"solve(-laplacian(u) + v = -{laplacian} + {V}, -laplacian(v) - u = -{u_text})"])
    errors = np.zeros((3, 2 * len(TIMES)))
    for level in range(3):
        dec = _dec(mesh, level)
        model = compile_model(spec, dec, solver_factory("direct"))
        (what, system), = model.order
        assert what == "system" and set(system.unknowns) == {"u", "v"}
        border = model.fixed["u"][0]  # the border vertices (v's too)
        assert np.array_equal(model.fixed["v"][0], border)
        factorization = None
        for i, t in enumerate(TIMES):
            env = model.environment({}, t)
            factorization = factorization or system.system.solver
            assert system.system.solver is factorization
            for j, (name, function) in enumerate((("u", exact), ("v", _v))):
                exact_values = _exact(dec, function, t)
                assert np.abs(env[name][border] - exact_values[border]).max() <= 1e-14
                errors[level, 2 * i + j] = _l2(dec, env[name] - exact_values)
    orders = _orders(errors)
    assert orders.min() >= 1.8, (errors, orders)


#: dt(c) = 3 sin²t cos t x³ (c = sin³t x³) and solve(−Δu + u³ = c) with u = sin(t) x on the border:
#: u = sin(t) x exactly (DEC's Laplacian of a linear u is zero inside), at every step's t only
NEWTON = ["app.equations=['dt(c) = 3*sin(t)**2*cos(t)*x**3', 'solve(-laplacian(u) + u**3 = c)']",
          "+app.fields.c={form: 0, initial: 0}", "+app.fields.u.dirichlet='sin(t)*x'",
          "+app.metrics.u_error='max(abs(u - sin(t)*x))'"]
#: dt(c) = cos(t) x (c = sin(t) x) and solve(−Δu + v = 1 + x + 2y, −Δv − u = −c) with u = sin(t) x and
#: v = 1 + x + 2y on the border: u = sin(t) x and v = 1 + x + 2y exactly
SYSTEM = ["app.equations=['dt(c) = cos(t)*x', 'solve(-laplacian(u) + v = 1 + x + 2*y, -laplacian(v) - u = -c)']",
          "+app.fields.c={form: 0, initial: 0}", "+app.fields.u.dirichlet='sin(t)*x'",
          "+app.fields.v={form: 0, dirichlet: '1 + x + 2*y'}",
          "+app.metrics.u_error='max(abs(u - sin(t)*x)) + max(abs(v - (1 + x + 2*y)))'"]


@pytest.mark.parametrize("solve", [pytest.param(NEWTON, id="newton"), pytest.param(SYSTEM, id="system")])
def test_a_solve_inside_an_evolution_reads_its_moving_border_at_every_step_through_the_command(solve, tmp_path):
    """`decrun app=heat mesh=grid … +app.fields.u.dirichlet='sin(t)*x'` with the solve read by nothing
    but the metric, stepped by rk4 to t = 1: the run ends stable and u = sin(t) x at t = 1 to the
    time error of c (round-off here); border values frozen at t = 0 would leave u ≈ 0 (error 0.42)."""
    done = decrun("app=heat", "mesh=grid", "mesh.nx=9", "mesh.ny=9", "app.integrator=rk4", "app.dt=0.05",
                  "app.t_end=1", *solve, "figures=false", "progress=false", "hydra.run.dir=out", cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["stable"] is True and metrics["t_final"] == pytest.approx(1.0)
    assert metrics["u_error"] < 1e-10, metrics
    if solve is NEWTON:
        assert 1 <= metrics["u_newton_iterations"] <= 8
