"""Border conditions for 0-forms in DEC: Dirichlet, Neumann and Robin (issue #47, item 4).

Meshes: a :class:`~decrun.core.complex.SimplicialComplex` of dimension n = 2 (triangles in
2-D or 3-D) or n = 3 (tetrahedra), with the circumcentric stars of the thesis.

**Green's identity in DEC.** Let D_i be the circumcentric dual cell of vertex i (⋆0_i = |D_i|),
truncated at the border, and S = d0ᵀ ⋆1 d0 the cot stiffness. The dual face of an edge ij is
orthogonal to ij (its points are equidistant from i and j), so ⋆1_ij (u_j − u_i) is the flux
of ∇u through it, exact for linear u. The divergence theorem on D_i then reads

    ∫_{D_i} Δu = ∮_{∂D_i} ∂u/∂n  ≈  −(S u)_i + ∫_{Γ_i} ∂u/∂n ,

where Γ_i = ∂D_i ∩ ∂Ω is the part of the dual cell's boundary on the border (empty inside).
Dividing by ⋆0_i gives the language's ``laplacian`` L = −⋆0⁻¹ S (the Laplace–Beltrami sign)
plus a border term. Hence, row by row,

    ⋆0 (Δu) = −S u + b,      b_i = ∫_{Γ_i} ∂u/∂n ,

and the three conditions only say what ∂u/∂n is on Γ_i:

* Neumann  ∂u/∂n = g:            b = ∫_{Γ_i} g                    (:func:`border_load`)
* Robin    ∂u/∂n + α u = value:  b = ∫_{Γ_i} value − R u,  R = diag(∫_{Γ_i} α)  (:func:`robin_matrix`)
* Dirichlet u = g:               the border rows are dropped and u_D = g moved to the right
                                 side (:class:`Condensation`).

With no condition, b = 0: ``laplacian(u)`` on its own *is* the homogeneous Neumann operator.

**Γ_i, the border dual measure.** n = 2: Γ_i is the half of each adjacent border edge next to i,
|Γ_i| = ½ Σ |e|. n = 3: in a tetrahedron the dual cell of i meets the border triangle ijk in
the quadrilateral i, mid(ij), cc(ijk), mid(ik) (the dual faces of ij and ik pass through the
triangle's circumcentre cc), so |Γ_i| is the circumcentric (signed) share of i in its border
triangles, ⅛ Σ (|ij|² cot θ_k + |ik|² cot θ_j) — ⋆0 of the border surface. Being the
boundary of the same dual cells that give ⋆0 and ⋆1, this choice makes Green's identity
exact for linear u: S u = b with g = ∂u/∂n (tested; the barycentric share |T|/3 is not, on
tetrahedra whose circumcentres leave them). Σ_i |Γ_i| is the border's length/area.

**boundary=flux (§6.4.4) and #48 item 4.** Under ``boundary=flux`` δ_1 is replaced by
⋆0⁻¹ (d0ᵀ ⋆1 − M_border F) where F d0 u is the outward flux through each border edge of the
P1 gradient of u in its triangle and M_border gives half of it to each end vertex, i.e.

    −codifferential(d(u)) = L u + ⋆0⁻¹ b(∂u_h/∂n)   (b of :func:`border_load`, g = ∇u_h·n),

while ``laplacian(u)`` = L u stays unadapted. So ``laplacian(u)`` is the Laplacian with the
homogeneous Neumann condition (no flux through Γ_i); ``-codifferential(d(u))`` under
``flux`` counts the flux u itself pushes through the border (a free, "outflow" border).
They differ at border vertices only, by ⋆0⁻¹ b = O(|∂u/∂n| / h) — #48's 62 (tested).

**Time.** For M y' = L y + s(t) (M = ⋆0, or a non-diagonal Galerkin mass), Dirichlet data g(t)
on the fixed unknowns D gives, on the free ones F,

    M_FF y_F' = L_FF y_F + [L_FD g(t) − M_FD ∂g/∂t(t)] + s_F(t),

so only a non-diagonal mass needs ∂g/∂t (:meth:`Condensation.source`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from decrun.core.connectivity import edge_owners
from decrun.core.stars.circumcentric import circumcenter_barycentric

__all__ = ["BorderFaces", "BorderQuadrature", "Condensation", "border_faces", "border_load", "border_measures",
           "border_quadrature", "hat_quadrature", "outward_normals", "robin_matrix"]


@dataclass(frozen=True)
class BorderFaces:
    """The border (n−1)-faces of a complex.

    index : (b,) indices into ``K.simplices(n−1)``;  vertices : (b, n) their vertices (sorted);
    owner : (b,) the top simplex holding each;  opposite : (b,) that simplex's vertex off the face.
    """

    index: np.ndarray
    vertices: np.ndarray
    owner: np.ndarray
    opposite: np.ndarray


@dataclass(frozen=True)
class BorderQuadrature:
    """A second-order rule on the pieces Γ_i: ∫_{Γ_i} g ≈ Σ_{q: vertex[q] = i} weight[q] g(points[q]).

    points : (q, d) coordinates;  weights : (q,) signed measures (length or area) of the pieces;
    vertex : (q,) the vertex i each piece belongs to;  face : (q,) the border face (row of
    :class:`BorderFaces`) each point lies in. Exact for g linear on each face.
    """

    points: np.ndarray
    weights: np.ndarray
    vertex: np.ndarray
    face: np.ndarray


def _require_dimension(K) -> None:
    if K.dim not in (2, 3):
        raise ValueError(f"border conditions need triangles or tetrahedra, not a {K.dim}-complex")


def border_faces(K) -> BorderFaces:
    """The border (n−1)-faces of ``K`` (n = 2, 3) with their top simplex and its opposite vertex."""
    _require_dimension(K)
    index, _ = K.border_faces()
    owner, slot = edge_owners(K.facet_indices(K.dim), K.num_simplices(K.dim - 1))
    # facet `slot` of a top simplex omits its local vertex `slot`: that vertex is off the face
    opposite = K.simplices(K.dim)[owner[index], slot[index]]
    return BorderFaces(index, K.simplices(K.dim - 1)[index], owner[index], opposite)


def outward_normals(K, faces: BorderFaces | None = None) -> np.ndarray:
    """(b, d) unit outward normals of the border faces: p0 − q (q the opposite vertex) with its
    component along the face removed, normalized. In the plane of the triangle for surfaces
    in 3-D (the co-normal), the face normal for tetrahedra."""
    faces = border_faces(K) if faces is None else faces
    x = np.asarray(K.vertices, dtype=np.float64)
    base = x[faces.vertices[:, 0]]
    spans = x[faces.vertices[:, 1:]] - base[:, None, :]                   # (b, n−1, d)
    away = base - x[faces.opposite]                                        # (b, d)
    gram = np.einsum("bkd,bld->bkl", spans, spans)
    coefficients = np.linalg.solve(gram, np.einsum("bkd,bd->bk", spans, away)[..., None])[..., 0]
    normal = away - np.einsum("bk,bkd->bd", coefficients, spans)
    return normal / np.linalg.norm(normal, axis=1, keepdims=True)


def border_quadrature(K, faces: BorderFaces | None = None) -> BorderQuadrature:
    """The pieces Γ_i of the border dual cells with one point each (the piece's centroid).

    n = 2: the half edge [a, mid(ab)] of each end a: weight |ab|/2, point a + (b − a)/4.
    n = 3: for each border triangle, vertex i and other vertex j, the triangle
    (i, mid(ij), cc) with signed area |ij|² cot θ_k / 8 (k the third vertex) and its centroid;
    two such pieces make the quadrilateral of i. A centroid rule: error O(h³) per piece.
    """
    faces = border_faces(K) if faces is None else faces
    x = np.asarray(K.vertices, dtype=np.float64)
    corners = x[faces.vertices]                                            # (b, n, d)
    b, n = faces.vertices.shape
    if n == 2:
        a, c = corners[:, 0], corners[:, 1]
        length = np.linalg.norm(c - a, axis=1)
        points = np.stack([a + (c - a) / 4, c + (a - c) / 4], axis=1)
        weights = np.stack([length / 2, length / 2], axis=1)
        return BorderQuadrature(points.reshape(-1, x.shape[1]), weights.ravel(), faces.vertices.ravel(),
                                np.repeat(np.arange(b), 2))
    center = np.einsum("bc,bcd->bd", circumcenter_barycentric(corners), corners)
    # the six (i, j, k) rotations: i the piece's vertex, j the edge's other end, k the third
    order = np.array([[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]])
    i_at, j_at, k_at = (corners[:, order[:, m]] for m in range(3))        # (b, 6, d)
    to_i, to_j = i_at - k_at, j_at - k_at
    cross = np.linalg.norm(np.cross(to_i, to_j), axis=2)
    cot_k = np.einsum("bsd,bsd->bs", to_i, to_j) / cross
    weights = np.einsum("bsd,bsd->bs", i_at - j_at, i_at - j_at) * cot_k / 8
    points = (i_at + (i_at + j_at) / 2 + center[:, None, :]) / 3
    return BorderQuadrature(points.reshape(-1, x.shape[1]), weights.ravel(),
                            faces.vertices[:, order[:, 0]].ravel(), np.repeat(np.arange(b), 6))


def hat_quadrature(K, faces: BorderFaces | None = None) -> BorderQuadrature:
    """The border pieces of the P1 hat functions φ_i, for a Galerkin ⋆0 (``operator=whitney``):
    ∫_∂Ω g φ_i ≈ Σ_{q: vertex[q] = i} weight[q] g(points[q]), exact for g linear on each face.

    Each border face F (n vertices) gives each of its vertices i the weight |F|/n = ∫_F φ_i at the
    point (2 x_i + Σ_{j≠i} x_j)/(n + 1), where a linear g takes the value n ∫_F g φ_i / |F|. With
    it the P1 stiffness S of a linear u is the border load of its ∂u/∂n exactly (S u = ∫_∂Ω ∂u/∂n φ_i:
    integration by parts with Δu = 0), on tetrahedra too, where the circumcentric pieces of
    :func:`border_quadrature` are the Γ_i of DEC's dual cells instead."""
    faces = border_faces(K) if faces is None else faces
    x = np.asarray(K.vertices, dtype=np.float64)
    corners = x[faces.vertices]                                            # (b, n, d)
    b, n = faces.vertices.shape
    spans = corners[:, 1:] - corners[:, :1]
    gram = np.einsum("bkd,bld->bkl", spans, spans)
    measure = np.sqrt(np.abs(np.linalg.det(gram))) / (1.0 if n == 2 else 2.0)
    points = (corners + corners.sum(axis=1, keepdims=True)) / (n + 1)
    return BorderQuadrature(points.reshape(-1, x.shape[1]), np.repeat(measure / n, n), faces.vertices.ravel(),
                            np.repeat(np.arange(b), n))


def border_load(K, quadrature: BorderQuadrature, values: np.ndarray | float) -> np.ndarray:
    """(n0,) b_i = ∫_{Γ_i} g, from ``values`` (q,) = g at ``quadrature.points``, or one number (zero inside).

    The Neumann term of ⋆0 Δu = −S u + b (module doc): add it to the right side of a
    ⋆0-weighted equation, b = +Σ weight·g with g the *outward* normal derivative."""
    values = np.broadcast_to(np.asarray(values, dtype=np.float64), quadrature.weights.shape)
    return np.bincount(quadrature.vertex, quadrature.weights * values, minlength=K.num_simplices(0))


def border_measures(K, quadrature: BorderQuadrature | None = None) -> np.ndarray:
    """(n0,) |Γ_i|, the border dual measure of each vertex (0 inside); Σ = the border's
    length (n = 2) or area (n = 3)."""
    quadrature = border_quadrature(K) if quadrature is None else quadrature
    return border_load(K, quadrature, 1.0)


def robin_matrix(K, quadrature: BorderQuadrature, alpha: np.ndarray) -> sp.csr_matrix:
    """R (n0, n0) = diag(∫_{Γ_i} α), ``alpha`` (q,) at the quadrature points.

    Robin ∂u/∂n + α u = value turns ⋆0 Δu = −S u + b into −(S + R) u + ∫_{Γ_i} value: R joins
    the stiffness. With α > 0 and |Γ_i| ≥ 0 it is positive semi-definite and fixes the constant;
    in 3-D an obtuse border triangle gives a negative share, and |Γ_i| itself may be negative
    at a vertex surrounded by such triangles (signed circumcentric duals, like ⋆0 and ⋆1)."""
    return sp.diags(border_load(K, quadrature, alpha)).tocsr()


@dataclass(frozen=True)
class Condensation:
    """Dirichlet values by condensation (scikit-fem's ``condense``): unknowns split into free F
    and fixed D; A u = b becomes A_FF u_F = b_F − A_FD g, and u = expand(u_F, g).

    fixed : (n0,) bool mask of the Dirichlet unknowns (border vertices for ``dirichlet``).
    """

    fixed: np.ndarray

    @property
    def free_index(self) -> np.ndarray:
        """(f,) indices of the free unknowns."""
        return np.flatnonzero(~self.fixed)

    @property
    def fixed_index(self) -> np.ndarray:
        """(c,) indices of the fixed unknowns."""
        return np.flatnonzero(self.fixed)

    def matrix(self, A) -> sp.csr_matrix:
        """A_FF (f, f)."""
        free = self.free_index
        return sp.csr_matrix(A)[free][:, free]

    def coupling(self, A) -> sp.csr_matrix:
        """A_FD (f, c): how the fixed values enter the free rows."""
        return sp.csr_matrix(A)[self.free_index][:, self.fixed_index]

    def right_side(self, A, b: np.ndarray, values: np.ndarray) -> np.ndarray:
        """(f,) b_F − A_FD g for the solve A u = b with u_D = g (``values`` (c,))."""
        return np.asarray(b)[self.free_index] - self.coupling(A) @ values

    def source(self, stiff, mass, values: np.ndarray, rates: np.ndarray | None) -> np.ndarray:
        """(f,) L_FD g(t) − M_FD ∂g/∂t(t): the Dirichlet data's share of f in M y' = L y + s.

        ``stiff`` L (n0, n0), ``mass`` M (n0, n0) or None (diagonal/identity: no M_FD term),
        ``values`` g(t) (c,), ``rates`` ∂g/∂t (c,); ``rates`` may be None only when M_FD = 0."""
        result = self.coupling(stiff) @ values
        if mass is None:
            return result
        mass_coupling = self.coupling(mass)
        if mass_coupling.nnz == 0:
            return result
        if rates is None:
            raise ValueError("a non-diagonal mass couples the Dirichlet values' rate ∂g/∂t into the free rows")
        return result - mass_coupling @ rates

    def expand(self, free_values: np.ndarray, values: np.ndarray) -> np.ndarray:
        """(n0,) u with u_F = ``free_values`` (f,) and u_D = ``values`` (c,)."""
        u = np.empty(self.fixed.shape[0])
        u[self.free_index] = free_values
        u[self.fixed_index] = values
        return u
