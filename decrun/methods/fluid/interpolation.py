"""A continuous velocity field from the flux 1-form (thesis §7.2.3, ETK07, WSHD07).

1. Per triangle, the constant vector whose fluxes through the three edges are the
   values of the flux 1-form ``u`` (consistent because ``d1 u = 0``; it equals the
   Whitney ♯ (eq. 6.7) of the rotated form at the barycenter). It is the velocity at the
   circumcenter, the dual vertex.
2. At any point x: find its dual cell (the nearest corner of the triangle holding x),
   flatten the cell along the vertex normal, weight its corners with the generalized
   barycentric (Wachspress) weights of Warren, Schaefer, Hirani, Desbrun 2007

       c_j = det(n_j1, n_j2) / (<n_j1, p_j - x> <n_j2, p_j - x>),   w_j = c_j / Σ_i c_i,

   (n_j1, n_j2 outward normals of the two polygon edges at p_j) and project the
   interpolated vector back into the triangle's plane along the vertex normal.

Units: positions in mesh units, fluxes in (mesh units)²/s, velocities in mesh units/s.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.core.dec import DEC
from decrun.core.geometry import embed3
from decrun.methods.fluid.dual_cells import DualCells

__all__ = ["triangle_velocity_matrix", "wachspress_weights", "CellInterpolator", "dot3"]


def dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """<a, b> over the last axis (length 3) as (a0 b0 + a1 b1) + a2 b2: the order of the numba
    kernels (compiled.py), so both paths round alike (einsum's order depends on its SIMD
    width). Broadcasts like ``a * b``."""
    return (a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]) + a[..., 2] * b[..., 2]


def triangle_velocity_matrix(dec: DEC, face_normal: np.ndarray) -> sp.csr_matrix:
    """Sparse (3m, n1) map from a flux 1-form to the constant velocity per triangle.

    ``(M @ u).reshape(m, 3)[t]`` is v_t = ⅓ Σ_{edges ab of t} u_ab (∇λ_b − ∇λ_a) × N_t:
    the Whitney ♯ (eq. 6.7) at the barycenter of the 1-form ``u`` read as the
    circulation of the rotated field N × v, rotated back. For ``d1 u = 0`` on t this is
    the unique constant vector with flux ``<v, (x_b − x_a) × N_t> = u_ab`` through every
    edge a → b (the flux to the right of the edge, §7.2.1).
    """
    K = dec.K
    x = embed3(K.vertices)
    top = K.simplices(2)
    p = x[top]  # (m, 3, 3) sorted vertex order
    gradients = np.empty_like(p)
    for i in range(3):
        a, b = p[:, (i + 1) % 3], p[:, (i + 2) % 3]
        edge = b - a
        h = p[:, i] - a
        h = h - (np.einsum("md,md->m", h, edge) / np.einsum("md,md->m", edge, edge))[:, None] * edge
        gradients[:, i] = h / np.einsum("md,md->m", h, h)[:, None]
    rotated = np.cross(gradients, face_normal[:, None, :])  # ∇λ_i × N
    opposite = K.facet_indices(2)  # edge opposite local vertex l: (1,2), (0,2), (0,1)
    pairs = [(1, 2, 0), (0, 2, 1), (0, 1, 2)]  # (a, b, l): edge a<b opposite l
    m = top.shape[0]
    rows, cols, vals = [], [], []
    for a, b, l in pairs:
        value = (rotated[:, b] - rotated[:, a]) / 3.0  # (m, 3)
        for d in range(3):
            rows.append(3 * np.arange(m) + d)
            cols.append(opposite[:, l])
            vals.append(value[:, d])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(3 * m, K.num_simplices(1)))


def wachspress_weights(x: np.ndarray, corners: np.ndarray, valid: np.ndarray | None = None,
                       tiny: float = 1e-13) -> np.ndarray:
    """WSHD07 generalized barycentric weights of points in convex planar polygons.

    Parameters
    ----------
    x : (P, 2) query points
    corners : (P, K, 2) polygon corners, counter-clockwise; padded slots flagged in ``valid``
    valid : (P, K) bool, the first ``count`` slots of each row are the polygon (default all)
    tiny : edge distances are clamped to ``tiny`` × the squared polygon size, so points on
        an edge (or a corner) get the limit weights (linear along the edge)

    Returns
    -------
    (P, K) weights ≥ 0 summing to 1 (0 on padded slots); they reproduce linear
    functions: Σ_j w_j p_j = x for x inside the polygon.
    """
    P, Kc, _ = corners.shape
    valid = np.ones((P, Kc), dtype=bool) if valid is None else valid
    count = valid.sum(axis=1)
    slot = np.arange(Kc)[None, :]
    nxt = np.where(slot + 1 >= count[:, None], 0, slot + 1)
    prv = np.where(slot == 0, count[:, None] - 1, slot - 1)
    following = np.take_along_axis(corners, nxt[..., None], axis=1)
    edge = following - corners  # edge j: corner j -> corner j+1
    normal = np.stack([edge[..., 1], -edge[..., 0]], axis=-1)  # outward for counter-clockwise polygons
    offset = np.einsum("pkd,pkd->pk", normal, corners)
    det = _cross2(np.take_along_axis(normal, prv[..., None], axis=1), normal)
    return _weights_from_tables(x, normal, offset, det, prv, valid, tiny)


def _cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _weights_from_tables(x, normal, offset, det, prv, valid, tiny):
    scale = np.max(np.abs(det), axis=1, keepdims=True)
    h = offset - normal[..., 0] * x[:, None, 0] - normal[..., 1] * x[:, None, 1]  # <n_j, p_j − x>
    h = np.where(valid, np.maximum(h, tiny * scale), 1.0)
    c = np.where(valid, det / (np.take_along_axis(h, prv, axis=1) * h), 0.0)
    return c / c.sum(axis=1, keepdims=True)


class CellInterpolator:
    """WSHD07 interpolation of dual-point velocities over the flattened dual cells (§7.2.3).

    Geometry (vertex frames, flattened corners, edge normals, numerators) is computed once;
    each evaluation is a few gathers over (P, K) arrays. Flattening is linear, so the
    flattened interpolant Σ w_j (u_j − N_v <N_v, u_j>) followed by the projection back to
    the triangle's plane along N_v collapses to u = U − N_v <U, N_t> / <N_v, N_t> with
    U = Σ w_j u_j (the 3-D weighted sum of the corner velocities).

    Parameters
    ----------
    cells : DualCells
    triangles : (m, 3) vertex ids of the triangles (any order; used to find the nearest corner)
    vertices : (n0, 2|3) vertex positions
    """

    def __init__(self, cells: DualCells, triangles: np.ndarray, vertices: np.ndarray, tiny: float = 1e-13):
        self.cells = cells
        self.triangles = np.asarray(triangles, dtype=np.int64)
        self.vertices = embed3(vertices)
        self.tiny = tiny
        normal = cells.vertex_normal
        helper = np.where(np.abs(normal[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
        e1 = np.cross(normal, helper)
        e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
        self.e1, self.e2 = e1, np.cross(normal, e1)
        ids = cells.interpolation_corners
        self.valid = ids >= 0
        self.count = cells.interpolation_count
        self.ids = np.where(self.valid, ids, ids[:, :1])
        relative = cells.points[self.ids] - self.vertices[:, None, :]
        q = np.stack([np.einsum("nkd,nd->nk", relative, self.e1), np.einsum("nkd,nd->nk", relative, self.e2)], -1)
        Kc = ids.shape[1]
        slot = np.arange(Kc)[None, :]
        nxt = np.where(slot + 1 >= self.count[:, None], 0, slot + 1)
        prv = np.where(slot == 0, self.count[:, None] - 1, slot - 1)
        edge = np.take_along_axis(q, nxt[..., None], axis=1) - q
        normal2 = np.stack([edge[..., 1], -edge[..., 0]], axis=-1)  # outward edge normals
        offset = np.einsum("nkd,nkd->nk", normal2, q)
        det = _cross2(np.take_along_axis(normal2, prv[..., None], axis=1), normal2)
        self.convex = np.all((det >= -1e-12 * np.abs(det).max(axis=1, keepdims=True)) | ~self.valid, axis=1)
        # padded edges: zero normal and unit offset (distance 1, neutral); padded corners: det 0
        self.n1 = np.where(self.valid, normal2[..., 0], 0.0)
        self.n2 = np.where(self.valid, normal2[..., 1], 0.0)
        self.offset = np.where(self.valid, offset, 1.0)
        self.det = np.where(self.valid, det, 0.0)
        self.scale = self.tiny * np.abs(self.det).max(axis=1)
        self.last = self.count - 1
        self.flat_corners = q
        closing = self.count - 1  # column 0 repeats the closing edge, so corner j sits between columns j, j+1
        rows = np.arange(self.count.size)
        edge_table = np.stack([self.offset, self.n1, self.n2], axis=1)  # (n0, 3, K)
        edge_table = np.concatenate([edge_table[rows, :, closing][:, :, None], edge_table], axis=2)
        det = np.concatenate([np.zeros((self.count.size, 1)), self.det], axis=1)
        self.table = np.ascontiguousarray(np.concatenate([edge_table, det[:, None, :]], axis=1))  # (n0, 4, K+1)
        self.frames = np.ascontiguousarray(np.stack([self.e1, self.e2], axis=1))
        self.n_points = cells.points.shape[0]
        normal = cells.vertex_normal
        self.planar = bool(np.all(np.abs(normal - normal[:1]) < 1e-12))
        self.vertex_columns = [np.ascontiguousarray(self.vertices[:, a]) for a in range(3)]

    def nearest_vertex(self, triangle: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(P,) the corner of ``triangle`` (P,) nearest to ``x`` (P, 3): the dual cell holding x."""
        corners = np.take(self.triangles, triangle, axis=0)  # (P, 3)
        distance = np.zeros(corners.shape)
        for a in range(3):
            diff = self.vertex_columns[a][corners] - x[:, a, None]
            distance += diff * diff
        return corners[np.arange(corners.shape[0]), np.argmin(distance, axis=1)]

    def flatten(self, vertex: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(P, 2) coordinates of x projected along the normal of ``vertex`` into its frame."""
        relative = x - self.vertices[vertex]
        return np.stack([(relative * self.e1[vertex]).sum(axis=1), (relative * self.e2[vertex]).sum(axis=1)], axis=1)

    def weights(self, vertex: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(P, Ki) WSHD07 weights of the corners ``interpolation_corners[vertex]`` at x (P, 3)."""
        relative = x - np.take(self.vertices, vertex, axis=0)
        frame = np.take(self.frames, vertex, axis=0)  # (P, 2, 3)
        f1, f2 = dot3(relative, frame[:, 0]), dot3(relative, frame[:, 1])
        table = np.take(self.table, vertex, axis=0)  # (P, 4, K+1): offset, n1, n2 of edges (last, 0..K-1), det of corners
        h = table[:, 0] - table[:, 1] * f1[:, None] - table[:, 2] * f2[:, None]
        np.maximum(h, np.take(self.scale, vertex)[:, None], out=h)
        c = h[:, :-1] * h[:, 1:]  # h of the edge before and after each corner
        np.divide(table[:, 3, 1:], c, out=c)
        total = c[:, 0].copy()
        for k in range(1, c.shape[1]):  # in order, as the kernel sums (numpy's sum is pairwise)
            total += c[:, k]
        c /= total[:, None]
        return c

    def velocity(self, triangle: np.ndarray, x: np.ndarray, point_velocity: np.ndarray,
                 face_normal: np.ndarray) -> np.ndarray:
        """Interpolated velocities (P, 3, F) at points x (P, 3) lying in ``triangle`` (P,).

        ``point_velocity`` (n_points, 3, F) holds F velocity fields at the dual points.
        """
        vertex = self.nearest_vertex(triangle, x)
        w = self.weights(vertex, x)
        P, Kc = w.shape
        W = sp.csr_matrix((w.ravel(), np.take(self.ids, vertex, axis=0).ravel(), np.arange(0, P * Kc + 1, Kc)),
                          shape=(P, self.n_points))
        F = point_velocity.shape[2]
        U = (W @ point_velocity.reshape(self.n_points, 3 * F)).reshape(P, 3, F)
        if self.planar:
            return U
        n_v = np.take(self.cells.vertex_normal, vertex, axis=0)
        n_t = np.take(face_normal, triangle, axis=0)
        ratio = dot3(np.moveaxis(U, 1, 2), n_t[:, None, :]) / dot3(n_v, n_t)[:, None]
        U -= n_v[:, :, None] * ratio[:, None, :]
        return U

    def kernel_tables(self) -> tuple:
        """The interpolation tables as the tuple the numba kernels (compiled.py) read: triangles
        (m, 3); one row per vertex (n0, 13 + 4 (K+1)): position, frame (e1, e2), normal, clamp
        scale, then the edge/corner table (offset, n1, n2, det; K+1 columns each); corner ids
        (n0, K); planar; the scheme code 0 (WSHD07; 1 is the least-squares reconstruction's)."""
        if getattr(self, "_kernel_tables", None) is None:
            n0 = self.vertices.shape[0]
            cell_real = np.concatenate([self.vertices, self.frames.reshape(n0, 6), self.cells.vertex_normal,
                                        self.scale[:, None], self.table.reshape(n0, -1)], axis=1)
            self._kernel_tables = (np.ascontiguousarray(self.triangles, dtype=np.int64),
                                   np.ascontiguousarray(cell_real, dtype=np.float64),
                                   np.ascontiguousarray(self.ids, dtype=np.int64), bool(self.planar), 0)
        return self._kernel_tables

    def velocity_compiled(self, triangle: np.ndarray, x: np.ndarray, point_velocity: np.ndarray,
                          face_normal: np.ndarray) -> np.ndarray:
        """:meth:`velocity` by the numba kernel (compiled.py): (P, 3, F), equal to round-off."""
        from decrun.core import jit
        from decrun.methods.fluid import compiled

        return compiled.velocity_points(self.kernel_tables(), np.ascontiguousarray(triangle, dtype=np.int64),
                                        np.ascontiguousarray(x, dtype=np.float64),
                                        np.ascontiguousarray(point_velocity, dtype=np.float64),
                                        np.ascontiguousarray(face_normal, dtype=np.float64), jit.threads())
