"""The discrete operators the model language adds to DEC's own: wedge, ♯, ♭, averaging,
interior product and Lie derivative of 0-forms (thesis §3.1.3 for ∧, eq. 6.7 for ♯).

Everything else the language offers (d, the dual d, ⋆, ⋆⁻¹, δ, Δ) is taken from
:class:`decrun.core.dec.DEC` unchanged, so ``operator=`` and ``boundary=`` apply as they do to
every app. Conventions: a primal k-form is one number per k-simplex of ``K.simplices(k)``
(sorted tuples; top simplices carry ``K.orientation``); a "vector" is one vector per top simplex
``(n_n, d)`` (a piecewise-constant field); a dual 0-form is one number per top simplex.
"""

from __future__ import annotations

from itertools import combinations
from math import factorial

import numpy as np
import scipy.sparse as sp

from decrun.core.forms import barycentric_gradients

__all__ = ["average_matrix", "cell_to_edge_matrix", "wedge_0k", "wedge_11", "sharp", "sharp_matrices", "flat_weights",
           "flat", "interior_1", "vertex_average_matrix", "lie_0", "lie_0_matrix", "lie_1", "face_normals", "top_sign",
           "flux_field", "gradients", "normalize"]


def top_sign(K, k: int) -> np.ndarray | float:
    """±1 per k-simplex: the orientation of top simplices against their sorted tuple (k = n),
    1 for lower simplices (stored as sorted tuples)."""
    return K.orientation.astype(np.float64) if k == K.dim else 1.0


def average_matrix(K, k: int) -> sp.csr_matrix:
    """(n_k, n0) mean over the k+1 vertices of each k-simplex: ``(A f)_σ = Σ_{v∈σ} f_v / (k+1)``.
    With k = 1 this is the averaging of a 0-form onto edges (a diffusivity per edge). Made
    once per complex (every step's ∧ and averages reuse it)."""
    def compute():
        simplices = K.simplices(k)
        rows = np.repeat(np.arange(simplices.shape[0]), k + 1)
        data = np.full(rows.size, 1.0 / (k + 1))
        return sp.csr_matrix((data, (rows, simplices.ravel())), shape=(simplices.shape[0], K.num_simplices(0)))
    return K.require(("model", "average_matrix", k), compute)


def cell_to_edge_matrix(K) -> sp.csr_matrix:
    """(n1, n_n) mean over the top simplices that contain each edge:
    ``(A g)_e = Σ_{σ∋e} g_σ / #{σ ∋ e}`` — a dual 0-form (one value per top simplex, e.g. a
    diffusivity Γ h̄_σ^{n+2} |∇h|_σ^{n−1} computed per triangle) brought onto the edges as a
    coefficient per edge; a border edge takes its one top simplex. (On a triangulated square
    grid an axis edge gets the mean of the two triangles on either side of it: the triangle
    analogue of Mahaffy's staggered-grid diffusivity.)"""
    def compute():
        table = K.top_face_indices(1)  # (n_n, C(n+1, 2)) edge slots of every top simplex
        rows = table.ravel()
        cols = np.repeat(np.arange(table.shape[0]), table.shape[1])
        count = np.bincount(rows, minlength=K.num_simplices(1)).astype(np.float64)
        return sp.csr_matrix((1.0 / count[rows], (rows, cols)), shape=(K.num_simplices(1), table.shape[0]))
    return K.require(("model", "cell_to_edge_matrix"), compute)


def wedge_0k(K, f: np.ndarray, omega: np.ndarray, k: int) -> np.ndarray:
    """f ∧ ω for a 0-form f (n0,) and a k-form ω (n_k,): (f ∧ ω)(σ) = f̄_σ ω(σ), f̄_σ the mean of
    f over the vertices of σ (the discrete primal-primal wedge of Hirani 2003, §7, with
    barycentric weights; for k = 0 the pointwise product)."""
    if k == 0:
        return f * omega
    return (average_matrix(K, k) @ f) * omega


def _edges_of(K, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edge indices (three (n_k,) arrays) of the slots (0,1), (0,2), (1,2) of every 2-simplex's
    sorted tuple (k = 2 only)."""
    if K.dim == 2:
        table = K.top_face_indices(1)
        return table[:, 0], table[:, 1], table[:, 2]
    triangles = K.simplices(2)
    return tuple(K.find_simplices(triangles[:, [a, b]]) for a, b in ((0, 1), (0, 2), (1, 2)))


def wedge_11(K, alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """α ∧ β of two primal 1-forms (n1,), a 2-form on ``K.simplices(2)`` (Hirani 2003, eq. 7.2.1
    with barycentric weights): for the sorted triangle [v0 v1 v2]

        (α∧β) = 1/6 (α01 β12 − α12 β01 + α02 β12 − α12 β02 + α01 β02 − α02 β01)

    — the antisymmetrization of Σ_τ sign(τ) α(τ0 τ1) β(τ1 τ2) over the 6 permutations, which
    gives (dx∧dy)(σ) = the signed area for constant forms. Top triangles get their orientation."""
    e01, e02, e12 = _edges_of(K, 2)
    a01, a02, a12 = alpha[e01], alpha[e02], alpha[e12]
    b01, b02, b12 = beta[e01], beta[e02], beta[e12]
    value = (a01 * b12 - a12 * b01 + a02 * b12 - a12 * b02 + a01 * b02 - a02 * b01) / (factorial(2) * 3)
    return value * top_sign(K, 2)


def gradients(K) -> np.ndarray:
    """(n_n, n+1, d) gradients ∇λ_i of the barycentric coordinates in each top simplex
    (:func:`decrun.core.forms.barycentric_gradients`), computed once per complex."""
    return K.require(("model", "barycentric_gradients"), lambda: barycentric_gradients(K))


def sharp(K, omega: np.ndarray) -> np.ndarray:
    """ω♯ (n_n, d): the Whitney interpolation of a primal 1-form at the barycentre of each top
    simplex (eq. 6.7; equal to :func:`decrun.core.forms.whitney_sharp`):
    ω♯ = Σ_{edges ab} ω_ab (λ_a ∇λ_b − λ_b ∇λ_a) with every λ = 1/(n+1). For ω = d f it is the
    gradient of the piecewise-linear f, exactly."""
    return np.stack([matrix @ omega for matrix in sharp_matrices(K)], axis=1)


def sharp_matrices(K) -> list[sp.csr_matrix]:
    """[(n_n, n1)] × d: component a of :func:`sharp` as one sparse matrix per axis,
    ``(S_a ω)_σ = Σ_{edges ab of σ} ω_ab (∇λ_b − ∇λ_a)_a / (n+1)`` — made once per complex, so
    ♯ costs d sparse products per evaluation (every step of a nonlinear diffusion)."""
    def compute():
        n = K.dim
        grad = gradients(K)
        table = K.top_face_indices(1)  # edge slots in combinations order over the sorted top tuple
        pairs = list(combinations(range(n + 1), 2))  # (n+1 choose 2) slots, not simplices
        weights = np.stack([grad[:, b] - grad[:, a] for a, b in pairs], axis=1) / (n + 1)  # (n_n, slots, d)
        rows = np.repeat(np.arange(table.shape[0]), len(pairs))
        return [sp.csr_matrix((weights[:, :, axis].ravel(), (rows, table.ravel())),
                              shape=(table.shape[0], K.num_simplices(1))) for axis in range(grad.shape[2])]
    return K.require(("model", "sharp_matrices"), compute)


def flux_field(K, u: np.ndarray) -> np.ndarray:
    """The vector field (n_n, d) whose flux form is the Whitney (n−1)-form of ``u`` (one value
    per (n−1)-simplex: the flux through it), at the barycentre of each top simplex σ — the lowest
    order Raviart–Thomas field X(x) = Σ_i o_i u_{f_i} (x − p_i) / (n |σ|) over the faces f_i of σ
    (f_i opposite its vertex p_i, o_i = ±1 the incidence of f_i in σ's boundary, so o_i u_{f_i}
    is the flux out of σ), whose flux through f_i is u_{f_i} and whose divergence is (d u)_σ/|σ|.
    Constant fields are reproduced exactly. Orientation: σ as the complex orients it; on
    tetrahedra a negatively oriented σ (det < 0) flips the sign, on triangles the oriented
    triangle's normal is the surface's (as for ``{flux: […]}`` initial values)."""
    n = K.dim
    top = K.simplices(n)
    corners = K.vertices[top]  # sorted rows: slot c of top_face_indices(n−1) omits local vertex n − c
    volume = K.top_volumes
    incidence = K.boundary(n).tocsc()  # (n_{n−1}, n_n), with the top simplices' orientation
    faces = K.top_face_indices(n - 1)
    centre = corners.mean(axis=1)
    result = np.zeros((len(top), corners.shape[2]))
    for slot in range(n + 1):  # n + 1 faces of each top simplex: a loop over slots, not simplices
        opposite = n - slot
        face = faces[:, slot]
        sign = np.asarray(incidence[face, np.arange(len(top))]).ravel()
        result += (sign * u[face])[:, None] * (centre - corners[:, opposite])
    result /= (n * volume)[:, None]
    if n == 3:
        oriented = K.vertices[K.oriented_simplices()]
        det = np.einsum("ij,ij->i", np.cross(oriented[:, 1] - oriented[:, 0], oriented[:, 2] - oriented[:, 0]),
                        oriented[:, 3] - oriented[:, 0])
        result *= np.sign(det)[:, None]
    return result


def flat_weights(K) -> tuple[np.ndarray, np.ndarray]:
    """The weights of :func:`flat` on a triangle mesh: ``(edge_slots (n2, 3), weights (n2, 3))``,
    the edge index of the slots (1,2), (0,2), (0,1) of each sorted triangle (the edge opposite
    local vertex 0, 1, 2) and ½ cot of the angle opposite it — the length of the piece of the
    circumcentric dual edge ⋆e inside the triangle over |e| (§4.5.4)."""
    triangles = K.simplices(2)
    p = K.vertices[triangles]
    e01, e02, e12 = _edges_of(K, 2)
    slots = np.stack([e12, e02, e01], axis=1)
    weights = np.empty(slots.shape)
    for local in range(3):  # three columns, vectorized over every triangle
        a, b = p[:, (local + 1) % 3] - p[:, local], p[:, (local + 2) % 3] - p[:, local]
        cross = np.linalg.norm(np.cross(a, b) if p.shape[2] == 3 else
                               (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])[:, None], axis=1)
        weights[:, local] = 0.5 * np.einsum("ij,ij->i", a, b) / cross
    return slots, weights


def flat(K, vectors: np.ndarray) -> np.ndarray:
    """X♭ (n1,): the primal-primal flat of a piecewise-constant field X (n2, d) on a triangle
    mesh (Hirani 2003, def. 5.8.1): ω_e = Σ_{f∋e} (|⋆e ∩ f| / |⋆e|) X_f · (p_b − p_a), the
    dual-edge-weighted mean of the line integral along e over the triangles at e. So
    ⋆1 X♭ (the circumcentric ⋆1) is the flux of X across the dual edges, and
    −δ X♭ = ⋆0⁻¹ d0ᵀ ⋆1 X♭ is the integrated divergence of X (the cotan formula). Where the
    dual edge has length 0 (Σ_f cot = 0) the plain mean over the triangles is taken; a border
    edge takes its one triangle."""
    if K.dim != 2:
        raise ValueError("flat: defined here on triangle meshes (K.dim = 2)")
    slots, weights = flat_weights(K)
    edges = K.simplices(1)
    direction = K.vertices[edges[:, 1]] - K.vertices[edges[:, 0]]
    n1 = edges.shape[0]
    along = np.einsum("fsd,fsd->fs", np.broadcast_to(vectors[:, None, :], slots.shape + (vectors.shape[1],)),
                      direction[slots])
    total = np.bincount(slots.ravel(), weights=weights.ravel(), minlength=n1)
    weighted = np.bincount(slots.ravel(), weights=(weights * along).ravel(), minlength=n1)
    count = np.bincount(slots.ravel(), minlength=n1).astype(np.float64)
    plain = np.bincount(slots.ravel(), weights=along.ravel(), minlength=n1) / np.maximum(count, 1.0)
    scale = np.abs(weights).max() if weights.size else 1.0
    degenerate = np.abs(total) <= 1e-12 * scale
    return np.where(degenerate, plain, weighted / np.where(degenerate, 1.0, total))


def normalize(vectors: np.ndarray) -> np.ndarray:
    """X/|X| (n_n, d) row by row, and exactly 0 where X = 0 (its direction is undefined there:
    the heat method takes X = 0 where ∇u = 0). A nonzero X, however small, keeps its direction."""
    length = np.sqrt(np.einsum("fd,fd->f", vectors, vectors))
    zero = length == 0
    return np.where(zero[:, None], 0.0, vectors / np.where(zero, 1.0, length)[:, None])


def interior_1(K, vectors: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """i_X ω (n_n,) for a 1-form ω: ω♯ · X in each top simplex (a dual 0-form)."""
    return np.einsum("fd,fd->f", sharp(K, omega), vectors)


def vertex_average_matrix(K) -> sp.csr_matrix:
    """(n0, n_n) volume-weighted mean over the top simplices at each vertex:
    ``(A g)_v = Σ_{σ∋v} |σ| g_σ / Σ_{σ∋v} |σ|`` (a dual 0-form brought to the vertices). Made
    once per complex."""
    def compute():
        n = K.dim
        top = K.simplices(n)
        volume = np.repeat(K.top_volumes, n + 1)
        rows = top.ravel()
        cols = np.repeat(np.arange(top.shape[0]), n + 1)
        total = np.bincount(rows, weights=volume, minlength=K.num_simplices(0))
        data = volume / total[rows]
        return sp.csr_matrix((data, (rows, cols)), shape=(K.num_simplices(0), top.shape[0]))
    return K.require(("model", "vertex_average_matrix"), compute)


def lie_0(K, vectors: np.ndarray, f: np.ndarray) -> np.ndarray:
    """L_X f = i_X d f = X · ∇f (n0,) for a 0-form f: X · ∇f in each top simplex (∇f of the
    piecewise-linear f, :func:`decrun.core.forms.barycentric_gradients`), brought to the
    vertices by :func:`vertex_average_matrix` (a centred, not upwinded, advection term)."""
    top = K.simplices(K.dim)
    grad_f = np.einsum("fv,fvd->fd", f[top], gradients(K))
    return vertex_average_matrix(K) @ np.einsum("fd,fd->f", grad_f, vectors)


def lie_0_matrix(K, vectors: np.ndarray) -> sp.csr_matrix:
    """(n0, n0) the matrix of f ↦ :func:`lie_0` (K, vectors, f) for a fixed field X (n_n, d):
    A · diag-blocks, ``(L f)_v = Σ_σ A_vσ Σ_i (X_σ · ∇λ_i) f_{σ_i}`` with A the
    :func:`vertex_average_matrix` — made once when X does not change during a run (a velocity
    given by the coordinates), then one sparse product per evaluation."""
    top = K.simplices(K.dim)
    weights = np.einsum("fvd,fd->fv", gradients(K), vectors)  # X · ∇λ_i per top simplex and vertex slot
    rows = np.repeat(np.arange(top.shape[0]), top.shape[1])
    per_cell = sp.csr_matrix((weights.ravel(), (rows, top.ravel())), shape=(top.shape[0], K.num_simplices(0)))
    return sp.csr_matrix(vertex_average_matrix(K) @ per_cell)


def face_normals(K) -> np.ndarray:
    """(n2, 3) unit normals of the oriented top triangles (planar meshes: +z, times the
    orientation)."""
    top = K.oriented_simplices()
    p = K.vertices[top]
    if p.shape[2] == 2:
        p = np.concatenate([p, np.zeros(p.shape[:2] + (1,))], axis=2)
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return normal / np.linalg.norm(normal, axis=1, keepdims=True)


def lie_1(K, vectors: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """L_X ω (n1,) for a 1-form ω on a triangle mesh, by Cartan's formula
    L_X ω = i_X dω + d i_X ω: the 2-form dω = ρ dA gives i_X dω = (ρ N × X)♭ (ρ = dω/|f| per
    oriented triangle, N its normal; :func:`flat`), and i_X ω (per triangle,
    :func:`interior_1`) is brought to the vertices (:func:`vertex_average_matrix`) before d. So
    L_X d f = d L_X f exactly (d commutes with the Lie derivative)."""
    if K.dim != 2:
        raise ValueError("lie of a 1-form: defined here on triangle meshes (K.dim = 2)")
    density = (K.incidence(2) @ omega) / K.top_volumes  # dω per unit area of each oriented triangle
    normal = face_normals(K)
    d = vectors.shape[1]
    field = np.cross(normal, np.pad(vectors, ((0, 0), (0, 3 - d)))) * density[:, None]
    return flat(K, field[:, :d]) + K.incidence(1) @ (vertex_average_matrix(K) @ interior_1(K, vectors, omega))

