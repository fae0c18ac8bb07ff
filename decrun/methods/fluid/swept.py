"""Circulation change of a moving dual cell from the vorticity it sweeps (Stokes).

The circulation of the backtracked cell X(C) in the current velocity is, by Stokes, the
integral of the current vorticity over X(C). Writing X(C) as C plus the quadrilaterals its
sides sweep,

    Γ(X(C)) − Γ(C) = − Σ_s D[v, s] ∫_{Q_s} ω,    Q_s = (p_a, p_b, p_b', p_a'),

for the cell sides s = a → b (D the signed side incidence: +1 when the cell runs a → b
counter-clockwise; a counter-clockwise side moving outwards sweeps a clockwise quad, hence
the minus). ω is the vertex vorticity interpolated linearly in the primal triangles (P1,
continuous, within the vertex values' range); ∫_{Q_s} ω is the sum over the triangles
(p_a, p_b, p_b') and (p_a, p_b', p_a') of signed area × mean of ω at the three corners (exact
for linear ω). Each side's integral enters its two cells with opposite signs, so Σ ⋆0 w is
conserved exactly. The result does not depend on how the quad is cut when ω is linear.

Why not the trapezoid circulation of interpolated corner velocities: it differentiates the
velocity reconstruction once more, and the reconstruction's cell-scale errors (O(h) for the
thesis' WSHD07 corner values of a strain) then make the steady-flow drift O(dt) per step
independently of the mesh size (benchmarks/bench_fluid_drift.py).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.methods.fluid.interpolation import dot3

__all__ = ["SweptVorticity", "rest_point_interpolation"]


def rest_point_interpolation(top: np.ndarray, barycentric_at_circumcenters: np.ndarray, point_vertex: np.ndarray,
                             border_edge_ends: np.ndarray, n0: int) -> sp.csr_matrix:
    """Sparse (P, n0) P1 interpolation of a vertex function at the unmoved dual points:
    circumcenters (m) from their triangle's corners (``barycentric_at_circumcenters`` (m, 3)),
    border-edge midpoints from the edge's two ends (``border_edge_ends`` (nbe, 2)), border
    vertices (the rest of ``point_vertex``) the vertex itself."""
    m = top.shape[0]
    nbe = border_edge_ends.shape[0]
    n_fixed = point_vertex.size - m
    rows = np.concatenate([np.repeat(np.arange(m), 3), np.repeat(m + np.arange(nbe), 2),
                           m + np.arange(nbe, n_fixed)])
    cols = np.concatenate([top.ravel(), border_edge_ends.ravel(), point_vertex[m + nbe:]])
    vals = np.concatenate([barycentric_at_circumcenters.ravel(), np.full(2 * nbe, 0.5), np.ones(n_fixed - nbe)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(point_vertex.size, n0))


class SweptVorticity:
    """The swept-vorticity circulation change of the cells of ``dual_incidence`` (n0, S) whose
    sides run between dual points ``side_a`` → ``side_b`` (S,); ``vertex_normal`` (n0, 3)
    orients the signed areas (the mean normal of the side's cells)."""

    def __init__(self, vertex_normal: np.ndarray, dual_incidence: sp.csr_matrix, side_a: np.ndarray,
                 side_b: np.ndarray):
        D = dual_incidence.tocsc()
        D.sort_indices()
        per_side = np.diff(D.indptr)
        first = D.indices[D.indptr[:-1]]
        second = np.where(per_side > 1, D.indices[np.minimum(D.indptr[:-1] + 1, D.indices.size - 1)], first)
        normal = vertex_normal[first] + vertex_normal[second]
        self.normal = normal / np.linalg.norm(normal, axis=1, keepdims=True)
        self.incidence = dual_incidence.tocsr()
        self.side_a, self.side_b = side_a, side_b

    def change(self, before: np.ndarray, after: np.ndarray, value_before: np.ndarray,
               value_after: np.ndarray, compiled: bool = False, sides: tuple | None = None) -> np.ndarray:
        """(n0,) Γ(X(C)) − Γ(C) per cell, for the dual points ``before`` (P, 3), their
        backtracked positions ``after`` (P, 3) and the vorticity interpolated at both (P,).
        ``sides``: (side_a, side_b) (S,) in place of the constructor's, for the same points
        numbered otherwise (a permutation of the rows of ``before`` and ``after``).

        ``compiled``: by the numba twin (compiled.swept_change_add into zeros), the same arithmetic in the same
        order (3-vector dots as ``dot3``), the same bits."""
        a, b = (self.side_a, self.side_b) if sides is None else sides
        if compiled:
            from decrun.core import jit
            from decrun.methods.fluid import compiled as kernels

            D = self.incidence
            f64 = [np.ascontiguousarray(x, dtype=np.float64) for x in (before, after, value_before, value_after,
                                                                       self.normal)]
            change = np.zeros(D.shape[0])
            kernels.swept_change_add(change, *f64[:4], np.ascontiguousarray(a, dtype=np.int64),
                                     np.ascontiguousarray(b, dtype=np.int64), f64[4], D.indptr, D.indices, D.data,
                                     jit.threads())
            return change
        a0, b0, a1, b1 = before[a], before[b], after[a], after[b]
        first = 0.5 * dot3(np.cross(b0 - a0, b1 - a0), self.normal)
        second = 0.5 * dot3(np.cross(b1 - a0, a1 - a0), self.normal)
        wa0, wb0, wa1, wb1 = value_before[a], value_before[b], value_after[a], value_after[b]
        total = first * (wa0 + wb0 + wb1) / 3.0 + second * (wa0 + wb1 + wa1) / 3.0
        return -(self.incidence @ total)
