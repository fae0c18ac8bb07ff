"""The linear split: a sum into the terms linear in a set of unknowns — as
:class:`~decrun.methods.model.operators.Linear` blocks ``⋆⁻¹ A``, the matrices of implicit
integrators and solves — and the remaining terms, evaluated explicitly; and the Picard (lagged)
linearization of a term (:meth:`LinearSplit.lagged`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.evaluate import Evaluator
from decrun.methods.model.kinds import NUMBER, VECTOR
from decrun.methods.model.language import Binary, Call, ModelError, Name, Negate, Node, to_text
from decrun.methods.model.operators import ALIASES, OPERATORS, Linear
from decrun.methods.model.scaling import scale_rows

__all__ = ["LinearSplit", "NOT_LINEAR"]


class _NotLinear:
    def __repr__(self):
        return "NOT_LINEAR"


NOT_LINEAR = _NotLinear()


class _Fixed:
    """A lagged builder whose blocks read nothing of ``env`` (an unknown, and linear operators
    applied to it: ``d(h)``): made at its first call, then the same blocks at every step — not a
    sparse product per step. The blocks are never changed in place (callers build new ones)."""

    def __init__(self, make):
        self.make, self.blocks = make, None

    def __call__(self, env):
        if self.blocks is None:
            self.blocks = self.make(env)
        return self.blocks


def _rows_scaled(A: sp.spmatrix, values: np.ndarray) -> sp.csr_matrix:
    """diag(values) @ A as CSR (:func:`~decrun.methods.model.scaling.scale_rows`), its zeros
    dropped as the sparse product drops them."""
    scaled = scale_rows(A, values)
    scaled.eliminate_zeros()
    return scaled


class LinearSplit(Evaluator):
    """Linear blocks and lagged linearizations of expressions (closures from :class:`Evaluator`)."""

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
                return _Fixed(lambda env: {node.name: block})
            if node.name in self.definitions:
                return self.lagged(self.definitions[node.name], unknowns)
            return NOT_LINEAR
        if isinstance(node, Negate):
            inner = self.lagged(node.operand, unknowns)
            if inner is NOT_LINEAR:
                return NOT_LINEAR

            def negated(env):
                return {k: v.scaled(-1.0) for k, v in inner(env).items()}
            return _Fixed(negated) if isinstance(inner, _Fixed) else negated
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
        return _Fixed(applied) if isinstance(inner, _Fixed) else applied

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
                block = Linear(None, _rows_scaled(block.A, 1.0 / diagonal))
            out[name] = Linear(None, _rows_scaled(block.A, np.asarray(value, dtype=np.float64)))
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
