"""The first passes of the model compiler on small models: parse (text → classified equations),
resolve (which field each equation computes; unknown and misused names refused in one line) and
order (a topological order of definitions and solves; a cycle refused, named)."""

from __future__ import annotations

import pytest

from decrun.methods.model import FieldSpec, ModelError, ModelSpec
from decrun.methods.model.language import to_text
from decrun.methods.model.passes.order import _order
from decrun.methods.model.passes.parse import _parse_equations
from decrun.methods.model.passes.resolve import _check_known_names, _check_names, _resolve


def spec_of(equations, fields=None, constants=None, metrics=None, keys=None) -> ModelSpec:
    fields = {"u": FieldSpec(0, "x")} if fields is None else fields
    return ModelSpec(fields=fields, equations=list(equations), constants=dict(constants or {}),
                     metrics=dict(metrics or {}), equation_keys=keys)


def resolved_of(spec: ModelSpec):
    resolved = _resolve(spec, _parse_equations(spec))
    _check_known_names(spec, resolved)
    return resolved


def one_line(error: pytest.ExceptionInfo) -> str:
    message = str(error.value)
    assert "\n" not in message, message
    return message


# ---------------------------------------------------------------------------------------- parse
def test_parse_classifies_every_equation_and_names_its_key():
    spec = spec_of(["dt(u) = laplacian(u) + f", "f = 2*u", "solve(laplacian(p) = f)",
                    "solve(u2 - codifferential(p2) = 0, d(u2) = f)"])
    equations = _parse_equations(spec)
    assert [e.kind for e in equations] == ["evolution", "definition", "solve", "system"]
    assert [e.where for e in equations] == [f"app.equations[{i}]" for i in range(4)]
    assert [e.target for e in equations[:2]] == ["u", "f"]
    assert to_text(equations[0].rhs) == "laplacian(u) + f"
    assert len(equations[3].pairs) == 2


def test_parse_uses_a_composed_models_keys_and_refuses_no_equation():
    spec = spec_of(["dt(u) = laplacian(u)"], keys=["app.parts.heat.equations[0]"])
    assert _parse_equations(spec)[0].where == "app.parts.heat.equations[0]"
    with pytest.raises(ModelError) as error:
        _parse_equations(spec_of([]))
    assert one_line(error).startswith("app.equations: a model needs at least one equation")


# ---------------------------------------------------------------------------------------- resolve
def test_resolve_finds_what_each_equation_computes():
    fields = {"u": FieldSpec(0, "x"), "p": FieldSpec(0), "a": FieldSpec(1), "q": FieldSpec(2)}
    spec = spec_of(["dt(u) = laplacian(u) - p", "f = 2*u", "solve(laplacian(p) = f)",
                    "solve(a - codifferential(q) = 0, d(a) = f)"], fields=fields)
    resolved = resolved_of(spec)
    assert resolved.evolved == ["u"]
    assert list(resolved.definitions) == ["f"]
    assert [(e.target, e.targets) for e in resolved.solves] == [("p", ()), ("a", ("a", "q"))]
    assert resolved.targets == {"u": "app.equations[0]", "f": "app.equations[1]", "p": "app.equations[2]",
                                "a": "app.equations[3]", "q": "app.equations[3]"}


def test_a_solves_unknown_is_the_undetermined_field_without_initial_value():
    fields = {"u": FieldSpec(0, "x"), "phi": FieldSpec(0), "c": FieldSpec(0, 1.0)}
    resolved = resolved_of(spec_of(["dt(u) = laplacian(u)", "solve(laplacian(phi) - c*phi = u)"], fields=fields))
    assert resolved.solves[0].target == "phi"


@pytest.mark.parametrize("equations, fields, start", [
    (["dt(u) = laplacian(uu)"], None, "app.equations[0]: unknown name 'uu' (did you mean 'u'?); declare fields"),
    (["w = 2*u", "dt(u) = laplacian(w) + q"], None, "app.equations[1]: unknown name 'q'"),
    (["dt(v) = laplacian(v)"], None, "app.equations[0]: dt(v) evolves a field that is not declared; add "
                                     "app.fields.v"),
    (["pi = 2*u", "dt(u) = laplacian(u)"], None, "app.equations[0]: 'pi' is a built-in name"),
    (["dt(u) = laplacian(u)", "dt(u) = u"], None, "app.equations[1]: 'u' is already computed by app.equations[0]"),
    (["dt(u) = laplacian(u)", "solve(laplacian(u) = 1)"], None, "app.equations[1]: the solve has no unknown"),
    (["solve(a - codifferential(q) = 0, d(a) = 0)"], {"a": FieldSpec(1)},
     "app.equations[0]: the system has 2 equations but its left sides read 1 undetermined field(s)"),
])
def test_resolve_refuses_in_one_line_naming_the_key(equations, fields, start):
    with pytest.raises(ModelError) as error:
        resolved_of(spec_of(equations, fields=fields))
    assert one_line(error).startswith(start), str(error.value)


def test_names_are_checked_against_the_built_in_words():
    with pytest.raises(ModelError) as error:
        _check_names(spec_of(["dt(u) = laplacian(u)"], constants={"laplacian": 1.0}))
    assert one_line(error).startswith("app.constants.laplacian: 'laplacian' is a built-in name")
    with pytest.raises(ModelError) as error:
        _check_names(spec_of(["dt(u) = laplacian(u)"], metrics={"status": "integral(u)"}))
    assert one_line(error).startswith("app.metrics.status: 'status' is a metric every model run reports")


# ---------------------------------------------------------------------------------------- order
def ordered_targets(equations, fields=None) -> list[str]:
    spec = spec_of(equations, fields=fields)
    resolved = resolved_of(spec)
    ordered = _order(resolved.definitions, resolved.solves, set(spec.fields) | set(spec.constants), "app")
    return [",".join(e.targets or (e.target,)) for e in ordered]


def test_order_is_topological():
    """Each definition or solve comes after everything it reads, whatever order it is written in."""
    equations = ["dt(u) = laplacian(e)", "e = d_sum + c", "c = 2*b", "d_sum = b + a", "b = a*a", "a = u + 1"]
    order = ordered_targets(equations)
    assert sorted(order) == ["a", "b", "c", "d_sum", "e"]
    reads = {"e": {"d_sum", "c"}, "c": {"b"}, "d_sum": {"b", "a"}, "b": {"a"}, "a": set()}
    for name, needs in reads.items():
        assert all(order.index(other) < order.index(name) for other in needs), order


def test_a_solve_is_ordered_after_what_its_right_side_reads_and_a_system_once():
    fields = {"u": FieldSpec(0, "x"), "p": FieldSpec(0), "a": FieldSpec(1), "q": FieldSpec(2)}
    order = ordered_targets(["g = d(p)", "solve(a - codifferential(q) = g, d(a) = f)", "solve(laplacian(p) = f)",
                             "f = u*u", "dt(u) = laplacian(u)"], fields=fields)
    assert order.index("f") < order.index("p") < order.index("g") < order.index("a,q")
    assert order.count("a,q") == 1


@pytest.mark.parametrize("equations, cycle", [
    (["a = b + u", "b = c", "c = a", "dt(u) = laplacian(a)"], "a → b → c → a"),
    (["a = a + u", "dt(u) = laplacian(a)"], "a → a"),
])
def test_order_refuses_a_cycle_naming_it(equations, cycle):
    with pytest.raises(ModelError) as error:
        ordered_targets(equations)
    message = one_line(error)
    assert message.startswith(f"app.equations: the equations for {cycle} form a cycle"), message
