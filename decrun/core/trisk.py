"""TRiSK: the energy-conserving DEC discretization of the rotating shallow-water equations
(Thuburn, Ringler, Skamarock & Klemp 2009, J. Comput. Phys. 228; Ringler et al. 2010,
J. Comput. Phys. 229) on a closed triangulated surface and its circumcentric (Voronoi) dual.

TRiSK *is* DEC on the circumcentric dual; the dictionary (TRiSK ⇔ DEC, all lengths and areas
those of :class:`decrun.core.dec.DEC`, i.e. of the flat triangles and their circumcentric dual):

=======================  ===========================  =======================================
TRiSK                    DEC                          here
=======================  ===========================  =======================================
cell i (Voronoi cell)    vertex i / dual 2-cell ⋆i    ``cell_areas`` A_i = |⋆i| (= ⋆0)
vertex v (cell corner)   triangle v / dual 0-cell     ``triangle_areas`` A_v = |v|
edge e                   primal edge e ⟂ dual edge ⋆e d_e = |e| (``primal_lengths``), l_e = |⋆e|
normal velocity u_e      primal 1-form U_e = u_e d_e  circulation along e (m² s⁻¹)
flux l_e h_e u_e         dual 1-form G = ⋆1 (h_e U)   (m³ s⁻¹) through ⋆e, along e's orientation
depth h_i                dual 2-form A_i h_i          stored as the cell values h_i (m)
vorticity ζ_v            primal 2-form d1 U / A_v     a dual 0-form value (s⁻¹)
kite area A_{i,v}        the circumcentric corner     ``kite_areas`` (signed; Σ_v = A_i, Σ_i = A_v)
=======================  ===========================  =======================================

Edges are oriented from their smaller to their larger vertex index (``K.simplices(1)``); a
positive U_e or G_e points along that orientation. The semi-discrete equations (vector-invariant
form, b the bottom topography, f the Coriolis parameter at the triangles' circumcenters)::

    ∂(A_i h_i)/∂t = (d0ᵀ G)_i,                       G = ⋆1 (h_e U),  h_e = (h_i + h_j)/2
    ∂U/∂t = −d0 (K + g (h + b)) − Q(q_e, G),         q_v = (ζ_v + f_v)/h_v,  q_e = (q_v + q_v')/2

with Q(q_e, G)_e = Σ_e' W_ee' (q_e + q_e')/2 G_e' the perpendicular flux (TRiSK's W in DEC form:
an **antisymmetric** matrix from dual 1-forms to primal 1-forms, ≈ d_e q (h u)^⊥·t_e). Because W is
antisymmetric the Coriolis term does no work, Σ_e G_e Q(q, G)_e = 0, and with the kinetic energy
K_i = (1/(4A_i)) Σ_{e∋i} ⋆1_e U_e² the total energy

    E = Σ_i A_i (h_i K_i + g h_i (h_i/2 + b_i))

is conserved by the semi-discrete equations; mass Σ_i A_i h_i is conserved exactly (1ᵀ d0ᵀ = 0).

Every operator is a sparse matrix built once (vectorized; the only Python loop walks the at most
``max vertex degree`` steps around all cells at once).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.core.cache import Cached
from decrun.core.dec import DEC, diagonal_matrix
from decrun.errors import MeshError

__all__ = ["TRiSK", "corner_kite_areas", "sphere_radius"]


def sphere_radius(vertices: np.ndarray, rtol: float = 1e-9) -> float:
    """The radius a (model units) of the sphere centred at the origin that holds every vertex
    (the mean of |x_i|); raises :class:`MeshError` in one line when a vertex is off it by more than
    ``rtol`` a (a noisy or shifted mesh: the icosphere's default ``mesh.noise`` is 0.3)."""
    distance = np.linalg.norm(vertices, axis=1)
    radius = float(distance.mean())
    worst = int(np.argmax(np.abs(distance - radius)))
    if not radius > 0 or abs(distance[worst] - radius) > rtol * radius:
        raise MeshError(f"mesh: not a sphere centred at the origin: vertex {worst} is at {distance[worst]:.9g} from "
                        f"the origin, the mean is {radius:.9g} (use mesh=icosphere mesh.noise=0)")
    return radius


def corner_kite_areas(points: np.ndarray) -> np.ndarray:
    """Signed circumcentric (Voronoi) area of each corner of each triangle, (m, 3).

    ``points`` (m, 3, d) are the corners p0, p1, p2. The corner of p0 is the kite bounded by p0,
    the midpoints of its two edges and the circumcenter: (|e2|² cot θ2 + |e1|² cot θ1)/8 with
    e_i the edge opposite corner i and θ_i its angle (thesis §4.5.5); negative pieces where the
    circumcenter lies outside. The three corners sum to the triangle's area.
    """
    p0, p1, p2 = points[:, 0], points[:, 1], points[:, 2]
    e0, e1, e2 = p2 - p1, p0 - p2, p1 - p0
    double_area = np.linalg.norm(np.cross(e1, e2), axis=1)
    cot = -np.stack([np.einsum("md,md->m", e1, e2), np.einsum("md,md->m", e2, e0),
                     np.einsum("md,md->m", e0, e1)]) / double_area
    weighted = np.stack([np.einsum("md,md->m", e, e) for e in (e0, e1, e2)]) * cot  # |e_i|² cot θ_i
    return np.column_stack([weighted[2] + weighted[1], weighted[0] + weighted[2], weighted[1] + weighted[0]]) / 8.0


class TRiSK(Cached):
    """The TRiSK operators of a closed triangulated surface in R³ (module doc for the equations).

    Parameters
    ----------
    dec : DEC
        Its complex must be a closed oriented triangle mesh in R³ whose circumcentric dual edges
        all have positive length (a Delaunay mesh: the Voronoi cells are the TRiSK cells). The
        circumcentric dual volumes (``dec.dual_volumes``) are used whatever ``dec``'s star variant.

    Raises
    ------
    MeshError naming the offending simplices.
    """

    def __init__(self, dec: DEC):
        K = dec.K
        if K.dim != 2 or K.embedding_dim != 3:
            raise MeshError(f"TRiSK needs a triangle mesh in R³, got a {K.dim}-complex in R^{K.embedding_dim}")
        border, _ = K.border_faces()
        if border.size:
            raise MeshError(f"TRiSK needs a closed surface: the mesh has {border.size} border edges "
                            f"(e.g. edge {int(border[0])})")
        self.dec = dec
        self.K = K
        bad = np.flatnonzero(self.dual_lengths <= 0)
        if bad.size:
            raise MeshError(f"TRiSK needs positive dual edge lengths (a Delaunay mesh): {bad.size} edges have "
                            f"|⋆e| <= 0 (e.g. edge {int(bad[0])} {K.simplices(1)[bad[0]].tolist()})")

    # ------------------------------------------------------------------ geometry
    @property
    def cell_areas(self) -> np.ndarray:
        """(n0,) A_i = |⋆i|, the Voronoi cell areas (m²); Σ A_i is the surface's area."""
        return self.dec.dual_volumes(0)

    @property
    def triangle_areas(self) -> np.ndarray:
        """(n2,) A_v, the triangles' areas (m²)."""
        return self.K.top_volumes

    @property
    def primal_lengths(self) -> np.ndarray:
        """(n1,) d_e = |e|, the distance between the two cell centres of edge e (m)."""
        return self.dec.primal_volumes(1)

    @property
    def dual_lengths(self) -> np.ndarray:
        """(n1,) l_e = |⋆e|, the Voronoi edge lengths (m)."""
        return self.dec.dual_volumes(1)

    @property
    def star1(self) -> np.ndarray:
        """(n1,) ⋆1 = l_e/d_e: maps the circulation U to the flux u_e l_e through ⋆e."""
        return self.require("star1", lambda: self.dual_lengths / self.primal_lengths)

    def outward_triangles(self) -> np.ndarray:
        """(n2, 3) the triangles consistently oriented with normals pointing out of the enclosed
        volume (counterclockwise seen from outside): the orientation whose cell corners are
        walked counterclockwise."""

        def compute():
            oriented = self.K.oriented_simplices()
            p = self.K.vertices[oriented]
            volume = np.einsum("md,md->", p[:, 0], np.cross(p[:, 1], p[:, 2])) / 6.0
            return oriented if volume > 0 else oriented[:, ::-1].copy()

        return self.require("outward_triangles", compute)

    def kite_areas(self) -> np.ndarray:
        """(n2, 3) signed kite areas A_{i,v} of the corners of ``outward_triangles()`` (m²):
        Σ over a triangle's corners = A_v, Σ over a cell's corners = A_i (⋆0)."""
        return self.require("kite_areas", lambda: corner_kite_areas(self.K.vertices[self.outward_triangles()]))

    def coriolis_points(self) -> np.ndarray:
        """(n2, 3) the dual vertices (triangle circumcenters) where ζ, f and q live."""
        return self.dec.circumcenters(2)

    # ------------------------------------------------------------------ interpolations
    def edge_average(self) -> sp.csr_matrix:
        """(n1, n0) h_e = (h_i + h_j)/2: a cell field on the edges (|d0|/2)."""
        return self.require("edge_average", lambda: abs(self.dec.d(0)).multiply(0.5).tocsr())

    def cell_to_triangle(self) -> sp.csr_matrix:
        """(n2, n0) h_v = Σ_{i∈v} A_{i,v} h_i / A_v: the area-weighted depth on the triangles."""

        def compute():
            rows = np.repeat(np.arange(self.K.num_simplices(2)), 3)
            weights = self.kite_areas() / self.triangle_areas[:, None]
            return sp.csr_matrix((weights.ravel(), (rows, self.outward_triangles().ravel())),
                                 shape=(self.K.num_simplices(2), self.K.num_simplices(0)))

        return self.require("cell_to_triangle", compute)

    def triangle_to_edge(self) -> sp.csr_matrix:
        """(n1, n2) q_e = (q_v + q_v')/2: the mean of the two triangles of each edge (|d1|ᵀ/2)."""
        return self.require("triangle_to_edge", lambda: abs(self.dec.d(1)).T.multiply(0.5).tocsr())

    # ------------------------------------------------------------------ derivatives
    def gradient(self, phi: np.ndarray) -> np.ndarray:
        """(n1,) d0 φ: the primal 1-form φ_j − φ_i of a cell field (TRiSK's gradient times d_e)."""
        return self.dec.d(0) @ phi

    def divergence(self, flux: np.ndarray) -> np.ndarray:
        """(n0,) ∇·F on the cells: −(d0ᵀ G)_i / A_i for the dual 1-form G = ⋆1 (h_e U) (s⁻¹ times the
        units of h): the net outflow through the cell's Voronoi edges over its area. Σ_i A_i ∇·F = 0."""
        return -(self.dec.d(0).T @ flux) / self.cell_areas

    def vorticity(self, circulation: np.ndarray) -> np.ndarray:
        """(n2,) ζ_v = (d1 U)_v / A_v: the circulation around each triangle over its area (s⁻¹);
        ζ of a gradient is 0 exactly (d1 d0 = 0)."""
        return (self.dec.d(1) @ circulation) / self.triangle_areas

    # ------------------------------------------------------------------ fluxes and energies
    def mass_flux(self, depth: np.ndarray, circulation: np.ndarray) -> np.ndarray:
        """(n1,) G = ⋆1 (h_e U) = l_e h_e u_e: the volume flux through each Voronoi edge (m³ s⁻¹)."""
        return self.star1 * (self.edge_average() @ depth) * circulation

    def kinetic_matrix(self) -> sp.csr_matrix:
        """(n0, n1) the map U² ↦ K: K_i = (1/(4 A_i)) Σ_{e∋i} ⋆1_e U_e² = (1/A_i) Σ_{e∋i} (l_e d_e/4) u_e²
        (Ringler et al. 2010); Σ_i A_i K_i = Σ_e l_e d_e u_e²/2."""

        def compute():
            scale = diagonal_matrix(0.25 / self.cell_areas)
            return (scale @ abs(self.dec.d(0)).T @ diagonal_matrix(self.star1.copy())).tocsr()

        return self.require("kinetic_matrix", compute)

    def kinetic_energy(self, circulation: np.ndarray) -> np.ndarray:
        """(n0,) K_i, the kinetic energy per unit mass on the cells (m² s⁻²)."""
        return self.kinetic_matrix() @ (circulation * circulation)

    def potential_vorticity(self, circulation: np.ndarray, depth: np.ndarray, coriolis: np.ndarray) -> np.ndarray:
        """(n2,) q_v = (ζ_v + f_v) / h_v on the triangles (m⁻¹ s⁻¹), h_v from ``cell_to_triangle``."""
        return (self.vorticity(circulation) + coriolis) / (self.cell_to_triangle() @ depth)

    def pv_on_edges(self, pv: np.ndarray) -> np.ndarray:
        """(n1,) q_e = (q_v + q_v')/2, the mean of the potential vorticity of the edge's two triangles."""
        return self.triangle_to_edge() @ pv

    # ------------------------------------------------------------------ the perpendicular flux
    def perp(self) -> sp.csr_matrix:
        """(n1, n1) TRiSK's W in DEC form: (W G)_e ≈ d_e (F^⊥ · t_e) = ∫_e (k × F)·dl for the flux
        dual 1-form G_e = l_e F·t_e (F tangent, k the outward normal).

        Thuburn et al. (2009): around each cell i of edge e, with o_i(e) = ±1 the sign of
        the outward flux of cell i through ⋆e (+1 when e starts at i),

            W_ee' = Σ_{cells i ∋ e, e'} o_i(e) o_i(e') (Σ_{v from e to e'} A_{i,v}/A_i − 1/2),

        the sum over the cell's corners v met going counterclockwise from e to e'. Going the other
        way round gives 1 minus that sum, so W_e'e = −W_ee'; the matrix is assembled from its upper
        triangle as U − Uᵀ, antisymmetric bit for bit. With the flux weights l_e and 1/d_e of
        TRiSK's form, W^TRiSK_ee' = W_ee' / (d_e) acting on l_e' F_e'.
        """
        return self.require("perp", self._assemble_perp)

    def _assemble_perp(self) -> sp.csr_matrix:
        edges = self.K.simplices(1)
        n1 = edges.shape[0]
        triangles = self.outward_triangles()
        kites = self.kite_areas()
        # corner (triangle t, local l): vertex a = triangles[t, l]; counterclockwise around a the
        # corner lies between edge (a, b) and edge (a, c), b, c the next corners of the outward triangle
        a = triangles.ravel()
        b = np.roll(triangles, -1, axis=1).ravel()
        c = np.roll(triangles, -2, axis=1).ravel()
        edge_in = self.K.find_simplices(np.column_stack([a, b]))
        edge_out = self.K.find_simplices(np.column_stack([a, c]))
        # half-edge slot 2e + (a is e's end): one per (cell, edge) incidence
        slot_in = 2 * edge_in + (edges[edge_in, 1] == a)
        slot_out = 2 * edge_out + (edges[edge_out, 1] == a)
        corner_of_slot = np.empty(2 * n1, dtype=np.int64)
        corner_of_slot[slot_in] = np.arange(a.size)
        fraction = kites.ravel() / self.cell_areas[a]
        outward = 1.0 - 2.0 * (np.arange(2 * n1) % 2)  # o_i(e): +1 when e starts at i
        start = np.arange(2 * n1)
        current = start.copy()
        swept = np.zeros(2 * n1)
        rows, cols, values = [], [], []
        while start.size:  # at most (max degree) rounds, each over every unfinished walk at once
            corner = corner_of_slot[current]
            swept = swept + fraction[corner]
            current = slot_out[corner]
            going = current != start
            start, current, swept = start[going], current[going], swept[going]
            rows.append(start // 2)
            cols.append(current // 2)
            values.append(outward[start] * outward[current] * (swept - 0.5))
        rows_all, cols_all, values_all = np.concatenate(rows), np.concatenate(cols), np.concatenate(values)
        upper = rows_all < cols_all
        half = sp.csr_matrix((values_all[upper], (rows_all[upper], cols_all[upper])), shape=(n1, n1))
        return (half - half.T).tocsr()

    def coriolis_term(self, pv_edges: np.ndarray, flux: np.ndarray) -> np.ndarray:
        """(n1,) Q(q, G)_e = Σ_e' W_ee' (q_e + q_e')/2 G_e' = ½ (q_e (W G)_e + (W (q G))_e) ≈
        d_e q (h u)^⊥·t_e (m² s⁻²), energy-neutral: Σ_e G_e Q_e = 0 for any q, G (W antisymmetric)."""
        W = self.perp()
        return 0.5 * (pv_edges * (W @ flux) + W @ (pv_edges * flux))

    # ------------------------------------------------------------------ time step
    def laplacian_bound(self) -> float:
        """Gershgorin's bound on the largest eigenvalue of the cell Laplacian ⋆0⁻¹ d0ᵀ ⋆1 d0 (m⁻²):
        λ_max ≤ max_i (2/A_i) Σ_{e∋i} l_e/d_e. Gravity waves of speed c have frequencies ≤ c √λ_max."""
        return self.require("laplacian_bound", lambda: float(
            np.max(2.0 * (abs(self.dec.d(0)).T @ self.star1) / self.cell_areas)))
