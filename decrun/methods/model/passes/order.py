"""The order pass: definitions and solves sorted so each reads only what is computed before it
(a depth-first topological order); a cycle is refused in one line naming it."""

from __future__ import annotations

from typing import TYPE_CHECKING

from decrun.methods.model.language import Binary, Equation, ModelError, Node, names_in

if TYPE_CHECKING:
    pass


def _order(definitions: dict[str, Equation], solves: list[Equation], known: set[str], key: str) -> list[Equation]:
    """Definitions and solves in an order where each reads only what comes before it (or
    fields, constants and built-ins); a cycle is a ModelError naming it."""
    computed = {**definitions, **{target: eq for eq in solves for target in eq.targets or (eq.target,)}}

    def needs(equation: Equation) -> set[str]:
        if equation.kind == "system":  # a system reads its own unknowns
            return {name for name in names_in(_sides(equation)) if name in computed and name not in equation.targets}
        reads = names_in(equation.rhs) | (names_in(equation.lhs) if equation.kind == "solve" else set())
        # a solve reads its own unknown; a definition that reads itself is a cycle of one
        return {name for name in reads if name in computed and (name != equation.target or equation.kind != "solve")}

    order, state = [], {}

    def visit(name: str, path: list[str]):
        if state.get(name) == "done":
            return
        if state.get(name) == "active":
            cycle = path[path.index(name):] + [name]
            raise ModelError(f"{key}.equations: the equations for {' → '.join(cycle)} form a cycle; a definition may "
                             "read only what is computed before it (break the cycle with an evolved field or a solve)")
        state[name] = "active"
        for other in sorted(needs(computed[name])):
            visit(other, path + [name])
        state[name] = "done"
        if computed[name] not in order:  # a system is computed once for all its unknowns
            order.append(computed[name])

    for name in computed:  # in the order they were written, dependencies first
        visit(name, [])
    return order


def _sides(equation: Equation) -> Node:
    """One tree reading everything a solve or system reads (both sides of every equation):
    what its unknowns are computed from, for the dependency order."""
    pairs = equation.pairs or ((equation.lhs, equation.rhs),)
    terms = [Binary("-", lhs, rhs) for lhs, rhs in pairs]
    tree: Node = terms[0]
    for term in terms[1:]:
        tree = Binary("+", tree, term)
    return tree
