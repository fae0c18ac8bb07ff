"""The DEC operators on a simplicial complex (thesis §4.5).

``DEC(K, star=...)`` computes, lazily and cached, the exterior derivative ``d`` (§4.5.1),
the dual derivative (eq. 4.13), the diagonal Hodge stars (§4.5.4), the codifferential
(eq. 4.14), the Laplace–de Rham operators ``dδ + δd`` and the ⋆ inner product (eq. 4.15).

Hodge star variants (``star=``)
------------------------------
``circumcentric``
    The Voronoi (circumcentric) dual of §4.5.2–4.5.4 for every k and every dimension:
    ⋆_k = |⋆σ| / |σ| with **signed** dual volumes, so the dual cell of an obtuse triangle's
    circumcenter (outside the triangle, Fig. 4.17) contributes negatively and Σ ⋆0 is the
    total area exactly. On triangles ⋆1 is the cot formula ½(cot α + cot β) and ⋆0 the
    Voronoi area (§4.5.5). ⋆1 can be negative (non-Delaunay edges) or zero.
``mixed_area``
    Meyer, Desbrun, Schröder, Barr 2003: ⋆0 is the mixed Voronoi area — the Voronoi
    contribution in non-obtuse triangles; in an obtuse triangle, half its area to the
    obtuse vertex and a quarter to each other one — always positive. All other stars are
    circumcentric (⋆1 is still the cot formula and can be negative). Triangle meshes only.
``barycentric``
    ⋆0 is the lumped barycentric area |σ_top|/(n+1) summed over incident top simplices
    (always positive); all other stars are circumcentric. Any dimension.

Dual cells of border simplices are truncated at the border (they lie in the incident
top simplices only): the natural (Neumann) boundary condition of the Laplacians.
"""

from __future__ import annotations

import warnings
from itertools import combinations, permutations
from math import factorial

import numpy as np
import scipy.sparse as sp

from decrun.core.complex import SimplicialComplex, _vertex_volumes, simplex_volumes
from decrun.errors import ConfigError

__all__ = ["DEC", "STAR_VARIANTS", "circumcenter_barycentric"]

STAR_VARIANTS = ("circumcentric", "mixed_area", "barycentric")


def circumcenter_barycentric(points: np.ndarray) -> np.ndarray:
    """Barycentric coordinates of the circumcenters of simplices.

    The circumcenter of ``p_0..p_j`` is the point of their affine hull equidistant from all
    corners (§4.5.5 gives the triangle case). With ``E = [p_1-p_0, ..., p_j-p_0]`` it is
    ``p_0 + E μ`` where ``(EᵀE) μ = ½ diag(EᵀE)``.

    Parameters
    ----------
    points : (m, j+1, d) corner coordinates

    Returns
    -------
    (m, j+1) barycentric coordinates λ (rows sum to 1; negative entries mean the
    circumcenter lies outside, on the far side of the opposite face).
    """
    m, c, _ = points.shape
    if c == 1:
        return np.ones((m, 1))
    if c == 2:
        return np.full((m, 2), 0.5)
    edges = points[:, 1:, :] - points[:, :1, :]
    gram = np.einsum("mai,mbi->mab", edges, edges)
    rhs = 0.5 * np.einsum("maa->ma", gram)
    mu = np.linalg.solve(gram, rhs[..., None])[..., 0]
    return np.concatenate([1.0 - mu.sum(axis=1, keepdims=True), mu], axis=1)


class DEC:
    """Discrete exterior calculus operators on ``K`` (§4.5); everything lazy and cached.

    Parameters
    ----------
    K : SimplicialComplex
    star : {"circumcentric", "mixed_area", "barycentric"}
        The Hodge star variant (see the module docstring for what each changes).
    """

    def __init__(self, K: SimplicialComplex, star: str = "circumcentric"):
        if star not in STAR_VARIANTS:
            raise ConfigError(f"operator.star: unknown Hodge star {star!r}; choose one of {list(STAR_VARIANTS)}")
        if star == "mixed_area" and K.dim != 2:
            raise ConfigError(f"operator.star: mixed_area is defined for triangle meshes, not dimension {K.dim}")
        self.K = K
        self.n = K.dim
        self.star_variant = star
        self._cache: dict = {}

    def _cached(self, key, compute):
        if key not in self._cache:
            self._cache[key] = compute()
        return self._cache[key]

    def _check_form_degree(self, k: int, low: int = 0, high: int | None = None) -> None:
        high = self.n if high is None else high
        if not low <= k <= high:
            raise IndexError(f"form degree {k} outside {low}..{high} for a {self.n}-complex")

    # ---------------------------------------------------------------- derivatives
    def d(self, k: int) -> sp.csr_matrix:
        """Exterior derivative on primal k-forms, d_k = δ_{k+1}ᵀ (§4.5.1): (n_{k+1}, n_k)."""
        self._check_form_degree(k, 0, self.n - 1)
        return self._cached(("d", k), lambda: self.K.incidence(k + 1))

    def d_dual(self, j: int) -> sp.csr_matrix:
        """Exterior derivative on dual j-forms (eq. 4.13): d^dual_{n-k} = (-1)^k δ_k.

        Dual j-forms live on the duals of (n-j)-simplices, so the shape is
        (n_{n-j-1}, n_{n-j}).
        """
        self._check_form_degree(j, 0, self.n - 1)
        k = self.n - j
        return self._cached(("d_dual", j), lambda: ((-1) ** k * self.K.boundary(k)).tocsr())

    # ---------------------------------------------------------------- volumes
    def primal_volumes(self, k: int) -> np.ndarray:
        """(n_k,) unsigned k-volumes |σ| of the k-simplices (1 for vertices)."""
        self._check_form_degree(k)
        if k == self.n:
            return self.K._top_volumes
        return self._cached(("primal", k), lambda: _vertex_volumes(self.K.vertices, self.K.simplices(k)))

    def circumcenters(self, k: int | None = None) -> np.ndarray:
        """(n_k, d) circumcenters of the k-simplices (default: top simplices — the dual vertices)."""
        k = self.n if k is None else k
        self._check_form_degree(k)

        def compute():
            points = self.K.vertices[self.K.simplices(k)]
            lam = circumcenter_barycentric(points)
            return np.einsum("mc,mcd->md", lam, points)

        return self._cached(("circumcenter", k), compute)

    def dual_volumes(self, k: int) -> np.ndarray:
        """(n_k,) signed (n-k)-volumes |⋆σ| of the circumcentric dual cells (§4.5.2).

        Computed exactly as a sum over the flags σ = S_k ⊂ S_{k+1} ⊂ … ⊂ S_n of every
        incident top simplex: the dual cell piece is the orthoscheme on the circumcenters
        c(S_k), …, c(S_n), whose edges are mutually orthogonal, so its volume is
        Π_j h_j / (n-k)! with h_j the *signed* distance of c(S_{j+1}) from aff(S_j), positive
        towards the vertex S_{j+1} \\ S_j. Obtuse simplices thus contribute negatively.
        """
        self._check_form_degree(k)
        return self._cached(("dual", k), lambda: self._circumcentric_dual_volumes()[k])

    def _circumcentric_dual_volumes(self) -> dict[int, np.ndarray]:
        if "dual_all" in self._cache:
            return self._cache["dual_all"]
        if self.n == 2:
            self._cache["dual_all"] = self._triangle_dual_volumes()
            return self._cache["dual_all"]
        K, n = self.K, self.n
        top = K.simplices(n)
        points = K.vertices[top]  # (m, n+1, d)
        m = top.shape[0]
        subsets = {j: list(combinations(range(n + 1), j + 1)) for j in range(n + 1)}
        volume = {}
        lam = {}
        for j in range(n + 1):
            for S in subsets[j]:
                corner = points[:, list(S), :]
                volume[S] = simplex_volumes(corner)
                lam[S] = circumcenter_barycentric(corner)

        def height(S, T):
            """Signed distance of c(T) from aff(S) inside aff(T), T = S ∪ {q}."""
            q = next(v for v in T if v not in S)
            j = len(S) - 1
            return lam[T][:, T.index(q)] * (j + 1) * volume[T] / volume[S]

        heights = {}
        result = {n: np.ones(K.num_simplices(n))}
        full = tuple(range(n + 1))
        for k in range(n):
            accumulated = np.zeros((m, len(subsets[k])))
            for slot, S in enumerate(subsets[k]):
                rest = [v for v in full if v not in S]
                total = np.zeros(m)
                for order in permutations(rest):
                    product = np.ones(m)
                    chain = S
                    for q in order:
                        nxt = tuple(sorted(chain + (q,)))
                        key = (chain, nxt)
                        if key not in heights:
                            heights[key] = height(chain, nxt)
                        product = product * heights[key]
                        chain = nxt
                    total += product
                accumulated[:, slot] = total / factorial(n - k)
            result[k] = np.bincount(
                K._top_faces[k].ravel(), weights=accumulated.ravel(), minlength=K.num_simplices(k)
            )
        self._cache["dual_all"] = result
        return result

    def _triangle_dual_volumes(self) -> dict[int, np.ndarray]:
        """Closed forms of the flag sums for triangles (§4.5.5, Fig. 4.19).

        In a triangle with angle θ_i at corner i, the dual edge piece of the opposite edge
        is ½ cot θ_i |e_i| and corner i gets (|e_ij|² cot θ_k + |e_ik|² cot θ_j) / 8 of
        Voronoi area — signed, so obtuse triangles are exact.
        """
        K = self.K
        top = K.simplices(2)
        area = self.primal_volumes(2)
        # edge vectors opposite each sorted corner: e0 = p2 - p1, e1 = p0 - p2, e2 = p1 - p0,
        # one contiguous coordinate at a time, accumulated in place (few (m,) temporaries)
        m = top.shape[0]
        sq = np.zeros((3, m))  # sq[i] = |e_i|²
        dots = np.zeros((3, m))  # dots[i] = e_j · e_k for the two edges meeting at corner i
        edge = np.empty((3, m))
        columns = np.ascontiguousarray(K.vertices.T)
        for axis in range(K.embedding_dim):
            x = columns[axis]
            x0, x1, x2 = x[top[:, 0]], x[top[:, 1]], x[top[:, 2]]
            np.subtract(x2, x1, out=edge[0])
            np.subtract(x0, x2, out=edge[1])
            np.subtract(x1, x0, out=edge[2])
            del x0, x1, x2
            sq += edge * edge
            dots[0] += edge[1] * edge[2]
            dots[1] += edge[2] * edge[0]
            dots[2] += edge[0] * edge[1]
        del edge
        cot = dots  # cot θ_i = -(e_j · e_k) / (2A), computed in place
        cot *= -0.5 / area
        # dual edge piece ½ cot θ_i |e_i|; edge slots (0,1), (0,2), (1,2) are opposite corners 2, 1, 0
        dual_edge = np.sqrt(sq[::-1].T)  # (m, 3) in slot order
        dual_edge *= 0.5 * cot[::-1].T
        dual1 = np.bincount(K._top_faces[1].ravel(), weights=dual_edge.ravel(), minlength=K.num_simplices(1))
        del dual_edge
        weighted = sq * cot  # |e_i|² cot θ_i
        del sq, cot
        corner_area = np.empty((m, 3))
        np.add(weighted[2], weighted[1], out=corner_area[:, 0])
        np.add(weighted[0], weighted[2], out=corner_area[:, 1])
        np.add(weighted[1], weighted[0], out=corner_area[:, 2])
        del weighted
        corner_area *= 0.125
        dual0 = np.bincount(top.ravel(), weights=corner_area.ravel(), minlength=K.num_simplices(0))
        return {0: dual0, 1: dual1, 2: np.ones(top.shape[0])}

    # ---------------------------------------------------------------- Hodge stars
    def star_diagonal(self, k: int) -> np.ndarray:
        """(n_k,) diagonal of ⋆_k = |⋆σ| / |σ| (§4.5.4) for the selected variant."""
        self._check_form_degree(k)

        def compute():
            if k == 0 and self.star_variant == "mixed_area":
                return self._mixed_area_star0()
            if k == 0 and self.star_variant == "barycentric":
                K = self.K
                share = self.primal_volumes(self.n) / (self.n + 1)
                return np.bincount(K.simplices(self.n).ravel(), weights=np.repeat(share, self.n + 1),
                                   minlength=K.num_simplices(0))
            return self.dual_volumes(k) / self.primal_volumes(k)

        return self._cached(("star", k), compute)

    def _mixed_area_star0(self) -> np.ndarray:
        """Mixed Voronoi area (Meyer et al. 2003, Fig. 4): Voronoi in non-obtuse triangles,
        area/2 to an obtuse corner and area/4 to the two others."""
        K = self.K
        top = K.simplices(2)
        p = K.vertices[top]
        area = self.primal_volumes(2)
        contribution = np.zeros((top.shape[0], 3))
        cot = np.zeros((top.shape[0], 3))
        sq = np.zeros((top.shape[0], 3))  # squared length of the edge opposite corner i
        obtuse = np.zeros((top.shape[0], 3), dtype=bool)
        for i in range(3):
            a, b = p[:, (i + 1) % 3] - p[:, i], p[:, (i + 2) % 3] - p[:, i]
            dot = np.einsum("md,md->m", a, b)
            cot[:, i] = dot / (2.0 * area)
            obtuse[:, i] = dot < 0
            sq[:, i] = np.einsum("md,md->m", b - a, b - a)
        for i in range(3):
            j, l = (i + 1) % 3, (i + 2) % 3
            # Voronoi part of corner i: |e_ij|² cot(angle at l) + |e_il|² cot(angle at j), / 8
            contribution[:, i] = (sq[:, l] * cot[:, l] + sq[:, j] * cot[:, j]) / 8.0
        any_obtuse = obtuse.any(axis=1)
        contribution[any_obtuse] = np.where(obtuse[any_obtuse], 0.5, 0.25) * area[any_obtuse, None]
        return np.bincount(top.ravel(), weights=contribution.ravel(), minlength=K.num_simplices(0))

    def star(self, k: int) -> sp.csr_matrix:
        """⋆_k as a sparse diagonal (n_k, n_k) matrix (§4.5.4)."""
        return self._cached(("star_matrix", k), lambda: sp.diags(self.star_diagonal(k)).tocsr())

    def star_inv(self, k: int) -> sp.csr_matrix:
        """⋆_k⁻¹ as a sparse diagonal matrix. Zero dual volumes (e.g. the diagonal of a
        right-angled grid cell) give infinite entries and a warning naming them."""

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
                return sp.diags(np.where(zero, np.inf, 1.0 / np.where(zero, 1.0, diagonal))).tocsr()

        return self._cached(("star_inv", k), compute)

    # ---------------------------------------------------------------- codifferential, Laplacians
    def codifferential(self, k: int) -> sp.csr_matrix:
        """δ_k = ⋆_{k-1}⁻¹ d_{k-1}ᵀ ⋆_k (eq. 4.14): maps k-forms to (k-1)-forms, (n_{k-1}, n_k).

        Adjoint of d under the ⋆ inner product: ⟨d a, b⟩ = ⟨a, δ b⟩ (§4.5.6).
        """
        self._check_form_degree(k, 1, self.n)
        return self._cached(
            ("codifferential", k),
            lambda: (self.star_inv(k - 1) @ self.d(k - 1).T @ self.star(k)).tocsr(),
        )

    def laplacian(self, k: int) -> sp.csr_matrix:
        """Laplace–de Rham operator Δ_k = d δ + δ d on k-forms, (n_k, n_k).

        Positive semi-definite and self-adjoint under the ⋆ inner product. For k = 0 it is
        ⋆0⁻¹ d0ᵀ ⋆1 d0, the *negative* of the Laplace–Beltrami operator.
        """
        self._check_form_degree(k)

        def compute():
            size = self.K.num_simplices(k)
            result = sp.csr_matrix((size, size))
            if k > 0:
                result = result + self.d(k - 1) @ self.codifferential(k)
            if k < self.n:
                result = result + self.codifferential(k + 1) @ self.d(k)
            return result.tocsr()

        return self._cached(("laplacian", k), compute)

    def laplacian_symmetric(self, k: int) -> sp.csr_matrix:
        """⋆_k Δ_k, the symmetric positive semi-definite form of the Laplacian, (n_k, n_k).

        ⋆_k Δ_k = ⋆_k d δ + d_kᵀ ⋆_{k+1} d_k; for k = 0 this is the cot "stiffness" matrix
        d0ᵀ ⋆1 d0 and the generalized eigenproblem (⋆0 Δ0, ⋆0) gives the spectrum.
        """
        self._check_form_degree(k)

        def compute():
            size = self.K.num_simplices(k)
            result = sp.csr_matrix((size, size))
            if k > 0:
                star_d = self.star(k) @ self.d(k - 1)
                result = result + star_d @ self.star_inv(k - 1) @ star_d.T
            if k < self.n:
                result = result + self.d(k).T @ self.star(k + 1) @ self.d(k)
            return result.tocsr()

        return self._cached(("laplacian_symmetric", k), compute)

    def inner(self, k: int, a: np.ndarray, b: np.ndarray) -> np.ndarray | float:
        """⋆ inner product of k-forms, ⟨a, b⟩ = aᵀ ⋆_k b (eq. 4.15).

        ``a``, ``b``: (n_k,) or (n_k, c); returns a scalar or the (c, c) Gram matrix.
        """
        a, b = np.asarray(a), np.asarray(b)
        weighted = self.star_diagonal(k).reshape((-1,) + (1,) * (b.ndim - 1)) * b
        result = a.T @ weighted
        return float(result) if np.ndim(result) == 0 else result

    def norm(self, k: int, a: np.ndarray) -> float:
        """‖a‖ = sqrt(⟨a, a⟩) (Fig. 4.21)."""
        return float(np.sqrt(max(self.inner(k, a, a), 0.0)))

    def __repr__(self) -> str:
        return f"DEC({self.K!r}, star={self.star_variant!r})"
