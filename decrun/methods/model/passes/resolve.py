"""The resolve pass: the names of a model checked (fields, constants, metrics against the
built-in words) and, for each equation, the field it computes — an evolution's and a definition's
target, a solve's unknown (the one undetermined declared field of its left side), a system's
unknowns (one per equation) — each name computed once."""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import TYPE_CHECKING

from decrun.methods.model.compiler import BUILTIN_NAMES
from decrun.methods.model.language import Binary, Call, Equation, ModelError, Name, Negate, Node, names_in, to_text
from decrun.methods.model.names import check_lookalike_names, check_metric_names
from decrun.methods.model.operators import OPERATORS

if TYPE_CHECKING:
    from decrun.methods.model.system import ModelSpec

__all__ = ["RESERVED", "RESERVED_METRICS", "Resolved", "reserved"]

#: the built-in names and words of the language (the operators' names, plugins' included, too: :func:`reserved`)
RESERVED = {"x", "y", "z", "t", "dt", "h", "pi", "random", "solve"}

#: metric names the run itself reports (decrun.methods.model.metrics and the runner's status columns)
RESERVED_METRICS = {"status", "error", "stable", "unstable_reason", "diverged_at_step", "steps_done", "solve_seconds",
                    "steps_per_second", "step_seconds_max", "resumed_from_step", "t_final", "dt", "integrator",
                    "dt_stability_limit", "dt_over_stability_limit", "accepted_steps", "rhs_evaluations",
                    "headline_metrics", "factorizations", "total_seconds", "n_vertices", "n_faces", "warnings",
                    "dt_suggested"}


@dataclass
class Resolved:
    """What the resolve pass finds: the evolved fields in order, the definitions by target, the
    solves and systems (their unknowns resolved) and which equation computes each name."""

    equations: list[Equation]
    evolved: list[str]
    definitions: dict[str, Equation]
    solves: list[Equation]
    targets: dict[str, str]


def reserved() -> set[str]:
    """The names a field, constant or definition may not take: :data:`RESERVED` and every
    operator's name (the built-in ones and those of installed plugins)."""
    return RESERVED | set(OPERATORS)


def _check_names(spec: ModelSpec) -> None:
    key = spec.key
    for group, names in (("fields", spec.fields), ("constants", spec.constants), ("metrics", spec.metrics)):
        for name in names:
            if not isinstance(name, str) or not name.isidentifier() or name.startswith("_"):
                raise ModelError(f"{key}.{group}.{name}: a name is a letter followed by letters, digits or '_'")
            if group == "metrics" and name in RESERVED_METRICS:
                raise ModelError(f"{key}.metrics.{name}: {name!r} is a metric every model run reports (or a column of "
                                 f"the sweep table); name yours otherwise, e.g. {name}_value")
            if group != "metrics" and name in reserved():
                raise ModelError(f"{key}.{group}.{name}: {name!r} is a built-in name of the model language "
                                 "(x y z t dt h pi random and the operators); choose another")
    check_lookalike_names(key, {"fields": spec.fields, "constants": spec.constants})
    check_metric_names(key, spec.metrics, spec.fields)
    both = set(spec.fields) & set(spec.constants)
    if both:
        name = sorted(both)[0]
        raise ModelError(f"{key}.constants.{name}: {name!r} is also a field ({key}.fields.{name}); rename one")


def _resolve(spec: ModelSpec, equations: list[Equation]) -> Resolved:
    """The resolve pass: which field each equation computes — evolutions and definitions name
    theirs, a solve's unknown is the one declared field of its left side that nothing else
    computes, a system's are as many as its equations — each name computed once."""
    key = spec.key
    resolved = Resolved(list(equations), [], {}, [], {})
    targets = resolved.targets

    def claim(target: str, where: str):
        if target in reserved():
            raise ModelError(f"{where}: {target!r} is a built-in name; choose another name for the field")
        if target in spec.constants:
            raise ModelError(f"{where}: {target!r} is a constant (app.constants.{target}); an equation cannot set it")
        if target in targets:
            raise ModelError(f"{where}: {target!r} is already computed by {targets[target]}; a field has one equation")
        targets[target] = where

    for equation in equations:
        if equation.kind == "evolution":
            if equation.target not in spec.fields:
                raise ModelError(f"{equation.where}: dt({equation.target}) evolves a field that is not declared; add "
                                 f"{key}.fields.{equation.target} with its form and initial value")
            claim(equation.target, equation.where)
            resolved.evolved.append(equation.target)
        elif equation.kind == "definition":
            claim(equation.target, equation.where)
            resolved.definitions[equation.target] = equation
    for index, equation in enumerate(equations):
        if equation.kind == "system":
            equation = _system_unknowns(equation, spec, targets, resolved.evolved)
        elif equation.kind == "solve":
            equation = _solve_unknown(equation, spec, targets, resolved.evolved)
        else:
            continue
        resolved.equations[index] = equation
        for name in equation.targets or (equation.target,):
            claim(name, equation.where)
        resolved.solves.append(equation)
    return resolved


def _solve_unknown(equation: Equation, spec: ModelSpec, targets: dict, evolved: list) -> Equation:
    """The unknown of ``solve(lhs = rhs)``: the declared field of its left side that no other
    equation computes (the one without an initial value when there are several)."""
    key = spec.key
    candidates = sorted(name for name in names_in(equation.lhs)
                        if name in spec.fields and name not in targets and name not in evolved)
    if not candidates:
        raise ModelError(f"{equation.where}: the solve has no unknown: its left side {to_text(equation.lhs)} reads "
                         f"no declared field that another equation does not compute; declare the unknown under "
                         f"{key}.fields (e.g. {key}.fields.phi.form=0)")
    if len(candidates) > 1:
        without = [name for name in candidates if spec.fields[name].initial is None]
        if len(without) != 1:
            raise ModelError(f"{equation.where}: the solve's left side reads several undetermined fields "
                             f"{candidates}; a solve has one unknown")
        candidates = without
    return Equation("solve", candidates[0], equation.lhs, equation.rhs, equation.where, equation.text)


def _system_unknowns(equation: Equation, spec: ModelSpec, targets: dict, evolved: list) -> Equation:
    """The unknowns of ``solve(l1 = r1, l2 = r2, …)``: the declared fields its left sides read
    that no other equation computes (those without an initial value when there are more), as
    many as equations, in their declaration order."""
    key, count = spec.key, len(equation.pairs)
    read = set().union(*(names_in(lhs) for lhs, _ in equation.pairs))
    candidates = [name for name in spec.fields if name in read and name not in targets and name not in evolved]
    if len(candidates) > count:
        without = [name for name in candidates if spec.fields[name].initial is None]
        if len(without) == count:
            candidates = without
    if len(candidates) != count:
        example = f"{key}.fields.p.form=0" if "p" not in spec.fields else f"{key}.fields.q.form=0"
        raise ModelError(f"{equation.where}: the system has {count} equations but its left sides read "
                         f"{len(candidates)} undetermined field(s) {candidates}; a system solves for one unknown per "
                         f"equation (declare each unknown without an initial value under {key}.fields, e.g. "
                         f"`+{example}`)")
    return Equation("system", candidates[0], equation.lhs, equation.rhs, equation.where, equation.text,
                    equation.pairs, tuple(candidates))


def _check_initial_values(spec: ModelSpec, evolved: list[str], inputs: list[str]) -> None:
    """Every evolved field and every input (a field nothing computes) has an initial value."""
    key = spec.key
    for name in evolved + inputs:
        if spec.fields[name].initial is None:
            role = "dt(" + name + ") needs it" if name in evolved else "no equation computes it"
            raise ModelError(f"{key}.fields.{name}.initial: missing initial value ({role}); e.g. "
                             f"`{key}.fields.{name}.initial=0`")


def _names_in_order(node: Node) -> list[str]:
    """The names ``node`` reads, left to right, depth first (the order an error names the first)."""
    if isinstance(node, Name):
        return [node.name]
    if isinstance(node, Negate):
        return _names_in_order(node.operand)
    if isinstance(node, Binary):
        return _names_in_order(node.left) + _names_in_order(node.right)
    if isinstance(node, Call):
        return [name for arg in node.args for name in _names_in_order(arg)]
    return []


def _check_known_names(spec: ModelSpec, resolved: Resolved, internal: frozenset[str] | set[str] = frozenset()) -> None:
    """Every name an equation reads is declared: a field, a constant, a built-in name (x y z t dt
    h pi) or what another equation computes; an unknown name is refused in one line naming its
    equation's key (and the closest known name). ``internal``: names a rewrite introduced (the
    border loads of :func:`decrun.methods.model.borders.internal_names`)."""
    known = set(spec.fields) | set(spec.constants) | set(BUILTIN_NAMES) | set(resolved.targets) | set(internal)
    for equation in resolved.equations:
        sides = equation.pairs or ((equation.lhs, equation.rhs),)
        for side in (tree for pair in sides for tree in pair if tree is not None):
            for name in _names_in_order(side):
                if name in known:
                    continue
                close = difflib.get_close_matches(name, sorted(known), n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise ModelError(f"{equation.where}: unknown name {name!r}{hint}; declare fields under app.fields "
                                 "and numbers under app.constants")
