"""The typed tree: the intermediate form of a model's expressions after the kind pass.

Every node of a parsed tree (:mod:`~decrun.methods.model.language`) is paired with its kind
(:class:`~decrun.methods.model.kinds.Kind`: a primal or dual k-form, a number, a vector field) in
one :class:`Typed` node, whose children are the typed nodes of its operands. The kind pass builds
it once per node (:meth:`decrun.methods.model.compiler.Compiler.typed`); every later pass —
evaluation, linear blocks, derivatives, the stars a term needs, ``app.explain`` — reads the kind
kept there and never infers it again. :class:`TypedSide` names one side of one equation (or one
metric) of a compiled model: ``CompiledModel.typed`` lists them all.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from decrun.methods.model.kinds import Kind
from decrun.methods.model.language import Binary, Call, Name, Negate, Node, Number, to_text

__all__ = ["Typed", "TypedSide", "operands"]


def operands(node: Node) -> tuple[Node, ...]:
    """The direct operands of ``node`` (its children in the tree)."""
    if isinstance(node, Negate):
        return (node.operand,)
    if isinstance(node, Binary):
        return (node.left, node.right)
    if isinstance(node, Call):
        return tuple(node.args)
    return ()


@dataclass(frozen=True, eq=False)
class Typed:
    """One node of the typed tree: the parsed ``node``, its ``kind`` and its operands, typed."""

    node: Node
    kind: Kind
    children: tuple[Typed, ...] = ()

    @property
    def label(self) -> str:
        """The node as one word: a number or a name itself, an operator's name, ``negate``."""
        node = self.node
        if isinstance(node, (Number, Name)):
            return to_text(node)
        if isinstance(node, Negate):
            return "negate"
        if isinstance(node, Binary):
            return "wedge (^)" if node.op == "^" else node.op
        return node.function

    def nodes(self) -> Iterator[Typed]:
        """Every typed node of the tree, depth first, this one first."""
        yield self
        for child in self.children:
            yield from child.nodes()

    def lines(self, depth: int = 1) -> list[str]:
        """The tree as text, one node a line (``label : kind``), indented by depth."""
        out = [f"{'  ' * depth}{self.label} : {self.kind}"]
        for child in self.children:
            out += child.lines(depth + 1)
        return out


@dataclass(frozen=True)
class TypedSide:
    """One typed tree of a compiled model: ``where`` its config key, ``role`` which side it is
    (``right side``, ``left side``, ``metric``) and ``tree`` its :class:`Typed` root."""

    where: str
    role: str
    tree: Typed
