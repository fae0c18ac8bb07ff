"""Galerkin (Whitney) Hodge stars: the mass matrices of Whitney k-forms.

The Whitney k-form of the k-simplex [v_0 … v_k] (Whitney 1957; Bossavit 1988; Arnold,
Falk, Winther 2006 §5) is

    W = k! Σ_p (-1)^p λ_{v_p} dλ_{v_0} ∧ … ∧ \\widehat{dλ_{v_p}} ∧ … ∧ dλ_{v_k}

with λ the barycentric coordinates (P1 hat functions). Its mass matrix

    (M_k)_{στ} = ∫ ⟨W_σ, W_τ⟩ dV                                                   (1)

is the Galerkin replacement of the diagonal Hodge star ⋆_k (§4.5.4): symmetric positive
definite on every non-degenerate mesh (the W_σ are linearly independent), obtuse and
right-angled simplices included. On one top simplex σ_n, with G_ij = ∇λ_i·∇λ_j and
∫ λ_a λ_b = |σ_n| (1 + δ_ab) / ((n+1)(n+2)),

    ∫ ⟨W_I, W_J⟩ = (k!)² Σ_{p,q} (-1)^{p+q} ∫λ_{i_p} λ_{j_q} · det G[I \\ i_p, J \\ j_q]   (2)

(the inner product of two wedges of 1-forms is the Gram determinant). Special cases:
M_0 is the P1 mass matrix |σ|/((n+1)(n+2))·(1 + δ_ab); M_n = diag(1/|σ_n|).
The de Rham map commutes with d on Whitney forms, so d_0ᵀ M_1 d_0 is the P1 stiffness
matrix — on triangles the cotangent Laplacian, on tetrahedra the P1 Laplacian.

Orientation: every k-simplex (k < n) is the sorted tuple of ``K.simplices(k)``; a local
face of a top simplex (whose row is sorted) is a sub-tuple in increasing order, so local and
global orientations agree and no sign enters (2). For k = n the sign (``K.orientation``)
appears squared in M_n. Everything is vectorized over top simplices; loops run over the
C(n+1, k+1)² local pairs only.
"""

from __future__ import annotations

from itertools import combinations
from math import factorial

import numpy as np
import scipy.sparse as sp

from decrun.core.complex import SimplicialComplex

__all__ = ["whitney_mass_matrix", "whitney_lumped_mass"]


def _check(K: SimplicialComplex, k: int) -> None:
    if K.dim not in (2, 3):
        raise ValueError(
            f"Whitney mass matrices are implemented for triangle and tetrahedral meshes, not dimension {K.dim}")
    if not 0 <= k <= K.dim:
        raise IndexError(f"form degree {k} outside 0..{K.dim}")


def _index_dtype(*sizes: int):
    return np.int32 if max(sizes) < 2**31 - 1 else np.int64


def _cross(u, v):
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


def _dot(u, v):
    total = u[0] * v[0]
    for axis in range(1, len(u)):
        total += u[axis] * v[axis]
    return total


def _parity(perm) -> float:
    inversions = sum(perm[i] > perm[j] for i in range(len(perm)) for j in range(i + 1, len(perm)))
    return -1.0 if inversions % 2 else 1.0


class _TopGeometry:
    """Per-top-simplex arrays for eq. (2): volumes, G_ij = ∇λ_i·∇λ_j and Gram determinants.

    Triangles (in R² or R³, or R^d through Lagrange's identity): with e_1 = p_1 − p_0, e_2 = p_2 − p_0 and g = [e_i·e_j], the
    gradients of λ_1, λ_2 have Gram matrix g⁻¹ = adj(g) / |e_1×e_2|² (determinant from the
    cross product, not from g, so thin triangles keep their accuracy). Tetrahedra (in R³):
    ∇λ_1 = e_2×e_3 / D, ∇λ_2 = e_3×e_1 / D, ∇λ_3 = e_1×e_2 / D with D = e_1·(e_2×e_3).
    Always ∇λ_0 = −Σ_i ∇λ_i. Every array is (n_n,); components are handled one at a time.
    """

    def __init__(self, K: SimplicialComplex):
        n, d = K.dim, K.embedding_dim
        if n == 3 and d != 3:
            raise ValueError(f"tetrahedral meshes must have vertices in R³, not R^{d}")
        top = K.simplices(n)
        columns = np.ascontiguousarray(K.vertices.T)
        edges = [[None] * d for _ in range(n)]
        for axis in range(d):
            x = columns[axis]
            x0 = x[top[:, 0]]
            for i in range(n):
                edges[i][axis] = x[top[:, i + 1]] - x0
        del columns
        self.n = n
        self.metric = {}  # g_ij = e_i·e_j, 1-based like the vertices p_1..p_n
        for i in range(n):
            for j in range(i, n):
                self.metric[i + 1, j + 1] = self.metric[j + 1, i + 1] = _dot(edges[i], edges[j])
        gram = {}
        g = self.metric
        if n == 2:
            if d == 2:
                det = edges[0][0] * edges[1][1] - edges[0][1] * edges[1][0]
                det *= det
            elif d == 3:
                det = _dot(*[_cross(edges[0], edges[1])] * 2)
            else:  # R^d, d > 3 (e.g. the flat torus in R⁴): Lagrange's identity |e1|²|e2|² − (e1·e2)²
                det = g[1, 1] * g[2, 2] - g[1, 2] * g[1, 2]
            gram[1, 1], gram[2, 2], gram[1, 2] = g[2, 2] / det, g[1, 1] / det, -g[1, 2] / det
            self.volume = 0.5 * np.sqrt(det)
        else:
            gradients = [_cross(edges[1], edges[2]), _cross(edges[2], edges[0]), _cross(edges[0], edges[1])]
            D = _dot(edges[0], gradients[0])
            self.inverse_d2 = 1.0 / (D * D)
            for i in range(3):
                for j in range(i, 3):
                    gram[i + 1, j + 1] = _dot(gradients[i], gradients[j]) * self.inverse_d2
            self.volume = np.abs(D) / 6.0
        del edges
        for j in range(1, n + 1):  # G_0j = −Σ_i G_ij
            total = None
            for i in range(1, n + 1):
                entry = gram[min(i, j), max(i, j)]
                total = -entry if total is None else total - entry
            gram[0, j] = total
        total = -gram[0, 1]
        for j in range(2, n + 1):
            total = total - gram[0, j]
        gram[0, 0] = total
        self.gram = gram
        self._bivectors = {}

    def det(self, rows: tuple, cols: tuple) -> np.ndarray:
        """det G[rows, cols] for 1×1 and 2×2 blocks (the only sizes k ≤ n − 1 ≤ 2 needs).

        2×2 blocks occur on tetrahedra only. There ∇λ_a×∇λ_b = s·(p_y − p_x)/D with {x < y}
        the other two vertices and s the parity of (a, b, x, y), so the determinant
        (∇λ_a×∇λ_b)·(∇λ_c×∇λ_d) is a dot product of edge vectors over D² — accurate on
        slivers, unlike G_ac G_bd − G_ad G_bc.
        """
        if len(rows) == 1:
            a, b = rows[0], cols[0]
            return self.gram[min(a, b), max(a, b)]
        key = (rows, cols)
        if key not in self._bivectors:
            x, y = (v for v in range(4) if v not in rows)
            u, w = (v for v in range(4) if v not in cols)

            def g(a, b):  # p_a·p_b with p_0 at the origin
                return self.metric[a, b] if a and b else 0.0

            value = g(y, w) - g(y, u) - g(x, w) + g(x, u)  # (p_y − p_x)·(p_w − p_u)
            self._bivectors[key] = (_parity(rows + (x, y)) * _parity(cols + (u, w))) * value * self.inverse_d2
        return self._bivectors[key]


def _local_mass(geometry: _TopGeometry, k: int, I: tuple, J: tuple) -> np.ndarray:
    """(n_n,) ∫⟨W_I, W_J⟩ over each top simplex, eq. (2), for 1 ≤ k ≤ n − 1."""
    n = geometry.n
    scale = factorial(k) ** 2 / ((n + 1) * (n + 2))
    total = np.zeros(geometry.volume.shape[0])
    for p, a in enumerate(I):
        for q, b in enumerate(J):
            weight = scale * (-1) ** (p + q) * (2.0 if a == b else 1.0)
            total += weight * geometry.det(I[:p] + I[p + 1:], J[:q] + J[q + 1:])
    total *= geometry.volume
    return total


def whitney_mass_matrix(K: SimplicialComplex, k: int) -> sp.csr_matrix:
    """The Whitney k-form mass matrix M_k (the Galerkin Hodge star), eq. (1)–(2).

    Parameters
    ----------
    K : SimplicialComplex of dimension 2 (vertices in R² or R³) or 3
    k : form degree 0..n

    Returns
    -------
    (n_k, n_k) symmetric positive definite CSR matrix in length^(n−2k) units, rows and
    columns in the order of ``K.simplices(k)``. ``ωᵀ M_k ω`` is the L² norm² of the Whitney
    interpolant of the cochain ω. Assembled with one sparse constructor from the local
    C(n+1, k+1)² blocks of every top simplex.
    """
    _check(K, k)
    n = K.dim
    size = K.num_simplices(k)
    if k in (0, n):
        volume = K.top_volumes  # the complex's cached top volumes
    if k == n:
        return sp.diags(1.0 / volume).tocsr()
    if k == 0:
        # P1 mass: |σ|/((n+1)(n+2)) on every edge of σ, twice that on its vertices.
        share = volume / ((n + 1) * (n + 2))
        edges_of_top = K.top_face_indices(1)
        off = np.bincount(edges_of_top.ravel(), weights=np.repeat(share, edges_of_top.shape[1]),
                          minlength=K.num_simplices(1))
        del edges_of_top
        diagonal = np.bincount(K.simplices(n).ravel(), weights=np.repeat(2.0 * share, n + 1), minlength=size)
        edges = K.simplices(1)
        index = _index_dtype(size, 2 * edges.shape[0] + size)
        rows = np.concatenate([edges[:, 0], edges[:, 1], np.arange(size)]).astype(index)
        cols = np.concatenate([edges[:, 1], edges[:, 0], np.arange(size)]).astype(index)
        data = np.concatenate([off, off, diagonal])
        return sp.csr_matrix((data, (rows, cols)), shape=(size, size))
    geometry = _TopGeometry(K)
    faces = K.top_face_indices(k)  # (m, C)
    local = list(combinations(range(n + 1), k + 1))
    C = len(local)
    m = faces.shape[0]
    index = _index_dtype(size, m * C * (C - 1) + size)
    faces = faces.astype(index)
    count = m * C * (C - 1)
    rows = np.empty(count + size, dtype=index)
    cols = np.empty(count + size, dtype=index)
    data = np.empty(count + size)
    diagonal = np.zeros(size)
    position = 0
    for a in range(C):
        diagonal += np.bincount(faces[:, a], weights=_local_mass(geometry, k, local[a], local[a]),
                                minlength=size)
        for b in range(a + 1, C):
            value = _local_mass(geometry, k, local[a], local[b])
            for r, c in ((a, b), (b, a)):
                rows[position:position + m] = faces[:, r]
                cols[position:position + m] = faces[:, c]
                data[position:position + m] = value
                position += m
    del faces
    rows[count:] = np.arange(size)
    cols[count:] = np.arange(size)
    data[count:] = diagonal
    return sp.csr_matrix((data, (rows, cols)), shape=(size, size))


def whitney_lumped_mass(K: SimplicialComplex, k: int) -> np.ndarray:
    """A diagonal (lumped) Whitney mass matrix, as an (n_k,) array (``operator.lumped``).

    What lumping means for each degree:

    * k = 0: row-sum lumping, Σ_τ (M_0)_{στ} = Σ_{σ_n ∋ v} |σ_n| / (n+1) — the barycentric
      dual area/volume. Positive; consistent (it integrates constants exactly and the
      total is the area/volume).
    * k = n: M_n is already diagonal, 1/|σ_n|. Positive; exact.
    * 0 < k < n: row sums are meaningless for forms (they change sign when a neighbouring
      simplex's orientation is flipped), so this is *diagonal* lumping, (M_k)_{σσ} =
      ‖W_σ‖². Positive on every mesh, but **not consistent**: it does not reproduce
      ∫|a|² for constant fields. On a uniform equilateral triangulation it is 5/6 of the
      circumcentric ⋆1 = 1/√3 (each triangle contributes 5√3/36 instead of ½ cot 60° =
      √3/6), so a Laplacian built on it is off by that factor; use it only where positivity
      matters more than accuracy. (The consistent diagonal star is the circumcentric ⋆1 —
      d_0ᵀ ⋆1 d_0 = d_0ᵀ M_1 d_0 — which is not positive on non-Delaunay meshes.)

    Returns
    -------
    (n_k,) positive float array, units length^(n−2k).
    """
    _check(K, k)
    n = K.dim
    size = K.num_simplices(k)
    if k in (0, n):
        volume = K.top_volumes
    if k == n:
        return 1.0 / volume
    if k == 0:
        return np.bincount(K.simplices(n).ravel(), weights=np.repeat(volume / (n + 1), n + 1), minlength=size)
    geometry = _TopGeometry(K)
    faces = K.top_face_indices(k)
    local = list(combinations(range(n + 1), k + 1))
    diagonal = np.zeros(size)
    for a in range(len(local)):
        diagonal += np.bincount(faces[:, a], weights=_local_mass(geometry, k, local[a], local[a]),
                                minlength=size)
    return diagonal
