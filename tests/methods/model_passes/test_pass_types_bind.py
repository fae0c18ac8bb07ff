"""The kind pass (every definition's kind inferred in dependency order, the declared kinds of
fields and constants, mismatches refused in one line) and the bind pass (the built-in names,
constants, initial and Dirichlet values on the mesh) on small models."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.methods.model import FieldSpec, ModelError, ModelSpec
from decrun.methods.model.kinds import NUMBER, dual, primal
from decrun.methods.model.operators import Discrete
from decrun.methods.model.passes.bind import _bind_values, _dirichlet, border_simplices
from decrun.methods.model.passes.order import _order
from decrun.methods.model.passes.parse import _parse_equations
from decrun.methods.model.passes.resolve import _resolve
from decrun.methods.model.passes.types import _declared_kinds, _type_definitions
from decrun.runner.job.plugins import option


@lru_cache(maxsize=None)
def dec_of(source: str, **options) -> DEC:
    mesh = option("mesh", source, **options).load()
    return DEC(SimplicialComplex(mesh.vertices, mesh.simplices))


def square() -> DEC:
    return dec_of("grid", nx=5, ny=5)


def typed(equations, fields, constants=None, dec=None):
    """The kinds and the compiler after the kind pass."""
    spec = ModelSpec(fields=fields, equations=list(equations), constants=dict(constants or {}))
    ops = Discrete(dec or square())
    kinds = _declared_kinds(spec, ops.n)
    resolved = _resolve(spec, _parse_equations(spec))
    ordered = _order(resolved.definitions, resolved.solves, set(spec.fields) | set(spec.constants), "app")
    compiler = _type_definitions(spec, ops, kinds, resolved, ordered)
    return kinds, compiler


def test_the_kind_of_every_definition_is_inferred_in_dependency_order():
    """On triangles: d raises the degree, ⋆ maps a primal k-form to a dual (2−k)-form, integral
    gives a number, arithmetic keeps the kind; the definitions are written out of order."""
    kinds, _ = typed(["g_star = star(g)", "g = d(u)", "m = integral(u*u)", "s = m*u + 1", "flux = d(g_star)",
                      "dt(u) = laplacian(u) + s"], {"u": FieldSpec(0, "x")}, constants={"c": 2.0})
    assert kinds["u"] == primal(0) and kinds["c"] == NUMBER
    assert kinds["g"] == primal(1)
    assert kinds["g_star"] == dual(1)
    assert kinds["flux"] == dual(2)
    assert kinds["m"] == NUMBER
    assert kinds["s"] == primal(0)


def test_declared_forms_are_kinds_and_the_varying_names_follow_the_evolved_fields():
    kinds, compiler = typed(["dt(u) = laplacian(u)", "w = d(u)", "k = d(x)"],
                            {"u": FieldSpec(0, "x"), "rho": FieldSpec("dual0", 1.0), "a": FieldSpec(2, 0.0)})
    assert kinds["rho"] == dual(0) and kinds["a"] == primal(2)
    assert "w" in compiler.varying and "u" in compiler.varying
    assert "k" not in compiler.varying  # reads only coordinates: computed once


@pytest.mark.parametrize("equations, fields, constants, start", [
    (["w = d(u)", "dt(u) = laplacian(u)"], {"u": FieldSpec(0, "x"), "w": FieldSpec(0)}, {},
     "app.equations[0]: d(u) is a primal 1-form but w is declared a primal 0-form (app.fields.w.form)"),
    (["w = u + d(u)", "dt(u) = laplacian(u)"], {"u": FieldSpec(0, "x")}, {},
     "app.equations[0]: u + d(u) adds a primal 0-form and a primal 1-form"),
    (["dt(u) = laplacian(u)"], {"u": FieldSpec(0, "x")}, {"c": float("nan")}, "app.constants.c: must be a finite"),
    (["dt(u) = laplacian(u)"], {"u": FieldSpec(7, "x")}, {}, "app.fields.u.form"),
])
def test_the_kind_pass_refuses_in_one_line(equations, fields, constants, start):
    with pytest.raises(ModelError) as error:
        typed(equations, fields, constants)
    message = str(error.value)
    assert "\n" not in message and message.startswith(start), message


# ---------------------------------------------------------------------------------------- bind
def bound(fields, constants=None, dt=0.25, dec=None):
    spec = ModelSpec(fields=fields, equations=["dt(u) = laplacian(u)"], constants=dict(constants or {}), dt=dt)
    dec = dec or square()
    ops = Discrete(dec)
    kinds = _declared_kinds(spec, ops.n)
    names = list(fields)
    base, initial = _bind_values(spec, ops, kinds, names[:1], names[1:], None)
    return spec, kinds, base, initial, dec


def test_bind_gives_the_built_in_names_constants_inputs_and_sampled_initial_values():
    spec, kinds, base, initial, dec = bound({"u": FieldSpec(0, "x*y + c"), "f": FieldSpec(0, "sin(pi*x)")},
                                            constants={"c": 3.0})
    K = dec.K
    x, y = K.vertices[:, 0], K.vertices[:, 1]
    np.testing.assert_array_equal(base["x"], x)
    np.testing.assert_array_equal(base["y"], y)
    np.testing.assert_array_equal(base["z"], np.zeros(len(x)))
    edges = K.vertices[K.simplices(1)]
    assert base["h"] == pytest.approx(np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1).mean(), rel=1e-12)
    assert (base["pi"], base["t"], base["dt"], base["c"]) == (np.pi, 0.0, 0.25, 3.0)
    np.testing.assert_allclose(initial["u"], x * y + 3.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(base["f"], np.sin(np.pi * x), rtol=0, atol=1e-15)  # an input: in every evaluation
    assert "u" not in base  # an evolved field is the state, not a base value


def test_dirichlet_values_sit_on_the_border_simplices():
    fields = {"u": FieldSpec(0, "x", dirichlet="1 + x*y"), "a": FieldSpec(1, 0.0, dirichlet=0.5)}
    spec, kinds, base, initial, dec = bound(fields)
    fixed = _dirichlet(spec, kinds, dec, "app")
    K = dec.K
    border_vertices = np.flatnonzero(np.isclose(np.abs(K.vertices[:, :2]).max(axis=1), np.abs(K.vertices).max()))
    index, values = fixed["u"]
    np.testing.assert_array_equal(np.sort(index), border_vertices)  # the square's boundary vertices
    np.testing.assert_allclose(values, 1 + K.vertices[index, 0] * K.vertices[index, 1], rtol=0, atol=1e-15)
    edges, edge_values = fixed["a"]
    np.testing.assert_array_equal(edges, border_simplices(K, 1))
    assert len(edges) == len(border_vertices)  # a closed polygon: as many edges as vertices
    np.testing.assert_array_equal(edge_values, np.full(len(edges), 0.5))


@pytest.mark.parametrize("fields, start", [
    ({"u": FieldSpec(2, "x", dirichlet=0.0)}, "app.fields.u.dirichlet: border values fix primal forms of degree < 2"),
    ({"u": FieldSpec(0, "x", dirichlet="laplacian(x)")}, "app.fields.u.dirichlet: laplacian(x): an initial or border"),
])
def test_the_bind_pass_refuses_in_one_line(fields, start):
    spec, kinds, base, initial, dec = bound(fields)
    with pytest.raises(ModelError) as error:
        _dirichlet(spec, kinds, dec, "app")
    message = str(error.value)
    assert "\n" not in message and message.startswith(start), message


def test_a_closed_surface_has_no_border():
    spec, kinds, base, initial, dec = bound({"u": FieldSpec(0, "x", dirichlet=0.0)},
                                            dec=dec_of("icosphere", subdiv=1, noise=0.0))
    with pytest.raises(ModelError) as error:
        _dirichlet(spec, kinds, dec, "app")
    assert str(error.value).startswith("app.fields.u.dirichlet: this mesh has no border (a closed surface); drop the "
                                       "condition with `app.fields.u.dirichlet=null`")


def test_moving_dirichlet_values_are_bound_at_the_start_time():
    """Border values may read t (moving borders, decrun.methods.model.borders): the bind pass
    takes them at t = 0, so ``(1 + t)*x`` fixes x on the border."""
    spec, kinds, base, initial, dec = bound({"u": FieldSpec(0, "x", dirichlet="(1 + t)*x")})
    fixed = _dirichlet(spec, kinds, dec, "app")
    border, values = fixed["u"]
    np.testing.assert_allclose(values, dec.K.vertices[border, 0], atol=1e-15)
