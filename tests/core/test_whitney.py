"""Whitney (Galerkin) mass matrices: exact identities against independent references.

References used here are computed differently from the module: barycentric gradients by
pseudo-inverse, Whitney forms evaluated pointwise as vector proxies and integrated with
quadrature rules that are exact for their degree-2 integrands, closed-form P1 matrices
scattered with ``np.add.at``, and the cotangent Laplacian of ``decrun.core.dec.DEC``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pymeshlab
import pytest
import scipy.linalg
import scipy.sparse as sp

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.primitives import grid_triangles, kuhn_cube
from decrun.core.whitney import whitney_lumped_mass, whitney_mass_matrix

from meshes_for_tests import annulus, icosphere, random_planar, random_tets  # noqa: E402


# ---------------------------------------------------------------- meshes
def planar_obtuse():
    V, F = random_planar(80, seed=3)
    return SimplicialComplex(V, F, orient="fix")


def surface_sphere():
    V, F = icosphere(2)
    return SimplicialComplex(V, F, orient="fix")


def bunny():
    """pymeshlab's bunny10k: a scanned surface in R³ with obtuse triangles and 5 borders."""
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(Path(pymeshlab.__file__).parent / "tests/sample_meshes/bunny10k_textured.obj"))
    mesh = ms.current_mesh()
    return SimplicialComplex(mesh.vertex_matrix(), mesh.face_matrix().astype(np.int64))


def tets():
    V, T = random_tets(40, seed=1)
    return SimplicialComplex(V, T, orient="fix")


def pymeshlab_torus():
    ms = pymeshlab.MeshSet()
    ms.create_torus()
    mesh = ms.current_mesh()
    return SimplicialComplex(mesh.vertex_matrix(), mesh.face_matrix().astype(np.int64), orient="fix")


def grid_with_holes(holes: int = 3, cells: int = 12):
    """Right-angled triangulated grid with ``holes`` removed 2×2 blocks of cells."""
    V, F = grid_triangles(cells)
    centroid = V[F].mean(axis=1)
    keep = np.ones(F.shape[0], dtype=bool)
    h = 1.0 / cells
    for i in range(holes):
        x0 = (2 + 3 * i) * h
        inside = ((centroid[:, 0] > x0) & (centroid[:, 0] < x0 + 2 * h)
                  & (centroid[:, 1] > 5 * h) & (centroid[:, 1] < 7 * h))
        keep &= ~inside
    return SimplicialComplex(V, F[keep], orient="fix", unreferenced="drop")


def tet_ball(kind: str = "ball"):
    """Kuhn cube 3×3×3: a ball, with a tunnel (b1 = 1) or with a cavity (b2 = 1)."""
    if kind == "ball":
        keep = None
    elif kind == "tunnel":
        def keep(c):
            return ~((np.abs(c[:, 0] - 0.5) < 0.2) & (np.abs(c[:, 1] - 0.5) < 0.2))
    else:
        def keep(c):
            return ~np.all(np.abs(c - 0.5) < 0.2, axis=1)
    V, T = kuhn_cube(3, keep_cell=keep)
    return SimplicialComplex(V, T)


# ---------------------------------------------------------------- references
def gradients_by_pinv(K):
    """(m, n+1, d) ∇λ_i by pseudo-inverse of the edge matrix (independent of the module)."""
    p = K.vertices[K.simplices(K.dim)]
    E = np.transpose(p[:, 1:] - p[:, :1], (0, 2, 1))
    rest = np.linalg.pinv(E)
    return np.concatenate([-rest.sum(axis=1, keepdims=True), rest], axis=1)


def volumes(K):
    return DEC(K).primal_volumes(K.dim)


# degree-2 exact quadrature rules in barycentric coordinates
TRI_RULE = (np.array([[0.5, 0.5, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]]), np.full(3, 1 / 3))
_a, _b = 0.5854101966249685, 0.1381966011250105
TET_RULE = (np.array([[_a, _b, _b, _b], [_b, _a, _b, _b], [_b, _b, _a, _b], [_b, _b, _b, _a]]), np.full(4, 1 / 4))


def whitney_proxies(K, k, lam):
    """Vector proxies of the local Whitney k-forms at barycentric point ``lam``: (m, C, dim).

    k = 1: W_ab = λ_a∇λ_b − λ_b∇λ_a.
    k = 2 on tets: W_abc = 2(λ_a ∇λ_b×∇λ_c − λ_b ∇λ_a×∇λ_c + λ_c ∇λ_a×∇λ_b), the 2-form as
    the vector of its flux density."""
    from itertools import combinations

    g = gradients_by_pinv(K)
    n = K.dim
    out = []
    for face in combinations(range(n + 1), k + 1):
        if k == 1:
            a, b = face
            out.append(lam[a] * g[:, b] - lam[b] * g[:, a])
        else:
            a, b, c = face
            out.append(2 * (lam[a] * np.cross(g[:, b], g[:, c]) - lam[b] * np.cross(g[:, a], g[:, c])
                            + lam[c] * np.cross(g[:, a], g[:, b])))
    return np.stack(out, axis=1)


def quadrature_mass(K, k):
    """M_k assembled from pointwise Whitney proxies with an exact quadrature."""
    rule = TRI_RULE if K.dim == 2 else TET_RULE
    vol = volumes(K)
    local = 0.0
    for lam, w in zip(*rule, strict=True):
        W = whitney_proxies(K, k, lam)
        local = local + w * np.einsum("m,mad,mbd->mab", vol, W, W)
    faces = K.top_face_indices(k)
    C = faces.shape[1]
    rows = np.repeat(faces, C, axis=1).ravel()
    cols = np.tile(faces, (1, C)).ravel()
    n_k = K.num_simplices(k)
    return sp.coo_matrix((local.ravel(), (rows, cols)), shape=(n_k, n_k)).toarray()


def p1_matrices(K):
    """P1 mass (closed form |σ|/((n+1)(n+2))·(1+δ)) and stiffness Σ|σ|∇λ_i·∇λ_j, by np.add.at."""
    n = K.dim
    top = K.simplices(n)
    vol = volumes(K)
    g = gradients_by_pinv(K)
    nv = K.num_simplices(0)
    mass = np.zeros((nv, nv))
    stiff = np.zeros((nv, nv))
    local_mass = (np.ones((n + 1, n + 1)) + np.eye(n + 1)) / ((n + 1) * (n + 2))
    for i in range(n + 1):
        for j in range(n + 1):
            np.add.at(mass, (top[:, i], top[:, j]), vol * local_mass[i, j])
            np.add.at(stiff, (top[:, i], top[:, j]), vol * np.einsum("md,md->m", g[:, i], g[:, j]))
    return mass, stiff


# ---------------------------------------------------------------- exact identities
@pytest.mark.parametrize("make", [planar_obtuse, surface_sphere, bunny])
def test_stiffness_is_cotangent_laplacian(make):
    K = make()
    d0 = K.incidence(1)
    stiffness = d0.T @ whitney_mass_matrix(K, 1) @ d0
    cot = DEC(K).laplacian_symmetric(0)
    assert abs(stiffness - cot).max() <= 1e-12 * abs(cot).max()
    if make is not surface_sphere:  # the mesh really has obtuse triangles and negative cot weights
        assert (DEC(K).star_diagonal(1) < 0).any()


def test_tet_stiffness_and_mass_are_p1():
    K = tets()
    mass, stiff = p1_matrices(K)
    d0 = K.incidence(1)
    assert np.abs((d0.T @ whitney_mass_matrix(K, 1) @ d0).toarray() - stiff).max() <= 1e-11 * np.abs(stiff).max()
    assert np.abs(whitney_mass_matrix(K, 0).toarray() - mass).max() <= 1e-14 * np.abs(mass).max()


def test_derivatives_commute_with_whitney_forms():
    """d_kᵀ M_{k+1} d_k is ∫⟨dW, dW⟩ of the Whitney k-forms (de Rham commutes with d):
    rot W_ab = 2 ∇λ_a×∇λ_b (planar triangles, a scalar), curl W_ab = 2 ∇λ_a×∇λ_b (tets).
    This ties the signs of M_{k+1} to K.incidence(k+1)."""
    from itertools import combinations

    for K in (planar_obtuse(), tets()):
        g = gradients_by_pinv(K)
        vol = volumes(K)
        local = list(combinations(range(K.dim + 1), 2))
        if K.dim == 2:
            curls = [2 * (g[:, a, 0] * g[:, b, 1] - g[:, a, 1] * g[:, b, 0])[:, None] for a, b in local]
        else:
            curls = [2 * np.cross(g[:, a], g[:, b]) for a, b in local]
        curls = np.stack(curls, axis=1)  # (m, C, 1 or 3)
        local_matrix = np.einsum("m,mad,mbd->mab", vol, curls, curls)
        faces = K.top_face_indices(1)
        C = faces.shape[1]
        n1 = K.num_simplices(1)
        reference = sp.coo_matrix((local_matrix.ravel(), (np.repeat(faces, C, axis=1).ravel(),
                                                          np.tile(faces, (1, C)).ravel())), shape=(n1, n1))
        d1 = K.incidence(2)
        ours = d1.T @ whitney_mass_matrix(K, 2) @ d1
        assert abs(ours - reference).max() <= 1e-11 * abs(reference).max()
    # tets, k = 2: div W_abc = 6 ∇λ_a·(∇λ_b×∇λ_c)
    K = tets()
    g = gradients_by_pinv(K)
    triangles = list(combinations(range(4), 3))
    div = np.stack([6 * np.einsum("md,md->m", g[:, a], np.cross(g[:, b], g[:, c])) for a, b, c in triangles], 1)
    faces = K.top_face_indices(2)
    n2 = K.num_simplices(2)
    local_matrix = volumes(K)[:, None, None] * div[:, :, None] * div[:, None, :]
    reference = sp.coo_matrix((local_matrix.ravel(), (np.repeat(faces, 4, axis=1).ravel(),
                                                      np.tile(faces, (1, 4)).ravel())), shape=(n2, n2))
    d2 = K.incidence(3)
    ours = d2.T @ whitney_mass_matrix(K, 3) @ d2
    # the pinv reference loses digits on this mesh's worst sliver (1/|σ| ≈ 1.4e5): 1e-9, not 1e-11
    assert abs(ours - reference).max() <= 1e-9 * abs(reference).max()


@pytest.mark.parametrize("make", [planar_obtuse, surface_sphere])
def test_mass0_is_p1_closed_form(make):
    K = make()
    mass, _ = p1_matrices(K)  # area/12 · [2 1 1; 1 2 1; 1 1 2] per triangle
    M0 = whitney_mass_matrix(K, 0)
    assert np.abs(M0.toarray() - mass).max() <= 1e-15 * 10
    assert M0.sum() == pytest.approx(volumes(K).sum(), rel=1e-13)


def test_mass0_sums_to_volume_on_tets():
    K = tets()
    assert whitney_mass_matrix(K, 0).sum() == pytest.approx(volumes(K).sum(), rel=1e-13)


@pytest.mark.parametrize("make,k", [(planar_obtuse, 1), (surface_sphere, 1), (tets, 1), (tets, 2)])
def test_mass_matches_quadrature_of_whitney_forms(make, k):
    """M_k against pointwise Whitney forms integrated exactly (any cochain, not only constants)."""
    K = make()
    reference = quadrature_mass(K, k)
    M = whitney_mass_matrix(K, k).toarray()
    assert np.abs(M - reference).max() <= 1e-12 * np.abs(reference).max()


@pytest.mark.parametrize("make", [planar_obtuse, tets])
def test_constant_one_forms_are_reproduced(make):
    """ω_e = a·(p_b − p_a) is the 1-form of the constant field a: ωᵀ M1 ω = |a|²·area (volume)."""
    K = make()
    a = np.array([0.3, -1.7, 0.8])[: K.embedding_dim]
    edges = K.simplices(1)
    omega = (K.vertices[edges[:, 1]] - K.vertices[edges[:, 0]]) @ a
    M1 = whitney_mass_matrix(K, 1)
    assert omega @ (M1 @ omega) == pytest.approx((a @ a) * volumes(K).sum(), rel=1e-12)


def test_constant_two_forms_are_reproduced_on_tets():
    """The flux of a constant field b through each sorted triangle: ωᵀ M2 ω = |b|²·volume."""
    K = tets()
    b = np.array([0.4, 1.1, -0.6])
    p = K.vertices[K.simplices(2)]
    omega = 0.5 * np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]) @ b
    M2 = whitney_mass_matrix(K, 2)
    assert omega @ (M2 @ omega) == pytest.approx((b @ b) * volumes(K).sum(), rel=1e-12)


@pytest.mark.parametrize("make", [planar_obtuse, surface_sphere, tets])
def test_top_mass_is_inverse_volume(make):
    K = make()
    M = whitney_mass_matrix(K, K.dim)
    assert np.array_equal(M.indices, np.arange(K.num_simplices(K.dim)))  # diagonal
    np.testing.assert_allclose(M.diagonal(), 1.0 / volumes(K), rtol=1e-13)


@pytest.mark.parametrize("make", [planar_obtuse, surface_sphere, tets, lambda: grid_with_holes(0, 6)])
def test_mass_matrices_are_spd(make):
    K = make()
    for k in range(K.dim + 1):
        M = whitney_mass_matrix(K, k).toarray()
        assert np.abs(M - M.T).max() == 0.0
        assert np.linalg.eigvalsh(M).min() > 0


def test_spd_on_right_grid_where_circumcentric_star_vanishes():
    V, F = grid_triangles(6)
    K = SimplicialComplex(V, F)
    star1 = DEC(K).star_diagonal(1)
    assert (np.abs(star1) < 1e-14).sum() == 36  # every cell diagonal has a zero dual edge
    eig = np.linalg.eigvalsh(whitney_mass_matrix(K, 1).toarray())
    assert eig.min() > 1e-3 * eig.max()


# ---------------------------------------------------------------- lumping
@pytest.mark.parametrize("make", [planar_obtuse, tets])
def test_lumped_masses(make):
    K = make()
    n = K.dim
    np.testing.assert_allclose(whitney_lumped_mass(K, 0), DEC(K, star="barycentric").star_diagonal(0), rtol=1e-13)
    np.testing.assert_allclose(whitney_lumped_mass(K, 0), np.asarray(whitney_mass_matrix(K, 0).sum(axis=1)).ravel(),
                               rtol=1e-13)
    np.testing.assert_allclose(whitney_lumped_mass(K, n), 1.0 / volumes(K), rtol=1e-13)
    for k in range(1, n):
        lumped = whitney_lumped_mass(K, k)
        np.testing.assert_allclose(lumped, whitney_mass_matrix(K, k).diagonal(), rtol=1e-13)
        assert lumped.min() > 0


def test_lumped_one_form_mass_is_five_sixths_of_star1_on_equilateral_lattice():
    """Diagonal lumping is positive but inconsistent: 5/6 of ⋆1 = 1/√3 on interior edges."""
    i, j = np.meshgrid(np.arange(7), np.arange(7), indexing="ij")
    V = np.stack([i + 0.5 * j, j * np.sqrt(3) / 2], axis=-1).reshape(-1, 2)
    idx = np.arange(49).reshape(7, 7)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    K = SimplicialComplex(V, np.concatenate([np.stack([a, b, d], 1), np.stack([b, c, d], 1)]))
    interior = np.ones(K.num_simplices(1), dtype=bool)
    interior[K.border_faces()[0]] = False
    lumped = whitney_lumped_mass(K, 1)[interior]
    star1 = DEC(K).star_diagonal(1)[interior]
    np.testing.assert_allclose(star1, 1 / np.sqrt(3), rtol=1e-12)
    np.testing.assert_allclose(lumped / star1, 5 / 6, rtol=1e-12)


# ---------------------------------------------------------------- Hodge decomposition with Galerkin stars
def weak_hodge_laplacian(K, k, masses):
    """Dense A_k = d_kᵀ M_{k+1} d_k + (M_k d_{k-1}) M_{k-1}⁻¹ (d_{k-1}ᵀ M_k) and M_k.

    This is M_k Δ_k with Δ_k = dδ + δd and the Galerkin codifferential
    δ_k = M_{k-1}⁻¹ d_{k-1}ᵀ M_k (the ⋆_k⁻¹ d ⋆ of eq. 4.14 with M in place of ⋆). Its kernel
    is ker d_k ∩ ker δ_k, the harmonic k-forms; the generalized problem A v = λ M_k v has
    exactly dim H^k = Betti_k zero eigenvalues.
    """
    M = masses[k].toarray()
    A = np.zeros_like(M)
    if k < K.dim:
        d = K.incidence(k + 1).toarray()
        A += d.T @ masses[k + 1].toarray() @ d
    if k > 0:
        d_low = K.incidence(k).toarray()
        B = M @ d_low
        A += B @ scipy.linalg.cho_solve(scipy.linalg.cho_factor(masses[k - 1].toarray()), B.T)
    return A, M


def harmonic_basis(K, k, masses, tol=1e-9):
    """M_k-orthonormal basis of the weak-Laplacian kernel (columns) and the eigenvalues."""
    A, M = weak_hodge_laplacian(K, k, masses)
    values, vectors = scipy.linalg.eigh(A, M)
    scale = values.max()
    return vectors[:, values < tol * scale], values / scale


CASES = [
    ("pymeshlab torus", pymeshlab_torus, 1, 2),
    ("grid with 3 holes", grid_with_holes, 1, 3),
    ("annulus", lambda: SimplicialComplex(*annulus(0.02), orient="fix"), 1, 1),
    ("sphere", surface_sphere, 1, 0),
    ("sphere 2-forms", surface_sphere, 2, 1),
    ("tet ball 1-forms", tet_ball, 1, 0),
    ("tet ball 2-forms", tet_ball, 2, 0),
    ("tet cube with a tunnel", lambda: tet_ball("tunnel"), 1, 1),
    ("tet cube with a cavity", lambda: tet_ball("cavity"), 2, 1),
]


@pytest.mark.parametrize("name,make,k,betti", CASES, ids=[c[0] for c in CASES])
def test_galerkin_hodge_decomposition(name, make, k, betti):
    K = make()
    assert K.betti_numbers()[k] == betti
    masses = {j: whitney_mass_matrix(K, j) for j in range(K.dim + 1)}
    H, values = harmonic_basis(K, k, masses)
    assert H.shape[1] == betti
    if values.size > betti:  # a clear spectral gap after the harmonic eigenvalues
        assert values[betti] > 1e-6
    M = masses[k].toarray()
    rng = np.random.default_rng(7)
    omega = rng.standard_normal(K.num_simplices(k))
    harmonic = H @ (H.T @ (M @ omega))
    exact = np.zeros_like(omega)
    if k > 0:
        d_low = K.incidence(k).toarray()
        alpha = np.linalg.lstsq(d_low.T @ M @ d_low, d_low.T @ M @ omega, rcond=None)[0]
        exact = d_low @ alpha
    coexact = omega - exact - harmonic
    norm2 = omega @ M @ omega
    # M-orthogonality of the three parts
    for u, v in ((exact, coexact), (exact, harmonic), (harmonic, coexact)):
        assert abs(u @ M @ v) <= 1e-10 * norm2
    # harmonic: closed and coclosed (d h = 0, d_{k-1}ᵀ M h = 0)
    if k < K.dim:
        assert np.abs(K.incidence(k + 1) @ harmonic).max() <= 1e-10 * np.sqrt(norm2)
    if k > 0:
        assert np.abs(d_low.T @ (M @ harmonic)).max() <= 1e-10 * np.sqrt(norm2)
    # the remainder is coexact: M_k c = d_kᵀ M_{k+1} β has an exact solution
    if k < K.dim:
        d = K.incidence(k + 1).toarray()
        rhs_op = d.T @ masses[k + 1].toarray()
        beta = np.linalg.lstsq(rhs_op, M @ coexact, rcond=None)[0]
        assert np.linalg.norm(rhs_op @ beta - M @ coexact) <= 1e-9 * np.linalg.norm(M @ omega)
    else:
        assert np.abs(coexact).max() <= 1e-10 * np.sqrt(norm2)
