"""Sampling ♭ commutes with d, Whitney ♯ reproduces edge integrals, Hodge decomposition (Theorem 5)."""

import numpy as np
import pytest
import scipy.spatial

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.forms import barycentric_gradients, sample_density, sample_function, sample_vector_field, whitney_sharp
from decrun.core.hodge import HodgeDecomposer, harmonic_basis, hodge_decomposition
from decrun.errors import MeshError

from meshes_for_tests import (
    annulus,
    grid_triangles,
    icosphere,
    kuhn_cube,
    planar_domain,
    random_planar,
    random_tets,
    remeshed_torus,
)


def cubic(points):
    x, y = points[:, 0], points[:, 1]
    return x**3 - 2 * x * y**2 + y + 0.5


def cubic_gradient(points):
    x, y = points[:, 0], points[:, 1]
    return np.stack([3 * x**2 - 2 * y**2, -4 * x * y + 1], axis=1)


def test_sampling_commutes_with_d_on_functions():
    # ∫_e ∇f · dl = f(b) - f(a): d0 ♭f = ♭(df) exactly with 2-point Gauss (∇f quadratic)
    K = SimplicialComplex(*random_planar(100, seed=3), orient="fix")
    dec = DEC(K)
    np.testing.assert_allclose(dec.d(0) @ sample_function(K, cubic), sample_vector_field(K, cubic_gradient, order=2),
                               rtol=1e-12, atol=1e-14)


def test_sampling_commutes_with_d_on_one_forms():
    # Stokes on each triangle: d1 ♭X = ♭(curl X) exactly for a quadratic field X
    K = SimplicialComplex(*random_planar(100, seed=4), orient="fix")
    dec = DEC(K)

    def field(p):
        x, y = p[:, 0], p[:, 1]
        return np.stack([x * y - y**2, x**2 + 3 * y], axis=1)

    def curl(p):  # ∂x X_y - ∂y X_x
        x, y = p[:, 0], p[:, 1]
        return 2 * x - (x - 2 * y)

    # orientation of each triangle in the plane (+1 counter-clockwise)
    tri = K.oriented_simplices()
    p = K.vertices[tri]
    u, v = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    ccw = np.sign(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
    np.testing.assert_allclose(dec.d(1) @ sample_vector_field(K, field), ccw * sample_density(K, curl, order=2),
                               rtol=1e-11, atol=1e-14)


def test_sample_density_integrates_volume():
    points, tets = random_tets(60, seed=5)
    K = SimplicialComplex(points, tets, orient="fix")
    # the Delaunay tets fill the convex hull: an independent volume (qhull)
    assert sample_density(K, 1.0).sum() == pytest.approx(scipy.spatial.ConvexHull(points).volume, rel=1e-12)
    assert np.all(sample_density(K, 1.0) > 0)


def test_whitney_reproduces_constant_fields_and_edge_integrals():
    K = SimplicialComplex(*icosphere(2))
    # a constant ambient field projected per face is reproduced at every point of the face
    for vertices, faces in {"planar": random_planar(80, seed=6), "grid": grid_triangles(5)}.values():
        Kp = SimplicialComplex(vertices, faces, orient="fix")
        omega = sample_vector_field(Kp, np.array([0.7, -0.2]))
        for bary in ([1 / 3] * 3, [0.6, 0.3, 0.1], [0.0, 0.5, 0.5]):
            np.testing.assert_allclose(whitney_sharp(Kp, omega, barycentric=bary), [[0.7, -0.2]] * Kp.num_simplices(2),
                                       atol=1e-12)
    # tangential component along each edge of each face integrates to the edge value
    omega = np.random.default_rng(7).standard_normal(K.num_simplices(1))
    tri = K.simplices(2)
    for a, b, _c in [(0, 1, 2), (0, 2, 1), (1, 2, 0)]:
        bary = np.zeros((len(tri), 3))
        bary[:, a] = bary[:, b] = 0.5
        u = whitney_sharp(K, omega, barycentric=bary)
        edge = K.vertices[tri[:, b]] - K.vertices[tri[:, a]]
        ids = K.find_simplices(tri[:, [a, b]])
        np.testing.assert_allclose(np.einsum("fd,fd->f", u, edge), omega[ids], rtol=1e-10, atol=1e-12)


def test_barycentric_gradients_are_the_thesis_perpendiculars():
    K = SimplicialComplex(*random_planar(30, seed=8), orient="fix")
    g = barycentric_gradients(K)
    p = K.vertices[K.simplices(2)]
    area = DEC(K).primal_volumes(2)
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        e = p[:, k] - p[:, j]
        perp = np.stack([-e[:, 1], e[:, 0]], 1)
        perp *= np.sign(np.einsum("fd,fd->f", perp, p[:, i] - p[:, j]))[:, None]  # towards vertex i
        np.testing.assert_allclose(g[:, i], perp / (2 * area[:, None]), rtol=1e-10, atol=1e-12)


def relative_inner(dec, k, a, b):
    """|⟨a, b⟩_⋆| / (‖a‖ ‖b‖) with the norms taken in |⋆_k| (⋆ is indefinite where cot weights
    are negative, e.g. random tets: ⟨a, a⟩_⋆ may be negative)."""
    weight = np.abs(dec.star_diagonal(k))
    return abs(dec.inner(k, a, b)) / np.sqrt(np.sum(weight * a**2) * np.sum(weight * b**2))


def dense_projections(dec, omega):
    """Exact and coexact parts of a 1-form computed densely from scratch, with the condition
    numbers of the two systems: the ⋆1-orthogonal projections onto im d0 and onto
    im ⋆1⁻¹d1ᵀ = ⋆1⁻¹ im d1ᵀ, written in orthonormal bases P of im d0 and Q of im d1ᵀ (numpy
    SVD and solve on dense matrices — no decrun solver, no shift, no refinement):
    (Pᵀ⋆1P) a = Pᵀ⋆1ω, exact = P a; (Qᵀ⋆1⁻¹Q) y = Qᵀ(ω − exact), coexact = ⋆1⁻¹Q y.
    Where ⋆1 is indefinite with entries near 0 (random tets: |⋆1| from 1e-6 to 2e2) the second
    system's condition number reaches 1e11, and no dense reference is then better than
    eps × cond (the former normal equations, cond², moved by 1e-6 with the BLAS thread count)."""
    d0, d1 = dec.d(0).toarray(), dec.d(1).toarray()
    star1 = dec.star_diagonal(1)

    def basis(matrix):  # orthonormal columns spanning the column space
        u, singular, _ = np.linalg.svd(matrix, full_matrices=False)
        return u[:, singular > 1e-10 * singular[0]]

    P, Q = basis(d0), basis(d1.T)
    exact_system = P.T @ (star1[:, None] * P)
    exact = P @ np.linalg.solve(exact_system, P.T @ (star1 * omega))
    coexact_system = Q.T @ (Q / star1[:, None])
    coexact = (Q / star1[:, None]) @ np.linalg.solve(coexact_system, Q.T @ (omega - exact))
    return exact, coexact, np.linalg.cond(exact_system), np.linalg.cond(coexact_system)


@pytest.mark.parametrize("mesh", [lambda: remeshed_torus(0.2), lambda: planar_domain(3, max_area=0.006),
                                  lambda: random_tets(80, seed=9)], ids=["torus", "disk_3_holes", "tets"])
def test_hodge_parts_match_dense_projections_and_are_orthogonal(mesh):
    """Theorem 5 against an independent computation: the exact and coexact parts equal the
    dense ⋆1-orthogonal projections (to 1e-9, or to what the dense reference's conditioning
    allows: 1e-4 relative for the coexact part on random tets, whose orthogonality below is
    still checked to 1e-10); the three parts are pairwise ⋆-orthogonal (all three
    pairs whenever Betti_1 > 0); the harmonic part is closed and coclosed, and vanishes
    when Betti_1 = 0."""
    dec = DEC(SimplicialComplex(*mesh(), orient="fix"))
    omega = np.random.default_rng(10).standard_normal(dec.K.num_simplices(1))
    parts = hodge_decomposition(dec, omega)
    exact, coexact, exact_condition, coexact_condition = dense_projections(dec, omega)
    scale = np.abs(omega).max()
    # the reference is good to about eps × cond (1e-15 × cond: a margin of ~4 over eps)
    np.testing.assert_allclose(parts.exact, exact, atol=max(1e-9, 1e-15 * exact_condition) * scale)
    np.testing.assert_allclose(parts.coexact, coexact, atol=max(1e-9, 1e-15 * coexact_condition) * scale)
    np.testing.assert_allclose(parts.exact, dec.d(0) @ parts.alpha, atol=1e-12)
    np.testing.assert_allclose(parts.coexact, dec.codifferential(2) @ parts.beta, atol=1e-10 * np.abs(parts.coexact).max())
    betti_1 = dec.K.betti_numbers()[1]
    if betti_1 == 0:
        assert dec.norm(1, parts.harmonic) <= 1e-10 * dec.norm(1, omega)
        assert relative_inner(dec, 1, parts.exact, parts.coexact) <= 1e-10
    else:
        for a, b in [(parts.exact, parts.coexact), (parts.exact, parts.harmonic), (parts.coexact, parts.harmonic)]:
            assert relative_inner(dec, 1, a, b) <= 1e-10
        assert dec.norm(1, parts.harmonic) > 1e-3 * dec.norm(1, omega)
    assert np.abs(dec.d(1) @ parts.harmonic).max() <= 1e-9 * scale
    assert np.abs(dec.codifferential(1) @ parts.harmonic).max() <= 1e-8 * np.abs(dec.codifferential(1) @ omega).max()


def test_exact_and_coexact_inputs_stay_pure():
    dec = DEC(SimplicialComplex(*icosphere(3)))
    rng = np.random.default_rng(11)
    exact = dec.d(0) @ rng.standard_normal(dec.K.num_simplices(0))
    coexact = dec.codifferential(2) @ rng.standard_normal(dec.K.num_simplices(2))
    decomposer = HodgeDecomposer(dec, 1)
    parts = decomposer.decompose(np.stack([exact, coexact], axis=1))
    np.testing.assert_allclose(parts.exact[:, 0], exact, atol=1e-11 * np.abs(exact).max())
    assert np.abs(parts.coexact[:, 0]).max() <= 1e-11 * np.abs(exact).max()
    np.testing.assert_allclose(parts.coexact[:, 1], coexact, atol=1e-10 * np.abs(coexact).max())
    assert np.abs(parts.exact[:, 1]).max() <= 1e-10 * np.abs(coexact).max()
    # on the sphere nothing is harmonic
    assert np.abs(parts.harmonic).max() <= 1e-10 * np.abs(coexact).max()


@pytest.mark.parametrize("mesh, k, expected", [
    (lambda: icosphere(3), 1, 0),
    (remeshed_torus, 1, 2),
    (lambda: planar_domain(0), 1, 0),
    (annulus, 1, 1),
    (lambda: planar_domain(3), 1, 3),
    (lambda: icosphere(2), 0, 1),
    (lambda: icosphere(2), 2, 1),
    (lambda: kuhn_cube(4, keep_cell=lambda c: ~((abs(c[:, 0] - .5) < .2) & (abs(c[:, 1] - .5) < .2))), 0, 1),
])
def test_harmonic_dimension_equals_betti(mesh, k, expected):
    K = SimplicialComplex(*mesh(), orient="fix")
    dec = DEC(K)
    basis = harmonic_basis(dec, k)
    assert basis.shape[1] == expected == K.betti_numbers()[k]
    np.testing.assert_allclose(dec.inner(k, basis, basis), np.eye(expected), atol=1e-9)


def test_tet_solid_torus_has_one_harmonic_one_form():
    # Kuhn cubes have right angles (⋆1 = 0 on some edges): perturb every vertex a little.
    vertices, tets = kuhn_cube(6, keep_cell=lambda c: ~((abs(c[:, 0] - .5) < .2) & (abs(c[:, 1] - .5) < .2)))
    vertices = vertices + np.random.default_rng(12).uniform(-0.02, 0.02, vertices.shape)
    dec = DEC(SimplicialComplex(vertices, tets))
    assert np.abs(dec.star_diagonal(1)).min() > 1e-9
    assert harmonic_basis(dec, 1).shape[1] == 1 == dec.K.betti_numbers()[1]


def test_degenerate_star_gives_clear_error():
    dec = DEC(SimplicialComplex(*grid_triangles(4)))
    with pytest.raises(MeshError, match="invertible ⋆_1"):
        hodge_decomposition(dec, np.ones(dec.K.num_simplices(1)))


def test_configured_solver_instance_serves_both_poisson_problems_with_its_options():
    from decrun.core.solvers import make_solver

    dec = DEC(SimplicialComplex(*icosphere(2)))
    solver = make_solver("cg", tol=1e-13, preconditioner="none")
    decomposer = HodgeDecomposer(dec, 1, solver)
    exact_solver, coexact_solver = decomposer._exact.solver, decomposer._coexact.solver
    assert exact_solver is not coexact_solver  # each problem keeps its own factorization
    assert (coexact_solver.tol, coexact_solver.preconditioner) == (1e-13, "none")
    omega = np.random.default_rng(13).standard_normal(dec.K.num_simplices(1))
    parts = decomposer.decompose(omega)
    assert relative_inner(dec, 1, parts.exact, parts.coexact) <= 1e-10
    np.testing.assert_allclose(parts.exact + parts.coexact + parts.harmonic, omega, atol=1e-12)
