"""A solve whose right side reads its own unknown (issue 48, item 4).

``solve(laplacian(u) = u + x)`` is a linear equation in u, but a solve's right side is evaluated
before u exists (it is what u is solved from), so reading u there died with ``KeyError: 'u'``.
It is refused when the model loads, in one line that shows the equation with the unknown's terms
moved to the left: ``solve(laplacian(u) - u = x)``."""

from __future__ import annotations

from decrun.methods.model.language import Binary, Equation, ModelError, Negate, Node, Number, to_text

__all__ = ["refuse_unknown_on_right", "summed"]


def _summands(node: Node, sign: int = 1) -> list[tuple[int, Node]]:
    """``node`` as ±terms through + − and negation."""
    if isinstance(node, Binary) and node.op in "+-":
        return _summands(node.left, sign) + _summands(node.right, sign if node.op == "+" else -sign)
    if isinstance(node, Negate):
        return _summands(node.operand, -sign)
    return [(sign, node)]


def summed(terms: list[tuple[int, Node]]) -> Node:
    """The tree of Σ ±term (0 for none)."""
    if not terms:
        return Number(0.0)
    sign, tree = terms[0]
    out: Node = tree if sign > 0 else Negate(tree)
    for sign, term in terms[1:]:
        out = Binary("+" if sign > 0 else "-", out, term)
    return out


def refuse_unknown_on_right(equation: Equation, compiler) -> None:
    """Refuse a ``solve(lhs = rhs)`` whose right side reads its unknown (definitions followed),
    suggesting the equation with those terms moved to the left."""
    unknown = equation.target
    if equation.kind != "solve" or equation.lhs is None or not compiler.depends_on(equation.rhs, {unknown}):
        return
    terms = _summands(equation.rhs)
    moved = [(-sign, term) for sign, term in terms if compiler.depends_on(term, {unknown})]
    kept = [(sign, term) for sign, term in terms if not compiler.depends_on(term, {unknown})]
    suggestion = f"solve({to_text(summed([*_summands(equation.lhs), *moved]))} = {to_text(summed(kept))})"
    raise ModelError(f"{equation.where}: the right side {to_text(equation.rhs)} reads the unknown {unknown}, which a "
                     f"solve computes from its right side; move the terms of {unknown} to the left: {suggestion!r}")
