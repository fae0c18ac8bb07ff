"""The model language (decrun.methods.model): parsed, never evaluated; typed, with one-line errors
that name the config key and the term; initial values sampled as the docstrings promise; the
linear split of the compiler.

The operators' mathematics (equal to DEC, exact identities of ∧ ♯ ♭ …) is in
test_model_operators.py."""

from __future__ import annotations

import ast
import builtins
import difflib  # noqa: F401 - imported here so that its first import (namedtuple → eval) is not under the guard
import os
import subprocess
from functools import lru_cache

import numpy as np
import pytest

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.solvers import solver_factory
from decrun.methods.model import FieldSpec, ModelError, ModelSpec, compile_model
from decrun.methods.model.compiler import NOT_LINEAR, Compiler
from decrun.methods.model.kinds import NUMBER, primal
from decrun.methods.model.language import MAX_EXPRESSION_LENGTH, parse_equation, parse_expression, to_text
from decrun.methods.model.operators import Discrete
from decrun.runner.job.plugins import option


@lru_cache(maxsize=None)
def dec_of(source: str, star: str = "circumcentric", **options) -> DEC:
    mesh = option("mesh", source, **options).load()
    return DEC(SimplicialComplex(mesh.vertices, mesh.simplices), star=star)


def sphere() -> DEC:
    return dec_of("icosphere", subdiv=2, noise=0.0)


def square() -> DEC:
    return dec_of("grid", nx=6, ny=6)


def planar() -> DEC:
    return dec_of("planar")


def compile_(equations, fields=None, constants=None, metrics=None, seed=0, dec=None):
    fields = {"u": {"form": 0, "initial": "x*y"}} if fields is None else fields
    spec = ModelSpec(fields={name: FieldSpec(**value) for name, value in fields.items()}, equations=list(equations),
                     constants=dict(constants or {}), metrics=dict(metrics or {}), seed=seed)
    return compile_model(spec, dec or sphere(), solver_factory("direct"))


def refused(*args, **kwargs) -> str:
    """The one-line message of the ModelError that compiling the model raises."""
    with pytest.raises(ModelError) as info:
        compile_(*args, **kwargs)
    message = str(info.value)
    assert "\n" not in message, message
    assert len(message) < 400, message
    return message


# ---------------------------------------------------------------------------------------- safety
#: every string must be refused by the parser, whatever key it is written under; the file
#: MARKER must never appear (the strings that would create it are marked with {marker})
HOSTILE = {
    "import_call": "__import__('os').system('touch {marker}')",
    "import_in_operator": "laplacian(__import__('os').system('touch {marker}'))",
    "attribute": "u.__class__",
    "attribute_of_tuple": "().__class__.__bases__[0].__subclasses__()",
    "subscript": "u[0]",
    "lambda": "(lambda: __import__('os').system('touch {marker}'))()",
    "list_comprehension": "[os.system('touch {marker}') for os in [__import__('os')]]",
    "generator": "sum(u for u in x)",
    "keyword_argument": "laplacian(u, k=1)",
    "string": "'touch {marker}'",
    "f_string": "f\"{{__import__('os').system('touch {marker}')}}\"",
    "walrus": "(v := u)",
    "conditional": "u if u else x",
    "comparison": "u < 1",
    "chained_comparison": "0 < u < 1",
    "boolean": "u and x",
    "dunder_name": "__builtins__",
    "dunder_call": "__import__",
    "private_name": "_secret",
    "private_operator": "_laplacian(u)",
    "star_argument": "laplacian(*u)",
    "dict": "{{'a': u}}",
    "set": "{{u}}",
    "matmul": "u @ u",
    "not": "not u",
    "bitwise_or": "u | x",
    "ellipsis": "...",
    "none": "None",
    "bool": "True",
    "complex": "1j",
    "bytes": "b'x'",
    "await": "await u",
    "statement": "u; __import__('os').system('touch {marker}')",
    "null_byte": "u\x00",
    "huge": "u + " * 25_000 + "u",  # 100 kB
    "nested_10000": "(" * 10_000 + "u" + ")" * 10_000,
    "nested_within_length": "(" * 1_000 + "u" + ")" * 1_000,
    "deep_unary": "-" * 3_000 + "u",
    "deep_calls": "exp(" * 500 + "u" + ")" * 500,
}

#: where a hostile expression may stand, and the key the error must name
KEYS = ["equation", "metric", "initial", "initial_vector", "dirichlet"]


def _model_with(where: str, text: str):
    """(compile arguments, the key the message must name) for ``text`` written at ``where``."""
    fields = {"u": {"form": 0, "initial": "x*y"}}
    equations = ["dt(u) = laplacian(u)"]
    metrics = {"mass": "integral(u)"}
    dec = sphere()
    if where == "equation":
        equations = [equations[0], f"w = {text}"]
        key = "app.equations[1]:"
    elif where == "metric":
        metrics = {"mass": "integral(u)", "evil": text}
        key = "app.metrics.evil:"
    elif where == "initial":
        fields["u"]["initial"] = text
        key = "app.fields.u.initial:"
    elif where == "initial_vector":
        fields["g"] = {"form": 1, "initial": ["x", text, "0"]}
        key = "app.fields.g.initial[1]:"
    else:
        dec = square()
        fields["u"]["dirichlet"] = text
        key = "app.fields.u.dirichlet:"
    return dict(equations=equations, fields=fields, metrics=metrics, dec=dec), key


@pytest.fixture
def guard(monkeypatch, tmp_path):
    """No eval, exec, compile (other than to a syntax tree), os.system or subprocess while the
    test runs; returns the marker file that a hostile string would create."""
    marker = tmp_path / "PWNED"
    monkeypatch.chdir(tmp_path)
    # meshes loaded and a valid model compiled first: what Python imports on first use (pymeshlab,
    # the runner's modules) compiles code, and that is not the language's doing
    compile_(["dt(u) = laplacian(u)"], metrics={"m": "integral(u)"})
    compile_(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": 0, "dirichlet": "x"}}, dec=square())
    real_compile = builtins.compile

    def forbidden(name):
        def fail(*args, **kwargs):
            raise AssertionError(f"{name} was called with {str(args)[:200]}")
        return fail

    def compile_to_tree_only(source, filename, mode, flags=0, *args, **kwargs):
        if not flags & ast.PyCF_ONLY_AST:  # ast.parse: builds a tree, runs nothing
            raise AssertionError(f"compile was called on {str(source)[:200]!r} (not to a syntax tree)")
        return real_compile(source, filename, mode, flags, *args, **kwargs)

    for name in ("eval", "exec"):
        monkeypatch.setattr(builtins, name, forbidden(name))
    monkeypatch.setattr(builtins, "compile", compile_to_tree_only)
    monkeypatch.setattr(os, "system", forbidden("os.system"))
    monkeypatch.setattr(os, "popen", forbidden("os.popen"))
    monkeypatch.setattr(subprocess, "Popen", forbidden("subprocess.Popen"))
    return marker


def test_the_guard_itself_catches_eval_and_exec(guard):
    with pytest.raises(AssertionError, match="eval was called"):
        eval("1")  # noqa: S307 - the guard's own test
    with pytest.raises(AssertionError, match="compile was called"):
        compile("1", "<x>", "eval")
    assert isinstance(ast.parse("u + 1", mode="eval"), ast.Expression)  # the parser itself still works


@pytest.mark.parametrize("where", KEYS)
@pytest.mark.parametrize("name", HOSTILE)
def test_hostile_expressions_are_refused_in_one_line_naming_the_key(guard, where, name):
    text = HOSTILE[name].format(marker=guard)
    arguments, key = _model_with(where, text)
    message = refused(**arguments)
    assert message.startswith(key), message
    assert not guard.exists()


def test_a_hostile_left_side_or_whole_equation_is_refused(guard):
    for text in (f"__import__('os').system('touch {guard}') = u", f"__import__('os').system('touch {guard}')",
                 "dt(__import__('os')) = u", f"solve(__import__('os').system('touch {guard}') = u)",
                 "u == 1", "dt(u) = laplacian(u) = u", "x"*(MAX_EXPRESSION_LENGTH + 1) + " = u"):
        message = refused(["dt(u) = laplacian(u)", text])
        assert message.startswith("app.equations[1]:"), message
    assert not guard.exists()


def test_hostile_names_of_fields_constants_and_metrics_are_refused(guard):
    assert refused(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": 0},
                                                    "__class__": {"form": 0, "initial": 0}}) \
        .startswith("app.fields.__class__:")
    assert refused(["dt(u) = laplacian(u)"], constants={"__import__": 1.0}).startswith("app.constants.__import__:")
    assert refused(["dt(u) = laplacian(u)"], metrics={"a b": "integral(u)"}).startswith("app.metrics.a b:")
    assert refused(["dt(u) = laplacian(u)"], constants={"k": "__import__('os')"}).startswith("app.constants.k:")
    assert refused(["dt(u) = laplacian(u)"], fields={"u": {"form": "__import__('os')", "initial": 0}}) \
        .startswith("app.fields.u.form:")
    assert refused(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": f"result:__import__('os').system("
                                                                                 f"'touch {guard}')"}}) \
        .startswith("app.fields.u.initial:")
    assert not guard.exists()


def test_a_valid_model_still_compiles_under_the_guard(guard):
    model = compile_(["dt(u) = k*laplacian(u) + exp(-t)*u"], constants={"k": 0.5}, metrics={"mass": "integral(u)"})
    env = model.environment(dict(model.initial_values), 0.0)
    assert np.isfinite(model.metric_values(env)["mass"])


def test_parser_whitelist_in_isolation():
    """parse_expression builds only Number/Name/Call/Binary/Negate; unicode spellings are
    rewritten to the same tree as their ASCII names."""
    assert parse_expression("Δu", "k") == parse_expression("laplacian(u)", "k")
    assert parse_expression("⋆(d(u))", "k") == parse_expression("star(d(u))", "k")
    assert parse_expression("a ∧ b", "k") == parse_expression("a ^ b", "k")
    assert parse_expression("δ(w)", "k") == parse_expression("codifferential(w)", "k")
    assert parse_expression("−u·v", "k") == parse_expression("-u*v", "k")
    assert parse_equation("∂ₜu = Δu", "k").kind == "evolution"
    for bad in (True, None, [1], {"a": 1}):
        with pytest.raises(ModelError, match="^k: "):
            parse_expression(bad, "k")


@pytest.mark.parametrize("text", ["1e400", "-1e400", "1e400 - 1e400", "exp(1e400)", "1" + "0" * 400])
def test_non_finite_number_literals_are_refused(text):
    """1e400 is inf to Python's parser; a model with an infinite literal is an error at load,
    not a run that is `stable: false` (as a non-finite app.constants entry already is)."""
    message = refused([f"dt(u) = {text}*laplacian(u)"])
    assert message.startswith("app.equations[0]:") and "finite" in message, message
    message = refused(["dt(u) = laplacian(u)"], metrics={"m": text})
    assert message.startswith("app.metrics.m:") and "finite" in message, message
    for value in (float("inf"), float("nan"), 10 ** 400):
        with pytest.raises(ModelError, match=r"^app.metrics.m: .*finite"):
            parse_expression(value, "app.metrics.m")


# ---------------------------------------------------------------------------------------- types
def test_type_mismatch_names_the_equation_and_both_terms():
    message = refused(["dt(w) = laplacian(u)"], fields={"u": {"form": 0, "initial": 0}, "w": {"form": 1, "initial": 0}})
    assert message == "app.equations[0]: laplacian(u) is a primal 0-form but dt(w) is a primal 1-form"
    message = refused(["dt(u) = laplacian(u) + d(u)"])
    assert message.startswith("app.equations[0]: laplacian(u) + d(u) adds a primal 0-form and a primal 1-form")
    message = refused(["dt(u) = u", "v = u ^ star(u)"])
    assert message.startswith("app.equations[1]: u ^ star(u): wedge (^) takes two primal forms, got a primal "
                              "0-form and a dual 2-form"), message
    message = refused(["dt(u) = codifferential(u)"])
    assert message.startswith("app.equations[0]: codifferential(u): codifferential takes a primal k-form with k ≥ 1, "
                              "got a primal 0-form"), message
    message = refused(["dt(u) = d(d(d(u)))"])
    assert message.startswith("app.equations[0]: d(d(d(u))): d takes a form of degree < 2"), message
    message = refused(["dt(u) = laplacian(u)"], metrics={"m": "d(u)"})
    assert message.startswith("app.metrics.m: d(u) is a primal 1-form; a metric is a number"), message
    message = refused(["v = sharp(d(u)) + 1", "dt(u) = laplacian(u)"])
    assert message.startswith("app.equations[0]: sharp(d(u)) + 1 adds a number and a vector field"), message
    message = refused(["solve(laplacian(p) = d(u))", "dt(u) = laplacian(u)"],
                      fields={"u": {"form": 0, "initial": 0}, "p": {"form": 0}})
    assert message.startswith("app.equations[0]: laplacian(p) is a primal 0-form but d(u) is a primal 1-form"), message
    message = refused(["dt(u) = laplacian(u)", "v = wedge(u)"])
    assert message.startswith("app.equations[1]: wedge takes 2 argument(s), got 1 in wedge(u)"), message


def test_a_definition_declared_as_a_field_must_have_its_kind():
    message = refused(["dt(u) = laplacian(u)", "g = d(u)"],
                      fields={"u": {"form": 0, "initial": 0}, "g": {"form": 2}})
    assert message.startswith("app.equations[1]: d(u) is a primal 1-form but g is declared a primal 2-form"), message


@pytest.mark.parametrize("equation, expected", [
    ("dt(u) = lapalcian(u)", "app.equations[0]: unknown operator 'lapalcian' in lapalcian(u) (did you mean "
                             "'laplacian'?)"),
    ("dt(u) = laplacian(uu)", "app.equations[0]: unknown name 'uu' (did you mean 'u'?)"),
    ("dt(u) = codiferential(d(u))", "app.equations[0]: unknown operator 'codiferential' in codiferential(d(u)) "
                                    "(did you mean 'codifferential'?)"),
    ("dt(u) = kk*laplacian(u)", "app.equations[0]: unknown name 'kk' (did you mean 'k'?)"),
])
def test_unknown_names_and_operators_suggest_the_closest(equation, expected):
    assert refused([equation], constants={"k": 1.0}).startswith(expected)


def test_unknown_metric_operator_suggests():
    message = refused(["dt(u) = laplacian(u)"], metrics={"m": "integrl(u)"})
    assert message.startswith("app.metrics.m: unknown operator 'integrl' in integrl(u) (did you mean 'integral'?)")


def test_a_definition_cycle_names_the_cycle():
    message = refused(["a = b + u", "b = c", "c = 2*a", "dt(u) = a"])
    assert message.startswith("app.equations: the equations for a → b → c → a form a cycle"), message
    message = refused(["a = a + u", "dt(u) = a"])  # was "unknown name 'a'"
    assert message.startswith("app.equations: the equations for a → a form a cycle"), message


def test_a_solve_with_no_unknown():
    message = refused(["dt(u) = laplacian(u)", "solve(laplacian(u) = 1)"])
    assert message.startswith("app.equations[1]: the solve has no unknown: its left side laplacian(u)"), message
    message = refused(["dt(u) = laplacian(u)", "solve(laplacian(2*x) = 1)"])
    assert message.startswith("app.equations[1]: the solve has no unknown"), message


def test_a_nonlinear_solve_is_solved_by_newton_from_its_initial_value():
    """solve(p*p = 1) (refused before as 'not linear'): Newton from p = 0.5 finds p = 1; from
    p = 0 its Jacobian 2p is singular, and the refusal is one line naming the equation and the
    override of a start."""
    model = compile_(["solve(p*p = 1)"], fields={"p": {"form": 0, "initial": 0.5}})
    model.bind(solver_factory("direct"))
    assert np.allclose(model.environment({}, 0.0)["p"], 1.0, rtol=0, atol=1e-12)
    model = compile_(["solve(p*p = 1)"], fields={"p": {"form": 0}})
    model.bind(solver_factory("direct"))
    with pytest.raises(ModelError) as info:
        model.environment({}, 0.0)
    message = str(info.value)
    assert "\n" not in message and message.startswith("app.equations[0]: Newton's method did not converge"), message
    assert "`app.fields.p.initial=<expression>`" in message


def test_missing_initial_values():
    message = refused(["dt(u) = laplacian(u)"], fields={"u": {"form": 0}})
    assert message.startswith("app.fields.u.initial: missing initial value (dt(u) needs it)"), message
    message = refused(["dt(u) = laplacian(u) + f"], fields={"u": {"form": 0, "initial": 0}, "f": {"form": 0}})
    assert message.startswith("app.fields.f.initial: missing initial value (no equation computes it)"), message


@pytest.mark.parametrize("value", [float("inf"), float("-inf"), float("nan"), True, "1"])
def test_non_finite_or_non_number_constants(value):
    message = refused(["dt(u) = k*laplacian(u)"], constants={"k": value})
    assert message.startswith("app.constants.k: must be a finite number"), message


@pytest.mark.parametrize("value", [float("inf"), float("nan")])
def test_non_finite_initial_numbers_and_values(value):
    assert refused(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": value}}) \
        .startswith("app.fields.u.initial: must be a finite number")
    message = refused(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": "1/(x - x)"}})
    assert message.startswith("app.fields.u.initial: the value is not finite at 162 of 162 points"), message


def test_built_in_names_cannot_be_targets_or_fields():
    assert refused(["x = 2*u", "dt(u) = laplacian(u)"]).startswith("app.equations[0]: 'x' is a built-in name")
    assert refused(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": 0},
                                                    "laplacian": {"form": 0, "initial": 0}}) \
        .startswith("app.fields.laplacian: 'laplacian' is a built-in name")
    assert refused(["dt(u) = laplacian(u)", "dt(u) = u"]).startswith("app.equations[1]: 'u' is already computed")


def test_dt_is_only_a_left_side():
    message = refused(["dt(u) = dt(u)"])
    assert message.startswith("app.equations[0]: dt(...) is the time derivative and stands only on the left"), message
    message = refused(["dt(2*u) = u"])
    assert message.startswith("app.equations[0]: the left side of an evolution equation is dt(<field>)"), message


# ---------------------------------------------------------------------------------------- initial values
def _cubic():
    phi = "x**3 - 2*x*y*z + 3*y**2*z - z**3 + x*y"
    grad = ["3*x**2 - 2*y*z + y", "-2*x*z + 6*y*z + x", "-2*x*y + 3*y**2 - 3*z**2"]
    return phi, grad


@pytest.mark.parametrize("source", ["icosphere", "torus"])
def test_a_gradient_field_samples_to_d_of_the_potential(source):
    """The 1-form of X = ∇φ (line integrals, 5-point Gauss: exact for the quadratic ∇φ of a cubic
    φ) equals d0 of φ's 0-form to round-off."""
    dec = sphere() if source == "icosphere" else dec_of("torus")
    phi, grad = _cubic()
    model = compile_(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": phi},
                                                      "g": {"form": 1, "initial": grad}}, dec=dec)
    u, g = model.initial_values["u"], model.initial_values["g"]
    expected = dec.d(0) @ u
    np.testing.assert_allclose(g, expected, rtol=0, atol=1e-13 * np.abs(expected).max())


@pytest.mark.parametrize("source", ["icosphere", "torus"])
def test_a_2_form_sampled_from_a_curl_is_d_of_the_1_form_stokes(source):
    """A 2-form on a surface in R³ sampled from a vector field B is its flux through each oriented
    triangle; for B = curl A (A quadratic, so B linear: exact quadrature) it equals d of A's 1-form
    to round-off — the orientation of the flux and of d's rows agree."""
    dec = sphere() if source == "icosphere" else dec_of("torus")
    fields = {"u": {"form": 0, "initial": 0}, "A": {"form": 1, "initial": ["-y + x*z", "x + y**2", "x*y"]},
              "B": {"form": 2, "initial": ["x", "x - y", "2"]}}  # curl A
    model = compile_(["dt(u) = laplacian(u)"], fields=fields, dec=dec)
    expected = dec.d(1) @ model.initial_values["A"]
    np.testing.assert_allclose(model.initial_values["B"], expected, rtol=0, atol=1e-13 * np.abs(expected).max())


def test_a_dual_0_form_is_evaluated_at_circumcentres():
    dec = planar()
    K = dec.K
    model = compile_(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": 0},
                                                      "r": {"form": "dual0", "initial": "x**2 + 3*y - x*y"}}, dec=dec)
    p = K.vertices[K.simplices(2)]  # circumcentres by the textbook formula
    a, b, c = p[:, 0], p[:, 1], p[:, 2]
    D = 2 * (a[:, 0] * (b[:, 1] - c[:, 1]) + b[:, 0] * (c[:, 1] - a[:, 1]) + c[:, 0] * (a[:, 1] - b[:, 1]))
    sq = (p ** 2).sum(axis=2)
    cx = (sq[:, 0] * (b[:, 1] - c[:, 1]) + sq[:, 1] * (c[:, 1] - a[:, 1]) + sq[:, 2] * (a[:, 1] - b[:, 1])) / D
    cy = (sq[:, 0] * (c[:, 0] - b[:, 0]) + sq[:, 1] * (a[:, 0] - c[:, 0]) + sq[:, 2] * (b[:, 0] - a[:, 0])) / D
    np.testing.assert_allclose(model.initial_values["r"], cx ** 2 + 3 * cy - cx * cy, rtol=1e-12, atol=1e-13)
    assert model.kinds["r"].size(K) == K.num_simplices(2)


def test_a_top_form_is_a_density_integrated_and_a_dual_form_is_star_of_the_primal():
    dec = planar()
    model = compile_(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": 0}, "rho": {"form": 2, "initial": 1},
                                                      "area": {"form": 2, "initial": "1 + 0*x"},
                                                      "s": {"form": "dual2", "initial": "2*x - y"},
                                                      "p": {"form": 0, "initial": "2*x - y"}}, dec=dec)
    assert np.allclose(model.initial_values["rho"], 1.0)  # a number: that value on every simplex
    p = dec.K.vertices[dec.K.oriented_simplices()]  # ∫_σ 1 dx∧dy over the oriented triangles (all ccw here)
    signed = 0.5 * ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                    - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
    assert np.all(signed > 0)
    np.testing.assert_allclose(model.initial_values["area"], signed, rtol=1e-13)
    np.testing.assert_allclose(model.initial_values["s"], dec.star(0) @ model.initial_values["p"], rtol=1e-13)


def test_random_is_reproducible_per_seed_and_differs_between_fields():
    fields = {"u": {"form": 0, "initial": "random"}, "v": {"form": 0, "initial": "random"}}
    first = compile_(["dt(u) = laplacian(u)", "dt(v) = laplacian(v)"], fields=fields, seed=7).initial_values
    again = compile_(["dt(u) = laplacian(u)", "dt(v) = laplacian(v)"], fields=fields, seed=7).initial_values
    other = compile_(["dt(u) = laplacian(u)", "dt(v) = laplacian(v)"], fields=fields, seed=8).initial_values
    assert np.array_equal(first["u"], again["u"]) and np.array_equal(first["v"], again["v"])
    assert not np.allclose(first["u"], first["v"])
    assert not np.allclose(first["u"], other["u"])
    assert np.all(np.abs(first["u"]) <= 1) and first["u"].std() > 0.3  # uniform in [−1, 1]


@pytest.mark.parametrize("initial, constants", [("vertex(162)", {}), ("vertex(-1)", {}), ("vertex(1.5)", {}),
                                                ("vertex(source)", {"source": 1000})])
def test_vertex_out_of_range_is_refused(initial, constants):
    message = refused(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": initial}}, constants=constants)
    assert message.startswith("app.fields.u.initial: vertex(") and "vertices 0..161" in message, message


def test_vertex_is_an_indicator_and_only_a_0_form():
    model = compile_(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": "vertex(5)"}})
    expected = np.zeros(162)
    expected[5] = 1
    assert np.array_equal(model.initial_values["u"], expected)
    message = refused(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": 0},
                                                       "r": {"form": "dual0", "initial": "vertex(5)"}})
    assert message.startswith("app.fields.r.initial: vertex(i) is a 0-form"), message


def test_initial_values_refuse_operators_and_unknown_names():
    message = refused(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": "laplacian(x)"}})
    assert message.startswith("app.fields.u.initial: laplacian(x): an initial or border value is an expression"), message
    message = refused(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": "sin(xx)"}})
    assert message.startswith("app.fields.u.initial: unknown name 'xx' (did you mean 'x'?)"), message
    message = refused(["dt(u) = laplacian(u)"], fields={"u": {"form": 0, "initial": 0}, "g": {"form": 1,
                                                                                           "initial": ["x", "y"]}})
    assert message.startswith("app.fields.g.initial: a vector field has 3 components"), message


# ---------------------------------------------------------------------------------------- linear split
def _compiler(dec, kinds, constants=None, varying=("u",)):
    compiler = Compiler(Discrete(dec), kinds, varying=set(varying))
    K = dec.K
    compiler.static_env = {"x": K.vertices[:, 0], "y": K.vertices[:, 1], "z": K.vertices[:, 2], "pi": np.pi,
                           "h": K.mean_edge_length, "dt": 0.1, **(constants or {})}
    return compiler


@pytest.mark.parametrize("star", ["circumcentric", "mixed_area", "whitney"])
def test_split_of_k_laplacian_plus_f(star):
    """k*laplacian(u) + f → one block −k·S in weak form (⋆0⁻¹ on the left) and the rest term f."""
    dec = dec_of("icosphere", star=star, subdiv=2, noise=0.0)
    compiler = _compiler(dec, {"u": primal(0), "f": primal(0), "k": NUMBER}, {"k": 2.5})
    blocks, rest = compiler.split(parse_expression("k*laplacian(u) + f", "e"), {"u"})
    assert list(blocks) == ["u"]
    assert blocks["u"].inv == 0
    S = dec.laplacian_symmetric(0)
    assert abs(blocks["u"].A - (-2.5) * S).max() <= 1e-14 * abs(S).max()
    assert len(rest) == 1 and rest[0][0] == 1.0 and to_text(rest[0][1]) == "f"
    # minus signs and scaling on the right go into the block too
    blocks, rest = compiler.split(parse_expression("f - laplacian(u)/4 - 3*u", "e"), {"u"})
    M = dec.star(0)
    assert blocks["u"].inv == 0 and abs(blocks["u"].A - (0.25 * S - 3 * M)).max() <= 1e-13 * abs(S).max()
    assert [sign for sign, _ in rest] == [1.0]


def test_products_of_unknowns_and_varying_coefficients_are_not_linear():
    dec = sphere()
    compiler = _compiler(dec, {"u": primal(0), "v": primal(0), "f": primal(0)}, varying=("u", "v"))
    for text in ("u*v", "u*u", "v*laplacian(u)", "exp(u)", "u/v", "laplacian(u*v)", "t*u"):
        assert compiler.linear(parse_expression(text, "e"), {"u", "v"}) is NOT_LINEAR, text
        blocks, rest = compiler.split(parse_expression(text, "e"), {"u", "v"})
        assert blocks == {} and len(rest) == 1, text
    assert compiler.linear(parse_expression("f + x", "e"), {"u"}) is None  # reads no unknown
    blocks, rest = compiler.split(parse_expression("laplacian(u) + u*v - laplacian(v)", "e"), {"u", "v"})
    assert set(blocks) == {"u", "v"} and [s for s, _ in rest] == [1.0]
    # a static coefficient form scales value by value: diag(c) ⋆0⁻¹ S
    blocks, _ = compiler.split(parse_expression("(1 + x**2)*laplacian(u)", "e"), {"u"})
    c = 1 + dec.K.vertices[:, 0] ** 2
    u = np.random.default_rng(0).standard_normal(162)
    np.testing.assert_allclose(Discrete(dec).matrix(blocks["u"])(u), -c * (dec.laplacian(0) @ u), rtol=1e-12,
                               atol=1e-12)


def test_the_wedge_binds_like_a_product():
    """`a ^ b + c` is (a ∧ b) + c, as written in the thesis — Python's own ^ binds looser than +
    and read it as a ∧ (b + c) (silently, for 0-forms: f*(g + h))."""
    assert parse_expression("f ^ g + h", "k") == parse_expression("(f ^ g) + h", "k")
    assert parse_expression("d(f) ^ b + f ^ d(b)", "k") == parse_expression("(d(f) ^ b) + (f ^ d(b))", "k")
    assert parse_expression("a - b ∧ c", "k") == parse_expression("a - (b ^ c)", "k")
    assert parse_expression("2 * a ^ b", "k") == parse_expression("(2 * a) ^ b", "k")
    for text in ("f ^ g + h", "a - b ^ c", "a ^ (b + c)", "(2 * a) ^ b", "a * (b ^ c)", "-a ^ b", "a ^ (b ^ c)"):
        tree = parse_expression(text, "k")
        assert parse_expression(to_text(tree), "k") == tree, to_text(tree)  # messages show the same term
    model = compile_(["dt(u) = laplacian(u)", "w = u ^ v + u"], fields={"u": {"form": 0, "initial": "x"},
                                                                         "v": {"form": 0, "initial": "y"}})
    env = model.environment(dict(model.initial_values), 0.0)
    x, y = sphere().K.vertices[:, 0], sphere().K.vertices[:, 1]
    np.testing.assert_allclose(env["w"], x * y + x, rtol=1e-15, atol=1e-15)
    assert refused(["dt(u) = laplacian(u)", "w = u @ u"]).startswith("app.equations[1]: the operator @ is not part")


@pytest.mark.parametrize("equations, metrics, constants, key", [
    (["s = vertex(1000)", "dt(u) = laplacian(u) + s"], {}, {}, "app.equations[0]: vertex(1000): the mesh has vertices"),
    (["s = vertex(src)", "dt(u) = laplacian(u) + s"], {}, {"src": 1.5}, "app.equations[0]: vertex(1.5): the mesh"),
    (["dt(u) = laplacian(u)"], {"m": "integral(vertex(-1))"}, {}, "app.metrics.m: vertex(-1): the mesh has vertices"),
    (["dt(u) = laplacian(u) + vertex(t)"], {}, {}, "app.equations[0]: vertex(t): vertex takes a fixed vertex index"),
])
def test_vertex_in_equations_and_metrics_is_checked_when_the_model_loads(equations, metrics, constants, key):
    """Was a ValueError (with a traceback) at the first evaluation — for a metric, after the run."""
    message = refused(equations, metrics=metrics, constants=constants)
    assert message.startswith(key), message
    model = compile_(["s = vertex(src)", "dt(u) = laplacian(u) + s"], constants={"src": 161})
    assert model.environment(dict(model.initial_values), 0.0)["s"][161] == 1.0


def test_each_node_is_typed_once():
    """The kind pass runs once per node: typing, evaluating, finding the stars and splitting a
    tree read the kinds kept on its nodes, never re-infer them."""
    calls: dict[int, int] = {}

    class Counting(Compiler):
        def _infer(self, node, where):
            calls[id(node)] = calls.get(id(node), 0) + 1
            return super()._infer(node, where)

    dec = sphere()
    compiler = Counting(Discrete(dec), {"u": primal(0)}, varying={"u"})
    compiler.static_env = {"x": dec.K.vertices[:, 0], "t": 0.0}
    tree = parse_expression("laplacian(laplacian(u)) + u*u - exp(u) + 2*codifferential(d(u))", "test")
    compiler.kind(tree, "test")
    compiler.compile(tree, "test")
    compiler.star_degrees(tree, "test")
    compiler.split(tree, {"u"})
    assert calls and max(calls.values()) == 1
