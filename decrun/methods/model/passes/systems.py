"""Lowering a system ``solve(l1 = r1, …, lm = rm)``: one block matrix in its m unknowns, each row
in weak form over its one ⋆, assembled and factorized once; a constant kernel is refused."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.compiler import Compiler
from decrun.methods.model.kinds import NUMBER, Kind
from decrun.methods.model.language import Equation, ModelError, Node, to_text
from decrun.methods.model.solve import BlockSystem, LinearSystem

if TYPE_CHECKING:
    from decrun.methods.model.system import CompiledModel

__all__ = ["SystemSolve"]


@dataclass
class SystemSolve:
    """A compiled ``solve(l1 = r1, …)``: the block system of its unknowns (one
    :class:`LinearSystem`, factorized once) and each row's weak right-hand side."""

    equation: Equation
    unknowns: tuple
    system: LinearSystem
    rows: list  # per equation: env ↦ its weak right-hand side
    offsets: np.ndarray  # (m + 1,) where each unknown's values start in the stacked vector
    fixed_values: np.ndarray | None
    #: t ↦ the fixed values when some read t (:mod:`decrun.methods.model.moving_solves`); None: static
    moving_values: Callable[[float], np.ndarray] | None = None

    def solve(self, env: dict) -> dict[str, np.ndarray]:
        """Every unknown's values at ``env`` (one solve of the block system, factorized once)."""
        fixed = self.fixed_values if self.moving_values is None else self.moving_values(float(env["t"]))
        x = self.system.solve(np.concatenate([row(env) for row in self.rows]), fixed)
        return {name: x[self.offsets[i]:self.offsets[i + 1]] for i, name in enumerate(self.unknowns)}


def _system_row_kinds(equation: Equation, compiler: Compiler, unknowns, kinds: list[Kind]) -> list[Kind]:
    """The kind of each equation of a system (its left side's; the right side a number or the
    same kind), refused unless they are the unknowns' kinds, as a multiset (a square system)."""
    where = equation.where
    row_kinds = []
    for lhs, rhs in equation.pairs:
        lhs_kind, rhs_kind = compiler.kind(lhs, where), compiler.kind(rhs, where)
        if rhs_kind != lhs_kind and rhs_kind != NUMBER:
            raise ModelError(f"{where}: {to_text(lhs)} is a {lhs_kind} but {to_text(rhs)} is a {rhs_kind}")
        row_kinds.append(lhs_kind)
    if sorted(map(str, row_kinds)) != sorted(map(str, kinds)):
        given = ", ".join(f"{to_text(lhs)} : {kind}" for (lhs, _), kind in zip(equation.pairs, row_kinds, strict=True))
        wanted = ", ".join(f"{name} : {kind}" for name, kind in zip(unknowns, kinds, strict=True))
        missing = list((Counter(map(str, kinds)) - Counter(map(str, row_kinds))).elements())
        raise ModelError(f"{where}: the system's equations ({given}) do not match its unknowns ({wanted}): each unknown "
                         f"needs one equation of its kind, and one more left side should be a {missing[0]}; "
                         "write that equation in its unknown's kind (e.g. d(u) = f for a top-form pressure)")
    return row_kinds


def _compile_system(equation: Equation, model: CompiledModel, new_solver: Callable) -> SystemSolve:
    """The block system of ``solve(l1 = r1, …, lm = rm)`` in its m unknowns u_1 … u_m.

    Row i is equation i in weak form: its left side split into Σ_j ⋆_k⁻¹ A_ij u_j (+ terms that
    read no unknown, moved to the right), multiplied by the row's one ⋆_k (``u - codifferential(p)``
    is ⋆_{n−1}⁻¹(⋆_{n−1} u − d_{n−1}ᵀ ⋆_n p): the row ⋆_{n−1} u − d_{n−1}ᵀ ⋆_n p = ⋆_{n−1} r), so a
    Galerkin ⋆ is never inverted. Row i must have the kind of one unknown: the left sides' kinds
    and the unknowns' kinds are the same multiset, so that the block matrix [A_ij] is square
    (Σ sizes of the rows = Σ sizes of the unknowns). The matrix is assembled once (``sp.bmat``)
    and factorized once; it is in general indefinite (a saddle point has a zero block), so a
    solver that needs SPD matrices is refused."""
    compiler, ops, K = model.compiler, model.ops, model.ops.K
    where, unknowns = equation.where, equation.targets
    kinds = [model.kinds[name] for name in unknowns]
    row_kinds = _system_row_kinds(equation, compiler, unknowns, kinds)
    sizes = [kind.size(K) for kind in kinds]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    grid, rows = [], []
    for (lhs, rhs), row_kind in zip(equation.pairs, row_kinds, strict=True):
        if compiler.depends_on(rhs, set(unknowns)):
            read = sorted(compiler.reads(rhs) & set(unknowns))
            raise ModelError(f"{where}: the right side {to_text(rhs)} reads the unknown {read[0]}; move the terms of "
                             "the unknowns to the left side")
        blocks, rest = compiler.split(lhs, set(unknowns))
        for _sign, term in rest:
            if compiler.depends_on(term, set(unknowns)):
                raise ModelError(f"{where}: the term {to_text(term)} of {to_text(lhs)} is not linear in the unknowns "
                                 f"{', '.join(unknowns)} with constant coefficients (a system is linear)")
        if not blocks:
            raise ModelError(f"{where}: the left side {to_text(lhs)} reads none of the unknowns {', '.join(unknowns)} "
                             "linearly; every equation of a system is linear in its unknowns")
        stars = sorted({block.inv for block in blocks.values() if block.inv is not None})
        if len(stars) > 1:
            raise ModelError(f"{where}: the terms of {to_text(lhs)} carry different inverse stars "
                             f"(⋆_{stars[0]}⁻¹ and ⋆_{stars[1]}⁻¹): no one weak form; write the equation over one ⋆")
        star = ops.dec.star(stars[0]) if stars else None
        line: list = []
        for name in unknowns:
            block = blocks.get(name)
            if block is None:
                line.append(None)
            elif block.inv is None and star is not None:
                line.append(sp.csr_matrix(star @ block.A))
            else:
                line.append(block.A)
        grid.append(line)
        rows.append(_weak_row(compiler, rhs, rest, star, stars[0] if stars else None, row_kind.size(K), where))
    for j, name in enumerate(unknowns):
        if all(line[j] is None for line in grid):
            raise ModelError(f"{where}: no equation of the system reads {name} linearly; it cannot be solved for")
    # rows in the order of the unknowns whose kind they have (a square block matrix with its
    # diagonal blocks on the unknowns)
    order, free = [], list(range(len(grid)))
    for kind in kinds:
        match = next(i for i in free if str(row_kinds[i]) == str(kind))
        free.remove(match)
        order.append(match)
    grid = [grid[i] for i in order]
    rows = [rows[i] for i in order]
    for i, line in enumerate(grid):  # bmat needs each row's height: an all-None row cannot occur
        for j, block in enumerate(line):
            if block is not None and block.shape != (sizes[i], sizes[j]):
                raise ModelError(f"{where}: block ({i}, {j}) of the system has shape {block.shape}, expected "
                                 f"{(sizes[i], sizes[j])}")
    matrix = sp.bmat(grid, format="csr")
    fixed, values = [], []
    for j, name in enumerate(unknowns):
        if name in model.fixed:
            border, fixed_values = model.fixed[name]
            fixed.append(border + offsets[j])
            values.append(fixed_values)
    fixed_index = np.concatenate(fixed).astype(np.int64) if fixed else np.zeros(0, dtype=np.int64)
    system = BlockSystem(matrix, new_solver, fixed_index, where=where, unknowns=tuple(unknowns))
    _refuse_constant_kernel(system, unknowns, kinds, offsets, K, where,
                            [f"{model.spec.key}.fields.{name}.dirichlet" for name in unknowns if name in model.fixed])
    return SystemSolve(equation, tuple(unknowns), system, rows, offsets,
                       np.concatenate(values) if values else None)


def _refuse_constant_kernel(system: BlockSystem, unknowns, kinds, offsets, K, where: str, fixed: list) -> None:
    """Before any work: an unknown determined only up to a constant — the block matrix (its free
    rows and columns) maps the constant of one unknown to zero, e.g. a pressure when every border
    flux is fixed (``fields.u.dirichlet``) and no border value enters — is refused; a factorization
    of a singular matrix would give a quiet wrong answer. The constant of a 0-form or dual 0-form
    is 1 everywhere; of a top form, the integral of the density 1 over each top simplex."""
    A = system.A_full[system.free][:, system.free]
    scale = abs(A).max() if A.nnz else 0.0
    for j, (name, kind) in enumerate(zip(unknowns, kinds, strict=True)):
        if kind.is_form and kind.degree == K.dim and not kind.dual:
            constant = K.top_volumes
        elif kind.is_form and kind.simplex_dimension(K.dim) in (0, K.dim):
            constant = np.ones(kind.size(K))
        else:
            continue
        full = np.zeros(system.A_full.shape[0])
        full[offsets[j]:offsets[j + 1]] = constant
        vector = full[system.free]
        if scale and np.abs(A @ vector).max() <= 1e-10 * scale * np.abs(vector).max():
            given = f"drop {' and '.join(fixed)} and " if fixed else ""
            raise ModelError(f"{where}: the block system of {', '.join(unknowns)} is singular: {name} is determined "
                             "only up to a constant (no border value fixes it, as when every border flux is given); "
                             f"{given}let border values of {name} enter the weak form (a term border(q), as in "
                             "app=darcy)")


def _weak_row(compiler: Compiler, rhs: Node, rest: list, star, degree, size: int, where: str) -> Callable:
    """env ↦ ⋆_k (rhs − the left side's terms without unknowns) of one row of a system, k =
    ``degree`` (None: no ⋆). A term linear in a form with a constant ⋆_k⁻¹ A matrix
    (``border(pb)``, ``codifferential(q)``) contributes A·value: the ⋆_k⁻¹ it carries is not
    applied only to be multiplied back (for a Galerkin ⋆, a factorization saved)."""
    terms = [(1.0, term) for term in [rhs]] + [(-sign, term) for sign, term in rest]
    split = []
    for sign, tree in terms:
        names = {name for name in compiler.reads(tree) if name not in compiler.definitions and name in compiler.kinds
                 and compiler.kinds[name].is_form}
        blocks, others = compiler.split(tree, names) if names else ({}, compiler.terms(tree))
        for name, block in blocks.items():
            if block.inv == degree and degree is not None:
                split.append(("weak", name, (sign * block.A).tocsr()))
            elif block.inv is None:
                split.append(("weak", name, (sign * (star @ block.A if star is not None else block.A)).tocsr()))
            else:
                apply = compiler.ops.matrix(block)
                split.append(("strong", name, lambda x, apply=apply, sign=sign: sign * apply(x)))
        for inner_sign, term in others:
            closure = compiler.compile(term, where)
            split.append(("value", None, (sign * inner_sign, closure)))

    def weak(env):
        strong = np.zeros(size)
        total = np.zeros(size)
        for what, name, item in split:
            if what == "weak":
                total += item @ env[name]
            elif what == "strong":
                strong += item(env[name])
            else:
                factor, closure = item
                strong += factor * np.broadcast_to(np.asarray(closure(env), dtype=np.float64), (size,))
        return total + (star @ strong if star is not None else strong)
    return weak
