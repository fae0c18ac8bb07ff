"""The lowering pass and the passes after it on small models: evolutions split into a mass, the
linear blocks with constant coefficients (implicit), the nonlinear terms (reading an evolved
field) and the explicit ones (reading none); solves into one factorized matrix, a nonlinear solve
into Newton, a system into one block matrix; metrics compiled to numbers; the stars checked."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
import scipy.sparse as sp

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.solvers import solver_factory
from decrun.methods.model import FieldSpec, ModelError, ModelSpec, compile_model
from decrun.methods.model.language import parse_expression, to_text
from decrun.methods.model.passes.stars import _check_stars
from decrun.runner.job.plugins import option


@lru_cache(maxsize=None)
def dec_of(source: str, star: str = "circumcentric", **options) -> DEC:
    mesh = option("mesh", source, **options).load()
    return DEC(SimplicialComplex(mesh.vertices, mesh.simplices), star=star)


def square() -> DEC:
    return dec_of("grid", nx=5, ny=5)


def compiled(equations, fields, constants=None, metrics=None, dec=None):
    spec = ModelSpec(fields=fields, equations=list(equations), constants=dict(constants or {}),
                     metrics=dict(metrics or {}))
    return compile_model(spec, dec or square(), solver_factory("direct"))


def blocks_apply(model, u: str, state: dict) -> np.ndarray:
    """M_u⁻¹ Σ_v A_uv v: what the linear blocks of dt(u) give (a diagonal mass here)."""
    evolution = model.evolution
    total = sum(A @ state[v] for (row, v), A in evolution.blocks.items() if row == u)
    return total / evolution.mass[u].diagonal()


def rest(model, u: str) -> list[tuple[float, str]]:
    return [(sign, to_text(term)) for sign, term in model.evolution.rest_trees[u]]


def laplacian(model, values: np.ndarray) -> np.ndarray:
    closure = model.compiler.compile(parse_expression("laplacian(u)", "test"), "test")
    return closure({"u": values})


def test_heat_is_one_linear_block_and_nothing_else():
    model = compiled(["dt(u) = laplacian(u)"], {"u": FieldSpec(0, "x*y")})
    evolution = model.evolution
    assert list(evolution.blocks) == [("u", "u")] and rest(model, "u") == []
    M = evolution.mass["u"]
    np.testing.assert_array_equal(M.toarray(), model.ops.dec.star(0).toarray())  # the weak form's ⋆0
    u = model.initial_values["u"]
    np.testing.assert_allclose(blocks_apply(model, "u", {"u": u}), laplacian(model, u), rtol=1e-12, atol=1e-12)
    assert model.evolution is evolution  # lowered once, shared by every caller


def test_allen_cahn_is_a_linear_block_and_one_nonlinear_term():
    model = compiled(["dt(u) = eps*laplacian(u) + u - u**3"], {"u": FieldSpec(0, "x - y")}, {"eps": 0.01})
    assert list(model.evolution.blocks) == [("u", "u")]
    assert rest(model, "u") == [(-1.0, "u ** 3")]
    assert model.evolution.reads_evolved("u")  # the cubic term is nonlinear
    u = model.initial_values["u"]
    np.testing.assert_allclose(blocks_apply(model, "u", {"u": u}), 0.01 * laplacian(model, u) + u, rtol=1e-12,
                               atol=1e-12)


def test_gray_scott_splits_into_diagonal_linear_blocks_nonlinear_and_explicit_terms():
    constants = {"Du": 1e-3, "Dv": 5e-4, "F": 0.035, "k": 0.065}
    model = compiled(["dt(v) = Dv*laplacian(v) + u*v**2 - (F + k)*v", "dt(u) = Du*laplacian(u) - u*v**2 + F*(1 - u)"],
                     {"v": FieldSpec(0, "x"), "u": FieldSpec(0, "1 - y")}, constants)
    evolution = model.evolution
    assert sorted(evolution.blocks) == [("u", "u"), ("v", "v")]  # no linear coupling
    assert rest(model, "v") == [(1.0, "u * v ** 2")]
    assert rest(model, "u") == [(-1.0, "u * v ** 2"), (1.0, "F * 1")]  # F*(1 - u) distributed: F*u is linear
    evolved = set(evolution.names)
    kinds = {to_text(term): model.compiler.depends_on(term, evolved) for _s, term in evolution.rest_trees["u"]}
    assert kinds == {"u * v ** 2": True, "F * 1": False}  # nonlinear, explicit
    state = dict(model.initial_values)
    np.testing.assert_allclose(blocks_apply(model, "u", state), 1e-3 * laplacian(model, state["u"]) - 0.035 * state["u"],
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(blocks_apply(model, "v", state), 5e-4 * laplacian(model, state["v"]) - 0.1 * state["v"],
                               rtol=1e-12, atol=1e-12)


def test_a_linear_solve_is_one_matrix_a_nonlinear_one_newton_a_system_one_block_matrix():
    fields = {"u": FieldSpec(0, "x"), "p": FieldSpec(0, 0.5), "q": FieldSpec(0, 0.5), "a": FieldSpec(1), "b": FieldSpec(2),
              "f": FieldSpec(2, "x")}
    model = compiled(["dt(u) = laplacian(u) + p + q", "solve(p - laplacian(p) = u)", "solve(q + q**3 = 2)",
                      "solve(a - codifferential(b) = 0, d(a) = f)"], fields, dec=square())
    what = {item.unknown if kind != "system" else ",".join(item.unknowns): kind for kind, item in model.order}
    assert what == {"p": "solve", "q": "newton", "a,b": "system"}
    env = model.environment(dict(model.initial_values), 0.0)
    u, p = env["u"], env["p"]
    fixed = model.fixed.get("p", (np.zeros(0, dtype=int),))[0]
    free = np.setdiff1d(np.arange(len(p)), fixed)
    np.testing.assert_allclose((p - laplacian(model, p))[free], u[free], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(env["q"] + env["q"] ** 3, 2.0, rtol=1e-10)  # q = 1
    system = next(item for kind, item in model.order if kind == "system")
    n1, n2 = model.ops.K.num_simplices(1), model.ops.K.num_simplices(2)
    assert system.system.A_full.shape == (n1 + n2, n1 + n2) and sp.issparse(system.system.A_full)


def test_metrics_are_numbers_compiled_once():
    model = compiled(["dt(u) = laplacian(u)"], {"u": FieldSpec(0, "x")},
                     metrics={"area": "integral(1 + 0*u)", "peak": "max(u)"})
    values = model.metric_values(model.environment(dict(model.initial_values), 0.0))
    assert values["area"] == pytest.approx(1.0, rel=1e-12)  # the unit square
    assert values["peak"] == pytest.approx(0.5, rel=1e-12)
    with pytest.raises(ModelError) as error:
        compiled(["dt(u) = laplacian(u)"], {"u": FieldSpec(0, "x")}, metrics={"m": "u*u"})
    assert str(error.value).startswith("app.metrics.m: u * u is a primal 0-form; a metric is a number")


def test_the_stars_pass_refuses_a_star_the_variant_lacks():
    """operator=intrinsic_delaunay has ⋆0 (and its intrinsic ⋆1) only: a term needing ⋆2 is refused."""
    model = compiled(["dt(u) = laplacian(u)"], {"u": FieldSpec(0, "x")})
    tree = parse_expression("star(d(d(u)))", "app.equations[0]")
    model.compiler.kind(tree, "app.equations[0]")
    _check_stars(model.compiler, square(), [("app.equations[0]", tree)])  # circumcentric: every ⋆
    with pytest.raises(ModelError) as error:
        _check_stars(model.compiler, dec_of("grid", "intrinsic_delaunay", nx=5, ny=5), [("app.equations[0]", tree)])
    message = str(error.value)
    assert message.startswith("app.equations[0]: star(d(d(u))) needs ⋆_2, but operator=intrinsic_delaunay "
                              "provides ⋆ on [0, 1]-forms only"), message
