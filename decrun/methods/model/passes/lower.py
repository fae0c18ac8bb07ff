"""The lowering pass: definitions into closures, solves and systems into factorized linear
systems (:mod:`.solves`, :mod:`.systems`) or Newton solves (:mod:`decrun.methods.model.nonlinear`),
evolutions' right sides into closures, their kinds checked against the evolved fields."""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

from decrun.methods.model.kinds import NUMBER
from decrun.methods.model.language import Equation, ModelError, Node, to_text
from decrun.methods.model.nonlinear import compile_nonlinear_solve
from decrun.methods.model.passes.solves import _compile_solve
from decrun.methods.model.passes.systems import _compile_system
from decrun.methods.model.sides import refuse_unknown_on_right

if TYPE_CHECKING:
    from decrun.methods.model.system import CompiledModel


def _lower_equations(model: CompiledModel, ordered: list[Equation], new_solver: Callable) -> list[tuple[str, Node]]:
    """The lowering pass: definitions into closures, solves and systems into factorized linear
    systems, evolutions' right sides into closures (their kinds checked against the fields).
    Returns every tree of the equations with its key (for :func:`_check_stars`)."""
    compiler, kinds, equations = model.compiler, model.kinds, model.equations
    for equation in ordered:
        refuse_unknown_on_right(equation, compiler)
        if equation.kind == "definition":
            model.order.append(("definition", (equation.target, compiler.compile(equation.rhs, equation.where))))
        elif equation.kind == "system":
            model.order.append(("system", _compile_system(equation, model, new_solver)))
        elif _nonlinear(equation, model):
            model.order.append(("newton", compile_nonlinear_solve(equation, model, new_solver)))
        else:
            model.order.append(("solve", _compile_solve(equation, model, new_solver)))
    for equation in equations:
        if equation.kind != "evolution":
            continue
        kind = compiler.kind(equation.rhs, equation.where)
        target_kind = kinds[equation.target]
        if kind != target_kind and kind != NUMBER:
            raise ModelError(f"{equation.where}: {to_text(equation.rhs)} is a {kind} but dt({equation.target}) is a "
                             f"{target_kind}")
        model.rhs[equation.target] = compiler.compile(equation.rhs, equation.where)
    trees: list[tuple[str, Node]] = [(eq.where, eq.rhs) for eq in equations]
    trees += [(eq.where, eq.lhs) for eq in equations if eq.kind == "solve" and eq.lhs is not None]
    trees += [(eq.where, side) for eq in equations if eq.kind == "system" for pair in eq.pairs for side in pair]
    return trees


def _nonlinear(equation: Equation, model: CompiledModel) -> bool:
    """True when a solve's left side is not a constant sparse matrix times its unknown plus terms
    without it: Newton's method solves it (:mod:`decrun.methods.model.nonlinear`)."""
    compiler, unknown, lhs = model.compiler, equation.target, equation.lhs
    assert lhs is not None  # a solve has a left side
    if compiler.kind(lhs, equation.where) != model.kinds[unknown]:
        return False  # refused by _compile_solve, naming both kinds
    blocks, rest = compiler.split(lhs, {unknown})
    return unknown not in blocks or any(compiler.depends_on(term, {unknown}) for _sign, term in rest)
