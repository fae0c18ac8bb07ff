"""The kind pass: the declared kinds (fields' forms, constants as numbers) and every definition's
kind inferred in dependency order by the model's :class:`~decrun.methods.model.compiler.Compiler`
(a declared field's form must agree); the names whose values vary in a run; then every side of
every equation and every metric typed (:func:`_type_trees`): after this pass each node of the
model is a :class:`~decrun.methods.model.typed.Typed` node carrying its kind."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from decrun.methods.model import borders
from decrun.methods.model.compiler import Compiler
from decrun.methods.model.kinds import NUMBER, Kind, form_kind
from decrun.methods.model.language import Equation, ModelError, Name, Node, to_text
from decrun.methods.model.operators import Discrete
from decrun.methods.model.passes.order import _sides
from decrun.methods.model.passes.resolve import Resolved
from decrun.methods.model.typed import TypedSide

if TYPE_CHECKING:
    from decrun.methods.model.system import FieldSpec, ModelSpec


def _kind_of_field(name: str, spec: FieldSpec, key: str, n: int) -> Kind:
    return form_kind(spec.form, f"{key}.fields.{name}.form", n)


def _declared_kinds(spec: ModelSpec, n: int) -> dict[str, Kind]:
    """The kinds of the declared fields (their ``form``) and of the constants (numbers)."""
    kinds = {name: _kind_of_field(name, field_spec, spec.key, n) for name, field_spec in spec.fields.items()}
    for name, value in spec.constants.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
            raise ModelError(f"{spec.key}.constants.{name}: must be a finite number, got {value!r}")
        kinds[name] = NUMBER
    return kinds


def _type_definitions(spec: ModelSpec, ops: Discrete, kinds: dict[str, Kind], resolved: Resolved,
                      ordered: list[Equation]) -> Compiler:
    """The kind pass: the :class:`Compiler` of the model, every definition typed in dependency
    order (a declared field's form must agree), and the names whose values vary in a run."""
    key, n = spec.key, ops.n
    varying = set(resolved.evolved) | {"t"} | borders.moving_names(spec)
    inlinable = {name: eq.rhs for name, eq in resolved.definitions.items()}
    solved = {target: _sides(eq) for eq in resolved.solves for target in eq.targets or (eq.target,)}
    compiler = Compiler(ops, kinds, inlinable, varying, solved)
    for equation in ordered:  # type every definition in order (solve unknowns are declared)
        if equation.kind == "definition":
            kinds[equation.target] = compiler.kind(equation.rhs, equation.where)
            if equation.target in spec.fields:
                declared = _kind_of_field(equation.target, spec.fields[equation.target], key, n)
                if declared != kinds[equation.target]:
                    raise ModelError(f"{equation.where}: {to_text(equation.rhs)} is a {kinds[equation.target]} but "
                                     f"{equation.target} is declared a {declared} ({key}.fields.{equation.target}.form)")
        compiler.kinds.update(kinds)
    compiler.kinds.update(kinds)
    compiler.varying |= {name for name in resolved.targets if compiler.reads(Name(name)) & compiler.varying} | \
        {target for eq in resolved.solves for target in eq.targets or (eq.target,)
         if compiler.reads(Name(target)) & compiler.varying}
    return compiler


def _type_trees(compiler: Compiler, equations: list[Equation], metrics: dict[str, tuple[str, Node]]) -> list[TypedSide]:
    """Every side of every equation (in the order written) and every metric, typed: the typed
    trees of the model (:class:`~decrun.methods.model.typed.TypedSide`), each node with its kind."""
    sides = []
    for equation in equations:
        pairs = equation.pairs or ((equation.lhs, equation.rhs),)
        for i, (left, right) in enumerate(pairs):
            row = f" {i + 1}" if len(pairs) > 1 else ""  # a system's equations, numbered
            if equation.kind in ("solve", "system"):  # an evolution's left side is dt(u), not a term
                sides.append(TypedSide(equation.where, f"left side{row}", compiler.typed(left, equation.where)))
            sides.append(TypedSide(equation.where, f"right side{row}", compiler.typed(right, equation.where)))
    for where, tree in metrics.values():
        sides.append(TypedSide(where, "metric", compiler.typed(tree, where)))
    return sides
