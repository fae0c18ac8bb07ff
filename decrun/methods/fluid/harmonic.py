"""The harmonic part c of the flux (thesis §7.2.5, eq. 7.9–7.11; ETK07 §4.4).

Wanted: a flux 1-form c with d1 c = 0 (no divergence), zero vorticity at interior
vertices, zero circulation around each obstacle (its merged dual cell, Fig. 7.12),
c = 0 on obstacle edges and c = the flux of a uniform velocity v on the outer border
(eq. 7.10). With zero flux through an obstacle loop the period of c around it is 0, so c
is exact: c = d0 χ with

    χ = <N × v, x> on the outer border(s),  χ = one unknown constant per obstacle,
    (d0ᵀ ⋆1 d0 χ)_i = 0 at interior vertices,  Σ_{i ∈ obstacle} (d0ᵀ ⋆1 d0 χ)_i = 0,

a square symmetric system (:func:`harmonic_flux`). Computing c as d0 χ keeps
``d1 c = 0`` to round-off, which the least-squares form (7.11) only reaches to its
solver accuracy; :func:`harmonic_flux_least_squares` solves (7.11) as printed (with the
printed formula corrected) for comparison and reports its residual.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.core.connectivity import edge_owners
from decrun.core.dec import DEC
from decrun.core.geometry import embed3

__all__ = ["border_layout", "uniform_flux", "harmonic_flux", "harmonic_flux_least_squares"]


def border_layout(dec: DEC, obstacle_loops=None) -> tuple[list[np.ndarray], np.ndarray]:
    """Obstacle loops and a per-vertex border label.

    Parameters
    ----------
    obstacle_loops : list of (L,) vertex-id arrays, each a border loop that is an obstacle;
        default: every border loop except the longest (the outer border)

    Returns
    -------
    obstacles : list of (L,) int64 arrays
    label : (n0,) int64: -1 interior, 0 outer border, i+1 on obstacle i
    """
    K = dec.K
    loops = K.border_loops()
    if obstacle_loops is None:
        obstacles = [np.asarray(loop, dtype=np.int64) for loop in loops[1:]]
    else:
        obstacles = [np.asarray(loop, dtype=np.int64) for loop in obstacle_loops]
    label = np.full(K.num_simplices(0), -1, dtype=np.int64)
    label[K.border_vertices()] = 0
    for i, loop in enumerate(obstacles):
        if not np.all(label[loop] >= 0):
            raise ValueError(f"obstacle loop {i} contains vertices that are not on the border")
        label[loop] = i + 1
    return obstacles, label


def uniform_flux(dec: DEC, face_normal: np.ndarray, velocity) -> np.ndarray:
    """(n1,) flux of the uniform velocity v through every edge (eq. 7.10): <v, t × N>.

    t = x_b − x_a for the edge a < b and N the normal of the (first) triangle holding the
    edge; on a planar mesh this is exact: d0 of χ = <N × v, x>.
    """
    K = dec.K
    x = embed3(K.vertices)
    v = embed3(np.atleast_2d(np.asarray(velocity, dtype=np.float64)))[0]
    edges = K.simplices(1)
    owner, _ = edge_owners(K.facet_indices(2), edges.shape[0])
    t = x[edges[:, 1]] - x[edges[:, 0]]
    return np.einsum("d,ed->e", v, np.cross(t, face_normal[owner]))


def _reduction(n0: int, label: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """R (n0, n_free): interior vertices keep their column, obstacle vertices share one;
    outer-border vertices are fixed (zero rows). Also returns the fixed mask."""
    interior = np.flatnonzero(label < 0)
    n_obstacles = int(label.max()) if label.size and label.max() > 0 else 0
    rows = [interior]
    cols = [np.arange(interior.size)]
    for i in range(n_obstacles):
        loop = np.flatnonzero(label == i + 1)
        rows.append(loop)
        cols.append(np.full(loop.size, interior.size + i))
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    R = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n0, interior.size + n_obstacles))
    return R, label == 0


def harmonic_flux(dec: DEC, face_normal: np.ndarray, label: np.ndarray, inflow_velocity, new_solver) -> np.ndarray:
    """The harmonic flux c = d0 χ of eq. 7.9 with the obstacle-period constraints (7.11).

    Parameters
    ----------
    label : (n0,) border labels from :func:`border_layout`
    inflow_velocity : (2|3,) uniform velocity v imposed on the outer border, or None (c = 0)
    new_solver : callable returning a solver with ``factorize`` / ``solve``

    Returns
    -------
    (n1,) c with ``d1 c = 0`` to round-off (mesh units² / s)
    """
    K = dec.K
    n0 = K.num_simplices(0)
    if inflow_velocity is None or not np.any(label == 0):
        return np.zeros(K.num_simplices(1))
    x = embed3(K.vertices)
    v = embed3(np.atleast_2d(np.asarray(inflow_velocity, dtype=np.float64)))[0]
    # χ = <N × v, x> on the outer border, with the average vertex normal there (exact when planar)
    normal = np.zeros(3)
    F = K.oriented_simplices()
    for c in range(3):
        normal += face_normal[np.isin(F[:, c], np.flatnonzero(label == 0))].sum(axis=0)
    normal /= np.linalg.norm(normal)
    chi = np.where(label == 0, x @ np.cross(normal, v), 0.0)
    S = dec.laplacian_symmetric(0)
    R, _ = _reduction(n0, label)
    if R.shape[1]:
        A = (R.T @ S @ R).tocsr()
        solver = new_solver()
        solver.factorize(A)
        chi = chi + R @ solver.solve(-(R.T @ (S @ chi)))
    return K.incidence(1) @ chi


def harmonic_flux_least_squares(dec: DEC, label: np.ndarray, border_flux: np.ndarray, new_solver,
                                weight: float | None = None) -> tuple[np.ndarray, dict]:
    """Eq. 7.11, corrected (the printed version is wrong):

        (d1ᵀ ⋆2 d1 + ⋆1 d̃ᵀ ⋆̃0⁻¹ d̃ ⋆1 + λ I_B) c = λ u_B

    d̃ holds the rows of d0ᵀ of interior vertices plus one summed row per obstacle
    (border-vertex rows dropped), ⋆̃0 their ⋆0 (summed per obstacle); I_B selects the
    border edges, ``border_flux`` (n1,) gives u_B on them (0 on obstacles).

    Returns
    -------
    c : (n1,)
    residual : dict with the relative residual of the linear system and the norms of the
        three constraint groups at the solution (d1 c, d̃ ⋆1 c, c − u_B on the border)
    """
    K = dec.K
    n0, n1 = K.num_simplices(0), K.num_simplices(1)
    R, _ = _reduction(n0, label)
    d0T = K.boundary(1)  # (n0, n1)
    d_tilde = (R.T @ d0T).tocsr()
    star0_tilde = R.T @ dec.star_diagonal(0)
    border = np.zeros(n1)
    border[K.border_faces()[0]] = 1.0
    star1 = dec.star(1)
    d1 = dec.d(1)
    A_core = d1.T @ dec.star(2) @ d1 + star1 @ d_tilde.T @ sp.diags(1.0 / star0_tilde) @ d_tilde @ star1
    lam = float(abs(A_core.diagonal()).max()) if weight is None else weight
    A = (A_core + lam * sp.diags(border)).tocsr()
    b = lam * border * border_flux
    solver = new_solver()
    solver.factorize(A)
    c = solver.solve(b)
    report = {
        "relative_residual": float(np.linalg.norm(A @ c - b) / np.linalg.norm(b)) if np.any(b) else 0.0,
        "max_abs_divergence": float(np.abs(d1 @ c).max()),
        "max_abs_vorticity_rows": float(np.abs(d_tilde @ (star1 @ c)).max()) if d_tilde.shape[0] else 0.0,
        "max_abs_border_error": float(np.abs((c - border_flux)[border > 0]).max()),
    }
    return c, report
