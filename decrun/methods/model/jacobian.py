"""The derivative pass: exact sparse Jacobians of typed expression trees, from the registry's
derivative rules (no finite differences).

:func:`derivative` turns a tree and one unknown name into ``J(env) -> csr (rows, cols)``, the
matrix ∂tree/∂unknown at the values ``env``, built once (the value closures of the subtrees it
needs are compiled once) and evaluated at any state. The rules, with D the derivative of a
subtree (``None``: it does not read the unknown; an array: a value-by-value factor, the diagonal
matrix diag(a); else a sparse matrix):

- a name: the identity for the unknown, its definition's D (definitions are followed), ``None``
  for anything else; a solve's result that reads the unknown is refused (its Jacobian is dense);
- ``a ± b``: D_a ± D_b;  ``a * b``: diag(b) D_a + diag(a) D_b;  ``a / b``: diag(1/b) D_a − diag(a/b²) D_b;
  ``a ** b``: diag(b a^(b−1)) D_a + diag(a^b log a) D_b;
- a linear operator L (one argument): L D (L its matrix ⋆⁻¹A with a diagonal ⋆; a Galerkin ⋆⁻¹
  would make it dense and is refused);
- an operator with a derivative rule: Σ_i ∂op/∂arg_i · D_i (value-by-value functions, max, min);
- ``lie(X, u)`` with a fixed X: its matrix times D_u;
- ♯, |·|, normalize, ♭ (also the intrinsic one), interior, ∧, flux_field and lie (of 0- and
  1-forms, in the velocity and in the form): their rules in
  :mod:`decrun.methods.model.vector_derivatives` (a vector field's values flattened row by row).

Anything else that reads the unknown — a number computed from it (``integral(u)``, ``inner``,
``mean``, ``norm`` of a form, one-argument ``max``/``min``: each couples every value, a dense
Jacobian), a linear operator with a Galerkin ⋆⁻¹ (dense), an operator of a plugin without a
derivative rule — is one :class:`ModelError` line naming the term.
"""

from __future__ import annotations

from typing import Any, Callable, Optional

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.kinds import NUMBER, VECTOR
from decrun.methods.model.language import Binary, Call, ModelError, Name, Negate, Node, to_text
from decrun.methods.model.operators import ALIASES, OPERATORS
from decrun.methods.model.scaling import scale_columns
from decrun.methods.model.vector_derivatives import vector_shape

__all__ = ["derivative", "derivative_values", "Derivative", "pattern"]

#: env ↦ D (None, an array: diag(a), or a sparse matrix)
Derivative = Callable[[dict], object]


def _add(first, second):
    if first is None:
        return second
    if second is None:
        return first
    if isinstance(first, np.ndarray) and isinstance(second, np.ndarray):
        return first + second
    return _matrix(first) + _matrix(second)


def _matrix(D) -> sp.csr_matrix:
    return sp.diags(D).tocsr() if isinstance(D, np.ndarray) else sp.csr_matrix(D)


def _times(factor, D):
    """diag(factor) · D for a value-by-value factor (a number or an array)."""
    if D is None:
        return None
    if np.ndim(factor) == 0:
        return float(factor) * D
    factor = np.asarray(factor, dtype=np.float64)
    if isinstance(D, np.ndarray):
        return factor * D
    return sp.diags(factor) @ D


def _apply(matrix, D):
    """matrix · D (a sparse matrix applied to a derivative)."""
    if D is None:
        return None
    if isinstance(D, np.ndarray):  # matrix · diag(D): its columns scaled, no sparse product
        return scale_columns(matrix, D)
    return (matrix @ D).tocsr()


class _Builder:
    def __init__(self, compiler, unknown: str, size: int, where: str):
        self.compiler, self.unknown, self.size, self.where = compiler, unknown, size, where

    def refuse(self, node: Node, why: str) -> ModelError:
        return ModelError(f"{self.where}: {to_text(node)}: {why}; write the term so that it is value by value or "
                          "linear in the unknown, or use an explicit integrator (`app.integrator=rk4`)")

    def value(self, node: Node) -> Callable[[dict], object]:
        return self.compiler.compile(node, self.where)

    def build(self, node: Node) -> Optional[Derivative]:
        """D of ``node`` as a closure of env, or None when ``node`` does not read the unknown."""
        compiler = self.compiler
        if not compiler.depends_on(node, {self.unknown}):
            return None
        if isinstance(node, Name):
            return self._name(node)
        if isinstance(node, Negate):
            operand = self.build(node.operand)
            assert operand is not None  # the operand reads the unknown
            return lambda env: _times(-1.0, operand(env))
        if compiler.kind(node, self.where) == NUMBER:
            raise self.refuse(node, f"a number computed from {self.unknown} couples all its values (a dense Jacobian)")
        if isinstance(node, Binary):
            if node.op == "^":
                return self._call(Call("wedge", (node.left, node.right)), node)
            return self._arithmetic(node)
        if isinstance(node, Call):
            return self._call(node, node)
        raise TypeError(node)

    def _name(self, node: Name) -> Optional[Derivative]:
        if node.name == self.unknown:
            identity = np.ones(self.size)
            return lambda env: identity
        if node.name in self.compiler.definitions:
            return self.build(self.compiler.definitions[node.name])
        raise self.refuse(node, f"{node.name} is a solve's result, which reads {self.unknown} through a "
                                "factorized inverse (a dense Jacobian)")

    def _arithmetic(self, node: Binary) -> Derivative:
        left, right = self.build(node.left), self.build(node.right)
        if node.op in "+-":
            sign = 1.0 if node.op == "+" else -1.0
            return lambda env: _add(left(env) if left else None, _times(sign, right(env)) if right else None)
        a, b = self.value(node.left), self.value(node.right)
        if node.op == "*":
            return lambda env: _add(_times(b(env), left(env)) if left else None,
                                    _times(a(env), right(env)) if right else None)
        if node.op == "/":
            def quotient(env):
                numerator, denominator = a(env), np.asarray(b(env), dtype=np.float64)
                return _add(_times(1.0 / denominator, left(env)) if left else None,
                            _times(-numerator / denominator ** 2, right(env)) if right else None)
            return quotient

        def power(env):
            base, exponent = np.asarray(a(env), dtype=np.float64), b(env)
            with np.errstate(divide="ignore", invalid="ignore"):
                through_base = _times(exponent * base ** (np.asarray(exponent) - 1.0), left(env)) if left else None
                through_exponent = _times(base ** exponent * np.log(base), right(env)) if right else None
            return _add(through_base, through_exponent)
        return power

    def _call(self, node: Call, shown: Node) -> Derivative:
        compiler = self.compiler
        name = ALIASES.get(node.function, node.function)
        operator = OPERATORS[name]
        kinds = [compiler.kind(arg, self.where) for arg in node.args]
        if operator.linear is not None and len(node.args) == 1:
            step = operator.linear(compiler.ops, kinds[0])
            matrix = None if step is None else _strong(compiler.ops, step)
            if matrix is None:
                raise self.refuse(shown, f"{name} has no sparse matrix here (a Galerkin ⋆⁻¹)")
            argument = self.build(node.args[0])
            assert argument is not None  # the argument reads the unknown
            return lambda env: _apply(matrix, argument(env))
        if operator.fixed_first is not None and len(node.args) == 2 and not compiler.depends_on(node.args[0],
                                                                                                  {self.unknown}):
            first, second = self.value(node.args[0]), self.build(node.args[1])
            assert second is not None  # the second argument reads the unknown
            cache: list = []

            def fixed(env):
                if not cache or not compiler.is_static(node.args[0]):
                    cache[:] = [operator.fixed_first(compiler.ops, kinds, first(env))]
                if cache[0] is None:
                    raise self.refuse(shown, f"{name} has no matrix for a {kinds[1]}")
                return _apply(cache[0], second(env))
            return fixed
        if operator.derivative is None:
            raise self.refuse(shown, f"the operator {name} has no derivative rule")
        values = [self.value(arg) for arg in node.args]
        inners = [self.build(arg) for arg in node.args]
        rule = operator.derivative

        def chained(env):
            arguments = [value(env) for value in values]
            total = None
            for i, inner in enumerate(inners):
                if inner is None:
                    continue
                partial = rule(compiler.ops, kinds, arguments, i)
                if partial is None:
                    raise self.refuse(shown, f"the operator {name} has no derivative in argument {i + 1}")
                total = _add(total, _apply(partial, inner(env)) if sp.issparse(partial) else _times(partial, inner(env)))
            return total
        return chained


def _strong(ops, linear) -> sp.csr_matrix | None:
    """⋆_inv⁻¹ A as one sparse matrix (None for a non-diagonal ⋆_inv: its inverse is dense)."""
    if linear.inv is None:
        return sp.csr_matrix(linear.A)
    diagonal = ops.diagonal(linear.inv)
    if diagonal is None:
        return None
    return (sp.diags(1.0 / diagonal) @ linear.A).tocsr()


def derivative_values(compiler, node: Node, unknown: str, where: str) -> tuple[Optional[Derivative], int, int]:
    """``(D, rows, cols)``: D(env) the derivative of ``node`` in ``unknown`` as the rules build it —
    an array a (the diagonal matrix diag(a): a value-by-value term, its Jacobian a diagonal) or a
    sparse matrix — or None when ``node`` does not read ``unknown``; rows × cols its shape. What
    :func:`derivative` wraps, for an assembly that reuses a sparsity pattern
    (:mod:`decrun.methods.model.jacobian_assembly`)."""
    ops = compiler.ops
    cols = compiler.kinds[unknown].size(ops.K)
    kind = compiler.kind(node, where)
    rows = kind.size(ops.K) if kind.is_form else cols
    return _Builder(compiler, unknown, cols, where).build(node), rows, cols


def derivative(compiler, node: Node, unknown: str, where: str) -> Callable[[dict], sp.csr_matrix]:
    """``J(env) -> csr (rows, cols)``: ∂node/∂unknown at ``env`` (rows: the values of ``node``'s
    kind; cols: the unknown's values), from the registry's rules (module docstring); built once.
    A term the rules cannot differentiate is refused now, naming ``where`` and the term."""
    built, rows, cols = derivative_values(compiler, node, unknown, where)
    zero = sp.csr_matrix((rows, cols))

    def jacobian(env: dict) -> sp.csr_matrix:
        D: Any = built(env) if built is not None else None
        if D is None:
            return zero
        if sp.issparse(D):
            return sp.csr_matrix(D)
        return sp.diags(np.broadcast_to(np.asarray(D, dtype=np.float64), (cols,))).tocsr()
    return jacobian


def _structure(matrix) -> sp.csr_matrix:
    """The 0/1 structure of a sparse matrix (its stored entries; explicit zeros dropped)."""
    out = sp.csr_matrix(matrix, dtype=np.float64, copy=True)
    out.eliminate_zeros()
    out.data[:] = 1.0
    return out


def _union(first, second):
    if first is None:
        return second
    if second is None:
        return first
    return _structure(first + second)


class _Pattern:
    """The structure of the exact Jacobian, by the rules of :class:`_Builder` read on structures
    (see :func:`pattern`); refuses, in one line, every term the rules refuse."""

    def __init__(self, compiler, unknown: str, size: int, where: str):
        self.compiler, self.unknown, self.size, self.where = compiler, unknown, size, where
        self._generic = np.random.default_rng(47)

    def refuse(self, node: Node, why: str) -> ModelError:
        return ModelError(f"{self.where}: integrator=bdf/radau: no sparse Jacobian pattern through {to_text(node)} "
                          f"({why}); use `app.integrator=imex` or `app.integrator=rk4`")

    def build(self, node: Node) -> sp.csr_matrix | None:
        """The structure of ∂node/∂unknown, or None when ``node`` does not read the unknown."""
        compiler = self.compiler
        if not compiler.depends_on(node, {self.unknown}):
            return None
        if isinstance(node, Name):
            if node.name == self.unknown:
                return sp.identity(self.size, format="csr")
            if node.name in compiler.definitions:
                return self.build(compiler.definitions[node.name])
            raise self.refuse(node, f"{node.name} is a solve's result, whose Jacobian is dense")
        if isinstance(node, Negate):
            return self.build(node.operand)
        if compiler.kind(node, self.where) == NUMBER:
            raise self.refuse(node, f"a number computed from {self.unknown} couples all its values")
        if isinstance(node, Binary):
            if node.op == "^":
                return self._call(Call("wedge", (node.left, node.right)), node)
            return _union(self.build(node.left), self.build(node.right))  # diag(b) D_a + diag(a) D_b, …
        if isinstance(node, Call):
            return self._call(node, node)
        raise TypeError(node)

    def _call(self, node: Call, shown: Node) -> sp.csr_matrix | None:
        compiler = self.compiler
        operator = OPERATORS[ALIASES.get(node.function, node.function)]
        kinds = [compiler.kind(arg, self.where) for arg in node.args]
        inners = [self.build(arg) for arg in node.args]
        if operator.linear is not None and len(node.args) == 1:
            step = operator.linear(compiler.ops, kinds[0])
            matrix = None if step is None else _strong(compiler.ops, step)
            if matrix is None:
                raise self.refuse(shown, f"{operator.name} has no sparse matrix here")
            return _structure(_structure(matrix) @ inners[0])
        if operator.fixed_first is not None and len(node.args) == 2 and inners[0] is None and (
                compiler.is_static(node.args[0]) or operator.derivative is None):  # else: its rule's structure
            if not compiler.is_static(node.args[0]):
                raise self.refuse(shown, f"the matrix of {operator.name} changes with {to_text(node.args[0])}")
            matrix = operator.fixed_first(compiler.ops, kinds, compiler.static_value(node.args[0]))
            if matrix is None:
                raise self.refuse(shown, f"{operator.name} has no matrix for a {kinds[1]}")
            return _structure(_structure(matrix) @ inners[1])
        if operator.derivative is None:
            raise self.refuse(shown, f"the operator {operator.name} has no derivative rule")
        total = None
        for i, inner in enumerate(inners):
            if inner is not None:
                total = _union(total, _structure(self._partial(operator, kinds, i, shown) @ inner))
        return total

    def _partial(self, operator, kinds, i: int, shown: Node) -> sp.csr_matrix:
        """The structure of ∂op/∂arg_i at every state: the identity for a value-by-value operator
        (its rule gives a diagonal, some of whose values may vanish at one state — max, sign);
        else the rule's structure at generic values (uniform in [1, 2], seeded), where no entry
        vanishes but by cancellation."""
        size = self.compiler.ops.K
        if operator.pointwise:
            rows = kinds[i].size(size) if kinds[i].is_form else self.size
            return sp.identity(rows, format="csr")
        values = [self._generic.uniform(1.0, 2.0, kind.size(size)) if kind.is_form else
                  self._generic.uniform(1.0, 2.0, vector_shape(self.compiler.ops)) if kind == VECTOR else 1.5
                  for kind in kinds]
        partial = operator.derivative(self.compiler.ops, kinds, values, i)
        if partial is None:
            raise self.refuse(shown, f"the operator {operator.name} has no derivative in argument {i + 1}")
        return _structure(partial) if sp.issparse(partial) else \
            sp.identity(np.size(partial) if np.ndim(partial) else kinds[i].size(size), format="csr")


def pattern(compiler, node: Node, unknown: str, where: str) -> sp.csr_matrix:
    """(rows, cols) the 0/1 sparsity of ∂node/∂unknown over every state: the structure of the
    exact Jacobian that :func:`derivative` builds, by its rules (module docstring) read on
    structures — a name the identity, a sum or product the union of its operands' structures, a
    linear operator its matrix's structure times its argument's, ``lie(X, u)`` with a fixed X its
    matrix's, a value-by-value operator the identity, another operator with a derivative rule its
    rule's structure. What :func:`derivative` refuses is refused here (one line, bdf/radau's fix)."""
    ops = compiler.ops
    cols = compiler.kinds[unknown].size(ops.K)
    kind = compiler.kind(node, where)
    rows = kind.size(ops.K) if kind.is_form else cols
    built = _Pattern(compiler, unknown, cols, where).build(node)
    return sp.csr_matrix((rows, cols)) if built is None else built
