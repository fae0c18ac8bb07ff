"""One evaluator: initial and border values run through the closures of the model's compiler —
the same evaluation as equations and metrics — at the vertices (and circumcentres, quadrature
points); the bdf/radau sparsity pattern is the structure of the exact Jacobian
(decrun.methods.model.jacobian)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
import scipy.sparse as sp

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.solvers import solver_factory
from decrun.methods.model import FieldSpec, ModelError, ModelSpec, compile_model
from decrun.methods.model.integrators import jacobian_pattern
from decrun.methods.model.jacobian import derivative, pattern
from decrun.runner.job.plugins import option

EXPRESSION = "exp(-x**2)*sin(3*y) + max(x, y)**2 - c*abs(x - 0.1)/(1 + y**2) + sqrt(2 + cos(pi*x)) - tanh(-c)"


@lru_cache(maxsize=None)
def square() -> DEC:
    mesh = option("mesh", "grid", nx=6, ny=6).load()
    return DEC(SimplicialComplex(mesh.vertices, mesh.simplices))


def compiled(equations, fields, constants=None):
    spec = ModelSpec(fields=fields, equations=list(equations), constants=dict(constants or {"c": 0.7}))
    return compile_model(spec, square(), solver_factory("direct"))


def test_an_initial_value_is_the_equations_evaluation_of_the_same_expression_bit_for_bit():
    model = compiled(["dt(u) = laplacian(u)", f"w = {EXPRESSION}"], {"u": FieldSpec(0, EXPRESSION)})
    env = model.environment(dict(model.initial_values), 0.0)
    np.testing.assert_array_equal(model.initial_values["u"], env["w"])
    x, y = square().K.vertices[:, 0], square().K.vertices[:, 1]
    exact = (np.exp(-x ** 2) * np.sin(3 * y) + np.maximum(x, y) ** 2 - 0.7 * np.abs(x - 0.1) / (1 + y ** 2)
             + np.sqrt(2 + np.cos(np.pi * x)) - np.tanh(-0.7))
    np.testing.assert_allclose(env["w"], exact, rtol=1e-15, atol=1e-15)


def test_a_border_value_and_a_dual_value_use_the_same_evaluator():
    model = compiled(["dt(u) = laplacian(u)", "r2 = star(1 + x*y)"],
                     {"u": FieldSpec(0, 0.0, dirichlet="1 + x*y"), "r": FieldSpec("dual2", "1 + x*y")})
    index, values = model.fixed["u"]
    x, y = square().K.vertices[index, 0], square().K.vertices[index, 1]
    np.testing.assert_array_equal(values, 1 + x * y)
    env = model.environment(dict(model.initial_values), 0.0)
    np.testing.assert_allclose(env["r"], env["r2"], rtol=1e-14, atol=1e-15)  # ⋆ of the same primal values


@pytest.mark.parametrize("initial", ["1/0", "(-8)**(1/3)", "10.0**400", "1/(x - x)", "log(x - 10)"])
def test_a_value_that_is_not_finite_is_refused_in_one_line(initial):
    with pytest.raises(ModelError) as error:
        compiled(["dt(u) = laplacian(u)"], {"u": FieldSpec(0, initial)})
    message = str(error.value)
    assert "\n" not in message and message.startswith("app.fields.u.initial: the value is not finite at "), message


def test_operators_stay_out_of_values_and_vertex_is_checked_when_the_model_loads():
    for text, start in (("laplacian(x)", "app.fields.u.initial: laplacian(x): an initial or border value"),
                        ("vertex(36)", "app.fields.u.initial: vertex(36): the mesh has vertices 0..35"),
                        ("vertex(x)", "app.fields.u.initial: vertex(x): vertex takes a vertex index (a number)")):
        with pytest.raises(ModelError) as error:
            compiled(["dt(u) = laplacian(u)"], {"u": FieldSpec(0, text)})
        assert str(error.value).startswith(start), str(error.value)
    model = compiled(["dt(u) = laplacian(u)"], {"u": FieldSpec(0, "2*vertex(c)")}, constants={"c": 7})
    np.testing.assert_array_equal(np.flatnonzero(model.initial_values["u"]), [7])
    assert model.initial_values["u"][7] == 2.0


# ---------------------------------------------------------------------------------------- patterns
def structure(matrix) -> set[tuple[int, int]]:
    coo = sp.coo_matrix(matrix)
    keep = coo.data != 0
    return set(zip(coo.row[keep].tolist(), coo.col[keep].tolist(), strict=True))


@pytest.mark.parametrize("term, superset", [
    ("0.01*laplacian(u) - 0.1*cosh(u)", False),
    ("u*v**2 - laplacian(v*u) + star(d(star(d(u))))", False),
    ("exp(-u)/(1 + v**2) + sin(laplacian(u))", False),
    ("max(u, v) + sign(u)*v", True),  # the rules give 0 at some values: the pattern holds every state's
])
def test_the_bdf_radau_pattern_is_the_structure_of_the_exact_jacobian(term, superset):
    model = compiled([f"dt(u) = {term}", "dt(v) = laplacian(v)"],
                     {"u": FieldSpec(0, "0.3 + 0.2*x*y + 0.1*sin(5*x)"), "v": FieldSpec(0, "0.5 + 0.1*cos(3*y)")})
    env = model.environment(dict(model.initial_values), 0.0)
    tree = model.equations[0].rhs
    for unknown in ("u", "v"):
        expected = structure(derivative(model.compiler, tree, unknown, "app.equations[0]")(env))
        got = structure(pattern(model.compiler, tree, unknown, "app.equations[0]"))
        assert expected <= got if superset else expected == got, (unknown, len(expected), len(got))
    stacked = jacobian_pattern(model)  # the integrators' pattern over (u, v) is built from it
    n = model.ops.K.num_simplices(0)
    assert stacked.shape == (2 * n, 2 * n) and stacked.nnz < 0.2 * (2 * n) ** 2


@pytest.mark.parametrize("term, why", [
    ("laplacian(u) - u*mean(u)", "no sparse Jacobian pattern through mean(u) (a number computed from u couples"),
])
def test_bdf_and_radau_refuse_a_term_without_a_sparse_jacobian_in_one_line(term, why):
    with pytest.raises(ModelError) as error:
        jacobian_pattern(compiled([f"dt(u) = {term}"], {"u": FieldSpec(0, "x")}))
    message = str(error.value)
    assert "\n" not in message and message.startswith(f"app.equations[0]: integrator=bdf/radau: {why}"), message
    assert message.endswith("use `app.integrator=imex` or `app.integrator=rk4`")
