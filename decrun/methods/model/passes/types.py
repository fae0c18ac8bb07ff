"""The kind pass: the declared kinds (fields' forms, constants as numbers) and every definition's
kind inferred in dependency order by the model's :class:`~decrun.methods.model.compiler.Compiler`
(a declared field's form must agree); the names whose values vary in a run."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from decrun.methods.model.compiler import Compiler
from decrun.methods.model.kinds import NUMBER, Kind, form_kind
from decrun.methods.model.language import Equation, ModelError, Name, to_text
from decrun.methods.model.operators import Discrete
from decrun.methods.model.passes.order import _sides
from decrun.methods.model.passes.resolve import Resolved

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
    varying = set(resolved.evolved) | {"t"}
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
