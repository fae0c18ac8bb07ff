"""Typed expression trees → numpy closures and sparse linear blocks.

:class:`Compiler` knows the kind of every name (fields, definitions, constants and the built-in
names ``x y z t dt h area pi``) and

- :meth:`~Compiler.kind` infers the kind of a tree, raising one :class:`ModelError` line that
  names the key and the offending term;
- :meth:`~Compiler.compile` turns a tree into ``f(env) -> value`` (``env``: name → array or
  float), with every maximal linear chain of operators applied to one name folded into one
  sparse matrix (``codifferential(d(u))`` is one product per evaluation);
- :meth:`~Compiler.linear_terms` splits a sum into the terms linear in a set of unknowns — as
  :class:`~decrun.methods.model.operators.Linear` blocks ``⋆⁻¹ A``, the matrices of implicit
  integrators and solves — and the remaining terms, evaluated explicitly.
"""

from __future__ import annotations

import difflib
from typing import Callable

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.kinds import NUMBER, VECTOR, Kind, dual, primal
from decrun.methods.model.language import Binary, Call, ModelError, Name, Negate, Node, Number, to_text
from decrun.methods.model.numbers import number_arithmetic
from decrun.methods.model.operators import ALIASES, OPERATORS, POINTWISE, Discrete, Linear, Mismatch
from decrun.methods.model.wording import hint

__all__ = ["Compiler", "BUILTIN_NAMES", "NOT_LINEAR"]

#: names every expression may read: coordinates (primal 0-forms), time, step, mean edge length, π
BUILTIN_NAMES = {"x": primal(0), "y": primal(0), "z": primal(0), "t": NUMBER, "dt": NUMBER, "h": NUMBER, "area": NUMBER,
                 "pi": NUMBER}
#: the names whose values change during a run (a term reading them is not a constant matrix)
TIME_VARYING = {"t"}


class _NotLinear:
    def __repr__(self):
        return "NOT_LINEAR"


NOT_LINEAR = _NotLinear()


class Compiler:
    """Kinds, closures and linear blocks of expressions over one mesh's operators.

    Parameters
    ----------
    ops : Discrete — the mesh's operators
    kinds : dict name → Kind of fields, definitions and constants (built-ins are added)
    definitions : dict name → tree of the definitions that may be inlined into linear terms
    varying : names whose values change from step to step (evolved fields, definitions of them,
        solve targets, ``t``)
    solved : dict name → tree of what each solve target is computed from (its equation's two
        sides), followed by :meth:`reads` but never inlined
    """

    def __init__(self, ops: Discrete, kinds: dict[str, Kind], definitions: dict[str, Node] | None = None,
                 varying: set[str] | None = None, solved: dict[str, Node] | None = None):
        self.ops, self.n = ops, ops.n
        self.kinds = {**BUILTIN_NAMES, **kinds}
        self.definitions = definitions or {}
        self.solved = solved or {}
        self.varying = set(varying or ()) | TIME_VARYING
        self._static_env: dict | None = None
        #: id(node) → (node, its kind): the kind of every node typed so far (:meth:`kind`)
        self._typed: dict[int, tuple[Node, Kind]] = {}

    # ------------------------------------------------------------------ kinds
    def kind(self, node: Node, where: str) -> Kind:
        """The kind of ``node``; ModelError naming ``where`` and the term on a mismatch. Each
        node is typed once: its kind is kept (by the node's identity, the node held with it) and
        every later pass — evaluation, linear blocks, derivatives, explain — reads it back."""
        known = self._typed.get(id(node))
        if known is not None and known[0] is node:
            return known[1]
        kind = self._infer(node, where)
        self._typed[id(node)] = (node, kind)
        return kind

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

    # ------------------------------------------------------------------ closures
    def compile(self, node: Node, where: str) -> Callable[[dict], object]:
        """``f(env) -> value`` for ``node`` (its kind checked first)."""
        self.kind(node, where)
        return self._compile(node, where)

    def _compile(self, node: Node, where: str) -> Callable[[dict], object]:
        """The closure of ``node``; a static subtree (constants, coordinates, static definitions:
        :meth:`is_static`) is evaluated once, at its first call, and its value reused — read-only,
        so no step can change it — instead of being recomputed at every step and stage."""
        closure = self._compile_node(node, where)
        if isinstance(node, (Number, Name)) or not self.is_static(node):
            return closure
        cache: list = []

        def once(env):
            if not cache:
                value = closure(env)
                if isinstance(value, np.ndarray):
                    value.setflags(write=False)
                cache.append(value)
            return cache[0]
        return once

    def _compile_node(self, node: Node, where: str) -> Callable[[dict], object]:
        if isinstance(node, Number):
            value = node.value
            return lambda env: value
        if isinstance(node, Name):
            name = node.name
            return lambda env: env[name]
        chain = self._linear_chain(node)
        if chain is not None:
            name, apply = chain
            return lambda env: apply(env[name])
        if isinstance(node, Negate):
            inner = self._compile(node.operand, where)
            return lambda env: -inner(env)
        if isinstance(node, Binary):
            if node.op == "^":
                return self._compile(Call("wedge", (node.left, node.right)), where)
            scaled = self._scaled_chain(node, where)
            if scaled is not None:
                return scaled
            left, right = self._compile(node.left, where), self._compile(node.right, where)
            lk, rk = self.kind(node.left, where), self.kind(node.right, where)
            return _arithmetic(node.op, left, right, lk, rk)
        if isinstance(node, Call):
            operator = self.operator(node.function, where, node)
            kinds = [self.kind(arg, where) for arg in node.args]
            args = [self._compile(arg, where) for arg in node.args]
            ops = self.ops
            if operator.name == "vertex":
                self._check_vertex(node, where)
            if operator.evaluate is None:  # a linear operator evaluated through its matrix
                apply = ops.matrix(operator.linear(ops, kinds[0]))
                (arg,) = args
                return lambda env: apply(arg(env))
            evaluate = operator.evaluate
            if operator.fixed_first is not None and self.is_static(node.args[0]):
                matrix: list = []  # made at the first evaluation, from the static first argument's value
                first, second = args

                def applied(env):
                    if not matrix:
                        matrix.append(operator.fixed_first(ops, kinds, first(env)))
                    if matrix[0] is None:
                        return evaluate(ops, kinds, first(env), second(env))
                    return matrix[0] @ second(env)
                return applied
            if len(args) == 1:
                (arg,) = args
                return lambda env: evaluate(ops, kinds, arg(env))
            return lambda env: evaluate(ops, kinds, *(a(env) for a in args))
        raise TypeError(node)

    def _check_vertex(self, node: Call, where: str) -> None:
        """``vertex(i)`` in an equation or a metric: ``i`` fixed for the run and a vertex of the
        mesh, checked when the model loads — not when the term is first evaluated (for a metric,
        after the whole run)."""
        (arg,) = node.args
        if not self.is_static(arg):
            raise ModelError(f"{where}: {to_text(node)}: vertex takes a fixed vertex index (a number or a constant), "
                             "not a value that changes during the run")
        if self._static_env is None:
            return
        try:
            evaluate = OPERATORS["vertex"].evaluate
            assert evaluate is not None  # vertex has its own evaluation (no matrix)
            evaluate(self.ops, [NUMBER], self.static_value(arg))
        except ValueError as why:
            raise ModelError(f"{where}: {why}") from None

    def _linear_chain(self, node: Node):
        """``(name, apply)`` when ``node`` is one or more linear operators applied to one name
        (``laplacian(u)``, ``codifferential(d(u))``): ``apply`` is the folded matrix; else None."""
        chain = self._chain_linear(node)
        return None if chain is None else (chain[0], self.ops.matrix(chain[1]))

    def _scaled_chain(self, node: Node, where: str):
        """The closure of ``c * chain`` or ``chain * c`` — a static number times a
        :meth:`_linear_chain` (``c**2 * laplacian(u)``, ``D*s*laplacian(c)``) — with c folded
        into the chain's matrix at the first evaluation (one sparse product per evaluation, not
        a product and a scaling); None for any other node."""
        if not (isinstance(node, Binary) and node.op == "*"):
            return None
        for factor, other in ((node.left, node.right), (node.right, node.left)):
            if not self.is_static(factor) or self.kind(factor, where) != NUMBER:
                continue
            chain = self._chain_linear(other)
            if chain is None:
                continue
            name, linear = chain
            value = self._compile(factor, where)
            folded: list = []

            def applied(env, name=name, linear=linear, value=value, folded=folded):
                if not folded:
                    folded.append(self.ops.matrix(linear.scaled(float(value(env)))))
                return folded[0](env[name])
            return applied
        return None

    def _chain_linear(self, node: Node):
        """``(name, Linear)``: the operators of a :meth:`_linear_chain` composed, or None."""
        operators, inner = [], node
        while isinstance(inner, Call) and len(inner.args) == 1:
            name = ALIASES.get(inner.function, inner.function)
            operator = OPERATORS.get(name)
            if operator is None or operator.linear is None:
                return None
            operators.append((operator, inner.args[0]))
            inner = inner.args[0]
        if not operators or not isinstance(inner, Name):
            return None
        linear = None
        for operator, argument in reversed(operators):
            step = operator.linear(self.ops, self.kind(argument, "?"))
            if step is None:
                return None
            linear = step if linear is None else self.ops.compose(step, linear)
            if linear is None:
                return None
        return inner.name, linear

    # ------------------------------------------------------------------ linear terms
    def terms(self, node: Node, sign: float = 1.0) -> list[tuple[float, Node]]:
        """The summands of ``node`` with their signs: through + − and negation, and distributed
        over what is linear — a linear operator of a sum (``laplacian(c**3 - c)`` is
        ``laplacian(c**3) - laplacian(c)``), a static factor times a sum, and a definition that
        is a sum — so that the linear part of a term is found wherever it stands."""
        if isinstance(node, Binary) and node.op in "+-":
            return self.terms(node.left, sign) + self.terms(node.right, sign if node.op == "+" else -sign)
        if isinstance(node, Negate):
            return self.terms(node.operand, -sign)
        if isinstance(node, Name) and node.name in self.definitions:
            inner = self.terms(self.definitions[node.name])
            if len(inner) > 1:
                return [(sign * s, term) for s, term in inner]
            return [(sign, node)]
        if isinstance(node, Call) and len(node.args) == 1:
            operator = OPERATORS.get(ALIASES.get(node.function, node.function))
            if operator is not None and operator.linear is not None:
                inner = self.terms(node.args[0])
                if len(inner) > 1:
                    return [(sign * s, Call(node.function, (term,))) for s, term in inner]
        if isinstance(node, Binary) and node.op in "*/":
            for side, other in ((node.left, node.right), (node.right, node.left)):
                if node.op == "/" and side is node.right:
                    continue
                if self.is_static(other) and self.kind(other, "?") == NUMBER:
                    inner = self.terms(side)
                    if len(inner) > 1:
                        return [(sign * s, Binary(node.op, term, other) if side is node.left else
                                 Binary(node.op, other, term)) for s, term in inner]
        return [(sign, node)]

    def static_value(self, node: Node):
        """The value of a static ``node`` (numbers, constants, coordinates, static fields and
        the definitions made of them, inlined)."""
        return self._compile(self.inline(node), "?")(self.static_env)

    def inline(self, node: Node) -> Node:
        """``node`` with every definition replaced by its tree (recursively)."""
        if isinstance(node, Name) and node.name in self.definitions:
            return self.inline(self.definitions[node.name])
        if isinstance(node, Call):
            return Call(node.function, tuple(self.inline(arg) for arg in node.args))
        if isinstance(node, Binary):
            return Binary(node.op, self.inline(node.left), self.inline(node.right))
        if isinstance(node, Negate):
            return Negate(self.inline(node.operand))
        return node

    @property
    def static_env(self) -> dict:
        if self._static_env is None:
            raise RuntimeError("Compiler.static_env must be set before static values are computed")
        return self._static_env

    @static_env.setter
    def static_env(self, env: dict) -> None:
        self._static_env = env

    def linear(self, node: Node, unknowns: set[str]):
        """``{name: Linear}`` when ``node`` equals Σ_name Linear·value(name) over ``unknowns``
        (constant matrices: the coefficients are static), None when it reads no unknown, or
        :data:`NOT_LINEAR`."""
        if not self.depends_on(node, unknowns):
            return None
        if isinstance(node, Name):
            if node.name in unknowns:
                return {node.name: self.ops.identity(self.kinds[node.name])}
            if node.name in self.definitions:
                return self.linear(self.definitions[node.name], unknowns)
            return NOT_LINEAR  # a solve target that reads an unknown: a dense inverse, explicit
        if isinstance(node, Negate):
            inner = self.linear(node.operand, unknowns)
            return inner if inner is NOT_LINEAR else {k: v.scaled(-1.0) for k, v in inner.items()}
        if isinstance(node, Binary):
            if node.op in "+-":
                left, right = self.linear(node.left, unknowns), self.linear(node.right, unknowns)
                if left is NOT_LINEAR or right is NOT_LINEAR or left is None or right is None:
                    return NOT_LINEAR  # a constant inside a sum under an operator: an explicit term
                if node.op == "-":
                    right = {k: v.scaled(-1.0) for k, v in right.items()}
                return self._merge(left, right)
            if node.op in "*/":
                return self._linear_product(node, unknowns)
            return NOT_LINEAR
        if isinstance(node, Call):
            step = self._operator_matrix(node)
            if step is None:
                return NOT_LINEAR
            inner = self.linear(node.args[0], unknowns)
            if inner is NOT_LINEAR:
                return NOT_LINEAR
            out = {}
            for name, block in inner.items():
                composed = self.ops.compose(step, block)
                if composed is None:
                    return NOT_LINEAR
                out[name] = composed
            return out
        return NOT_LINEAR

    def _linear_product(self, node: Binary, unknowns: set[str]):
        """:meth:`linear` of ``a * b`` or ``a / b``: one side linear in ``unknowns``, the other a
        static factor (a number or a fixed form), else :data:`NOT_LINEAR`."""
        left_dep = self.depends_on(node.left, unknowns)
        right_dep = self.depends_on(node.right, unknowns)
        if left_dep and right_dep:
            return NOT_LINEAR
        if node.op == "/" and right_dep:
            return NOT_LINEAR
        linear_side, factor = (node.left, node.right) if left_dep else (node.right, node.left)
        if not self.is_static(factor):
            return NOT_LINEAR
        inner = self.linear(linear_side, unknowns)
        if inner is NOT_LINEAR:
            return NOT_LINEAR
        value = self.static_value(factor)
        if node.op == "/":
            value = 1.0 / value
        return self._scale(inner, value)

    def lagged(self, node: Node, unknowns: set[str]):
        """The Picard (lagged-coefficient) linearization of ``node`` in ``unknowns``: a builder
        ``env ↦ {name: Linear}`` such that ``node = Σ_name Linear(env)·value(name)`` when every
        factor that reads an unknown but is not itself linear in them is frozen at ``env`` (the
        current state) — ``codifferential(D * d(h))`` with ``D`` a function of ``h`` gives
        ``⋆0⁻¹ d0ᵀ ⋆1 diag(D(hⁿ)) d0``, the lagged-diffusivity matrix. A product of two factors
        that are both linear in the unknowns freezes the left one. None when ``node`` reads no
        unknown, :data:`NOT_LINEAR` when no unknown is left linear (the term stays explicit).
        Terms :meth:`linear` accepts give the same blocks (their factors are static)."""
        if not self.depends_on(node, unknowns):
            return None
        if isinstance(node, Name):
            if node.name in unknowns:
                block = self.ops.identity(self.kinds[node.name])
                return lambda env: {node.name: block}
            if node.name in self.definitions:
                return self.lagged(self.definitions[node.name], unknowns)
            return NOT_LINEAR
        if isinstance(node, Negate):
            inner = self.lagged(node.operand, unknowns)
            if inner is NOT_LINEAR:
                return NOT_LINEAR
            return lambda env: {k: v.scaled(-1.0) for k, v in inner(env).items()}
        if isinstance(node, Binary):
            return self._lagged_binary(node, unknowns)
        if isinstance(node, Call):
            return self._lagged_call(node, unknowns)
        return NOT_LINEAR

    def _lagged_binary(self, node: Binary, unknowns: set[str]):
        """:meth:`lagged` of a sum, difference, product or quotient."""
        if node.op in "+-":
            left, right = self.lagged(node.left, unknowns), self.lagged(node.right, unknowns)
            if left is NOT_LINEAR or right is NOT_LINEAR or left is None or right is None:
                return NOT_LINEAR
            sign = -1.0 if node.op == "-" else 1.0

            def summed(env):
                merged = self._merge(left(env), {k: v.scaled(sign) for k, v in right(env).items()})
                if merged is NOT_LINEAR:
                    raise ModelError(f"{to_text(node)}: its two sides have different inverse stars; write it "
                                     "over one ⋆ or use an explicit integrator")
                return merged
            return summed
        if node.op in "*/":
            # the right factor linear and the left frozen first; a quotient freezes its denominator
            options = [(node.left, node.right)] if node.op == "/" else \
                [(node.right, node.left), (node.left, node.right)]
            for linear_side, factor in options:
                inner = self.lagged(linear_side, unknowns)
                if inner is None or inner is NOT_LINEAR:
                    continue
                if self.kind(factor, "?") == VECTOR:
                    return NOT_LINEAR
                value = self._compile(factor, "?")
                divide = node.op == "/"

                def scaled(env, inner=inner, value=value, divide=divide):
                    factor_value = value(env)
                    if divide:
                        factor_value = 1.0 / np.asarray(factor_value, dtype=np.float64)
                    out = self._scale(inner(env), factor_value)
                    if out is NOT_LINEAR:
                        raise ModelError(f"{to_text(node)}: a coefficient form times a Galerkin ⋆⁻¹ has no sparse "
                                         "matrix; use an explicit integrator")
                    return out
                return scaled
            return NOT_LINEAR
        return NOT_LINEAR

    def _lagged_call(self, node: Call, unknowns: set[str]):
        """:meth:`lagged` of a one-argument linear operator applied to a lagged term."""
        step = self._operator_matrix(node)
        if step is None:
            return NOT_LINEAR
        inner = self.lagged(node.args[0], unknowns)
        if inner is NOT_LINEAR:
            return NOT_LINEAR

        def applied(env):
            out = {}
            for name, block in inner(env).items():
                composed = self.ops.compose(step, block)
                if composed is None:
                    raise ModelError(f"{to_text(node)}: a Galerkin ⋆⁻¹ inside the term has no sparse matrix; use "
                                     "an explicit integrator")
                out[name] = composed
            return out
        return applied

    def _operator_matrix(self, node: Call) -> Linear | None:
        """The :class:`Linear` of the one-argument linear operator ``node`` calls, or None (not a
        linear operator, or no sparse matrix for it here)."""
        operator = OPERATORS.get(ALIASES.get(node.function, node.function))
        if operator is None or operator.linear is None or len(node.args) != 1:
            return None
        return operator.linear(self.ops, self.kind(node.args[0], "?"))

    def _merge(self, left: dict, right: dict):
        out = dict(left)
        for name, block in right.items():
            if name in out:
                merged = self.ops.add(out[name], block)
                if merged is None:
                    return NOT_LINEAR
                out[name] = merged
            else:
                out[name] = block
        return out

    def _scale(self, blocks: dict, value):
        if np.ndim(value) == 0:
            return {name: block.scaled(float(value)) for name, block in blocks.items()}
        out = {}
        for name, block in blocks.items():  # a static coefficient form, value by value: diag(c) ⋆⁻¹ A
            if block.inv is not None:
                diagonal = self.ops.diagonal(block.inv)
                if diagonal is None:
                    return NOT_LINEAR
                block = Linear(None, (sp.diags(1.0 / diagonal) @ block.A).tocsr())
            out[name] = Linear(None, (sp.diags(np.asarray(value, dtype=np.float64)) @ block.A).tocsr())
        return out

    def split(self, node: Node, unknowns: set[str]) -> tuple[dict, list[tuple[float, Node]]]:
        """``(blocks, rest)``: the terms of ``node`` linear in ``unknowns`` summed into
        ``{name: Linear}``, and the other terms ``[(sign, tree)]`` (explicit ones)."""
        blocks: dict = {}
        rest = []
        for sign, term in self.terms(node):
            linear = self.linear(term, unknowns)
            if linear is None or linear is NOT_LINEAR:
                rest.append((sign, term))
                continue
            merged = self._merge(blocks, {k: v.scaled(sign) for k, v in linear.items()})
            if merged is NOT_LINEAR:
                rest.append((sign, term))
                continue
            blocks = merged
        return blocks, rest


def _arithmetic(op: str, left, right, lk: Kind, rk: Kind):
    """The closure of ``left op right`` (vectors scaled by per-simplex values broadcast)."""
    if lk == NUMBER and rk == NUMBER:  # numpy's semantics: 1/0 is inf, not ZeroDivisionError
        return number_arithmetic(op, left, right)
    if lk == VECTOR and rk not in (VECTOR, NUMBER):
        if op == "*":
            return lambda env: left(env) * right(env)[:, None]
        return lambda env: left(env) / right(env)[:, None]
    if rk == VECTOR and lk not in (VECTOR, NUMBER):
        return lambda env: left(env)[:, None] * right(env)
    if op == "+":
        return lambda env: left(env) + right(env)
    if op == "-":
        return lambda env: left(env) - right(env)
    if op == "*":
        return lambda env: left(env) * right(env)
    if op == "/":
        return lambda env: left(env) / right(env)
    return lambda env: left(env) ** right(env)


#: the one-argument value-by-value functions (for :mod:`decrun.methods.model.initial`)
PURE = POINTWISE
