"""``boundary=flux``: the border-flux adaptation of δ_1 (§6.4.4, eq. 6.10).

The flux through each border edge is estimated from the two other edges of its triangle,
assuming zero curl there (eq. 6.10), and half of it is added to each end vertex (the two
matrices printed after eq. 6.10):

    δ_flux = ⋆0⁻¹ (d0ᵀ ⋆1 − M_border F)

with ``F`` (#edges × #edges, :func:`border_flux_matrix`) the outward flux through each border
edge and ``M_border`` (#vertices × #edges, :func:`border_vertex_matrix`). A field may now
cross the border, but δ_flux is no longer the adjoint of d0 and the Hodge decomposition of
Theorem 5 fails with it — as the thesis warns. On closed meshes δ_flux = δ_1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from decrun.core.boundary import BoundaryAdaptation, border_edge_frames, signed_edges
from decrun.core.geometry import embed3
from decrun.errors import ConfigError

__all__ = ["Flux", "border_flux_matrix", "border_vertex_matrix"]


def _require_triangles(K, what: str) -> None:
    if K.dim != 2:
        raise ConfigError(f"boundary=flux: {what} is defined for triangle meshes, not dimension {K.dim}")


def border_flux_matrix(dec) -> sp.csr_matrix:
    """F (#edges, #edges): outward flux through each border edge, eq. 6.10.

    For the border edge e_ij of the triangle t_ijk (i → j in the orientation of t, so the
    outside is to the right of i → j), assuming zero curl on t the Whitney field (eq. 6.7)
    is constant and its flux *out of the mesh* through e_ij is

        f_out(e_ij) = w_ki cot θ_j − w_jk cot θ_i ,

    the negative of eq. 6.10's f_ij, which is the flux through e_ij towards the inside of
    t (the left of i → j; Fig. 6.11). θ_i, θ_j are the triangle's angles at i and j.
    Rows of interior edges are zero; each border row has entries in the columns of e_jk
    and e_ki, with signs for the reference edge orientations.
    """
    K = dec.K
    _require_triangles(K, "the border flux")
    edges_idx, face, i_v, j_v, k_v = border_edge_frames(K)
    x = embed3(K.vertices)

    def cot(at, p, q):
        a, b = x[p] - x[at], x[q] - x[at]
        return np.einsum("md,md->m", a, b) / np.linalg.norm(np.cross(a, b), axis=1)

    cot_i = cot(i_v, j_v, k_v)
    cot_j = cot(j_v, k_v, i_v)
    e_ki, s_ki = signed_edges(K, k_v, i_v)
    e_jk, s_jk = signed_edges(K, j_v, k_v)
    rows = np.concatenate([edges_idx, edges_idx])
    cols = np.concatenate([e_ki, e_jk])
    vals = np.concatenate([s_ki * cot_j, -s_jk * cot_i])
    n1 = K.num_simplices(1)
    return sp.csr_matrix((vals, (rows, cols)), shape=(n1, n1))


def border_vertex_matrix(K) -> sp.csr_matrix:
    """M_border (#vertices, #edges): half of each border edge's flux to each of its two
    end vertices (the first matrix after eq. 6.10; the signs of the thesis' version are
    absorbed into :func:`border_flux_matrix`, which already returns *outward* flux)."""
    _require_triangles(K, "the border vertex matrix")
    edges_idx, _ = K.border_faces()
    ends = K.simplices(1)[edges_idx]
    rows = ends.ravel()
    cols = np.repeat(edges_idx, 2)
    return sp.csr_matrix((np.full(rows.size, 0.5), (rows, cols)), shape=(K.num_simplices(0), K.num_simplices(1)))


@dataclass
class Flux(BoundaryAdaptation):
    """§6.4.4: δ_1 counts the estimated flux through border edges (eq. 6.10)."""

    name = "flux"

    def check(self, K) -> None:
        _require_triangles(K, "the §6.4.4 adaptation")

    def codifferential(self, dec, k: int):
        """δ_flux = ⋆0⁻¹ (d0ᵀ ⋆1 − M_border F) for k = 1 on meshes with a border."""
        if k != 1 or dec.K.border_faces()[0].size == 0:
            return None
        adapted = dec.d(0).T @ dec.star(1) - border_vertex_matrix(dec.K) @ border_flux_matrix(dec)
        return (dec.star_inv(0) @ adapted).tocsr()
