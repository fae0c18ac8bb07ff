"""The evaluator: typed expression trees → numpy closures ``f(env) -> value`` (``env``: name →
array or float) — the one evaluation every integrator, solve, metric and initial value runs.

Every maximal linear chain of operators applied to one name is folded into one sparse matrix
(``codifferential(d(u))`` is one product per evaluation), a static number times such a chain is
folded into its matrix, and a static subtree is evaluated once and reused.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from decrun.methods.model.kind_inference import KindInference
from decrun.methods.model.kinds import NUMBER, VECTOR, Kind
from decrun.methods.model.language import Binary, Call, ModelError, Name, Negate, Node, Number, to_text
from decrun.methods.model.numbers import number_arithmetic
from decrun.methods.model.operators import ALIASES, OPERATORS
from decrun.methods.model.powers import fixed_power

__all__ = ["Evaluator"]


class Evaluator(KindInference):
    """Closures of typed trees over one mesh's operators (kinds from :class:`KindInference`)."""

    _static_env: dict | None

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
            if node.op == "**" and lk != NUMBER and rk == NUMBER and self.is_static(node.right):  # u**3: products
                return fixed_power(left, right)
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
