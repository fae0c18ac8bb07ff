"""Numerical kernels shared by the methods: singular PSD solves and fixed values.

* :class:`SingularSolve` — A x = b for a symmetric positive *semi*-definite A with b ∈ im A
  (Poisson problems on closed meshes, least squares with a kernel): factorize A + εW once,
  then iterative refinement x ← x + (A + εW)⁻¹ P (b − A x) (P: the projection onto im A
  along the kernel A's zero row sums give away, :func:`constant_kernel`), and project the
  kernel out of x: the result is the solution W-orthogonal to ker A, the same for every solver.
* :func:`solve_with_fixed` — A x = b with some entries of x given
  (Dirichlet values, pinned vertices), by eliminating them (scikit-fem's ``condense``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["SingularSolve", "constant_kernel", "solve_with_fixed"]


def constant_kernel(A, rtol: float = 1e-12) -> np.ndarray:
    """(n, h) the indicators of the connected components C of A's graph (i ~ j when A_ij ≠ 0)
    whose rows sum to zero, |Σ_j A_ij| ≤ ``rtol`` max|A| on every row of C: then A 1_C = 0, so
    1_C ∈ ker A. The known part of ker A: the constants of the 0-form Laplacian d0ᵀ ⋆1 d0 on
    each piece of a mesh (ker d0), and the consistently oriented top forms of the coexact
    system d_{n-1} ⋆⁻¹ d_{n-1}ᵀ on each closed piece (ker d_{n-1}ᵀ, Hⁿ), the kernels of the
    thesis' Hodge decomposition (§6.3). Columns are 0/1, one per such component; (n, 0)
    when none (a Dirichlet border, or a kernel that is not constant). Sparse (CSC, n nonzeros
    at most): a mesh of many pieces has as many columns."""
    from scipy.sparse.csgraph import connected_components

    A = sp.csr_matrix(A)
    n = A.shape[0]
    if n == 0 or A.nnz == 0:
        return sp.csc_matrix((n, 0))
    count, label = connected_components(A, directed=False)
    scale = float(np.abs(A.data).max())
    off = np.abs(np.asarray(A.sum(axis=1)).ravel()) > rtol * scale
    closed = np.ones(count, dtype=bool)
    closed[label[off]] = False
    keep = np.flatnonzero(closed)
    where = np.searchsorted(keep, label)
    inside = closed[label]
    rows = np.flatnonzero(inside)
    return sp.csc_matrix((np.ones(rows.size), (rows, where[inside])), shape=(n, keep.size))


class SingularSolve:
    """Solve A x = b for symmetric PSD, possibly singular A and consistent b.

    The answer is the solution W-orthogonal to ker A (Zᵀ W x = 0 for a kernel basis Z),
    whatever the solver. In exact arithmetic (A + εW)⁻¹ gives it by itself (ε zᵀ W x =
    zᵀ b = 0), but a solve that stops at a residual r — an iterative one at its ``tol``, a
    backward-stable LU at u ‖A‖ ‖x‖ — leaves a kernel component ~ ‖r‖ / ε that the
    refinement (which sees only A x) never removes. Measured on ω of the Fig. 6.9 square with
    boundary=flux (no strokes): 1.3 % with cg, 4.5e-4 amg, 4.5e-8 iterative, 2e-8 direct
    itself. So the kernel is computed once (:meth:`kernel_basis`) and projected out of every
    solution, x ← x − Z Zᵀ W x; the solvers then agree to ≤ 1e-9.

    The part of ker A that A's zero row sums give away (:func:`constant_kernel`, the
    constants of a closed mesh's Laplacian) is removed from every right-hand side the solver
    sees, r ← r − Z_c (Z_cᵀ Z_c)⁻¹ Z_cᵀ r (im A = (ker A)^⊥ for symmetric A), and from every
    solution, also with ``project=False`` (it costs no solve). Without it a right-hand side
    with a kernel part of round-off — a refinement residual, whose round-off is no longer
    small beside it — asks (A + εW)⁻¹ for a part ~ 1/ε along the kernel, which an iterative
    solver (amg) does not reach and may diverge on. A b with a kernel part beyond round-off
    is solved in the least-squares sense, A x = P b; :attr:`kernel_part` says how much of the
    last b that was, ‖(I − P) b‖ / ‖b‖.
    Parameters
    ----------
    A : (n, n) sparse symmetric PSD
    solver : a fresh decrun Solver; ``A + ε W`` is factorized once
    weight : (n,) positive diagonal W of the shift (default: identity)
    shift : ε relative to mean|diag A| / mean W
    tol, max_steps : refinement stops when ‖b − A x‖ ≤ tol ‖b‖ or after max_steps
    project : False skips the kernel (and its solves) for a caller that only uses A x — the
        Hodge parts d α, δ β — and accepts x up to ker A (but for the constant kernel)
    """

    def __init__(self, A, solver, weight: np.ndarray | None = None, shift: float = 1e-10,
                 tol: float = 1e-14, max_steps: int = 30, project: bool = True):
        self.A = sp.csr_matrix(A)
        n = self.A.shape[0]
        weight = np.ones(n) if weight is None else np.asarray(weight, dtype=np.float64)
        scale = float(np.abs(self.A.diagonal()).mean() / weight.mean()) if n else 1.0
        self.weight = weight
        self.solver = solver
        self.solver.factorize((self.A + sp.diags((shift * (scale or 1.0)) * weight)).tocsc())
        self.tol, self.max_steps = tol, max_steps
        self.project = project
        self._kernel: np.ndarray | None = None
        self.steps = 0  # refinement steps of the last solve
        #: ‖(I − P) b‖ / ‖b‖ of the last b (per column for b of shape (n, s)): its part along the constant kernel
        self.kernel_part: np.ndarray | float = 0.0
        constant = constant_kernel(self.A)
        sizes = np.asarray(constant.sum(axis=0)).ravel()
        # Euclidean-orthonormal: P r = r − Q Qᵀ r; W-orthonormal: x − Z Zᵀ W x (both sparse, n × h)
        self._range_basis = (constant @ sp.diags(1.0 / np.sqrt(sizes))).tocsc()
        self._constant_w = (constant @ sp.diags(1.0 / np.sqrt(constant.T @ weight))).tocsc()

    def _to_range(self, r: np.ndarray) -> np.ndarray:
        """``r`` without its part along the constant kernel: P r, P the projection onto im A."""
        Q = self._range_basis
        return r - Q @ (Q.T @ r) if Q.shape[1] else r

    def _without_constants(self, x: np.ndarray) -> np.ndarray:
        """``x`` without its W-part along the constant kernel (W-orthogonal to it)."""
        Z = self._constant_w
        if not Z.shape[1]:
            return x
        return x - Z @ (Z.T @ (self.weight.reshape((-1,) + (1,) * (x.ndim - 1)) * x))

    def _refine(self, b: np.ndarray) -> np.ndarray:
        """x with A x = P b to ``tol``: refinement with every residual projected onto im A."""
        b = self._to_range(b)
        x = np.zeros_like(b)
        norm_b = float(np.linalg.norm(b)) or 1.0
        residual = b.copy()
        self.steps = 0
        while self.steps < self.max_steps and np.linalg.norm(residual) > self.tol * norm_b:
            x = self._without_constants(x + np.asarray(self.solver.solve(residual), dtype=np.float64))
            residual = self._to_range(b - self.A @ x)
            self.steps += 1
        return x

    def kernel_basis(self, block: int = 4, seed: int = 0, rank_tol: float = 1e-8) -> np.ndarray:
        """(n, h) W-orthonormal basis of ker A (Zᵀ W Z = I), computed once with the solver.

        For random R (n, p), Y = refined solve of A Y = A R is R up to a kernel part, so the
        columns of R − Y lie in ker A (‖A (R − Y)‖ = the refined residual); their numerical
        W-rank (singular values above ``rank_tol`` × those of R) is h, and p doubles while
        all p columns stay independent. Costs p refined solves (p = 4 for h < 4)."""
        if self._kernel is not None:
            return self._kernel
        n = self.A.shape[0]
        root = np.sqrt(self.weight)
        rng = np.random.default_rng(seed)
        count = min(block, n)
        while True:
            R = rng.standard_normal((n, count))
            Z = R - self._refine(self.A @ R)
            U, s, _ = np.linalg.svd(root[:, None] * Z, full_matrices=False)
            reference = np.linalg.norm(root[:, None] * R, 2)
            keep = s > rank_tol * reference
            if keep.sum() < count or count >= n:
                break
            count = min(2 * count, n)
        self._kernel = U[:, keep] / root[:, None]
        return self._kernel

    def solve(self, b: np.ndarray) -> np.ndarray:
        """x with A x = b (the solution W-orthogonal to ker A); b (n,) or (n, s)."""
        b = np.asarray(b, dtype=np.float64)
        norms = np.atleast_1d(np.linalg.norm(b, axis=0))
        removed = np.atleast_1d(np.linalg.norm(b - self._to_range(b), axis=0))
        part = np.where(norms > 0, removed / np.where(norms > 0, norms, 1.0), 0.0)
        self.kernel_part = float(part[0]) if b.ndim == 1 else part
        if not self.project:
            return self._refine(b)
        Z = self.kernel_basis()
        x = self._refine(b)
        if Z.shape[1]:
            x = x - Z @ (Z.T @ (self.weight.reshape((-1,) + (1,) * (x.ndim - 1)) * x))
        return x

    def relative_residual(self, x: np.ndarray, b: np.ndarray) -> float:
        """‖b − A x‖ / ‖b‖ (‖b − A x‖ when b = 0)."""
        r = float(np.linalg.norm(b - self.A @ x))
        norm_b = float(np.linalg.norm(b))
        return r / norm_b if norm_b > 0 else r


def solve_with_fixed(A, b: np.ndarray, fixed: np.ndarray, values: np.ndarray, solver,
                     least_squares: bool = False) -> np.ndarray:
    """x with x[fixed] = values solving the remaining equations of A x = b, by eliminating the
    fixed unknowns (scikit-fem's ``condense``).

    Square A: the free rows, A_ff x_f = b_f − A_fd values. ``least_squares=True`` (A may be
    rectangular): min ‖A x − b‖ over x_f through the normal equations A_fᵀ A_f x_f = A_fᵀ b_f,
    A_f = A[:, free] and b_f = b − A[:, fixed] values.
    ``solver`` is a fresh decrun Solver (factorized once here).
    """
    A = sp.csr_matrix(A)
    fixed = np.asarray(fixed, dtype=np.int64)
    values = np.asarray(values, dtype=np.float64)
    free = np.setdiff1d(np.arange(A.shape[1]), fixed)
    rows = A if least_squares else A[free]
    A_free = rows[:, free].tocsc()
    rhs = np.asarray(b, dtype=np.float64)[slice(None) if least_squares else free] - rows[:, fixed] @ values
    if least_squares:
        rhs = A_free.T @ rhs
        A_free = (A_free.T @ A_free).tocsc()
    x = np.empty(A.shape[1])
    x[fixed] = values
    x[free] = solver.factorize(A_free).solve(rhs)
    return x
