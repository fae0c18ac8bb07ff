"""Kind inference and name analysis of expression trees — the first third of the model's
:class:`~decrun.methods.model.compiler.Compiler` (its typing; :mod:`.evaluate` and :mod:`.linear`
build on it).

:class:`KindInference` knows the kind of every name (fields, definitions, constants and the
built-in names ``x y z t dt h area pi``) and

- :meth:`~KindInference.typed` / :meth:`~KindInference.kind` type a tree once per node, raising one
  :class:`ModelError` line that names the key and the offending term;
- :meth:`~KindInference.star_degrees` lists the Hodge stars a term reads;
- :meth:`~KindInference.reads` / :meth:`~KindInference.is_static` say which names a tree reads,
  definitions followed, and whether its value is fixed for the run.
"""

from __future__ import annotations

import difflib

from decrun.methods.model.kinds import NUMBER, VECTOR, Kind, dual, primal
from decrun.methods.model.language import Binary, Call, ModelError, Name, Negate, Node, Number, to_text
from decrun.methods.model.operators import ALIASES, OPERATORS, Discrete, Mismatch
from decrun.methods.model.typed import Typed, operands
from decrun.methods.model.wording import hint

__all__ = ["KindInference", "BUILTIN_NAMES", "TIME_VARYING"]

#: names every expression may read: coordinates (primal 0-forms), time, step, mean edge length, π
BUILTIN_NAMES = {"x": primal(0), "y": primal(0), "z": primal(0), "t": NUMBER, "dt": NUMBER, "h": NUMBER, "area": NUMBER,
                 "pi": NUMBER}
#: the names whose values change during a run (a term reading them is not a constant matrix)
TIME_VARYING = {"t"}


class KindInference:
    """The kinds of expressions and the names they read; the state is set by
    :class:`~decrun.methods.model.compiler.Compiler` (its parameters)."""

    ops: Discrete
    n: int
    kinds: dict[str, Kind]
    definitions: dict[str, Node]
    solved: dict[str, Node]
    varying: set[str]
    _typed: dict[int, Typed]

    # ------------------------------------------------------------------ kinds
    def typed(self, node: Node, where: str) -> Typed:
        """The typed tree of ``node`` (:class:`~decrun.methods.model.typed.Typed`: each node with
        its kind); ModelError naming ``where`` and the term on a mismatch. Each node is typed
        once, by the kind pass: its typed node is kept (by the node's identity) and every later
        pass — evaluation, linear blocks, derivatives, stars, explain — reads the kind there."""
        known = self._typed.get(id(node))
        if known is not None and known.node is node:
            return known
        kind = self._infer(node, where)  # types the operands first (each once)
        typed = Typed(node, kind, tuple(self.typed(operand, where) for operand in operands(node)))
        self._typed[id(node)] = typed
        return typed

    def kind(self, node: Node, where: str) -> Kind:
        """The kind of ``node``: read from its typed node (:meth:`typed`), inferred only once."""
        return self.typed(node, where).kind

    def _infer(self, node: Node, where: str) -> Kind:
        if isinstance(node, Number):
            return NUMBER
        if isinstance(node, Name):
            if node.name not in self.kinds:
                raise ModelError(f"{where}: unknown name {node.name!r}{self._suggest(node.name, self.kinds)}; "
                                 "declare fields under app.fields and numbers under app.constants")
            return self.kinds[node.name]
        if isinstance(node, Negate):
            return self.kind(node.operand, where)
        if isinstance(node, Binary):
            if node.op == "^":
                return self._operator_kind(Call("wedge", (node.left, node.right)), where, shown=node)
            return self._arithmetic_kind(node, where)
        if isinstance(node, Call):
            return self._operator_kind(node, where)
        raise TypeError(node)

    @staticmethod
    def _suggest(name: str, known) -> str:
        close = difflib.get_close_matches(name, list(known), n=1)
        return f" (did you mean {close[0]!r}?)" if close else ""

    def operator(self, name: str, where: str, node: Node):
        name = ALIASES.get(name, name)
        if name == "dt":
            raise ModelError(f"{where}: dt(...) is the time derivative and stands only on the left of an evolution "
                             f"equation ('dt(u) = ...'); in {to_text(node)!r}")
        if name == "solve":
            raise ModelError(f"{where}: solve(...) is a whole equation ('solve(laplacian(phi) = f)'), not a term")
        if name not in OPERATORS:
            raise ModelError(f"{where}: unknown operator {name!r} in {to_text(node)}"
                             f"{self._suggest(name, list(OPERATORS) + list(ALIASES))}")
        return OPERATORS[name]

    def _operator_kind(self, node: Call, where: str, shown: Node | None = None) -> Kind:
        operator = self.operator(node.function, where, node)
        if len(node.args) not in operator.arity:
            counts = " or ".join(str(a) for a in operator.arity)
            raise ModelError(f"{where}: {operator.name} takes {counts} argument(s), got {len(node.args)} in "
                             f"{to_text(shown or node)}")
        kinds = [self.kind(arg, where) for arg in node.args]
        try:
            return operator.kind(kinds, self.n)
        except Mismatch as why:
            raise ModelError(f"{where}: {to_text(shown or node)}: {why}{hint(shown or node, where)}") from None

    def _arithmetic_kind(self, node: Binary, where: str) -> Kind:
        left, right = self.kind(node.left, where), self.kind(node.right, where)
        verb = {"+": "adds", "-": "subtracts", "*": "multiplies", "/": "divides", "**": "raises"}[node.op]
        if left == NUMBER or right == NUMBER:
            other = right if left == NUMBER else left
            if other == VECTOR and (node.op in "+-" or node.op == "**" or (node.op == "/" and left == NUMBER)):
                raise ModelError(f"{where}: {to_text(node)} {verb} a number and a vector field (a vector field can be "
                                 "scaled: 2*X, X/2)")
            return other
        if left == VECTOR or right == VECTOR:
            if left == right and node.op in "+-":
                return VECTOR
            scalar = right if left == VECTOR else left
            if node.op == "*" and scalar == dual(0):
                return VECTOR
            if node.op == "/" and left == VECTOR and right == dual(0):
                return VECTOR
            raise ModelError(f"{where}: {to_text(node)} {verb} a {left} and a {right} (a vector field is scaled by "
                             "numbers or dual 0-forms; use inner(X, Y) or interior(X, w) for products)")
        if left != right:
            raise ModelError(f"{where}: {to_text(node)} {verb} a {left} and a {right}; values combine only within "
                             "one kind (apply d, star, average … to bring them together)")
        return left

    # ------------------------------------------------------------------ stars a term needs
    def star_degrees(self, node: Node, where: str) -> dict[int, Node]:
        """The degrees k whose ⋆_k evaluating ``node`` reads, each with the first term that
        needs it (so a variant that lacks ⋆_k — intrinsic Delaunay has ⋆0 only — is refused
        when the model loads, naming the term)."""
        out: dict[int, Node] = {}

        def need(k: int, term: Node):
            if 0 <= k <= self.n:
                out.setdefault(k, term)

        def walk(node: Node):
            if isinstance(node, Binary):
                if node.op == "^":
                    walk(Call("wedge", (node.left, node.right)))
                    return
                walk(node.left)
                walk(node.right)
            elif isinstance(node, Negate):
                walk(node.operand)
            elif isinstance(node, Call):
                for arg in node.args:
                    walk(arg)
                name = ALIASES.get(node.function, node.function)
                kinds = [self.kind(arg, where) for arg in node.args]
                first = kinds[0] if kinds else NUMBER
                if name in ("star", "inv_star") and first.is_form:
                    need(first.simplex_dimension(self.n), node)
                elif name == "border":
                    need(self.n - 1, node)
                elif name == "codifferential":
                    need(first.degree, node)
                    need(first.degree - 1, node)
                elif name in ("laplacian", "laplace_de_rham"):
                    need(first.degree, node)
                    if first.degree > 0:
                        need(first.degree - 1, node)
                        need(first.degree + 1, node)
                elif name in ("inner", "norm", "integral") and first.is_form:
                    if not (name == "integral" and (first.degree == self.n or first.dual)):
                        need(first.simplex_dimension(self.n), node)

        walk(node)
        return out

    # ------------------------------------------------------------------ dependencies
    def depends_on(self, node: Node, names: set[str]) -> bool:
        """Whether ``node`` reads any of ``names``, following inlinable definitions."""
        return bool(self.reads(node) & names)

    def reads(self, node: Node, seen: frozenset = frozenset()) -> set[str]:
        """Every name ``node`` reads, definitions followed to what they read (and kept)."""
        if isinstance(node, Name):
            out = {node.name}
            source = self.definitions.get(node.name, self.solved.get(node.name))
            if source is not None and node.name not in seen:
                out |= self.reads(source, seen | {node.name})
            return out
        if isinstance(node, Call):
            return set().union(*(self.reads(arg, seen) for arg in node.args)) if node.args else set()
        if isinstance(node, Binary):
            return self.reads(node.left, seen) | self.reads(node.right, seen)
        if isinstance(node, Negate):
            return self.reads(node.operand, seen)
        return set()

    def is_static(self, node: Node) -> bool:
        """True when ``node``'s value never changes during a run (no evolved field, no solve
        target, no definition of them, no ``t``)."""
        return not (self.reads(node) & self.varying)
