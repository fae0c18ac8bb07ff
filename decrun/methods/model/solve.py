"""Linear systems of a model: fixed values condensed out, kernels of singular systems handled.

A system ``A x = b`` (A sparse, square, constant during a run) is factorized once by a fresh
solver of the configured kind (``solver=``) and solved every step. Two things are handled here
and never silently:

- **fixed values** (Dirichlet rows): the unknowns at ``fixed`` take the values ``g``, the others
  solve ``A_FF x_F = b_F − A_FB g`` (scikit-fem's ``condense``);
- **a kernel of constants** (a Laplacian of 0-forms with no fixed value: a closed surface, or
  natural borders): one vertex per connected piece is pinned, the right-hand side's component
  along the kernel is removed (``b ← b − (Σ_c b) ⋆0_c / Σ_c ⋆0``, i.e. the mean of f — reported,
  and refused when it is not round-off-small compared with b), and the solution is shifted to
  zero ⋆0-weighted mean on every piece: "the mean fixed".

A symmetric negative definite A (the Laplace–Beltrami sign) is negated with b, so that
Cholesky-based solvers see an SPD matrix.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.language import ModelError

__all__ = ["LinearSystem", "BlockSystem", "KernelReport", "COMPATIBILITY_LIMIT", "RESIDUAL_LIMIT"]

#: largest |Σ b| / Σ |b| accepted on a singular system (the part removed from b); beyond it the
#: problem has no solution and the model is refused
COMPATIBILITY_LIMIT = 0.05
#: largest max|A x − b| / max|b| accepted from a block system's solve: a backward-stable solve
#: leaves ≤ ε cond(A) of b, so this admits cond(A) up to ~1e10 and refuses an x with no solution
RESIDUAL_LIMIT = 1e-6


@dataclass
class KernelReport:
    """What a singular system's handling did: ``pieces`` pinned (one per connected piece) and
    the largest relative part of b removed (``removed``: |Σ_c b| / Σ_c |b|) and, on that piece,
    the right side's mean that was subtracted (``mean``: Σ_c b / Σ_c ⋆0, in the units of the right
    side as written — for ``solve(laplacian(u) = f)`` the ⋆0-weighted mean of f)."""

    pieces: int = 0
    removed: float = 0.0
    mean: float = 0.0


@dataclass
class LinearSystem:
    """``A x = b`` with fixed values and an optional kernel of constants (see the module
    docstring). ``A`` (n, n) sparse; ``fixed`` (m,) indices with values from ``fixed_values``;
    ``pieces`` (n,) connected-piece labels and ``mass`` (n,) weights when the kernel is the
    constants on each piece (None otherwise); ``new_solver()`` a fresh solver."""

    A: sp.spmatrix
    new_solver: Callable | None
    fixed: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    pieces: np.ndarray | None = None
    mass: np.ndarray | None = None
    report: KernelReport = field(default_factory=KernelReport)

    def __post_init__(self):
        A = sp.csr_matrix(self.A, dtype=np.float64)
        n = A.shape[0]
        self.sign = 1.0
        diagonal = A.diagonal()
        if diagonal.size and np.all(diagonal <= 0) and np.any(diagonal < 0) and _symmetric(A):
            self.sign = -1.0  # the Laplace–Beltrami sign: hand the SPD −A to the solver
        A = -A if self.sign < 0 else A  # (sign +1: no copy of a matrix the solver copies if it must)
        keep = np.ones(n, dtype=bool)
        keep[self.fixed] = False
        self.pinned = np.zeros(0, dtype=np.int64)
        if self.pieces is not None:
            labels = np.unique(self.pieces)
            self.pinned = np.array([int(np.flatnonzero(self.pieces == label)[0]) for label in labels], dtype=np.int64)
            keep[self.pinned] = False
            self.report.pieces = len(labels)
        self.free = np.flatnonzero(keep)
        self.all_free = self.free.size == n  # no fixed value, nothing pinned: no condensation
        self.A_full = A
        self.A_free_fixed = A[self.free][:, self.fixed] if self.fixed.size else None
        self.solver = None  # factorized at the first solve, with the solver bound then

    def free_matrix(self) -> sp.csr_matrix:
        """A over the free rows and columns (A itself when nothing is fixed or pinned: no copies)."""
        return self.A_full if self.all_free else self.A_full[self.free][:, self.free].tocsr()

    def bind(self, new_solver: Callable) -> None:
        """Use ``new_solver()`` for the factorization (before the first solve)."""
        if self.solver is None:
            self.new_solver = new_solver

    def factorize(self) -> None:
        """Factorize A (free rows and columns) once."""
        if self.solver is None:
            if self.new_solver is None:
                from decrun.core.solvers import solver_factory

                self.new_solver = solver_factory(None)
            solver = self.new_solver()
            matrix = self.free_matrix()
            if getattr(solver, "needs_spd", False) and not _symmetric(matrix):
                raise UnsymmetricSystem(solver.name)
            solver.factorize(matrix)
            self.solver = solver

    def solve(self, b: np.ndarray, fixed_values: np.ndarray | None = None) -> np.ndarray:
        """x (n,) with ``x[fixed] = fixed_values``; ``b`` (n,) the right-hand side — or (n, m)
        columns solved at once with ``fixed_values`` (k, m) (a system without a kernel)."""
        b = self.sign * np.asarray(b, dtype=np.float64)
        if b.ndim == 2 and self.pieces is not None:
            raise ValueError("LinearSystem.solve: several right-hand sides on a system with a kernel of constants")
        if self.all_free:  # the plain solve, without copies in and out of the free rows
            self.factorize()
            return self.solver.solve(b)
        x = np.zeros((self.A_full.shape[0],) + b.shape[1:])
        if self.pieces is not None:
            b = self._compatible(b)
        self.factorize()
        rhs = b[self.free]
        if self.fixed.size:
            x[self.fixed] = fixed_values
            rhs = rhs - self.A_free_fixed @ fixed_values
        x[self.free] = self.solver.solve(rhs)
        if self.pieces is not None:
            totals = np.bincount(self.pieces, weights=self.mass)
            means = np.bincount(self.pieces, weights=self.mass * x) / totals
            x = x - means[self.pieces]
        return x

    def _compatible(self, b: np.ndarray) -> np.ndarray:
        sums = np.bincount(self.pieces, weights=b)
        sizes = np.bincount(self.pieces, weights=np.abs(b))
        relative = np.abs(sums) / np.where(sizes > 0, sizes, 1.0)
        totals = np.bincount(self.pieces, weights=self.mass)
        worst = int(np.argmax(relative))
        if relative[worst] >= self.report.removed:
            self.report.removed = float(relative[worst])
            self.report.mean = float(self.sign * sums[worst] / totals[worst])  # b here is sign × the given b
        if relative.max(initial=0.0) > COMPATIBILITY_LIMIT:
            raise IncompatibleRightHandSide(float(relative.max()))
        return b - (sums / totals)[self.pieces] * self.mass


@dataclass
class BlockSystem(LinearSystem):
    """The block matrix of a system of equations in several unknowns (``solve(l1 = r1, l2 = r2)``):
    a :class:`LinearSystem` (fixed values condensed out) whose matrix is in general indefinite —
    a saddle point [[M, B], [C, 0]] has a zero block — so a solver that needs SPD matrices
    (Cholesky, CG, AMG) is refused unless the matrix is symmetric with a positive diagonal; LU
    (``solver=direct``, or ``auto``'s SuperLU) factorizes it once. ``where`` names the equation
    and ``unknowns`` its unknowns in messages."""

    where: str = "app.equations"
    unknowns: tuple = ()
    #: the largest |entry| of the matrix, for the residual check (read at the first solve)
    largest: float | None = field(default=None, init=False, repr=False)

    def factorize(self) -> None:
        """Factorize once; refuse an SPD-only solver for a matrix that cannot be SPD."""
        if self.solver is None and self.new_solver is not None:
            solver = self.new_solver()
            matrix = self.free_matrix()
            if getattr(solver, "needs_spd", False):
                diagonal = matrix.diagonal()
                if not _symmetric(matrix) or diagonal.size and diagonal.min() <= 0:
                    why = "not symmetric" if not _symmetric(matrix) else \
                        f"indefinite: {int((diagonal <= 0).sum())} of its diagonal entries are not positive"
                    raise ModelError(f"{self.where}: solver={solver.name} needs a symmetric positive definite matrix, "
                                     f"but the block system of {', '.join(self.unknowns)} is {why} (a saddle point); "
                                     "use `solver=direct`")
            try:
                solver.factorize(matrix)
            except Exception as error:  # noqa: BLE001 - say which equation could not be factorized
                raise ModelError(f"{self.where}: the block system of {', '.join(self.unknowns)} could not be "
                                 f"factorized ({str(error).splitlines()[0]}); is an unknown determined only up to a "
                                 "constant? check the equations and their border values, or use `solver=direct`"
                                 ) from None
            self.solver = solver
        super().factorize()

    def solve(self, b: np.ndarray, fixed_values: np.ndarray | None = None) -> np.ndarray:
        """x with ``x[fixed] = fixed_values``. The backward error of the free rows,
        max|A x − b| / (max|A| max|x| + max|b|), is checked (≤ 1e-8), and x must be finite: a
        solver that did not converge or a singular factorization is refused, not returned. The
        residual is also checked against the right-hand side alone, max|A x − b| ≤ 1e-6 max|b|
        (:data:`RESIDUAL_LIMIT`): an inconsistent system (``solve(u + v = 1, u + v = 2)``) has no
        x, and a solver that answers with a blown-up x (max|x| ≈ 1e14) passes the backward-error
        check, whose denominator grows with max|x|, but never this one."""
        x = super().solve(b, fixed_values)
        rhs = self.sign * np.asarray(b, dtype=np.float64)
        residual = (self.A_full @ x - rhs)[self.free]
        if self.largest is None:
            self.largest = abs(self.A_full).max() if self.A_full.nnz else 0.0
        size = self.largest * np.abs(x).max() + np.abs(rhs[self.free]).max(initial=0.0)
        right = np.abs(rhs[self.free]).max(initial=0.0)
        worst = np.abs(residual).max(initial=0.0)
        if not (np.all(np.isfinite(x)) and worst <= 1e-8 * size):
            error = np.abs(residual).max(initial=0.0) / size if size > 0 and np.isfinite(size) else float("nan")
            raise ModelError(f"{self.where}: the solution of the block system of {', '.join(self.unknowns)} is not "
                             f"one (backward error {error:.2g}, or values not finite): the solver did not converge "
                             "or the matrix is singular; check the equations and their border values, or use "
                             "`solver=direct`")
        if right > 0 and worst > RESIDUAL_LIMIT * right:
            raise ModelError(f"{self.where}: the block system of {', '.join(self.unknowns)} has no solution: the "
                             f"residual of the solve is {worst / right:.2g} of the right side (the equations "
                             "contradict each other or the matrix is singular); write independent equations, e.g. "
                             "give each unknown its own equation as in app=darcy")
        return x


class UnsymmetricSystem(ModelError):
    """A solver that needs SPD matrices was handed an unsymmetric one."""

    def __init__(self, solver: str):
        super().__init__(f"solver={solver}: needs a symmetric positive definite matrix, but this system is not "
                         "symmetric; use `solver=direct` (or `solver=iterative`)")


class IncompatibleRightHandSide(ValueError):
    """The right-hand side of a singular system has a part along the kernel beyond round-off."""

    def __init__(self, relative: float):
        super().__init__(relative)
        self.relative = relative


def _symmetric(A: sp.csr_matrix) -> bool:
    difference = abs(A - A.T).max() if A.nnz else 0.0
    scale = abs(A).max() if A.nnz else 1.0
    return bool(difference <= 1e-12 * scale)


def constant_kernel(A: sp.spmatrix, pieces: np.ndarray) -> bool:
    """Whether every piece's constant vector is in A's kernel (‖A 1_c‖ ≤ 1e-10 ‖A‖)."""
    A = sp.csr_matrix(A)
    scale = abs(A).max() if A.nnz else 0.0
    if scale == 0:
        return True
    for label in np.unique(pieces):
        indicator = (pieces == label).astype(np.float64)
        if np.abs(A @ indicator).max() > 1e-10 * scale * max(1.0, np.sqrt(indicator.sum())):
            return False
    return True
