"""The metrics pass: every declared metric (parsed and typed by the earlier passes) checked to be a
number and compiled."""

from __future__ import annotations

from typing import TYPE_CHECKING

from decrun.methods.model.kinds import NUMBER
from decrun.methods.model.language import ModelError, Node, to_text

if TYPE_CHECKING:
    from decrun.methods.model.system import CompiledModel


def _compile_metrics(model: CompiledModel, metrics: dict[str, tuple[str, Node]]) -> list[tuple[str, Node]]:
    """Every metric (name → (key, tree)) checked to be a number and compiled; returns their trees."""
    trees = []
    for name, (where, tree) in metrics.items():
        kind = model.compiler.kind(tree, where)
        if kind != NUMBER:
            raise ModelError(f"{where}: {to_text(tree)} is a {kind}; a metric is a number: e.g. integral(...), "
                             "norm(...), max(...) or inner(..., ...)")
        model.metrics[name] = model.compiler.compile(tree, where)
        trees.append((where, tree))
    return trees
