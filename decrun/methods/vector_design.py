"""Vector field design with DEC (thesis §6.4, after Fisher et al. [FSDH07]).

A tangential vector field is a discrete 1-form ``w`` (one value per edge: the integral of
the field along the edge, edges oriented from the smaller to the larger vertex index).
The design problem of §6.1 is the weighted least-squares problem (eq. 6.5–6.6)

    argmin_w ‖ (d ; δ ; Z) w − (r ; s ; c) ‖²_L ,   L = diag(⋆2, ⋆0, W)

whose normal equations are

    (dᵀ ⋆2 d + δᵀ ⋆0 δ + Zᵀ W Z) w = dᵀ ⋆2 r + δᵀ ⋆0 s + Zᵀ W c .                  (6.6)

Here ``d = d_1`` (curl: a 2-form, integrated over each face), ``δ = δ_1`` (the
codifferential, a 0-form: point value per vertex), ``Z`` selects the edges touched by
stroke constraints and ``W`` is their diagonal weight.

Sign conventions (written next to the equations they affect)
------------------------------------------------------------
* δ_1 = ⋆0⁻¹ d0ᵀ ⋆1 (eq. 4.14) is the *negative* divergence: for the gradient of a
  function, δ d0 f = Δ0 f is the positive semi-definite Laplacian. A user's
  ``divergence`` value ``q`` at vertex v is the **net outflow** through the dual cell of v
  (a source has q > 0), so the δ-target is ``s_v = −q / ⋆0[v]``.
* A user's ``curl`` value ``c`` on a face is the **circulation** around the face in the
  orientation of the complex (counter-clockwise seen from the outside for a consistently
  oriented closed surface), i.e. the 2-form target ``r_t = c`` directly (d1 w integrates
  the curl over the face).
  Both are integrated quantities, so a prescribed singularity has the same far field on a
  coarse and a fine mesh.

Boundary adaptation (§6.4.4)
----------------------------
The δ_1 passed to :func:`normal_matrix` / :func:`solve_design` is ``dec.codifferential(1)`` of
the configured adaptation (:mod:`decrun.core.boundary`): ``boundary=none`` makes the field
tangential to the border and keeps d, δ adjoint; ``boundary=flux`` (eq. 6.10) lets it cross
the border at the price of adjointness, which :func:`adjointness_defect` measures.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from decrun.core.choices import Choice
from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.errors import ConfigError, TopologyError
from decrun.core.forms import whitney_sharp
from decrun.core import geometry
from decrun.core.boundary import border_edge_frames
from decrun.core.geometry import embed3
from decrun.core.solvers import SingularSolve, Solver

__all__ = [
    "StrokeMagnitude",
    "DesignConstraints",
    "DesignSolution",
    "nearest_vertices",
    "PrincipalExtremes",
    "principal_extremes",
    "nearest_faces",
    "face_normals",
    "adjointness_defect",
    "field_change_relative",
    "divergence_target",
    "stroke_face_directions",
    "stroke_edge_targets",
    "normal_matrix",
    "solve_design",
    "design_residuals",
    "smoothness_energy",
    "border_normal_flux",
]


class StrokeMagnitude(Choice):
    """``app.stroke_magnitude``: |v| along a stroke — ``fixed`` λ (eq. 6.8) or ``precomputed``
    |ν_pre| of a solve without strokes (eq. 6.9)."""

    fixed = "fixed"
    precomputed = "precomputed"


# ----------------------------------------------------------------------------------
# geometry helpers
# ----------------------------------------------------------------------------------


def _require_surface(K: SimplicialComplex, what: str) -> None:
    if K.dim != 2:
        raise TopologyError(f"{what} needs a triangle mesh (a 2-complex), got a {K.dim}-complex")


def face_normals(K: SimplicialComplex) -> np.ndarray:
    """(n2, 3) unit normals of the consistently oriented faces ``K.oriented_simplices()``
    (right-hand rule; a planar mesh in the xy-plane oriented counter-clockwise gets +z)."""
    _require_surface(K, "face_normals")
    return geometry.face_normals(K.vertices, K.oriented_simplices())


def nearest_vertices(K: SimplicialComplex, points) -> np.ndarray:
    """Indices (P,) of the vertices nearest to ``points`` (P, d) — snapping of sources/sinks."""
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    _check_point_dim(K, points, "point")
    return cKDTree(K.vertices).query(points)[1].astype(np.int64)


def _check_point_dim(K: SimplicialComplex, points: np.ndarray, key: str) -> None:
    if points.shape[1] != K.embedding_dim:
        raise ConfigError(
            f"app {key}: points must have {K.embedding_dim} coordinates (the mesh's embedding dimension), "
            f"got {points.shape[1]}"
        )


def nearest_faces(K: SimplicialComplex, points, candidates: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """The face containing (or nearest to) each point and the point projected onto it.

    Candidates are the ``candidates`` faces with the nearest barycenters; among them the
    one with the smallest distance to the point (distance to the plane plus the distance
    by which the projection falls outside the triangle) wins.

    Parameters
    ----------
    points : (P, d)

    Returns
    -------
    faces : (P,) int64 indices into ``K.simplices(2)``
    projected : (P, 3) the points projected into the plane of their face, clamped into it
    """
    _require_surface(K, "nearest_faces")
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    _check_point_dim(K, points, "point")
    points3 = embed3(points)
    x = embed3(K.vertices)
    top = K.simplices(2)
    corners = x[top]  # (m, 3, 3)
    barycenters = corners.mean(axis=1)
    k = int(min(candidates, top.shape[0]))
    _, cand = cKDTree(barycenters).query(points3, k=k)
    cand = np.asarray(cand).reshape(points3.shape[0], k)
    c = corners[cand]  # (P, k, 3, 3)
    e1 = c[:, :, 1] - c[:, :, 0]
    e2 = c[:, :, 2] - c[:, :, 0]
    rel = points3[:, None, :] - c[:, :, 0]
    g11 = np.einsum("pkd,pkd->pk", e1, e1)
    g12 = np.einsum("pkd,pkd->pk", e1, e2)
    g22 = np.einsum("pkd,pkd->pk", e2, e2)
    r1 = np.einsum("pkd,pkd->pk", rel, e1)
    r2 = np.einsum("pkd,pkd->pk", rel, e2)
    det = g11 * g22 - g12 * g12
    mu1 = (g22 * r1 - g12 * r2) / det
    mu2 = (g11 * r2 - g12 * r1) / det
    lam = np.stack([1.0 - mu1 - mu2, mu1, mu2], axis=-1)  # (P, k, 3)
    in_plane = c[:, :, 0] + mu1[..., None] * e1 + mu2[..., None] * e2
    plane_distance = np.linalg.norm(points3[:, None, :] - in_plane, axis=-1)
    scale = np.sqrt(det) / np.sqrt(g11 + g22)  # ~ a triangle height
    outside = np.clip(-lam, 0.0, None).sum(axis=-1) * scale
    best = np.argmin(plane_distance + outside, axis=1)
    rows = np.arange(points3.shape[0])
    lam_best = np.clip(lam[rows, best], 0.0, None)
    lam_best /= lam_best.sum(axis=1, keepdims=True)
    projected = np.einsum("pc,pcd->pd", lam_best, c[rows, best])
    return cand[rows, best].astype(np.int64), projected


# ----------------------------------------------------------------------------------
# boundary adaptation (§6.4.4): decrun.core.boundary.flux; here only its measurement
# ----------------------------------------------------------------------------------


def adjointness_defect(dec: DEC, delta: sp.spmatrix, seed: int = 0) -> float:
    """Relative failure of ⟨d0 a, w⟩_⋆1 = ⟨a, δ w⟩_⋆0 (eq. 6.4) for random a, w.

    Returns |⟨d0 a, w⟩ − ⟨a, δ w⟩| / (‖d0 a‖ ‖w‖) in the ⋆ norms (with |⋆| weights, so
    negative cot weights do not make the norm imaginary): ~1e-16 for the unadapted δ_1,
    O(1) on a mesh with border for the flux-adapted one.
    """
    rng = np.random.default_rng(seed)
    a = rng.standard_normal(dec.K.num_simplices(0))
    w = rng.standard_normal(dec.K.num_simplices(1))
    da = dec.d(0) @ a
    lhs = dec.inner(1, da, w)
    rhs = dec.inner(0, a, delta @ w)
    s1 = np.abs(dec.star_diagonal(1))
    norm = np.sqrt((da * s1 * da).sum() * (w * s1 * w).sum())
    return float(abs(lhs - rhs) / norm)


# ----------------------------------------------------------------------------------
# constraints
# ----------------------------------------------------------------------------------


def divergence_target(dec: DEC, vertices: np.ndarray, outflow: np.ndarray) -> np.ndarray:
    """The δ-target s (n0,) of eq. 6.5 for prescribed net outflows at vertices.

    ``outflow[i]`` is the flux out of the dual cell of ``vertices[i]`` (source > 0,
    sink < 0). Because δ_1 = −div as a point value, s_v = −outflow / ⋆0[v]; several entries
    for the same vertex add up.
    """
    s = np.zeros(dec.K.num_simplices(0))
    np.add.at(s, np.asarray(vertices, dtype=np.int64), -np.asarray(outflow, dtype=np.float64))
    return s / dec.star_diagonal(0)


def stroke_face_directions(
    K: SimplicialComplex, polyline, closed: bool = False, step: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Faces crossed by a stroke and the stroke's unit direction in each (§6.4.2, Fig. 6.6).

    The polyline is resampled with spacing ``step`` (default: a quarter of the mean edge
    length); each piece is attached to the face nearest to its midpoint, projected into
    that face's plane, and the pieces of one face are summed (length-weighted) and
    normalized.

    Parameters
    ----------
    polyline : (P, d) points, P ≥ 2 (d = the embedding dimension)
    closed : also join the last point to the first

    Returns
    -------
    faces : (F,) int64 distinct face indices, in the order the stroke first visits them
    directions : (F, 3) unit tangent vectors (zero-sum faces — a stroke going back and forth —
        are dropped)
    """
    _require_surface(K, "strokes")
    points = np.atleast_2d(np.asarray(polyline, dtype=np.float64))
    if points.shape[0] < 2:
        raise ConfigError("app strokes: a stroke needs at least two points")
    _check_point_dim(K, points, "strokes")
    if closed:
        points = np.concatenate([points, points[:1]])
    points = embed3(points)
    if step is None:
        step = 0.25 * K.mean_edge_length
    seg = np.diff(points, axis=0)
    lengths = np.linalg.norm(seg, axis=1)
    pieces = np.maximum(1, np.ceil(lengths / step).astype(np.int64))
    seg_index = np.repeat(np.arange(seg.shape[0]), pieces)
    local = (np.concatenate([np.arange(p) for p in pieces]) + 0.5) / pieces[seg_index]
    midpoints = points[seg_index] + local[:, None] * seg[seg_index]
    piece_vectors = seg[seg_index] / pieces[seg_index, None]
    faces, _ = nearest_faces(K, midpoints[:, : K.embedding_dim])
    normals = face_normals(K)[faces]
    tangent = piece_vectors - np.einsum("pd,pd->p", piece_vectors, normals)[:, None] * normals
    unique, first, inverse = np.unique(faces, return_index=True, return_inverse=True)
    total = np.zeros((unique.size, 3))
    np.add.at(total, inverse, tangent)
    norm = np.linalg.norm(total, axis=1)
    keep = norm > 1e-12 * max(float(norm.max(initial=0.0)), 1e-300)
    order = np.argsort(first[keep])
    return unique[keep][order], (total[keep] / norm[keep, None])[order]


def stroke_edge_targets(K: SimplicialComplex, faces: np.ndarray, vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Edge targets c_z of the directional constraints (§6.4.2).

    A constant vector v on face t samples to c = ⟨v, e.end − e.start⟩ on each edge of t
    (§3.2.1, reference orientation: smaller → larger vertex index); an edge shared by
    several constrained faces takes the mean (the thesis' ½(⟨v1, e⟩ + ⟨v2, e⟩)).

    Parameters
    ----------
    faces : (F,) face indices; vectors : (F, 3) the vectors v_t (direction × magnitude)

    Returns
    -------
    edges : (E,) int64 sorted edge indices; targets : (E,) float64
    """
    faces = np.asarray(faces, dtype=np.int64)
    vectors = np.asarray(vectors, dtype=np.float64)
    if faces.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    edge_of_face = K.facet_indices(2)[faces]  # (F, 3)
    edge_vertices = K.simplices(1)[edge_of_face]  # (F, 3, 2)
    x = embed3(K.vertices)
    direction = x[edge_vertices[..., 1]] - x[edge_vertices[..., 0]]
    values = np.einsum("fd,fed->fe", vectors, direction)
    edges, inverse = np.unique(edge_of_face.ravel(), return_inverse=True)
    total = np.bincount(inverse, weights=values.ravel(), minlength=edges.size)
    count = np.bincount(inverse, minlength=edges.size)
    return edges.astype(np.int64), total / count


@dataclass
class DesignConstraints:
    """The right-hand sides of eq. 6.5 and the stroke selection.

    Attributes
    ----------
    curl : (n2,) r_t, target of d1 w (circulation per face; 0 = curl-free)
    codifferential : (n0,) s_v, target of δ1 w (point values; see :func:`divergence_target`)
    stroke_edges : (E,) edges selected by Z;  stroke_targets : (E,) c_z
    stroke_weights : (E,) diagonal of W
    """

    curl: np.ndarray
    codifferential: np.ndarray
    stroke_edges: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    stroke_targets: np.ndarray = field(default_factory=lambda: np.zeros(0))
    stroke_weights: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def empty(cls, K: SimplicialComplex) -> "DesignConstraints":
        return cls(curl=np.zeros(K.num_simplices(2)), codifferential=np.zeros(K.num_simplices(0)))

    def without_strokes(self) -> "DesignConstraints":
        return DesignConstraints(self.curl, self.codifferential)

    def with_strokes(self, edges, targets, weights) -> "DesignConstraints":
        return DesignConstraints(self.curl, self.codifferential, np.asarray(edges, dtype=np.int64),
                                 np.asarray(targets, dtype=np.float64), np.asarray(weights, dtype=np.float64))


def _selection(K: SimplicialComplex, edges: np.ndarray) -> sp.csr_matrix:
    """Z: rows of the identity at the constrained edges, (E, n1)."""
    return sp.csr_matrix((np.ones(edges.size), (np.arange(edges.size), edges)), shape=(edges.size, K.num_simplices(1)))


def normal_matrix(dec: DEC, delta: sp.spmatrix, constraints: DesignConstraints) -> tuple[sp.csr_matrix, np.ndarray]:
    """Left and right side of the normal equation 6.6 with L = diag(⋆2, ⋆0, W).

    Returns
    -------
    A : (n1, n1) dᵀ ⋆2 d + δᵀ ⋆0 δ + Zᵀ W Z  (symmetric positive semi-definite)
    b : (n1,)    dᵀ ⋆2 r + δᵀ ⋆0 s + Zᵀ W c
    """
    d1 = dec.d(1)
    star2, star0 = dec.star(2), dec.star(0)
    A = d1.T @ star2 @ d1 + delta.T @ star0 @ delta
    b = d1.T @ (star2 @ constraints.curl) + delta.T @ (star0 @ constraints.codifferential)
    if constraints.stroke_edges.size:
        Z = _selection(dec.K, constraints.stroke_edges)
        W = sp.diags(constraints.stroke_weights)
        A = A + Z.T @ W @ Z
        b = b + Z.T @ (constraints.stroke_weights * constraints.stroke_targets)
    return sp.csr_matrix(A), np.asarray(b, dtype=np.float64)


@dataclass
class DesignSolution:
    """A solved design: the 1-form and how the solve went."""

    omega: np.ndarray
    normal_equation_residual: float  # ‖A w − b‖ / ‖b‖ (Euclidean; ‖A w‖ when b = 0)
    refinement_steps: int  # iterative-refinement steps of the shifted factorization


def solve_design(
    dec: DEC,
    solver: Solver,
    constraints: DesignConstraints,
    delta: sp.spmatrix,
    shift: float = 1e-10,
    tol: float = 1e-13,
    max_steps: int = 50,
) -> DesignSolution:
    """Solve the normal equation 6.6 for the designed 1-form w (least squares, eq. 6.5).

    The normal matrix A = Dᵀ L D can be singular: without strokes it vanishes exactly on the
    forms with d w = 0 and δ w = 0 — the harmonic 1-forms for the unadapted δ (dimension
    Betti_1, §6.3.6: "there is no constraint on the harmonic component"), and for the
    flux-adapted δ on a flat domain also the constant fields, which now may cross the
    border freely. Since b = Dᵀ L t always lies in im A, the problem is consistent; we
    factorize A + ε M once (M = diag|⋆1|, ε = ``shift`` × the mean diagonal ratio) and
    refine x ← x + (A + εM)⁻¹ (b − A x). Every iterate stays M-orthogonal to ker A, so the
    result is the minimizer with no null-space (e.g. harmonic) component, and for a
    regular A it is simply the solution.

    Parameters
    ----------
    solver : a fresh decrun Solver (factorized here, once)
    delta : the δ_1 in use (``dec.codifferential(1)`` of the configured boundary adaptation)
    shift : relative size of the diagonal shift ε
    tol : stop when ‖A w − b‖ ≤ tol ‖b‖

    Returns
    -------
    DesignSolution
    """
    A, b = normal_matrix(dec, delta, constraints)
    weight = np.abs(dec.star_diagonal(1))
    weight = np.maximum(weight, 1e-3 * float(weight.mean()))
    singular = SingularSolve(A, solver, weight=weight, shift=shift, tol=tol, max_steps=max_steps)
    w = singular.solve(b)
    steps = singular.steps
    r = float(np.linalg.norm(b - A @ w))
    norm_b = float(np.linalg.norm(b))
    return DesignSolution(omega=w, normal_equation_residual=r / norm_b if norm_b > 0 else r, refinement_steps=steps)


# ----------------------------------------------------------------------------------
# measurements
# ----------------------------------------------------------------------------------


def smoothness_energy(dec: DEC, delta: sp.spmatrix, omega: np.ndarray) -> float:
    """⟨dω, dω⟩_⋆2 + ⟨δω, δω⟩_⋆0, the energy minimized away from constraints (§6.1)."""
    curl = dec.d(1) @ omega
    div = delta @ omega
    return float(dec.inner(2, curl, curl) + dec.inner(0, div, div))


def design_residuals(dec: DEC, delta: sp.spmatrix, constraints: DesignConstraints, omega: np.ndarray) -> dict:
    """Constraint residuals of eq. 6.5 in the norms of L (eq. 6.6).

    Returns a dict of floats:
    ``curl_residual`` ‖d w − r‖_⋆2, ``divergence_residual`` ‖δ w − s‖_⋆0,
    ``direction_residual`` ‖Z w − c‖_W (absent without strokes), and each ``*_relative`` =
    residual / ‖target‖ — absent when the target is zero (no vortices: curl target 0; no
    sources: divergence target 0), where a ratio to it does not exist.
    """
    out = {}
    pieces = {
        "curl": (2, dec.d(1) @ omega - constraints.curl, constraints.curl),
        "divergence": (0, delta @ omega - constraints.codifferential, constraints.codifferential),
    }
    for name, (k, residual, target) in pieces.items():
        r = np.sqrt(max(dec.inner(k, residual, residual), 0.0))
        t = np.sqrt(max(dec.inner(k, target, target), 0.0))
        out[f"{name}_residual"] = float(r)
        if t > 0:
            out[f"{name}_residual_relative"] = float(r / t)
    if constraints.stroke_edges.size:
        residual = omega[constraints.stroke_edges] - constraints.stroke_targets
        weights = constraints.stroke_weights
        r = np.sqrt((weights * residual**2).sum())
        t = np.sqrt((weights * constraints.stroke_targets**2).sum())
        out["direction_residual"] = float(r)
        if t > 0:
            out["direction_residual_relative"] = float(r / t)
    return out


def border_normal_flux(K: SimplicialComplex, omega: np.ndarray) -> dict:
    """How much the field crosses the border (§6.4.4, Fig. 6.9).

    The Whitney field (eq. 6.7) of each border triangle is evaluated at the midpoint of its
    border edge and split into the component along the outward normal and the tangential
    one (the latter is w_e/|e| by construction).

    Returns
    -------
    dict with ``border_normal_flux_mean`` (mean |u·n| over border edges, field units),
    ``border_normal_fraction`` (mean |u·n| / mean |u| there; 0 = tangential field,
    ~0.64 = directions uniformly random), ``border_edges`` (count). Zeros for closed meshes.
    """
    edges_idx, face, i_v, j_v, k_v = border_edge_frames(K)
    if edges_idx.size == 0:
        return {"border_normal_flux_mean": 0.0, "border_normal_fraction": 0.0, "border_edges": 0}
    top = K.simplices(2)
    lam = (top[face] == i_v[:, None]) * 0.5 + (top[face] == j_v[:, None]) * 0.5
    u = embed3(whitney_sharp(K, omega, barycentric=lam, faces=face))
    x = embed3(K.vertices)
    tangent = x[j_v] - x[i_v]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    outward = np.cross(tangent, face_normals(K)[face])  # right of i → j, in the face plane
    normal_part = np.abs(np.einsum("ed,ed->e", u, outward))
    magnitude = np.linalg.norm(u, axis=1)
    mean_mag = float(magnitude.mean())
    return {
        "border_normal_flux_mean": float(normal_part.mean()),
        "border_normal_fraction": float(normal_part.mean() / mean_mag) if mean_mag > 0 else 0.0,
        "border_edges": int(edges_idx.size),
    }


@dataclass
class PrincipalExtremes:
    """The default source/sink pair of ``app=vector_field`` (:func:`principal_extremes`)."""

    source: int  # vertex id: largest (x − c)·e1
    sink: int  # vertex id: smallest (x − c)·e1
    axis: np.ndarray  # (3,) e1, the principal axis of largest variance
    variances: np.ndarray  # (3,) the vertex covariance's eigenvalues, decreasing
    interior_only: bool  # chosen among the vertices off the border

    @property
    def axis_unique(self) -> bool:
        """False when the two largest variances agree to 1e-6 (relative): e1 is then any axis of
        their plane (a sphere, a cube) and the pair is one of many equally extreme ones."""
        return bool(self.variances[0] - self.variances[1] > 1e-6 * self.variances[0])


def principal_extremes(K: SimplicialComplex) -> PrincipalExtremes:
    """The vertices farthest apart along the principal axis e1 of the vertices (largest
    variance of the vertex covariance, :func:`decrun.core.geometry.principal_frame`).

    On a mesh with a border only the vertices off the border are candidates (when there are
    any): the flux-adapted δ (§6.4.4) counts a border vertex's estimated flow through the
    border in its divergence, so a source there may leave through the border instead of
    into the mesh (on the unit square, whose extremes are corners, the prescribed outflow of
    the corner comes out 0); with the unadapted δ a border vertex's dual cell is open. Ties
    go to the lowest vertex id.
    """
    c, E, _, variances = geometry.principal_frame(K.vertices)
    height = (embed3(K.vertices) - c) @ E[0]
    border = K.border_vertices()
    interior_only = bool(border.any() and not border.all())
    candidates = np.flatnonzero(~border) if interior_only else np.arange(height.size)
    h = height[candidates]
    return PrincipalExtremes(source=int(candidates[np.argmax(h)]), sink=int(candidates[np.argmin(h)]),
                             axis=E[0].copy(), variances=variances, interior_only=interior_only)


def field_change_relative(before: np.ndarray, after: np.ndarray, area: np.ndarray, region: np.ndarray) -> float:
    """Area-weighted ‖after − before‖ / ‖before‖ of face vectors (m, 3) over the faces in
    ``region`` (m,) bool (non-empty), ``area`` (m,) the face areas: how much the strokes of
    §6.4.2 changed the designed field (0: not at all; inf: a field made from nothing)."""
    a = area[region, None]
    diff = np.sqrt((a * (after[region] - before[region]) ** 2).sum())
    ref = np.sqrt((a * before[region] ** 2).sum())
    return float(diff / ref) if ref > 0 else float("inf") if diff > 0 else 0.0
