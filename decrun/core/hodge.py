"""Discrete Hodge decomposition (thesis §6.3, Theorem 5).

Every discrete k-form splits ⋆-orthogonally as ω = dα + δβ + γ with γ harmonic
(dγ = 0, δγ = 0). The exact part is the ⋆-orthogonal projection onto im d_{k-1}, the
coexact part the projection onto im δ_{k+1}; both come from one sparse solve each:

    (d_{k-1}ᵀ ⋆_k d_{k-1}) α = d_{k-1}ᵀ ⋆_k ω                       exact   = d_{k-1} α
    (d_k ⋆_k⁻¹ d_kᵀ) μ       = d_k ω,   β = ⋆_{k+1}⁻¹ μ             coexact = δ_{k+1} β = ⋆_k⁻¹ d_kᵀ μ

Both matrices are singular (their kernels are ker d_{k-1} and ker d_kᵀ) but the right
sides are compatible, and the kernels do not change dα or δβ. We factorize each matrix
once with a tiny diagonal shift and remove the shift's error by iterative refinement
(α and μ only up to their kernels, which dα and δβ do not see: no kernel projection).
The decomposition is exactly orthogonal when ⋆_k is positive (e.g. Delaunay meshes for
the circumcentric ⋆1); with negative cot weights ⟨·,·⟩_⋆ is indefinite. With a Galerkin
(non-diagonal, SPD) ⋆_k = M (``operator=whitney``) it is M-orthogonal on every mesh; the
coexact part then comes from a saddle-point system (:class:`_GalerkinCoexact`), never M⁻¹.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from decrun.core.dec import DEC
from decrun.core.solvers import SingularSolve, solver_factory
from decrun.errors import MeshError

__all__ = ["HodgeParts", "HodgeDecomposer", "hodge_decomposition", "harmonic_basis"]


@dataclass
class HodgeParts:
    """ω = exact + coexact + harmonic, exact = d_{k-1} α, coexact = δ_{k+1} β.

    ``alpha`` is None for k = 0; ``beta`` is None for k = n or where ⋆_{k+1} is singular
    (the coexact part itself only needs ⋆_k⁻¹).
    """

    exact: np.ndarray
    coexact: np.ndarray
    harmonic: np.ndarray
    alpha: np.ndarray | None
    beta: np.ndarray | None


class HodgeDecomposer:
    """Factorize the two Poisson problems of degree k once; decompose many k-forms.

    Parameters
    ----------
    dec : DEC
    k : form degree, 0 ≤ k ≤ n
    solver : a solver name, a configured Solver or a factory (default ``direct``); each
        Poisson problem gets its own fresh solver (``solver_factory``).
    """

    def __init__(self, dec: DEC, k: int = 1, solver=None):
        self.dec, self.k = dec, k
        n = dec.n
        new_solver = solver_factory(solver)
        self._exact = self._coexact = None
        if k > 0:
            d = dec.d(k - 1)
            self._exact = SingularSolve(d.T @ dec.star(k) @ d, new_solver(), project=False)
        if k < n and not dec.star_is_diagonal(k):
            self._coexact = _GalerkinCoexact(dec, k, new_solver())
        elif k < n:
            star = dec.star_diagonal(k)
            zero = np.abs(star) <= 1e-12 * np.abs(star).max()
            if zero.any() and n == 3:  # the surface remedies (noise, remeshing) do not apply to tetrahedra
                raise MeshError(
                    f"Hodge decomposition of {k}-forms needs an invertible ⋆_{k}, but it is zero on "
                    f"{int(zero.sum())} simplices (e.g. {np.flatnonzero(zero)[:5].tolist()}): their circumcentric "
                    "dual cells are degenerate (right angles, as in Kuhn cubes, or cocircular tetrahedra): use the "
                    "Galerkin stars, `operator=whitney` (SPD on every mesh)")
            if zero.any():
                raise MeshError(
                    f"Hodge decomposition of {k}-forms needs an invertible ⋆_{k}, but it is zero on "
                    f"{int(zero.sum())} simplices (e.g. {np.flatnonzero(zero)[:5].tolist()}): their circumcentric dual "
                    "cells are degenerate, as on the diagonals of a split grid of cyclic quads: use the "
                    "Galerkin stars, `operator=whitney` (SPD on every mesh), perturb the mesh, "
                    "`mesh.noise=0.05`, or remesh it, `mesh.refine=isotropic`"
                )
            d = dec.d(k)
            self._coexact = SingularSolve(d @ dec.star_inv(k) @ d.T, new_solver(), project=False)

    def decompose(self, omega: np.ndarray) -> HodgeParts:
        """Split ``omega`` ((n_k,) or (n_k, s) for s forms at once) into its Hodge parts."""
        dec, k = self.dec, self.k
        omega = np.asarray(omega, dtype=np.float64)
        exact = np.zeros_like(omega)
        coexact = np.zeros_like(omega)
        alpha = beta = None
        if self._exact is not None:
            d = dec.d(k - 1)
            alpha = self._exact.solve(d.T @ (dec.star(k) @ omega))
            exact = d @ alpha
        if isinstance(self._coexact, _GalerkinCoexact):
            coexact, mu = self._coexact.solve(omega)
            beta = dec.star_solve(k + 1, mu)
        elif self._coexact is not None:
            d = dec.d(k)
            mu = self._coexact.solve(d @ omega)
            coexact = _column(1.0 / dec.star_diagonal(k), omega) * (d.T @ mu)
            star_next = dec.star_diagonal(k + 1)
            if np.all(np.abs(star_next) > 1e-12 * np.abs(star_next).max()):
                beta = _column(1.0 / star_next, mu) * mu  # else β is undefined (⋆_{k+1} not invertible)
        return HodgeParts(exact, coexact, omega - exact - coexact, alpha, beta)


class _GalerkinCoexact:
    """The coexact part for a non-diagonal (Galerkin) ⋆_k = M without forming M⁻¹.

    c = M⁻¹ d_kᵀ μ with d_k c = d_k ω is the symmetric saddle-point system

        [ M    d_kᵀ ] [  c ]   [   0   ]
        [ d_k   0   ] [ −μ ] = [ d_k ω ],

    singular in μ exactly on ker d_kᵀ (which leaves c unchanged). It is factorized once
    with −ε I in the lower block (quasi-definite, so LU needs no pivoting there) and the
    regularization is removed by iterative refinement against the exact system. The matrix
    is indefinite: it needs a direct solver (``direct``, ``pardiso``), not cg/amg.
    """

    def __init__(self, dec: DEC, k: int, solver, shift: float = 1e-10, tol: float = 1e-13, max_steps: int = 30):
        M = sp.csr_matrix(dec.star(k))
        self.d = dec.d(k)
        self.n = M.shape[0]
        m = self.d.shape[0]
        self.A = sp.bmat([[M, self.d.T], [self.d, None]], format="csr")
        scale = float(np.abs(M.diagonal()).mean()) or 1.0
        regularized = self.A + sp.diags(np.concatenate([np.zeros(self.n), np.full(m, -shift * scale)]))
        self.solver = solver
        self.solver.factorize(regularized.tocsc())
        self.tol, self.max_steps = tol, max_steps

    def solve(self, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(coexact part c, μ = M_{k+1} β) for ``omega`` (n_k,) or (n_k, s)."""
        top = self.d @ omega
        b = np.concatenate([np.zeros_like(omega), top])
        x = np.zeros_like(b)
        residual = b.copy()
        norm_b = float(np.linalg.norm(b)) or 1.0
        for _ in range(self.max_steps):
            if np.linalg.norm(residual) <= self.tol * norm_b:
                break
            x = x + np.asarray(self.solver.solve(residual), dtype=np.float64)
            residual = b - self.A @ x
        return x[: self.n], -x[self.n:]


def _column(values: np.ndarray, like: np.ndarray) -> np.ndarray:
    return values.reshape((-1,) + (1,) * (like.ndim - 1))


def hodge_decomposition(dec: DEC, omega: np.ndarray, k: int = 1, solver=None) -> HodgeParts:
    """Hodge decomposition of a k-form (Theorem 5): ω = dα + δβ + γ.

    Parameters
    ----------
    dec : DEC operators of the complex
    omega : (n_k,) the k-form (or (n_k, s) for several)
    k : form degree
    solver : solver name or instance for the two Poisson problems

    Returns
    -------
    HodgeParts with exact = d_{k-1} α, coexact = δ_{k+1} β (β a (k+1)-form), harmonic γ.
    """
    return HodgeDecomposer(dec, k, solver).decompose(omega)


def harmonic_basis(dec: DEC, k: int = 1, solver=None, samples: int = 16, seed: int = 0,
                   rank_tol: float = 1e-8) -> np.ndarray:
    """A ⋆-orthonormal basis of the harmonic k-forms (ker Δ_k, §6.3.5).

    Random k-forms are stripped of their exact and coexact parts; the numerical rank of
    what remains is the dimension of the harmonic space (= Betti_k for the unadapted
    operators). If all ``samples`` stay independent, the number of samples is doubled.

    Returns
    -------
    (n_k, h) array with ⟨γ_i, γ_j⟩ = δ_ij; h = 0 gives an (n_k, 0) array.
    """
    decomposer = HodgeDecomposer(dec, k, solver)
    rng = np.random.default_rng(seed)
    size = dec.K.num_simplices(k)
    count = min(samples, size)
    while True:
        random_forms = rng.standard_normal((size, count))
        harmonic = decomposer.decompose(random_forms).harmonic
        gram = dec.inner(k, harmonic, harmonic)
        scale = np.trace(dec.inner(k, random_forms, random_forms)) / count
        values, vectors = np.linalg.eigh(0.5 * (gram + gram.T))
        keep = values > rank_tol * scale
        if keep.sum() < count or count >= size:
            break
        count = min(2 * count, size)
    return harmonic @ (vectors[:, keep] / np.sqrt(values[keep]))
