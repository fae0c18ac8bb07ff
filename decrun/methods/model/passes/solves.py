"""Lowering a linear ``solve(lhs = rhs)``: its left side split into one constant sparse matrix
of the unknown (factorized once, border values and a kernel of constants handled) and the weak
right-hand side ⋆ (rhs − the terms without the unknown)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np

from decrun.methods.model.kinds import NUMBER
from decrun.methods.model.language import Binary, Equation, ModelError, Node, to_text
from decrun.methods.model.operators import Linear
from decrun.methods.model.solve import IncompatibleRightHandSide, LinearSystem, constant_kernel

if TYPE_CHECKING:
    from decrun.methods.model.system import CompiledModel

__all__ = ["Solve", "vertex_pieces"]


@dataclass
class Solve:
    """A compiled ``solve(lhs = rhs)``: the unknown's system and the weak right-hand side."""

    equation: Equation
    unknown: str
    system: LinearSystem
    rhs: Callable[[dict], np.ndarray]  # the weak right-hand side ⋆_inv (rhs − other lhs terms)
    fixed_values: np.ndarray | None


def vertex_pieces(K) -> np.ndarray:
    """(n0,) label of the connected piece of each vertex (unused vertices: their own label)."""
    count, labels = K.connected_components()
    out = np.full(K.num_simplices(0), -1, dtype=np.int64)
    top = K.simplices(K.dim)
    out[top.ravel()] = np.repeat(labels, K.dim + 1)
    lonely = out < 0
    out[lonely] = count + np.arange(int(lonely.sum()))
    return out


def _compile_solve(equation: Equation, model: CompiledModel, new_solver: Callable) -> Solve:
    compiler, ops, K = model.compiler, model.ops, model.ops.K
    unknown, where = equation.target, equation.where
    kind = model.kinds[unknown]
    lhs_kind = compiler.kind(equation.lhs, where)
    rhs_kind = compiler.kind(equation.rhs, where)
    if lhs_kind != kind:
        raise ModelError(f"{where}: the left side {to_text(equation.lhs)} is a {lhs_kind} but the unknown {unknown} is "
                         f"a {kind}")
    if rhs_kind != kind and rhs_kind != NUMBER:
        raise ModelError(f"{where}: {to_text(equation.lhs)} is a {lhs_kind} but {to_text(equation.rhs)} is a "
                         f"{rhs_kind}")
    blocks, rest = compiler.split(equation.lhs, {unknown})
    if unknown not in blocks:
        raise ModelError(f"{where}: the left side {to_text(equation.lhs)} is not linear in {unknown} with constant "
                         "coefficients (a solve is linear); move nonlinear terms to an evolution equation")
    for _sign, term in rest:
        if compiler.depends_on(term, {unknown}):
            raise ModelError(f"{where}: the term {to_text(term)} of the left side is not linear in {unknown}; a solve "
                             "is linear in its unknown")
    linear: Linear = blocks[unknown]
    rhs_closure = compiler.compile(equation.rhs, where)
    rest_closures = [(sign, compiler.compile(term, where)) for sign, term in rest]
    star = ops.dec.star(linear.inv) if linear.inv is not None else None
    size = kind.size(K)

    def weak_rhs(env):
        value = rhs_closure(env)
        for sign, closure in rest_closures:
            value = value - sign * closure(env)
        value = np.broadcast_to(np.asarray(value, dtype=np.float64), (size,))
        return star @ value if star is not None else np.array(value)

    border, values = model.fixed.get(unknown, (np.zeros(0, dtype=np.int64), None))
    pieces = mass = None
    if not border.size and not kind.dual and kind.degree == 0:
        labels = vertex_pieces(K)
        if constant_kernel(linear.A, labels):
            pieces = labels
            mass = np.asarray(ops.dec.star(0).sum(axis=1)).ravel()
    elif not border.size and kind.degree >= 1 and not kind.dual and _pure_laplacian(equation.lhs):
        betti = K.betti_numbers()[kind.degree]
        if betti:
            raise ModelError(f"{where}: {to_text(equation.lhs)} = … is singular on this mesh: the harmonic "
                             f"{kind.degree}-forms (Betti_{kind.degree} = {betti}) are its kernel; add a term such as "
                             f"'{unknown} - t0*laplacian({unknown})' or fix border values")
    try:
        system = LinearSystem(linear.A, new_solver, border, pieces, mass)
    except Exception as error:  # noqa: BLE001 - a solver refusing the matrix: say which equation
        if isinstance(error, ModelError):
            raise
        raise ModelError(f"{where}: the system of {to_text(equation.lhs)} could not be factorized "
                         f"({str(error).splitlines()[0]}); try `solver=direct`") from None
    solve = Solve(equation, unknown, system, weak_rhs, values)
    original = system.solve

    def checked(b, fixed_values):
        try:
            return original(b, fixed_values)
        except IncompatibleRightHandSide as error:
            raise ModelError(_incompatible_message(where, equation, error.relative)) from None

    def check_only(b):
        try:
            system._compatible(system.sign * np.asarray(b, dtype=np.float64))
        except IncompatibleRightHandSide as error:
            checked_error = error
        else:
            return
        raise ModelError(_incompatible_message(where, equation, checked_error.relative)) from None

    system.solve = checked
    system.solve_check = check_only
    return solve


def _incompatible_message(where: str, equation: Equation, relative: float) -> str:
    return (f"{where}: on this mesh {to_text(equation.lhs)} is singular (constants are its kernel, no border value "
            f"fixes them) and the right side's integral is {relative:.2g} of its size, not zero: no solution exists; "
            "subtract its mean (a right side f becomes f - integral(f)/integral(1 + 0*x)) or fix border values "
            "(fields.<name>.dirichlet)")


def _pure_laplacian(node: Node) -> bool:
    """True when ``node`` is c·laplacian(u) or c·laplace_de_rham(u) alone (no shift)."""
    from decrun.methods.model.language import Call, Negate, Number

    while isinstance(node, (Negate, Binary)):
        if isinstance(node, Negate):
            node = node.operand
        elif node.op in "*/" and isinstance(node.left, Number):
            node = node.right
        elif node.op in "*/" and isinstance(node.right, Number):
            node = node.left
        else:
            return False
    return isinstance(node, Call) and node.function in ("laplacian", "laplace_de_rham", "laplace")
