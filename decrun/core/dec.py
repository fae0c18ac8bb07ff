"""The DEC operators on a simplicial complex (thesis §4.5).

``DEC(K, star=..., boundary=...)`` computes, lazily and cached (:class:`decrun.core.cache.Cached`),
the exterior derivative ``d`` (§4.5.1), the dual derivative (eq. 4.13), the Hodge stars of
the chosen variant (§4.5.4, :mod:`decrun.core.stars`), the codifferential (eq. 4.14) with
the chosen boundary adaptation (:mod:`decrun.core.boundary`), the Laplace–de Rham operators
``dδ + δd`` and the ⋆ inner product (eq. 4.15).

The variant objects supply the numbers; DEC never branches on their names. A variant
whose ⋆_k is not diagonal (Galerkin stars) is never inverted explicitly: ``star_solve``
applies ⋆_k⁻¹ by a factorization made once, and the operators that contain ⋆⁻¹
(codifferential, Laplacian) are then ``scipy.sparse.linalg.LinearOperator``s.
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

# the variants' resolver and the default adaptation load with DEC, not on the first DEC built
from decrun.core import plugins as _plugins  # noqa: F401
from decrun.core.boundary import BoundaryAdaptation, boundary_adaptation
from decrun.core.boundary import none as _default_boundary  # noqa: F401
from decrun.core.cache import Cached
from decrun.core.complex import SimplicialComplex
from decrun.core.simplex_arrays import vertex_volumes
from decrun.core.stars import HodgeStar, star_variant
from decrun.core.stars.circumcentric import circumcenter_barycentric, circumcentric_dual_volumes
from decrun.errors import ConfigError

if TYPE_CHECKING:
    from scipy.sparse.linalg import LinearOperator
# scipy.sparse.linalg (and scipy.linalg under it, ~0.1 s of CPU) is imported where a non-diagonal
# star is solved: building a complex and its diagonal operators does not load it

__all__ = ["DEC", "circumcenter_barycentric", "diagonal_matrix"]


def diagonal_matrix(diagonal: np.ndarray) -> sp.csr_matrix:
    """(n, n) CSR with ``diagonal`` on its diagonal — ``sp.diags(diagonal).tocsr()`` (which
    leaves zero entries out), built directly when no entry is zero: the matrix holds the float64
    ``diagonal`` itself as its data (no copy; the caller hands over an array it does not change)
    and one ``0..n`` array as both its row pointers and, without its last entry, its column
    indices."""
    diagonal = np.asarray(diagonal, dtype=np.float64)
    if not diagonal.all():
        return sp.diags(diagonal).tocsr()
    n = diagonal.shape[0]
    index_type = np.int32 if n < 2**31 - 1 else np.int64
    pointers = np.arange(n + 1, dtype=index_type)
    return sp.csr_matrix((diagonal, pointers[:n], pointers), shape=(n, n), copy=False)


class DEC(Cached):
    """Discrete exterior calculus operators on ``K`` (§4.5); everything lazy and cached.

    Parameters
    ----------
    K : SimplicialComplex
    star : str or HodgeStar
        The Hodge-star variant: a :class:`decrun.core.stars.HodgeStar` instance or the name of
        a built-in one (``circumcentric`` (default), ``mixed_area``, ``barycentric``, …).
    boundary : str or BoundaryAdaptation
        The boundary adaptation (``none`` (default), ``flux``, …).
    """

    def __init__(self, K: SimplicialComplex, star: str | HodgeStar = "circumcentric",
                 boundary: str | BoundaryAdaptation = "none"):
        self.K = K
        self.n = K.dim
        self.star_variant = star_variant(star)
        self.star_variant.check(K)
        self.boundary = boundary_adaptation(boundary)
        self.boundary.check(K)

    def _check_form_degree(self, k: int, low: int = 0, high: int | None = None) -> None:
        high = self.n if high is None else high
        if not low <= k <= high:
            raise IndexError(f"form degree {k} outside {low}..{high} for a {self.n}-complex")

    def _check_variant_degree(self, k: int) -> None:
        degrees = self.star_variant.form_degrees
        if degrees is not None and k not in degrees:
            raise ConfigError(f"operator={self.star_variant.name} provides ⋆_k on the mesh's own simplices only for "
                              f"k in {list(degrees)}, not k = {k}")

    # ---------------------------------------------------------------- derivatives
    def d(self, k: int) -> sp.csr_matrix:
        """Exterior derivative on primal k-forms, d_k = δ_{k+1}ᵀ (§4.5.1): (n_{k+1}, n_k)."""
        self._check_form_degree(k, 0, self.n - 1)
        return self.require(("d", k), lambda: self.K.incidence(k + 1))

    def d_dual(self, j: int) -> sp.csr_matrix:
        """Exterior derivative on dual j-forms (eq. 4.13): d^dual_{n-k} = (-1)^k δ_k.

        Dual j-forms live on the duals of (n-j)-simplices, so the shape is
        (n_{n-j-1}, n_{n-j}).
        """
        self._check_form_degree(j, 0, self.n - 1)
        k = self.n - j
        return self.require(("d_dual", j), lambda: ((-1) ** k * self.K.boundary(k)).tocsr())

    # ---------------------------------------------------------------- volumes
    def primal_volumes(self, k: int) -> np.ndarray:
        """(n_k,) unsigned k-volumes |σ| of the k-simplices (1 for vertices)."""
        self._check_form_degree(k)
        if k == self.n:
            return self.K.top_volumes
        if k == 0:
            return self.require(("primal", 0), lambda: np.ones(self.K.num_simplices(0)))
        if k == 1:  # the complex's own (cached; a triangle mesh's circumcentric dual volumes find them on the way)
            return self.K.edge_lengths()
        return self.require(("primal", k), lambda: vertex_volumes(self.K.vertices, self.K.simplices(k)))

    def circumcenters(self, k: int | None = None) -> np.ndarray:
        """(n_k, d) circumcenters of the k-simplices (default: top simplices — the dual vertices)."""
        k = self.n if k is None else k
        self._check_form_degree(k)

        def compute():
            points = self.K.vertices[self.K.simplices(k)]
            lam = circumcenter_barycentric(points)
            return np.einsum("mc,mcd->md", lam, points)

        return self.require(("circumcenter", k), compute)

    def dual_volumes(self, k: int) -> np.ndarray:
        """(n_k,) signed (n-k)-volumes |⋆σ| of the circumcentric dual cells (§4.5.2; see
        :func:`decrun.core.stars.circumcentric.circumcentric_dual_volumes`)."""
        self._check_form_degree(k)
        return self.require("dual_volumes", lambda: circumcentric_dual_volumes(self.K))[k]

    # ---------------------------------------------------------------- Hodge stars
    def star_is_diagonal(self, k: int) -> bool:
        """True when the variant's ⋆_k is diagonal (asked without computing it)."""
        return self.star_variant.is_diagonal(self.K, k)

    def star_diagonal_or_none(self, k: int) -> np.ndarray | None:
        """(n_k,) diagonal of ⋆_k, or None for a non-diagonal variant. The array is cached and
        read-only: ``star(k)`` holds it as its data, so writing into it would change both."""
        self._check_form_degree(k)
        self._check_variant_degree(k)
        if not self.star_is_diagonal(k):
            return None

        def compute():
            diagonal = np.asarray(self.star_variant.diagonal(self, k), dtype=np.float64)
            diagonal.setflags(write=False)
            return diagonal

        return self.require(("star_diagonal", k), compute)

    def star_diagonal(self, k: int) -> np.ndarray:
        """(n_k,) diagonal of ⋆_k = |⋆σ| / |σ| (§4.5.4) for the selected variant.

        Raises :class:`ConfigError` for a variant whose ⋆_k is not diagonal (use ``star``,
        ``star_solve`` or the variant's lumped option).
        """
        diagonal = self.star_diagonal_or_none(k)
        if diagonal is None:
            raise ConfigError(f"operator={self.star_variant.name}: ⋆_{k} is not diagonal; this computation needs a "
                              f"diagonal star (use `operator.lumped=true`, or a "
                              f"diagonal variant such as `operator=circumcentric`)")
        return diagonal

    def star(self, k: int) -> sp.csr_matrix:
        """⋆_k as a sparse symmetric (n_k, n_k) matrix (diagonal for the DEC variants)."""
        self._check_form_degree(k)
        self._check_variant_degree(k)

        def compute():
            diagonal = self.star_diagonal_or_none(k)
            return diagonal_matrix(diagonal) if diagonal is not None else self.star_variant.matrix(self, k).tocsr()

        return self.require(("star", k), compute)

    def star_inv(self, k: int) -> sp.csr_matrix:
        """⋆_k⁻¹ as a sparse diagonal matrix (diagonal variants only). Zero dual volumes
        (e.g. the diagonal of a right-angled grid cell) give infinite entries and a warning."""

        def compute():
            diagonal = self.star_diagonal(k)
            scale = np.abs(diagonal).max() if diagonal.size else 1.0
            zero = np.abs(diagonal) <= 1e-14 * scale
            if zero.any():
                warnings.warn(
                    f"⋆_{k} is zero on {int(zero.sum())} simplices (e.g. {np.flatnonzero(zero)[:5].tolist()}): "
                    f"their dual cells are degenerate (right angles); ⋆_{k}⁻¹ is infinite there",
                    RuntimeWarning,
                    stacklevel=3,
                )
            with np.errstate(divide="ignore"):
                return diagonal_matrix(np.where(zero, np.inf, 1.0 / np.where(zero, 1.0, diagonal)))

        return self.require(("star_inv", k), compute)

    def star_solve(self, k: int, b: np.ndarray) -> np.ndarray:
        """⋆_k⁻¹ b for b of shape (n_k,) or (n_k, c): a division for diagonal stars, else a
        solve with the factorization of ⋆_k made once (⋆_k⁻¹ is never formed)."""
        b = np.asarray(b, dtype=np.float64)
        diagonal = self.star_diagonal_or_none(k)
        if diagonal is not None:
            return b / diagonal.reshape((-1,) + (1,) * (b.ndim - 1))
        factor = self.require(("star_factor", k), lambda: _linalg().factorized(self.star(k).tocsc()))
        if b.ndim == 1:
            return factor(b)
        return np.column_stack([factor(b[:, j]) for j in range(b.shape[1])])

    # ---------------------------------------------------------------- codifferential, Laplacians
    def codifferential(self, k: int) -> sp.csr_matrix | LinearOperator:
        """δ_k = (−1)^k ⋆_{k-1}⁻¹ d^dual_{n-k} ⋆_k = ⋆_{k-1}⁻¹ d_{k-1}ᵀ ⋆_k (§4.5.6, eq. 4.13,
        4.14): maps k-forms to (k-1)-forms, (n_{k-1}, n_k).

        Adjoint of d under the ⋆ inner product: ⟨d a, b⟩ = ⟨a, δ b⟩ (§4.5.6) — unless the
        boundary adaptation replaces it (``boundary=flux`` for k = 1, §6.4.4). A sparse
        matrix for diagonal stars; a ``LinearOperator`` (factorized ⋆_{k-1} solve) otherwise.
        """
        self._check_form_degree(k, 1, self.n)

        def compute():
            adapted = self.boundary.codifferential(self, k)
            if adapted is not None:
                return adapted
            # the thesis' form ∂_k = (−1)^k ⋆⁻¹ d^dual_{n−k} ⋆ (§4.5.6); by eq. 4.13
            # (−1)^k d^dual_{n−k} = d_{k−1}ᵀ exactly, so this is eq. 4.14
            weak = ((-1) ** k * self.d_dual(self.n - k) @ self.star(k)).tocsr()
            if self.star_is_diagonal(k - 1):
                return (self.star_inv(k - 1) @ weak).tocsr()
            return _linalg().LinearOperator(weak.shape, matvec=lambda x: self.star_solve(k - 1, weak @ x), dtype=np.float64)

        return self.require(("codifferential", k), compute)

    def laplacian(self, k: int) -> sp.csr_matrix | LinearOperator:
        """Laplace–de Rham operator Δ_k = d δ + δ d on k-forms, (n_k, n_k).

        Positive semi-definite and self-adjoint under the ⋆ inner product. For k = 0 it is
        ⋆0⁻¹ d0ᵀ ⋆1 d0, the *negative* of the Laplace–Beltrami operator. Equals
        ⋆_k⁻¹ ``laplacian_symmetric(k)``; a ``LinearOperator`` for non-diagonal ⋆_k.
        """
        self._check_form_degree(k)

        def compute():
            if k == 0 and self.star_is_diagonal(0):  # ⋆0⁻¹ (the variant's stiffness), unadapted
                return (self.star_inv(0) @ self.laplacian_symmetric(0)).tocsr()
            if self.star_is_diagonal(k) and all(self.star_is_diagonal(j) for j in (k - 1,) if j >= 0):
                size = self.K.num_simplices(k)
                result = sp.csr_matrix((size, size))
                if k > 0:
                    result = result + self.d(k - 1) @ self.codifferential(k)
                if k < self.n:
                    result = result + self.codifferential(k + 1) @ self.d(k)
                return result.tocsr()
            symmetric = self.laplacian_symmetric(k)
            return _linalg().LinearOperator(symmetric.shape, matvec=lambda x: self.star_solve(k, symmetric @ x),
                                       dtype=np.float64)

        return self.require(("laplacian", k), compute)

    def laplacian_symmetric(self, k: int) -> sp.csr_matrix | LinearOperator:
        """⋆_k Δ_k, the symmetric positive semi-definite (weak) form of the Laplacian, (n_k, n_k).

        ⋆_k Δ_k = ⋆_k d δ + d_kᵀ ⋆_{k+1} d_k; for k = 0 this is the cot "stiffness" matrix
        d0ᵀ ⋆1 d0 (or the variant's own stiffness, e.g. of the intrinsic Delaunay mesh) and
        the generalized eigenproblem (⋆0 Δ0, ⋆0) gives the spectrum. For k > 0 the first term
        contains ⋆_{k-1}⁻¹: a sparse matrix for a diagonal ⋆_{k-1}, else a LinearOperator.
        """
        self._check_form_degree(k)

        def compute():
            if k == 0:
                return self.star_variant.stiffness(self).tocsr()
            size = self.K.num_simplices(k)
            up = self.d(k).T @ self.star(k + 1) @ self.d(k) if k < self.n else sp.csr_matrix((size, size))
            star_d = (self.star(k) @ self.d(k - 1)).tocsr()
            if self.star_is_diagonal(k - 1):
                return (star_d @ self.star_inv(k - 1) @ star_d.T + up).tocsr()
            up = up.tocsr()
            return _linalg().LinearOperator((size, size), dtype=np.float64,
                                       matvec=lambda x: star_d @ self.star_solve(k - 1, star_d.T @ x) + up @ x)

        return self.require(("laplacian_symmetric", k), compute)

    def inner(self, k: int, a: np.ndarray, b: np.ndarray) -> np.ndarray | float:
        """⋆ inner product of k-forms, ⟨a, b⟩ = aᵀ ⋆_k b (eq. 4.15).

        ``a``, ``b``: (n_k,) or (n_k, c); returns a scalar or the (c, c) Gram matrix.
        """
        a, b = np.asarray(a), np.asarray(b)
        diagonal = self.star_diagonal_or_none(k)
        weighted = diagonal.reshape((-1,) + (1,) * (b.ndim - 1)) * b if diagonal is not None else self.star(k) @ b
        result = a.T @ weighted
        return float(result) if np.ndim(result) == 0 else result

    def norm(self, k: int, a: np.ndarray) -> float:
        """‖a‖ = sqrt(⟨a, a⟩) (Fig. 4.21)."""
        return float(np.sqrt(max(self.inner(k, a, a), 0.0)))

    def __repr__(self) -> str:
        return f"DEC({self.K!r}, star={self.star_variant.describe()!r}, boundary={self.boundary.name!r})"


def _linalg():
    """scipy.sparse.linalg, imported on first use (see the imports)."""
    import scipy.sparse.linalg

    return scipy.sparse.linalg
