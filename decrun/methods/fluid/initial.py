"""Initial vorticities and stirring forces for the vorticity fluid (thesis §7.2.4, §6.4.2).

Pure functions of the DEC operators and plain arrays. Vorticities are per-vertex values
w (1/s); their dual 2-form is ⋆0 w (circulation, mesh units² / s). Forces are flux
1-forms (mesh units³ / s²), the rotated sampling of §7.2.1.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree

from decrun.core.dec import DEC
from decrun.core.geometry import embed3
from decrun.errors import ConfigError
from decrun.methods.fluid.dual_cells import face_normals

__all__ = ["zero_vorticity", "solid_body_rotation", "vortex_blobs", "sphere_vortex_pair", "random_vorticity",
           "stroke_force"]


def zero_vorticity(dec: DEC) -> np.ndarray:
    """(n0,) zeros: the fluid at rest (only the harmonic inflow moves it)."""
    return np.zeros(dec.K.num_simplices(0))


def solid_body_rotation(dec: DEC, axis=(0.0, 0.0, 1.0), angular_velocity: float = 1.0) -> np.ndarray:
    """(n0,) vorticity of a rigid rotation Ω about ``axis`` on a sphere centred at the origin.

    The velocity Ω â × x has vorticity 2Ω <â, n> with n = x / |x| the sphere normal; on the
    unit sphere its stream function is ψ = Ω <â, x> (a degree-1 harmonic, Δψ = 2ψ).
    """
    x = embed3(dec.K.vertices)
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    return 2.0 * angular_velocity * (x @ a) / np.linalg.norm(x, axis=1)


def vortex_blobs(dec: DEC, centers, circulations, radius: float) -> np.ndarray:
    """(n0,) Gaussian vortex blobs exp(−|x − c_k|² / (2 r²)), each scaled so that its
    circulation Σ_i ⋆0_i w_i is exactly Γ_k (Euclidean distance; on a sphere, chordal).

    Parameters
    ----------
    centers : (k, 2|3) blob centres; circulations : (k,) Γ_k (mesh units² / s)
    radius : r (mesh units)
    """
    x = embed3(dec.K.vertices)
    centers = embed3(np.atleast_2d(np.asarray(centers, dtype=np.float64)))
    circulations = np.atleast_1d(np.asarray(circulations, dtype=np.float64))
    star0 = dec.star_diagonal(0)
    w = np.zeros(x.shape[0])
    for center, gamma in zip(centers, circulations, strict=True):  # a handful of blobs
        g = np.exp(-np.sum((x - center) ** 2, axis=1) / (2.0 * radius**2))
        w += gamma * g / (star0 @ g)
    return w


def sphere_vortex_pair(dec: DEC, separation: float, circulation: float, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """A counter-rotating pair on the unit sphere: +Γ at longitude +θ/2, −Γ at −θ/2 (equator).

    Point vortices ±Γ at angular distance θ translate together, perpendicular to the
    great circle through them (here along ±z), at speed Γ / (4π) · cot(θ/2) (Kimura &
    Okamoto 1987; the plane limit is Γ / (2π d)).

    Returns
    -------
    w : (n0,) vorticity; centers : (2, 3) the blob centres (+Γ first)
    """
    half = 0.5 * separation
    centers = np.array([[np.cos(half), np.sin(half), 0.0], [np.cos(half), -np.sin(half), 0.0]])
    return vortex_blobs(dec, centers, [circulation, -circulation], radius), centers


def random_vorticity(dec: DEC, seed: int = 0, correlation_length: float = 0.2, amplitude: float = 1.0) -> np.ndarray:
    """(n0,) smooth random vorticity: seeded white noise smoothed by one implicit diffusion
    step (⋆0 + ℓ² d0ᵀ⋆1 d0) w = ⋆0 ξ, ⋆0-weighted mean removed, scaled to max |w| = amplitude."""
    rng = np.random.default_rng(seed)
    star0 = dec.star_diagonal(0)
    noise = rng.standard_normal(star0.size)
    A = (sp.diags(star0) + correlation_length**2 * dec.laplacian_symmetric(0)).tocsc()
    w = spla.spsolve(A, star0 * noise)
    w = w - (star0 @ w) / star0.sum()
    return amplitude * w / np.abs(w).max()


def _locate_faces(dec: DEC, points: np.ndarray, candidates: int = 8) -> np.ndarray:
    """(P,) the face containing (or nearest to) each point among the faces with the nearest
    barycenters (distance to the plane plus the distance outside the triangle)."""
    x = embed3(dec.K.vertices)
    top = dec.K.simplices(2)
    corners = x[top]
    k = int(min(candidates, top.shape[0]))
    _, cand = cKDTree(corners.mean(axis=1)).query(points, k=k)
    cand = np.asarray(cand).reshape(points.shape[0], k)
    c = corners[cand]
    e1, e2 = c[:, :, 1] - c[:, :, 0], c[:, :, 2] - c[:, :, 0]
    rel = points[:, None, :] - c[:, :, 0]
    g11, g12, g22 = (e1 * e1).sum(-1), (e1 * e2).sum(-1), (e2 * e2).sum(-1)
    r1, r2 = (rel * e1).sum(-1), (rel * e2).sum(-1)
    det = g11 * g22 - g12 * g12
    mu1, mu2 = (g22 * r1 - g12 * r2) / det, (g11 * r2 - g12 * r1) / det
    lam = np.stack([1.0 - mu1 - mu2, mu1, mu2], axis=-1)
    plane = np.linalg.norm(rel - mu1[..., None] * e1 - mu2[..., None] * e2, axis=-1)
    outside = np.clip(-lam, 0.0, None).sum(-1) * np.sqrt(det) / np.sqrt(g11 + g22)
    return cand[np.arange(points.shape[0]), np.argmin(plane + outside, axis=1)]


def stroke_force(dec: DEC, polyline, strength: float, step: float | None = None) -> np.ndarray:
    """(n1,) stirring force along a polyline stroke as a flux 1-form (§6.4.2 rotated by 90°).

    The stroke is cut into pieces of length ``step`` (default a quarter of the mean edge
    length); each piece is projected into the face holding its midpoint, the pieces of a
    face are summed and normalized to a direction d_t, and the force there is
    F_t = strength · d_t (mesh units / s²). Its flux through edge a → b (a < b) of the face is
    <F_t, (x_b − x_a) × N_t> — §6.4.2's <v, e> applied to the rotated vector N_t × F_t — and an
    edge of two stroked faces takes the mean (the thesis' ½(<v1, e> + <v2, e>)).
    In the step, w += dt ⋆0⁻¹ d0ᵀ ⋆1 f is then dt times the curl of F.
    """
    K = dec.K
    points = embed3(np.atleast_2d(np.asarray(polyline, dtype=np.float64)))
    if points.shape[0] < 2:
        raise ConfigError("stroke: a stroke needs at least two points")
    x = embed3(K.vertices)
    edges = K.simplices(1)
    if step is None:
        step = 0.25 * float(np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1).mean())
    segment = np.diff(points, axis=0)
    pieces = np.maximum(1, np.ceil(np.linalg.norm(segment, axis=1) / step).astype(np.int64))
    which = np.repeat(np.arange(segment.shape[0]), pieces)
    within = (np.arange(which.size) - np.repeat(np.cumsum(pieces) - pieces, pieces) + 0.5) / pieces[which]
    midpoints = points[which] + within[:, None] * segment[which]
    piece = segment[which] / pieces[which, None]
    faces = _locate_faces(dec, midpoints)
    normal = face_normals(dec)
    tangent = piece - (piece * normal[faces]).sum(1)[:, None] * normal[faces]
    unique, inverse = np.unique(faces, return_inverse=True)
    total = np.zeros((unique.size, 3))
    np.add.at(total, inverse, tangent)
    length = np.linalg.norm(total, axis=1)
    keep = length > 1e-12 * max(float(length.max(initial=0.0)), 1e-300)
    unique, force = unique[keep], strength * total[keep] / length[keep, None]
    edge_of_face = K.facet_indices(2)[unique]  # (F, 3)
    t = x[edges[edge_of_face, 1]] - x[edges[edge_of_face, 0]]  # (F, 3, 3)
    values = np.einsum("fd,fed->fe", force, np.cross(t, normal[unique][:, None, :]))
    n1 = K.num_simplices(1)
    total_flux = np.bincount(edge_of_face.ravel(), weights=values.ravel(), minlength=n1)
    count = np.bincount(edge_of_face.ravel(), minlength=n1)
    return np.where(count > 0, total_flux / np.maximum(count, 1), 0.0)
