"""Sampling (♭) and interpolation (♯) of discrete forms (thesis §3.2, eq. 6.7).

A discrete k-form holds one number per k-simplex: the integral of the smooth form over
that simplex (§3.2.1). Sampling integrates with Gauss quadrature; the Whitney map
interpolates a discrete 1-form back to a vector field inside each top simplex.
"""

from __future__ import annotations

import numpy as np

from decrun.core.complex import SimplicialComplex

__all__ = ["sample_function", "sample_vector_field", "sample_flux", "sample_density", "whitney_sharp", "whitney_sharp2",
           "barycentric_gradients"]


def _evaluate(values, points: np.ndarray, what: str, expected_tail: tuple) -> np.ndarray:
    if callable(values):
        out = np.asarray(values(points), dtype=np.float64)
    else:
        out = np.broadcast_to(np.asarray(values, dtype=np.float64), (points.shape[0],) + expected_tail)
    if out.shape != (points.shape[0],) + expected_tail:
        raise ValueError(f"{what}: expected values of shape {(points.shape[0],) + expected_tail}, got {out.shape}")
    return out


def sample_function(K: SimplicialComplex, f) -> np.ndarray:
    """Sample a 0-form: w⁰(v) = f(v) (§3.2.1).

    Parameters
    ----------
    f : callable (N, d) -> (N,), or an array (n0,)

    Returns
    -------
    (n0,) float64
    """
    if callable(f):
        return _evaluate(f, K.vertices, "sample_function", ())
    f = np.asarray(f, dtype=np.float64)
    if f.shape != (K.num_simplices(0),):
        raise ValueError(f"sample_function: expected {K.num_simplices(0)} vertex values, got shape {f.shape}")
    return f


def sample_vector_field(K: SimplicialComplex, X, order: int = 3) -> np.ndarray:
    """Sample a 1-form from a vector field: w¹(e) = ∫_e X · t dl along each edge (§3.2.1).

    Edges run from the smaller to the larger vertex index (the sorted reference
    orientation). Gauss–Legendre quadrature with ``order`` points is exact for fields
    polynomial of degree ≤ 2·order − 1 along the edge.

    Parameters
    ----------
    X : callable (N, d) -> (N, d), or a constant vector (d,)
    order : number of quadrature points per edge

    Returns
    -------
    (n1,) float64
    """
    nodes, weights = np.polynomial.legendre.leggauss(order)
    t = 0.5 * (nodes + 1.0)
    w = 0.5 * weights
    edges = K.simplices(1)
    start, end = K.vertices[edges[:, 0]], K.vertices[edges[:, 1]]
    direction = end - start
    points = (start[:, None, :] + t[None, :, None] * direction[:, None, :]).reshape(-1, K.embedding_dim)
    values = _evaluate(X, points, "sample_vector_field", (K.embedding_dim,)).reshape(len(edges), order, -1)
    return np.einsum("q,eqd,ed->e", w, values, direction)


# Symmetric quadrature on simplices in barycentric coordinates: (points (q, n+1), weights (q,))
_TRIANGLE_RULES = {
    1: (np.array([[1 / 3, 1 / 3, 1 / 3]]), np.array([1.0])),
    2: (np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]]), np.full(3, 1 / 3)),
}
_A, _B = 0.5854101966249685, 0.1381966011250105
_TET_RULES = {
    1: (np.array([[0.25] * 4]), np.array([1.0])),
    2: (np.array([[_A, _B, _B, _B], [_B, _A, _B, _B], [_B, _B, _A, _B], [_B, _B, _B, _A]]), np.full(4, 0.25)),
}


def sample_flux(K: SimplicialComplex, X, order: int = 2) -> np.ndarray:
    """Sample a 2-form from a vector field in R³: w²(f) = ∫_f X · n dA over each triangle (§3.2.1),
    n the unit normal of the sorted tuple (a < b < c) by the right-hand rule, n dA =
    ½ (p_b − p_a) × (p_c − p_a) dA/|f| — the orientation whose boundary is the incidence
    ``K.boundary(2)`` (Stokes: w²(f) of curl X = Σ ± w¹ of X over the edges of f).

    Parameters
    ----------
    X : callable (N, 3) → (N, 3), or a constant (3,)
    order : triangle quadrature (1: centroid, 2: three points, exact for quadratics)

    Returns
    -------
    (n2,) float64
    """
    if K.embedding_dim != 3:
        raise ValueError(f"sample_flux: needs vertices in R³, got dimension {K.embedding_dim}")
    faces = K.simplices(2)
    bary, weights = _TRIANGLE_RULES.get(order, _TRIANGLE_RULES[2])
    corners = K.vertices[faces]
    half_normal = 0.5 * np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    points = np.einsum("qc,mcd->mqd", bary, corners).reshape(-1, 3)
    values = _evaluate(X, points, "sample_flux", (3,)).reshape(len(faces), -1, 3)
    return np.einsum("mqd,md,q->m", values, half_normal, weights)


def sample_density(K: SimplicialComplex, rho, order: int = 2) -> np.ndarray:
    """Sample a top-degree form from a density: wⁿ(σ) = ∫_σ ρ dVol (§3.2.1).

    Each top simplex is taken with the complex's orientation, so a positive density gives
    positive values. ``order`` 1 (centroid) or 2 (exact for quadratic ρ) on triangles
    and tetrahedra; centroid rule otherwise.

    Parameters
    ----------
    rho : callable (N, d) -> (N,), or a constant

    Returns
    -------
    (n_n,) float64
    """
    n = K.dim
    rules = {2: _TRIANGLE_RULES, 3: _TET_RULES}.get(n, {})
    bary, weights = rules.get(order, (np.full((1, n + 1), 1.0 / (n + 1)), np.array([1.0])))
    corners = K.vertices[K.simplices(n)]
    points = np.einsum("qc,mcd->mqd", bary, corners).reshape(-1, K.embedding_dim)
    values = _evaluate(rho, points, "sample_density", ()).reshape(corners.shape[0], -1)
    from decrun.core.complex import simplex_volumes

    return simplex_volumes(corners) * (values @ weights)


def barycentric_gradients(K: SimplicialComplex, j: int | None = None) -> np.ndarray:
    """Gradients ∇λ_i of the barycentric coordinates in each j-simplex (default: top).

    With ``E = [p_1-p_0, ..., p_j-p_0]`` (d × j), the gradients of λ_1..λ_j are the rows of
    the pseudo-inverse of E (so they lie in the simplex's plane) and ∇λ_0 = −Σ ∇λ_i.
    For a triangle, ∇λ_i = e_jk^⊥ / (2 area) as in eq. 6.7.

    Returns
    -------
    (n_j, j+1, d), vertex order of ``K.simplices(j)``.
    """
    j = K.dim if j is None else j
    corners = K.vertices[K.simplices(j)]
    edges = np.transpose(corners[:, 1:, :] - corners[:, :1, :], (0, 2, 1))  # (m, d, j)
    rest = np.linalg.pinv(edges)  # (m, j, d)
    return np.concatenate([-rest.sum(axis=1, keepdims=True), rest], axis=1)


def whitney_sharp(K: SimplicialComplex, omega: np.ndarray, barycentric=None, faces=None) -> np.ndarray:
    """Whitney interpolation ♯ of a 1-form inside top simplices (eq. 6.7, [FSDH07]).

    u(λ) = Σ_{edges ab} w_ab (λ_a ∇λ_b − λ_b ∇λ_a), whose line integral along every edge of
    the simplex equals w_ab. On a triangle this is exactly eq. 6.7.

    Parameters
    ----------
    omega : (n1,) 1-form (edges oriented from the smaller to the larger vertex index)
    barycentric : (n+1,) or (F, n+1) point(s) in barycentric coordinates of the sorted top
        tuple ``K.simplices(n)``; default the barycenter
    faces : optional (F,) indices of the top simplices to evaluate (default: all)

    Returns
    -------
    (F, d) vectors in the embedding space (tangent to each simplex)
    """
    n = K.dim
    omega = np.asarray(omega, dtype=np.float64)
    if omega.shape != (K.num_simplices(1),):
        raise ValueError(f"whitney_sharp: expected a 1-form with {K.num_simplices(1)} values, got {omega.shape}")
    gradients = barycentric_gradients(K)
    top = K.simplices(n)
    index = np.arange(top.shape[0]) if faces is None else np.asarray(faces, dtype=np.int64)
    gradients = gradients[index]
    lam = np.full((index.size, n + 1), 1.0 / (n + 1)) if barycentric is None else np.broadcast_to(
        np.asarray(barycentric, dtype=np.float64), (index.size, n + 1))
    result = np.zeros((index.size, K.embedding_dim))
    local_edges = [(a, b) for a in range(n + 1) for b in range(a + 1, n + 1)]
    edge_ids = K.find_simplices(np.concatenate([top[index][:, [a, b]] for a, b in local_edges]))
    edge_ids = edge_ids.reshape(len(local_edges), index.size)
    for e, (a, b) in enumerate(local_edges):
        w = omega[edge_ids[e]][:, None]
        result += w * (lam[:, a, None] * gradients[:, b] - lam[:, b, None] * gradients[:, a])
    return result


def whitney_sharp2(K: SimplicialComplex, omega: np.ndarray) -> np.ndarray:
    """Whitney interpolation of a 2-form on a tetrahedral mesh, evaluated at the barycenters.

    W_abc = 2 (λ_a ∇λ_b × ∇λ_c + λ_b ∇λ_c × ∇λ_a + λ_c ∇λ_a × ∇λ_b) is the vector field whose
    flux through the face abc is 1 and through the other faces of the tetrahedron 0; the
    field of ω is Σ ω_f W_f (at the barycenter every λ = 1/4).

    Parameters
    ----------
    omega : (n2,) 2-form (faces oriented as their sorted tuple, :func:`sample_flux`)

    Returns
    -------
    (n3, 3) vectors
    """
    if K.dim != 3 or K.embedding_dim != 3:
        raise ValueError(f"whitney_sharp2: needs a tetrahedral mesh in R³, got dimension {K.dim}")
    omega = np.asarray(omega, dtype=np.float64)
    if omega.shape != (K.num_simplices(2),):
        raise ValueError(f"whitney_sharp2: expected a 2-form with {K.num_simplices(2)} values, got {omega.shape}")
    gradients = barycentric_gradients(K)
    top = K.simplices(3)
    result = np.zeros((top.shape[0], 3))
    for a, b, c in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
        w = omega[K.find_simplices(top[:, [a, b, c]])][:, None]
        ga, gb, gc = gradients[:, a], gradients[:, b], gradients[:, c]
        result += w * 0.5 * (np.cross(gb, gc) + np.cross(gc, ga) + np.cross(ga, gb))
    return result
