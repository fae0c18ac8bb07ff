"""DEC on an intrinsic triangulation: d0, ⋆1, ♯ and ♭ of its own edges and triangles.

An intrinsic triangulation (:class:`decrun.core.intrinsic_delaunay.IntrinsicTriangulation`)
shares the mesh's vertices but has edges and triangles of its own, known only by their lengths
— no positions. Its 1-forms live on its edges (``T.edge_sides`` order), its vector fields are one
vector per intrinsic triangle in that triangle's own 2-D frame (corner 0 at the origin, corner 1
on the +x axis, corner 2 above it): the frame is all the geometry a triangle has, and every
frame-free quantity (|X|, X·Y, the divergence) is the same in any frame.

* ``d0`` (e, n0): (d0 u)_e = u(head) − u(tail), the edge directed from corner c+1 to corner c+2
  of the triangle on its side 0 (``T.edge_sides[:, 0] = 3f + c``); a loop's row is 0.
* ``star1`` (e,): the cotan weights ½(cot α + cot β) — the primal/dual length ratio of the
  intrinsic triangulation's circumcentric dual (Bobenko–Springborn 2007); ≥ 0 once Delaunay;
  ``star0`` (n0,) the lumped barycentric areas. On a tufted cover both are halved (the cover is
  two sheets of the surface), so ``d0ᵀ diag(star1) d0`` is ``T.stiffness()``.
* ``sharp`` (the Whitney interpolation at each triangle's barycentre, eq. 6.7):
  ω♯ = Σ_{sides c} ω_c (∇λ_{c+2} − ∇λ_{c+1}) / 3, ω_c the form on the side from corner c+1
  to c+2; for ω = d0 u it is the gradient of the piecewise-linear u in the triangle, exactly.
* ``flat`` (Hirani's primal-primal ♭ as :func:`decrun.methods.model.discrete.flat` defines it on
  the mesh): ω_e = Σ_{sides} ½cot θ_side X_f · e_f / Σ_{sides} ½cot θ_side, e_f the edge's
  vector in the frame of the triangle f on that side; so ⋆1 X♭ is the flux of X across the dual
  edges and −δ X♭ = ⋆0⁻¹ d0ᵀ ⋆1 X♭ is the cotan divergence of X (Crane et al. 2013, eq. 4).
  Where Σ cot = 0 (the dual edge has length 0) the plain mean over the sides is taken.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import scipy.sparse as sp

from decrun.core.intrinsic_delaunay import IntrinsicTriangulation

__all__ = ["IntrinsicCalculus"]

_NEXT = np.array([1, 2, 0])
_PREV = np.array([2, 0, 1])


class IntrinsicCalculus:
    """d0, ⋆0, ⋆1, ♯, ♭ and δ1 of an intrinsic triangulation (module docstring). Matrices are
    built once, on first use."""

    def __init__(self, triangulation: IntrinsicTriangulation):
        self.T = triangulation
        self.n_vertices = triangulation.n_vertices
        self.n_edges = triangulation.edge_sides.shape[0]
        self.n_faces = triangulation.faces.shape[0]

    # ---------------------------------------------------------------- sides
    @cached_property
    def side_sign(self) -> np.ndarray:
        """(f, 3) +1 where side 3f + c runs along its edge's direction (the edge's side 0),
        −1 where it runs against it (side 1; the triangulation is consistently oriented)."""
        sign = np.zeros(3 * self.n_faces)
        sides = self.T.edge_sides
        sign[sides[:, 0]] = 1.0
        interior = sides[:, 1] >= 0
        sign[sides[interior, 1]] = -1.0
        return sign.reshape(self.n_faces, 3)

    @cached_property
    def corners(self) -> np.ndarray:
        """(f, 3, 2) the corners of every triangle in its own frame: corner 0 at the origin,
        corner 1 at (l_2, 0) (l_c the length of the side opposite corner c), corner 2 above."""
        lengths = self.T.edge_lengths[self.T.face_edges]
        l0, l1, l2 = lengths[:, 0], lengths[:, 1], lengths[:, 2]
        x2 = (l1 * l1 + l2 * l2 - l0 * l0) / (2.0 * l2)
        y2 = 2.0 * self.T.face_areas() / l2
        out = np.zeros((self.n_faces, 3, 2))
        out[:, 1, 0] = l2
        out[:, 2, 0], out[:, 2, 1] = x2, y2
        return out

    @cached_property
    def side_vectors(self) -> np.ndarray:
        """(f, 3, 2) the vector of side c (corner c+1 → corner c+2) in the triangle's frame."""
        p = self.corners
        return p[:, _PREV] - p[:, _NEXT]

    @cached_property
    def barycentric_gradients(self) -> np.ndarray:
        """(f, 3, 2) ∇λ_c in the triangle's frame: the side vector opposite c turned by −90°
        (inward), over twice the area."""
        side = self.side_vectors
        inward = np.stack([-side[..., 1], side[..., 0]], axis=-1)  # +90°: counter-clockwise frame
        return inward / (2.0 * self.T.face_areas())[:, None, None]

    # ---------------------------------------------------------------- operators
    @cached_property
    def d0(self) -> sp.csr_matrix:
        """(e, n0) exterior derivative on 0-forms: +1 at the head, −1 at the tail of each edge."""
        ends = self.T.edge_endpoints()  # (tail, head) along the edge's direction
        rows = np.repeat(np.arange(self.n_edges), 2)
        data = np.tile([-1.0, 1.0], self.n_edges)
        matrix = sp.csr_matrix((data, (rows, ends.ravel())), shape=(self.n_edges, self.n_vertices))
        matrix.sum_duplicates()
        matrix.eliminate_zeros()  # a loop: −1 + 1 at one vertex
        return matrix

    @cached_property
    def star1(self) -> np.ndarray:
        """(e,) ⋆1: the cotan weights ½(cot α + cot β), halved on a tufted cover."""
        weights = self.T.cotan_weights()
        return 0.5 * weights if self.T.cover else weights

    @cached_property
    def star0(self) -> np.ndarray:
        """(n0,) ⋆0: the lumped barycentric vertex areas (halved on a tufted cover)."""
        return self.T.star0()

    @cached_property
    def face_areas(self) -> np.ndarray:
        """(f,) areas of the intrinsic triangles (their volumes as top simplices)."""
        return self.T.face_areas()

    def codifferential_weak(self) -> sp.csr_matrix:
        """(n0, e) d0ᵀ ⋆1, so that δ1 = ⋆0⁻¹ d0ᵀ ⋆1 (eq. 4.14)."""
        return (self.d0.T @ sp.diags(self.star1)).tocsr()

    @cached_property
    def sharp_matrices(self) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        """The two frame components of ♯ as (f, e) sparse matrices."""
        grad = self.barycentric_gradients
        weights = (grad[:, _PREV] - grad[:, _NEXT]) / 3.0 * self.side_sign[..., None]  # (f, 3 sides, 2)
        rows = np.repeat(np.arange(self.n_faces), 3)
        cols = self.T.face_edges.ravel()
        return tuple(sp.csr_matrix((weights[:, :, axis].ravel(), (rows, cols)), shape=(self.n_faces, self.n_edges))
                     for axis in range(2))  # type: ignore[return-value]

    def sharp(self, omega: np.ndarray) -> np.ndarray:
        """ω♯ (f, 2): the Whitney interpolation of a 1-form (e,) at each triangle's barycentre."""
        return np.stack([matrix @ omega for matrix in self.sharp_matrices], axis=1)

    def gradient(self, u: np.ndarray) -> np.ndarray:
        """∇u (f, 2) of a piecewise-linear 0-form u (n0,): Σ_c u_c ∇λ_c (equals sharp(d0 u))."""
        return np.einsum("fc,fcd->fd", u[self.T.faces], self.barycentric_gradients)

    @cached_property
    def _half_cotangents(self) -> np.ndarray:
        """(3f,) ½ cot of the angle opposite each side (side 3f + c is opposite corner c)."""
        return 0.5 * self.T.corner_cotangents().ravel()

    def flat(self, vectors: np.ndarray) -> np.ndarray:
        """X♭ (e,) of a field X (f, 2) given in the triangles' frames (module docstring)."""
        half_cot = self._half_cotangents
        along = np.einsum("fd,fcd->fc", vectors, self.side_vectors * self.side_sign[..., None]).ravel()
        edges = self.T.face_edges.ravel()
        count = np.bincount(edges, minlength=self.n_edges).astype(np.float64)
        plain = np.bincount(edges, weights=along, minlength=self.n_edges) / np.maximum(count, 1.0)
        weighted = np.bincount(edges, weights=half_cot * along, minlength=self.n_edges)
        edge_total = np.bincount(edges, weights=half_cot, minlength=self.n_edges)
        scale = np.abs(half_cot).max() if half_cot.size else 1.0
        degenerate = np.abs(edge_total) <= 1e-12 * scale
        return np.where(degenerate, plain, weighted / np.where(degenerate, 1.0, edge_total))
