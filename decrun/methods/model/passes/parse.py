"""The parse pass: every equation string of a model → an :class:`~decrun.methods.model.language.Equation`
(its config key named in errors); the expression grammar itself is :mod:`decrun.methods.model.language`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from decrun.methods.model.language import Equation, ModelError, parse_equation

if TYPE_CHECKING:
    from decrun.methods.model.system import ModelSpec

__all__ = ["_parse_equations"]


def _parse_equations(spec: ModelSpec) -> list[Equation]:
    """The parse pass: every equation string → :class:`Equation` (its key named in errors)."""
    key = spec.key
    wheres = spec.equation_keys or [f"{key}.equations[{i}]" for i in range(len(spec.equations))]
    equations = [parse_equation(text, where) for text, where in zip(spec.equations, wheres, strict=True)]
    if not equations:
        raise ModelError(f"{key}.equations: a model needs at least one equation, e.g. "
                         f"'{key}.equations=[\"dt(u) = laplacian(u)\"]'")
    return equations
