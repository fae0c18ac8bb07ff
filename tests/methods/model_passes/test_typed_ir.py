"""The typed tree (decrun.methods.model.typed): after the kind pass every node of every equation
and metric is a Typed node carrying its kind, its children the typed operands of the parsed node;
the later passes (lowering, metrics, stars, the exact Jacobian, explain) read those kinds and never
infer one again."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.solvers import solver_factory
from decrun.methods.model import FieldSpec, ModelSpec, compile_model
from decrun.methods.model.compiler import Compiler
from decrun.methods.model.explain import explain
from decrun.methods.model.kinds import NUMBER, dual, primal
from decrun.methods.model.typed import operands
from decrun.runner.job.plugins import option


@lru_cache(maxsize=None)
def square() -> DEC:
    mesh = option("mesh", "grid", nx=5, ny=5).load()
    return DEC(SimplicialComplex(mesh.vertices, mesh.simplices))


GRAY_SCOTT = ModelSpec(fields={"v": FieldSpec(0, "x"), "u": FieldSpec(0, "1 - y")},
                       equations=["dt(v) = Dv*laplacian(v) + u*v**2 - (F + k)*v", "flux = star(d(u))",
                                  "dt(u) = Du*laplacian(u) - u*v**2 + F*(1 - u)"],
                       constants={"Du": 1e-3, "Dv": 5e-4, "F": 0.035, "k": 0.065},
                       metrics={"mass": "integral(v)", "spread": "inner(d(u), d(u))"})


def test_every_node_of_every_side_carries_its_kind():
    model = compile_model(GRAY_SCOTT, square(), solver_factory("direct"))
    sides = [(side.where, side.role) for side in model.typed]
    assert sides == [("app.equations[0]", "right side"), ("app.equations[1]", "right side"),
                     ("app.equations[2]", "right side"), ("app.metrics.mass", "metric"),
                     ("app.metrics.spread", "metric")]
    parsed = {eq.where: eq.rhs for eq in model.equations}
    for side in model.typed:
        if side.role == "right side":
            assert side.tree.node is parsed[side.where]  # the parsed tree itself, typed
        for typed in side.tree.nodes():  # the typed tree mirrors the parsed one, node by node
            assert [child.node for child in typed.children] == list(operands(typed.node))
            assert typed.kind == model.compiler.kind(typed.node, side.where)
    flux = model.typed[1].tree
    assert [(t.label, t.kind) for t in flux.nodes()] == [("star", dual(1)), ("d", primal(1)), ("u", primal(0))]
    mass, spread = model.typed[3].tree, model.typed[4].tree
    assert mass.kind == NUMBER and mass.children[0].kind == primal(0)
    assert spread.kind == NUMBER and {c.kind for c in spread.children} == {primal(1)}
    right = model.typed[2].tree  # Du*laplacian(u) - u*v**2 + F*(1 - u)
    assert right.label == "+" and right.kind == primal(0)
    assert [(t.label, str(t.kind)) for t in right.children[1].nodes()] == [  # F*(1 - u)
        ("*", "primal 0-form"), ("F", "number"), ("-", "primal 0-form"), ("1", "number"), ("u", "primal 0-form")]


def test_no_pass_after_the_kind_pass_infers_a_kind_again(monkeypatch):
    """Compiling Gray–Scott, lowering it, building its exact Jacobian, its metrics and its
    explanation: each node's kind is inferred once, whichever pass asks for it."""
    inferred: dict[int, list] = {}
    original = Compiler._infer

    def counting(self, node, where):
        entry = inferred.setdefault(id(node), [node, 0])  # the node kept alive: its id is not reused
        entry[1] += 1
        return original(self, node, where)

    monkeypatch.setattr(Compiler, "_infer", counting)
    model = compile_model(GRAY_SCOTT, square(), solver_factory("direct"))
    typed_nodes = {id(t.node) for side in model.typed for t in side.tree.nodes()}
    after_kind_pass = {key for key in inferred if key in typed_nodes}
    assert after_kind_pass == typed_nodes  # the kind pass typed them all
    problem = model.problem
    y = problem.free_values(dict(model.initial_values))
    problem.jacobian(y, 0.0)
    model.metric_values(model.environment(dict(model.initial_values), 0.0))
    text = explain(model)
    assert "laplacian : primal 0-form" in text
    assert max(count for _node, count in inferred.values()) == 1


def test_the_kind_of_a_node_is_read_from_its_typed_node():
    model = compile_model(GRAY_SCOTT, square(), solver_factory("direct"))
    node = model.equations[0].rhs
    typed = model.compiler.typed(node, "app.equations[0]")
    assert typed is model.typed[0].tree  # kept, not rebuilt
    with pytest.raises(AttributeError):
        typed.kind = NUMBER  # frozen: no pass changes a kind
    np.testing.assert_equal(typed.kind, primal(0))
