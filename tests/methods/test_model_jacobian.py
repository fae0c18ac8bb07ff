"""The derivative pass (methods/model/jacobian.py) and the compiled model's ``Problem``
(methods/model/problem.py, issue 47): exact sparse Jacobians from the registry's derivative rules,
checked against central differences of the evaluator itself, and M y' = f(y, t) over the free
unknowns with the Dirichlet values condensed out."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from test_model_operators import dec_of, env_of

from decrun.core.solvers import solver_factory
from decrun.methods.model import FieldSpec, ModelError, ModelSpec, compile_model
from decrun.methods.model.compiler import Compiler
from decrun.methods.model.jacobian import derivative
from decrun.methods.model.kinds import primal
from decrun.methods.model.language import parse_expression
from decrun.methods.model.operators import Discrete
from decrun.methods.model.problem import ModelProblem

EXPRESSIONS = ["laplacian(u) - 0.1*cosh(u)", "u*v**2 + exp(u)/(1 + u)", "codifferential(average(D) * d(u))",
               "max(u, v) + u**v - min(u, 0.4)", "codifferential(d(sin(u)))", "-(u - v)/v + sqrt(u)*tanh(u)",
               "lie(sharp(d(x)), u) + 2*laplace_de_rham(u)"]


def _compiler(dec):
    compiler = Compiler(Discrete(dec), {"u": primal(0), "v": primal(0), "D": primal(0)},
                        {"D": parse_expression("u**2 + 1", "D")}, {"u", "v", "D"})
    compiler.static_env = env_of(dec.K, {})
    return compiler


@pytest.mark.parametrize("text", EXPRESSIONS)
def test_the_exact_jacobian_equals_central_differences(text):
    """J·w against (F(u + εw) − F(u − εw)) / 2ε for a random direction w: agreement to 1e-8
    (the difference's own error is O(ε²)); sparse, with at most the operators' nonzeros."""
    dec = dec_of("lattice")
    K = dec.K
    compiler = _compiler(dec)
    rng = np.random.default_rng(0)
    u = 0.3 + 0.2 * rng.random(K.num_simplices(0))
    v = 0.5 + 0.1 * rng.random(K.num_simplices(0))

    def env(u):
        return env_of(K, {"u": u, "v": v, "D": u ** 2 + 1})
    tree = parse_expression(text, "test")
    F = compiler.compile(tree, "test")
    J = derivative(compiler, tree, "u", "test")(env(u))
    assert sp.issparse(J) and J.shape == (u.size, u.size)
    w = rng.standard_normal(u.size)
    eps = 1e-6
    numeric = (F(env(u + eps * w)) - F(env(u - eps * w))) / (2 * eps)
    assert np.abs(J @ w - numeric).max() <= 1e-8 * np.abs(numeric).max()
    assert J.nnz <= (abs(dec.d(0).T @ dec.d(0)) @ abs(dec.d(0).T @ dec.d(0))).nnz


@pytest.mark.parametrize("text, words", [("u * integral(u)", "couples all its values"),
                                         ("u * inner(u, u)", "couples all its values")])
def test_a_term_without_an_exact_jacobian_is_refused_in_one_line(text, words):
    compiler = _compiler(dec_of("lattice"))
    with pytest.raises(ModelError, match=words) as caught:
        derivative(compiler, parse_expression(text, "app.equations[0]"), "u", "app.equations[0]")
    assert "\n" not in str(caught.value) and str(caught.value).startswith("app.equations[0]: ")


def _problem(equations, fields, mesh="lattice", star="circumcentric"):
    spec = ModelSpec(fields=fields, equations=equations, dt=0.01)
    return ModelProblem(compile_model(spec, dec_of(mesh, star), solver_factory("auto")))


def test_the_problem_condenses_dirichlet_values_and_its_jacobian_is_exact():
    """dt(u) = 0.1 Δu − u v², dt(v) = Δv + u v² with u fixed on the border: y holds the free
    values only (u's border rows gone), M = ⋆0 there, f's Jacobian equals central differences,
    f = L y + g with L the constant Laplacian blocks."""
    fields = {"u": FieldSpec(0, "1 + 0.1*x", dirichlet="1 + 0.1*x"), "v": FieldSpec(0, "0.2 + 0.1*y")}
    problem = _problem(["dt(u) = 0.1*laplacian(u) - u*v**2", "dt(v) = laplacian(v) + u*v**2"], fields)
    K = dec_of("lattice").K
    border = problem.fixed_index
    assert border.size > 0 and problem.size == 2 * K.num_simplices(0) - border.size
    star0 = dec_of("lattice").star(0).diagonal()
    assert np.allclose(problem.mass.diagonal(), np.concatenate([star0, star0])[problem.free])
    rng = np.random.default_rng(2)
    y = problem.free_values({"u": 1 + 0.1 * K.vertices[:, 0], "v": 0.2 + 0.1 * K.vertices[:, 1]})
    y = y + 0.01 * rng.standard_normal(y.size)
    w = rng.standard_normal(y.size)
    numeric = (problem.f(y + 1e-6 * w, 0.0) - problem.f(y - 1e-6 * w, 0.0)) / 2e-6
    assert np.abs(problem.jacobian(y, 0.0) @ w - numeric).max() <= 1e-8 * np.abs(numeric).max()
    assert np.allclose(problem.f(y, 0.0), problem.stiff @ y + problem.nonstiff(y, 0.0), rtol=0, atol=1e-13)
    state = problem.state(y)
    assert np.array_equal(state["u"][np.sort(border)], (1 + 0.1 * K.vertices[:, 0])[np.sort(border)])


def test_a_linear_problem_is_its_stiff_part_on_a_galerkin_star():
    """Heat on Whitney's ⋆: M = ⋆0 (not diagonal), f = L y exactly, the Jacobian is L."""
    problem = _problem(["dt(u) = laplacian(u)"], {"u": FieldSpec(0, "x*y")}, mesh="sphere", star="whitney")
    y = np.random.default_rng(3).standard_normal(problem.size)
    assert problem.mass is not None and (problem.mass - sp.diags(problem.mass.diagonal())).count_nonzero() > 0
    assert np.allclose(problem.f(y, 0.0), problem.stiff @ y, rtol=0, atol=1e-12 * np.abs(problem.stiff @ y).max())
    assert abs(problem.jacobian(y, 0.0) - problem.stiff).max() == 0
