"""Derivative rules of the operators on vector fields, the wedge product and the Lie derivative,
for the exact Jacobians of the derivative pass (:mod:`decrun.methods.model.jacobian`).

A vector field is one vector per top simplex, ``(n_n, d)``; as an argument of a Jacobian it is
flattened row by row, value ``(σ, a)`` at index ``σ d + a``. Each rule has the signature of
:attr:`decrun.methods.model.operators.Operator.derivative`, ``(ops, kinds, values, i) ->
∂(op)/∂(argument i)`` at ``values``, a sparse matrix (rows: the output's values, flattened
likewise; columns: argument i's), or None where the operator has no derivative there (a refusal
naming the term):

- ``sharp(ω)`` is linear: S (n_n d, n1), the rows of the per-axis matrices S_a interleaved;
- ``norm(X) = |X|`` per top simplex: row σ holds X_σᵀ/|X_σ| (0 where X_σ = 0: |X| is not
  differentiable there, and its square |X|², which the models write, has derivative 0);
- ``normalize(X) = X/|X|``: the block (I − X̂X̂ᵀ)/|X| per top simplex (0 where X = 0, where
  normalize is 0 by definition);
- ``flat(X)`` (triangles) is linear: ω_e = Σ_{f∋e} w_fe X_f·e, on the mesh's own simplices or
  (``operator=intrinsic_delaunay``) on the intrinsic triangulation's, X in each triangle's frame;
- ``interior(X, ω) = X·ω♯``: diag-blocks X_σᵀ S in ω; ω♯_σᵀ per row in X (through ♯ when X is a
  1-form);
- ``wedge``: f∧ω = (A f)·ω is bilinear (A the vertex mean on k-simplices); α∧β of two 1-forms is
  bilinear with the six products of :func:`decrun.methods.model.discrete.wedge_11`;
- ``flux_field(u)`` is linear: row (σ, a) holds o_i (x̄_σ − p_i)_a / (n |σ|) at the face f_i of σ
  opposite p_i (the lowest-order Raviart–Thomas field at the barycentre);
- ``lie(X, f)`` of a 0-form, X · ∇f per top simplex averaged to the vertices (V): ``lie_0_matrix``
  in f, V · rows ∇f_σᵀ in X (through ♯ when X is a 1-form);
- ``lie(X, ω)`` of a 1-form (triangles), Cartan's L_X ω = (ρ N × X)♭ + d V (X·ω♯), ρ = dω/|f|,
  is bilinear: :func:`lie_1_matrix` in ω, the blocks ♭ · ρ_f [N_f ×] + d V · rows ω♯_fᵀ in X
  (through ♯ when X is a 1-form).
"""

from __future__ import annotations

from math import factorial

import numpy as np
import scipy.sparse as sp

from decrun.methods.model import discrete
from decrun.methods.model.kinds import VECTOR
from decrun.methods.model.scaling import scale_columns, scale_rows

__all__ = ["flux_field_matrix", "flux_field_derivative", "lie_derivative", "lie_1_matrix", "lie_1_derivative", "sharp_matrix", "vector_shape", "mesh_sharp_matrix", "sharp_derivative", "norm_derivative", "normalize_derivative", "flat_matrix",
           "intrinsic_flat_matrix", "flat_derivative", "interior_derivative", "wedge_derivative"]


def _interleaved(parts) -> sp.csr_matrix:
    """The per-axis matrices [(n_n, m)] × d as one (n_n d, m), row σ d + a = row σ of part a."""
    d, count = len(parts), parts[0].shape[0]
    stacked = sp.vstack([part.tocoo() for part in parts]).tocoo()  # row a n_n + σ
    rows = (stacked.row % count) * d + stacked.row // count
    return sp.csr_matrix((stacked.data, (rows, stacked.col)), shape=(count * d, parts[0].shape[1]))


def mesh_sharp_matrix(K) -> sp.csr_matrix:
    """(n_n d, n1) the matrix of :func:`decrun.methods.model.discrete.sharp` (the mesh's own
    simplices), vector values flattened row by row."""
    return K.require(("model", "sharp_matrix_flat"), lambda: _interleaved(discrete.sharp_matrices(K)))


def sharp_matrix(ops) -> sp.csr_matrix:
    """(n_n d, n1) the matrix of the language's ♯ (``ops.sharp``): of the intrinsic triangulation
    under ``operator=intrinsic_delaunay``, else :func:`mesh_sharp_matrix`."""
    if ops.intrinsic is None:
        return mesh_sharp_matrix(ops.K)
    return ops.K.require(("model", "intrinsic_sharp_matrix_flat"), lambda: _interleaved(ops.intrinsic.sharp_matrices))


def vector_shape(ops) -> tuple[int, int]:
    """(n_n, d) the shape of a vector field's value (``ops.sharp``'s: the intrinsic
    triangulation's triangles and their 2-D frames under ``operator=intrinsic_delaunay``)."""
    d = 2 if ops.intrinsic is not None else ops.K.vertices.shape[1]
    return sharp_matrix(ops).shape[0] // d, d


def sharp_derivative(ops, kinds, values, i) -> sp.csr_matrix:
    """∂ sharp(ω)/∂ω = S (linear)."""
    return sharp_matrix(ops)


def _per_simplex_rows(vectors: np.ndarray) -> sp.csr_matrix:
    """(n_n, n_n d): row σ holds ``vectors[σ]`` at the columns σ d … σ d + d − 1."""
    count, d = vectors.shape
    rows = np.repeat(np.arange(count), d)
    return sp.csr_matrix((vectors.ravel(), (rows, np.arange(count * d))), shape=(count, count * d))


def norm_derivative(ops, kinds, values, i) -> sp.csr_matrix | None:
    """∂|X|/∂X per top simplex: X_σᵀ/|X_σ|, 0 where X_σ = 0 (module docstring); None for the norm
    of a form (a number: it couples every value)."""
    if kinds[0] != VECTOR:
        return None
    vectors = np.asarray(values[0], dtype=np.float64)
    length = np.sqrt(np.einsum("fd,fd->f", vectors, vectors))
    zero = length == 0
    return _per_simplex_rows(np.where(zero[:, None], 0.0, vectors / np.where(zero, 1.0, length)[:, None]))


def normalize_derivative(ops, kinds, values, i) -> sp.csr_matrix:
    """∂(X/|X|)/∂X: the block (I − X̂X̂ᵀ)/|X| per top simplex, (n_n d, n_n d); 0 where X = 0."""
    vectors = np.asarray(values[0], dtype=np.float64)
    count, d = vectors.shape
    length = np.sqrt(np.einsum("fd,fd->f", vectors, vectors))
    zero = length == 0
    unit = np.where(zero[:, None], 0.0, vectors / np.where(zero, 1.0, length)[:, None])
    inverse = np.where(zero, 0.0, 1.0 / np.where(zero, 1.0, length))
    blocks = (np.eye(d)[None] - np.einsum("fa,fb->fab", unit, unit)) * inverse[:, None, None]  # (n_n, d, d)
    rows = np.repeat(np.arange(count * d), d)
    cols = (np.arange(count)[:, None, None] * d + np.arange(d)[None, None, :]).repeat(d, axis=1).ravel()
    return sp.csr_matrix((blocks.ravel(), (rows, cols)), shape=(count * d, count * d))


def flat_matrix(K) -> sp.csr_matrix:
    """(n1, n2 d) the matrix of :func:`decrun.methods.model.discrete.flat` (triangles): row e
    holds w_fe/Σ_f w_fe · (p_b − p_a) at the columns of each triangle f at e (the plain mean
    1/#{f ∋ e} where the dual edge has length 0, as ``flat`` takes it)."""
    def compute():
        slots, weights = discrete.flat_weights(K)
        edges = K.simplices(1)
        direction = K.vertices[edges[:, 1]] - K.vertices[edges[:, 0]]
        n1, d = edges.shape[0], direction.shape[1]
        total = np.bincount(slots.ravel(), weights=weights.ravel(), minlength=n1)
        count = np.bincount(slots.ravel(), minlength=n1).astype(np.float64)
        scale = np.abs(weights).max() if weights.size else 1.0
        degenerate = np.abs(total) <= 1e-12 * scale
        share = np.where(degenerate[slots], 1.0 / np.maximum(count, 1.0)[slots],
                         weights / np.where(degenerate, 1.0, total)[slots])  # (n2, 3)
        data = share[:, :, None] * direction[slots]  # (n2, 3, d)
        rows = np.repeat(slots.ravel(), d)
        cols = (np.arange(slots.shape[0])[:, None, None] * d + np.arange(d)[None, None, :]).repeat(3, axis=1)
        return sp.csr_matrix((data.ravel(), (rows, cols.ravel())), shape=(n1, slots.shape[0] * d))
    return K.require(("model", "flat_matrix"), compute)


def intrinsic_flat_matrix(ops) -> sp.csr_matrix:
    """(e, f 2) the matrix of the intrinsic triangulation's ♭
    (:meth:`decrun.core.intrinsic_calculus.IntrinsicCalculus.flat`, ``operator=intrinsic_delaunay``):
    row e holds share_s · ±(side vector of s) at the columns of the triangle of each side s on e,
    share_s = ½cot θ_s / Σ_{s∋e} ½cot θ_s (1/#{s ∋ e} where that sum is 0, as ``flat`` takes it),
    the vectors in each triangle's own frame."""
    calculus = ops.intrinsic

    def compute():
        half_cot = 0.5 * calculus.T.corner_cotangents().ravel()  # side 3f + c is opposite corner c
        edges = calculus.T.face_edges.ravel()
        n_edges, n_faces = calculus.n_edges, calculus.n_faces
        total = np.bincount(edges, weights=half_cot, minlength=n_edges)
        count = np.bincount(edges, minlength=n_edges).astype(np.float64)
        scale = np.abs(half_cot).max() if half_cot.size else 1.0
        degenerate = np.abs(total) <= 1e-12 * scale
        share = np.where(degenerate[edges], 1.0 / np.maximum(count, 1.0)[edges],
                         half_cot / np.where(degenerate, 1.0, total)[edges])  # (3f,)
        along = (calculus.side_vectors * calculus.side_sign[..., None]).reshape(-1, 2)  # (3f, 2)
        rows = np.repeat(edges, 2)
        cols = (np.repeat(np.arange(n_faces), 3)[:, None] * 2 + np.arange(2)[None, :]).ravel()
        return sp.csr_matrix(((share[:, None] * along).ravel(), (rows, cols)), shape=(n_edges, 2 * n_faces))
    return ops.K.require(("model", "intrinsic_flat_matrix"), compute)


def flat_derivative(ops, kinds, values, i) -> sp.csr_matrix:
    """∂ flat(X)/∂X (linear): :func:`flat_matrix`, or :func:`intrinsic_flat_matrix` under
    ``operator=intrinsic_delaunay`` (its ♭ lives on the intrinsic triangulation)."""
    if ops.intrinsic is not None:
        return intrinsic_flat_matrix(ops)
    return flat_matrix(ops.K)


def interior_derivative(ops, kinds, values, i) -> sp.csr_matrix:
    """∂(X·ω♯)/∂ω = diag-blocks X_σᵀ · S (n_n, n1); ∂/∂X = rows ω♯_σᵀ (n_n, n_n d), times S when
    the velocity is a 1-form (its ♯ is taken)."""
    field, omega = values
    sharp = mesh_sharp_matrix(ops.K)  # interior takes ♯ on the mesh's own simplices
    if i == 1:
        vectors = field if kinds[0] == VECTOR else discrete.sharp(ops.K, field)
        return (_per_simplex_rows(np.asarray(vectors, dtype=np.float64)) @ sharp).tocsr()
    rows = _per_simplex_rows(np.asarray(discrete.sharp(ops.K, omega), dtype=np.float64))
    return rows if kinds[0] == VECTOR else (rows @ sharp).tocsr()


def wedge_derivative(ops, kinds, values, i) -> sp.csr_matrix | np.ndarray:
    """∂(a∧b)/∂(argument i): for f∧ω (f a 0-form) diag(ω) A in f and diag(A f) in ω; for two
    1-forms the bilinear triangle rule of ``wedge_11`` in either argument."""
    K = ops.K
    ka, kb = kinds
    if ka.degree == 0 or kb.degree == 0:
        f_index = 0 if ka.degree == 0 else 1
        f, omega = values[f_index], values[1 - f_index]
        k = kinds[1 - f_index].degree
        if k == 0:
            return np.asarray(omega if i == f_index else f, dtype=np.float64)
        average = discrete.average_matrix(K, k)
        if i == f_index:
            return (sp.diags(np.asarray(omega, dtype=np.float64)) @ average).tocsr()
        return np.asarray(average @ f, dtype=np.float64)
    other = np.asarray(values[1 - i], dtype=np.float64)
    e01, e02, e12 = _triangle_edges(K)
    o01, o02, o12 = other[e01], other[e02], other[e12]
    # (α∧β)·6 = α01 (β12 + β02) + α02 (β12 − β01) − α12 (β01 + β02); in β the same with the sign flipped
    sign = 1.0 if i == 0 else -1.0
    coefficients = sign * np.stack([o12 + o02, o12 - o01, -(o01 + o02)], axis=1) / (factorial(2) * 3)
    coefficients = coefficients * np.asarray(discrete.top_sign(K, 2), dtype=np.float64).reshape(-1, 1)
    count = e01.size
    rows = np.repeat(np.arange(count), 3)
    cols = np.stack([e01, e02, e12], axis=1).ravel()
    return sp.csr_matrix((coefficients.ravel(), (rows, cols)), shape=(count, K.num_simplices(1)))


def _triangle_edges(K) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edge indices of the slots (0,1), (0,2), (1,2) of every triangle's sorted tuple."""
    if K.dim == 2:
        table = K.top_face_indices(1)
        return table[:, 0], table[:, 1], table[:, 2]
    triangles = K.simplices(2)
    return tuple(K.find_simplices(triangles[:, [a, b]]) for a, b in ((0, 1), (0, 2), (1, 2)))  # type: ignore[return-value]


def flux_field_matrix(K) -> sp.csr_matrix:
    """(n_n d, n_{n−1}) the matrix of :func:`decrun.methods.model.discrete.flux_field` (module
    docstring; the sign of a negatively oriented tetrahedron included), made once per complex."""
    def compute():
        n = K.dim
        top = K.simplices(n)
        corners = K.vertices[top]
        count, d = top.shape[0], corners.shape[2]
        incidence = K.boundary(n).tocsc()
        faces = K.top_face_indices(n - 1)
        centre = corners.mean(axis=1)
        scale = 1.0 / (n * K.top_volumes)
        if n == 3:
            oriented = K.vertices[K.oriented_simplices()]
            scale = scale * np.sign(np.einsum("ij,ij->i", np.cross(oriented[:, 1] - oriented[:, 0],
                                                                   oriented[:, 2] - oriented[:, 0]),
                                              oriented[:, 3] - oriented[:, 0]))
        rows, cols, data = [], [], []
        for slot in range(n + 1):  # a loop over the n + 1 face slots, not over simplices
            face = faces[:, slot]
            sign = np.asarray(incidence[face, np.arange(count)]).ravel()
            weight = (sign * scale)[:, None] * (centre - corners[:, n - slot])  # (n_n, d)
            rows.append((np.arange(count)[:, None] * d + np.arange(d)[None, :]).ravel())
            cols.append(np.repeat(face, d))
            data.append(weight.ravel())
        return sp.csr_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(count * d, K.num_simplices(n - 1)))
    return K.require(("model", "flux_field_matrix"), compute)


def flux_field_derivative(ops, kinds, values, i) -> sp.csr_matrix:
    """∂ flux_field(u)/∂u (linear): :func:`flux_field_matrix`."""
    return flux_field_matrix(ops.K)


def lie_derivative(ops, kinds, values, i) -> sp.csr_matrix:
    """∂ lie(X, f)/∂(argument i) for a 0-form f (module docstring); of a 1-form:
    :func:`lie_1_derivative`."""
    if kinds[1].degree != 0:
        return lie_1_derivative(ops, kinds, values, i)
    K = ops.K
    field, f = values
    if i == 1:
        vectors = field if kinds[0] == VECTOR else discrete.sharp(K, field)
        return discrete.lie_0_matrix(K, np.asarray(vectors, dtype=np.float64))
    top = K.simplices(K.dim)
    gradient = np.einsum("fv,fvd->fd", np.asarray(f, dtype=np.float64)[top], discrete.gradients(K))
    rows = discrete.vertex_average_matrix(K) @ _per_simplex_rows(gradient)
    return (rows if kinds[0] == VECTOR else rows @ mesh_sharp_matrix(K)).tocsr()


def _block_diagonal(blocks: np.ndarray) -> sp.csr_matrix:
    """(n_n a, n_n b) the block-diagonal matrix of the per-simplex blocks ``blocks`` (n_n, a, b):
    block σ at rows σ a …, columns σ b … (vector values flattened row by row)."""
    count, a, b = blocks.shape
    rows = np.repeat(np.arange(count * a), b)
    cols = (np.arange(count)[:, None, None] * b + np.arange(b)[None, None, :]).repeat(a, axis=1).ravel()
    return sp.csr_matrix((blocks.ravel(), (rows, cols)), shape=(count * a, count * b))


def _lie_1_pieces(K) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray, sp.csr_matrix]:
    """The fixed matrices of :func:`decrun.methods.model.discrete.lie_1` on a triangle mesh, with
    vector values flattened row by row (index f d + a): ``(P_d, F, N, G_d)`` — P_d (n2 d, n1) row
    f d + a the row f of P = diag(1/|f|) d1 (the density ρ of dω per unit area), F the ♭ matrix
    (n1, n2 d, :func:`flat_matrix`), N the unit normals (n2, 3), G_d (n1, n2 d) column f d + a the
    column f of G = d0 A (A the volume-weighted mean onto the vertices); so that
    L_X ω = F vec(ρ N × X) + G (X·ω♯), and every Jacobian below is one sparse product."""
    def compute():
        d = K.vertices.shape[1]
        count = K.num_simplices(2)
        spread = sp.csr_matrix((np.ones(count * d), (np.arange(count * d), np.repeat(np.arange(count), d))),
                               shape=(count * d, count))  # row f d + a ← f
        density = (sp.diags(1.0 / K.top_volumes) @ K.incidence(2)).tocsr()
        gather = (K.incidence(1) @ discrete.vertex_average_matrix(K)).tocsr()
        return (spread @ density).tocsr(), flat_matrix(K), discrete.face_normals(K), (gather @ spread.T).tocsr()
    return K.require(("model", "lie_1_pieces"), compute)


def _normal_cross(normals: np.ndarray, d: int) -> np.ndarray:
    """(n2, d, d) the matrices of X ↦ (N × X)[:d] per triangle (X in R^d padded with zeros to R³):
    column b is N × e_b."""
    basis = np.eye(3)[:d]  # (d, 3): e_b
    columns = np.cross(normals[:, None, :], basis[None, :, :])  # (n2, d: b, 3: a)
    return np.transpose(columns, (0, 2, 1))[:, :d, :]


def lie_1_matrix(K, vectors: np.ndarray) -> sp.csr_matrix:
    """(n1, n1) the matrix of ω ↦ :func:`decrun.methods.model.discrete.lie_1` (K, X, ω) for a
    fixed field X (n2, d) — Cartan's formula, linear in ω:
    F · vec(ρ_f (N_f × X_f)) with ρ = P ω, plus G · (X_fᵀ ω♯_f), i.e.
    F C P + G R S, C (n2 d, n2) the column N_f × X_f per triangle, R (n2, n2 d) the row X_fᵀ
    per triangle, S the ♯ matrix (:func:`_lie_1_pieces`)."""
    density, flat, normals, gather = _lie_1_pieces(K)
    vectors = np.asarray(vectors, dtype=np.float64)
    turned = np.einsum("fab,fb->fa", _normal_cross(normals, vectors.shape[1]), vectors)  # (N × X)[:d] per triangle
    rotation = scale_columns(flat, turned.ravel()) @ density  # F C P
    transport = gather @ scale_rows(mesh_sharp_matrix(K), vectors.ravel())  # G R S
    return (rotation + transport).tocsr()


def lie_1_derivative(ops, kinds, values, i) -> sp.csr_matrix:
    """∂ lie(X, ω)/∂(argument i) for a 1-form ω on a triangle mesh. L_X ω is bilinear (Cartan's
    formula, :func:`lie_1_matrix`): in ω its matrix at the given X; in X (n1, n2 d) the blocks
    F · blockdiag(ρ_f [N_f ×]) + G · rows ω♯_fᵀ, times the ♯ matrix S when the velocity is a
    1-form (lie takes its ♯ on the mesh's own simplices)."""
    K = ops.K
    field, omega = values
    vectors = field if kinds[0] == VECTOR else discrete.sharp(K, field)
    vectors = np.asarray(vectors, dtype=np.float64)
    if i == 1:
        return lie_1_matrix(K, vectors)
    density, flat, normals, gather = _lie_1_pieces(K)
    omega = np.asarray(omega, dtype=np.float64)
    d = vectors.shape[1]
    blocks = _normal_cross(normals, d) * (density @ omega)[::d, None, None]  # ρ_f [N_f ×]
    in_field = flat @ _block_diagonal(blocks) + scale_columns(gather, mesh_sharp_matrix(K) @ omega)
    return (in_field if kinds[0] == VECTOR else in_field @ mesh_sharp_matrix(K)).tocsr()
