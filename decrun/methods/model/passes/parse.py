"""The parse pass: every equation string of a model → an :class:`~decrun.methods.model.language.Equation`
and every metric string → a tree (their config keys named in errors); the expression grammar itself
is :mod:`decrun.methods.model.language`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from decrun.methods.model.language import Equation, ModelError, Node, parse_equation, parse_expression

if TYPE_CHECKING:
    from decrun.methods.model.system import ModelSpec



def _parse_equations(spec: ModelSpec) -> list[Equation]:
    """The parse pass: every equation string → :class:`Equation` (its key named in errors)."""
    key = spec.key
    wheres = spec.equation_keys or [f"{key}.equations[{i}]" for i in range(len(spec.equations))]
    equations = [parse_equation(text, where) for text, where in zip(spec.equations, wheres, strict=True)]
    if not equations:
        raise ModelError(f"{key}.equations: a model needs at least one equation, e.g. "
                         f"'{key}.equations=[\"dt(u) = laplacian(u)\"]'")
    return equations


def _parse_metrics(spec: ModelSpec) -> dict[str, tuple[str, Node]]:
    """Every declared metric: name → (its config key, its tree)."""
    out = {}
    for name, text in spec.metrics.items():
        where = f"{spec.key}.metrics.{name}"
        out[name] = (where, parse_expression(text, where))
    return out
