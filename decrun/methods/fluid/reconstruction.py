"""Velocity reconstructions for the vorticity fluid: a continuous velocity from the flux 1-form.

The fluid needs velocities at arbitrary points (to backtrack, step c) and at the backtracked
dual-cell corners (to measure circulation, step d). Two reconstructions, chosen by name
(``VELOCITY_RECONSTRUCTIONS``; ``app.velocity=...``):

``"wshd07"`` (the thesis, §7.2.3): the constant velocity per triangle matching its three edge
    fluxes, placed at the circumcenter, interpolated over the flattened dual cell with the
    WSHD07 weights (interpolation.py). The constant per triangle is the field at a point
    that depends on the field: for a rigid rotation it is exact at the circumcenter, for a
    strain it is not (the flux of a strain through the edges vanishes about another point),
    so a straining flow is interpolated from O(h)-wrong corner values and the circulation of
    a backtracked cell drifts by O(dt) per step whatever the mesh size.

``"least_squares"``: per vertex, the linear field v(x) = a + G (x − x_v) in the vertex's
    tangent plane that best matches (least squares) the fluxes of the edges of its triangles,
    each flux being exact for a linear field, ∫_e v·n dl = v(midpoint_e)·(x_b − x_a) × N;
    the vertex velocity is a. Inside a triangle the three vertex velocities are interpolated
    linearly (P1, barycentric) and projected to the triangle's plane. It reproduces linear
    fields exactly (planar meshes, any triangle shapes) and is O(h²) for smooth fields, so
    its derivatives — and the circulation change of a moving cell — are consistent.
    Vertices with fewer than ``min_triangles`` triangles (border corners) fit over the
    triangles of their 2-ring.

Both expose the same three calls: ``fields(fluxes)`` (per-point data for F flux forms at once),
``velocity(triangle, x, data)`` → (P, 3, F) and ``circumcenter_matrix`` (3m, n1), the linear map
flux → velocities at the circumcenters (the cell corners before they move).
Units: positions in mesh units, fluxes in mesh units² / s, velocities in mesh units / s.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.core.dec import DEC
from decrun.core.geometry import embed3
from decrun.methods.fluid.backtrack import TriangleWalker
from decrun.methods.fluid.dual_cells import DualCells
from decrun.methods.fluid.interpolation import CellInterpolator, dot3, triangle_velocity_matrix

__all__ = ["VELOCITY_RECONSTRUCTIONS", "WSHD07Velocity", "LeastSquaresVelocity", "make_reconstruction",
           "vertex_velocity_matrix"]


class WSHD07Velocity:
    """The thesis' reconstruction: triangle constants at the circumcenters, WSHD07 over dual cells.

    ``fixed_velocity`` (n_fixed, 3, F) are the velocities of the fixed border dual points
    (border-edge midpoints and border vertices: the wall velocity, no-slip).
    """

    name = "wshd07"

    def __init__(self, dec: DEC, cells: DualCells, face_normal: np.ndarray, walker=None):
        self.cells, self.face_normal = cells, face_normal
        self.interpolator = CellInterpolator(cells, dec.K.simplices(2), dec.K.vertices)
        self.circumcenter_matrix = triangle_velocity_matrix(dec, face_normal)

    def fields(self, fluxes: np.ndarray, fixed_velocity: np.ndarray) -> np.ndarray:
        """(P, 3, F) velocities of all dual points for the F flux forms ``fluxes`` (n1, F)."""
        m = self.cells.n_circumcenters
        at_circumcenters = (self.circumcenter_matrix @ fluxes).reshape(m, 3, -1)
        return np.concatenate([at_circumcenters, fixed_velocity])

    def velocity(self, triangle: np.ndarray, x: np.ndarray, data: np.ndarray) -> np.ndarray:
        """(P, 3, F) velocities at points x (P, 3) inside ``triangle`` (P,)."""
        return self.interpolator.velocity(triangle, x, data, self.face_normal)


def _tangent_frames(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.where(np.abs(normal[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    e1 = np.cross(normal, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(normal, e1)


def _padded_rows(matrix: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
    """(rows, width) table of the column ids of each row of a 0/1 sparse matrix, padded with -1."""
    matrix = matrix.tocsr()
    matrix.sort_indices()
    count = np.diff(matrix.indptr)
    width = max(int(count.max()), 1)
    table = np.full((matrix.shape[0], width), -1, dtype=np.int64)
    slot = np.arange(matrix.indices.size) - np.repeat(matrix.indptr[:-1], count)
    table[np.repeat(np.arange(matrix.shape[0]), count), slot] = matrix.indices
    return table, count


def vertex_velocity_matrix(dec: DEC, vertex_normal: np.ndarray, min_triangles: int = 4) -> sp.csr_matrix:
    """Sparse (3 n0, n1) map from a flux 1-form to the least-squares velocity at every vertex.

    For vertex v with tangent frame (e1, e2) ⊥ N_v, the unknowns are a ∈ R² and G ∈ R^{2×2} of
    v(x) = a + G q, q = frame coordinates of x − x_v. The rows are the edges of the triangles
    around v (of its 2-ring if it has fewer than ``min_triangles``): edge a → b with
    r = ((x_b − x_a) × N_v) in the frame and midpoint q_e gives
    r·a + rᵀ G q_e = u_ab (exact for linear fields), each row divided by |x_b − x_a|.
    The velocity a (3-D, tangent at v) is the first block of the pseudo-inverse.
    """
    K = dec.K
    x = embed3(K.vertices)
    n0, n1 = K.num_simplices(0), K.num_simplices(1)
    top = K.simplices(2)
    m = top.shape[0]
    vertex_triangle = sp.csr_matrix((np.ones(3 * m), (top.ravel(), np.repeat(np.arange(m), 3))), shape=(n0, m))
    triangle_edge = sp.csr_matrix((np.ones(3 * m), (np.repeat(np.arange(m), 3), K.facet_indices(2).ravel())),
                                  shape=(m, n1))
    valence = np.diff(vertex_triangle.indptr)
    adjacency = (vertex_triangle @ vertex_triangle.T).astype(bool).astype(np.float64)
    wide = valence < min_triangles
    chosen = vertex_triangle.copy()
    if wide.any():
        two_ring = (adjacency @ vertex_triangle).astype(bool).astype(np.float64).tocsr()
        pick = sp.diags(wide.astype(np.float64))
        chosen = (sp.diags((~wide).astype(np.float64)) @ vertex_triangle + pick @ two_ring).astype(bool)
    vertex_edge = (chosen.astype(np.float64) @ triangle_edge).astype(bool).astype(np.float64)
    edge_table, count = _padded_rows(vertex_edge)  # (n0, E)
    valid = edge_table >= 0
    ids = np.where(valid, edge_table, 0)
    edges = K.simplices(1)
    xa, xb = x[edges[ids, 0]], x[edges[ids, 1]]  # (n0, E, 3)
    tangent = xb - xa
    length = np.linalg.norm(tangent, axis=2)
    e1, e2 = _tangent_frames(vertex_normal)
    r3 = np.cross(tangent, vertex_normal[:, None, :])
    r = np.stack([np.einsum("nkd,nd->nk", r3, e1), np.einsum("nkd,nd->nk", r3, e2)], -1) / length[..., None]
    mid = 0.5 * (xa + xb) - x[:, None, :]
    q = np.stack([np.einsum("nkd,nd->nk", mid, e1), np.einsum("nkd,nd->nk", mid, e2)], -1)
    design = np.concatenate([r, r[..., :1] * q, r[..., 1:] * q], axis=2)  # (n0, E, 6)
    design *= valid[..., None]
    h = np.where(valid, length, 0).sum(axis=1) / np.maximum(count, 1)  # scale the G columns (conditioning)
    design[..., 2:] /= h[:, None, None]
    pseudo = np.linalg.pinv(design)  # (n0, 6, E)
    a = pseudo[:, :2, :] / np.where(valid, length, 1.0)[:, None, :]  # the rows were divided by the edge length
    velocity = a[:, 0, :, None] * e1[:, None, :] + a[:, 1, :, None] * e2[:, None, :]  # (n0, E, 3)
    rows = 3 * np.arange(n0)[:, None, None] + np.arange(3)[None, None, :]  # (n0, 1, 3)
    rows = np.broadcast_to(rows, velocity.shape)
    cols = np.broadcast_to(ids[..., None], velocity.shape)
    keep = np.broadcast_to(valid[..., None], velocity.shape)
    return sp.csr_matrix((velocity[keep], (rows[keep], cols[keep])), shape=(3 * n0, n1))


class LeastSquaresVelocity:
    """Per-vertex least-squares velocity, linear inside each triangle (see the module docstring).

    ``walker`` supplies the barycentric coordinates of the triangles (``walker.barycentric``).
    """

    name = "least_squares"

    def __init__(self, dec: DEC, cells: DualCells, face_normal: np.ndarray, walker=None, min_triangles: int = 4):
        self.K = dec.K
        self.top = dec.K.simplices(2)
        self.face_normal = face_normal
        self.walker = walker if walker is not None else TriangleWalker(dec, face_normal)
        self.planar = bool(np.all(np.abs(face_normal - face_normal[:1]) < 1e-12))
        self.vertex_matrix = vertex_velocity_matrix(dec, cells.vertex_normal, min_triangles)
        m = self.top.shape[0]
        circumcenters = cells.points[:m]
        lam = self.walker.barycentric(np.arange(m), circumcenters)  # (m, 3), ≥ 0 without obtuse triangles
        n0 = dec.K.num_simplices(0)
        rows = np.repeat(np.arange(m), 3)
        interpolate = sp.csr_matrix((lam.ravel(), (rows, self.top.ravel())), shape=(m, n0))
        project = sp.kron(interpolate, sp.identity(3), format="csr")  # (3m, 3 n0) per component
        if not self.planar:  # remove the component along the triangle normal
            n = face_normal
            block = np.eye(3)[None] - n[:, :, None] * n[:, None, :]  # (m, 3, 3)
            project = _block_diagonal(block) @ project
        self.circumcenter_matrix = (project @ self.vertex_matrix).tocsr()

    def fields(self, fluxes: np.ndarray, fixed_velocity: np.ndarray | None = None) -> np.ndarray:
        """(n0, 3, F) vertex velocities of the F flux forms ``fluxes`` (n1, F)."""
        return (self.vertex_matrix @ fluxes).reshape(self.K.num_simplices(0), 3, -1)

    def velocity(self, triangle: np.ndarray, x: np.ndarray, data: np.ndarray) -> np.ndarray:
        """(P, 3, F) P1 interpolation of the vertex velocities at x (P, 3) in ``triangle`` (P,).

        Summed as (λ0 U0 + λ1 U1) + λ2 U2 and projected with ``dot3``: the order of the numba
        twin (compiled._p1), so both give the same bits."""
        lam = self.walker.barycentric(triangle, x)
        corners = np.take(self.top, triangle, axis=0)
        U = (lam[:, 0, None, None] * data[corners[:, 0]] + lam[:, 1, None, None] * data[corners[:, 1]]) \
            + lam[:, 2, None, None] * data[corners[:, 2]]
        if self.planar:
            return U
        n = np.take(self.face_normal, triangle, axis=0)
        return U - n[:, :, None] * dot3(np.moveaxis(U, 1, 2), n[:, None, :])[:, None, :]

    def kernel_tables(self) -> tuple:
        """The tables the numba kernels (compiled.py) read for this reconstruction: triangles
        (m, ≥ 3: the corners first), per triangle ∇λ (9) and centroid (3) (m, ≥ 12: those first),
        an empty corner table, planar and the scheme code 1 (compiled._p1). The first two are the
        walker's own rows (TriangleWalker.kernel_tables: tri_int, tri_real, which begin so): the
        walk, bound by memory more than by arithmetic, reads one row per triangle for both
        instead of a copy beside it."""
        if getattr(self, "_kernel_tables", None) is None:
            walk, _ = self.walker.kernel_tables()
            self._kernel_tables = (walk[2], walk[1], np.zeros((0, 1), dtype=np.int64), bool(self.planar), 1)
        return self._kernel_tables

    def velocity_compiled(self, triangle: np.ndarray, x: np.ndarray, point_velocity: np.ndarray,
                          face_normal: np.ndarray | None = None) -> np.ndarray:
        """:meth:`velocity` by the numba kernel (compiled.velocity_points): (P, 3, F), the same bits."""
        from decrun.core import jit
        from decrun.methods.fluid import compiled

        return compiled.velocity_points(self.kernel_tables(), np.ascontiguousarray(triangle, dtype=np.int64),
                                        np.ascontiguousarray(x, dtype=np.float64),
                                        np.ascontiguousarray(point_velocity, dtype=np.float64),
                                        np.ascontiguousarray(self.face_normal, dtype=np.float64), jit.threads())


def _block_diagonal(blocks: np.ndarray) -> sp.csr_matrix:
    """Sparse block-diagonal matrix of (m, 3, 3) blocks."""
    m = blocks.shape[0]
    rows = 3 * np.arange(m)[:, None, None] + np.arange(3)[None, :, None]
    cols = 3 * np.arange(m)[:, None, None] + np.arange(3)[None, None, :]
    return sp.csr_matrix((blocks.ravel(), (np.broadcast_to(rows, blocks.shape).ravel(),
                                           np.broadcast_to(cols, blocks.shape).ravel())), shape=(3 * m, 3 * m))


VELOCITY_RECONSTRUCTIONS = {"wshd07": WSHD07Velocity, "least_squares": LeastSquaresVelocity}


def make_reconstruction(name: str, dec: DEC, cells: DualCells, face_normal: np.ndarray, walker=None):
    """The reconstruction called ``name`` (a key of ``VELOCITY_RECONSTRUCTIONS``)."""
    return VELOCITY_RECONSTRUCTIONS[name](dec, cells, face_normal, walker)
