"""Spectra of Δ_k (decrun.methods.spectrum): the analytic spectra themselves, convergence of
the discrete ones to them for every form degree, and the solver paths (dense, sparse
shift-invert, Galerkin saddle point, indefinite ⋆)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.primitives import flat_torus, grid_triangles, kuhn_cube
from decrun.errors import MeshError
from decrun.methods import spectrum
from decrun.methods.spectrum import Domain, analytic_spectrum, detect_domain, laplacian_eigenpairs, spectrum_errors

from meshes_for_tests import icosphere, pieces_mesh

PI2 = np.pi**2


def test_analytic_sphere_spectrum_has_the_multiplicities_of_spherical_harmonics():
    np.testing.assert_allclose(analytic_spectrum(Domain("sphere", (1.0,)), 0, 10), [0, 2, 2, 2, 6, 6, 6, 6, 6, 12])
    np.testing.assert_allclose(analytic_spectrum(Domain("sphere", (2.0,)), 1, 8), [0.5] * 6 + [1.5] * 2)
    np.testing.assert_allclose(analytic_spectrum(Domain("sphere", (1.0,)), 2, 4), [0, 2, 2, 2])


def test_analytic_box_spectrum_neumann_absolute_and_dirichlet():
    cube = Domain("box", (1.0, 1.0, 1.0))
    np.testing.assert_allclose(analytic_spectrum(cube, 0, 8), PI2 * np.array([0, 1, 1, 1, 2, 2, 2, 3]))
    # 1-forms f dx_i: sin in x_i (m_i ≥ 1), cos elsewhere: 3 × π², then 6 × 2π²
    np.testing.assert_allclose(analytic_spectrum(cube, 1, 9), PI2 * np.array([1, 1, 1, 2, 2, 2, 2, 2, 2]))
    np.testing.assert_allclose(analytic_spectrum(cube, 2, 4), PI2 * np.array([2, 2, 2, 3]))
    np.testing.assert_allclose(analytic_spectrum(cube, 3, 4), PI2 * np.array([3, 6, 6, 6]))  # Dirichlet
    np.testing.assert_allclose(analytic_spectrum(Domain("box", (2.0, 1.0)), 0, 4), PI2 * np.array([0, .25, 1, 1]))


def test_analytic_flat_torus_spectrum_repeats_per_form_component():
    torus = Domain("flat_torus", (2 * np.pi, 2 * np.pi))
    np.testing.assert_allclose(analytic_spectrum(torus, 0, 6), [0, 1, 1, 1, 1, 2])
    np.testing.assert_allclose(analytic_spectrum(torus, 1, 6), [0, 0, 1, 1, 1, 1])


def test_detect_domain_recognizes_sphere_box_and_flat_torus_only():
    assert detect_domain(SimplicialComplex(*icosphere(2))).describe() == "sphere(1)"
    assert detect_domain(SimplicialComplex(*kuhn_cube(2, size=2.0))).describe() == "box(2, 2, 2)"
    assert detect_domain(SimplicialComplex(*grid_triangles(3))).kind == "box"
    assert detect_domain(SimplicialComplex(*flat_torus(6), orient="fix")).kind == "flat_torus"
    tunnel = kuhn_cube(4, keep_cell=lambda c: ~((abs(c[:, 0] - .5) < .2) & (abs(c[:, 1] - .5) < .2)))
    assert detect_domain(SimplicialComplex(*tunnel)) is None
    vertices, faces = icosphere(2)
    assert detect_domain(SimplicialComplex(vertices * [1, 1, 1.1], faces)) is None


def errors(V, T, star, k, count=10):
    K = SimplicialComplex(V, T, orient="fix")
    pairs = laplacian_eigenpairs(DEC(K, star=star), k, count)
    return spectrum_errors(pairs.values, analytic_spectrum(detect_domain(K), k, count))


@pytest.mark.parametrize("star", ["circumcentric", "whitney"])
@pytest.mark.parametrize("k", [0, 1])
def test_sphere_spectrum_converges_for_functions_and_one_forms(star, k):
    coarse, fine = (errors(*icosphere(s), star, k)["eigenvalue_relative_error_max"] for s in (2, 3))
    assert fine < 0.025 and coarse > 3 * fine, (coarse, fine)


@pytest.mark.parametrize("k", [0, 1, 2, 3])
def test_cube_spectrum_with_whitney_stars_every_degree(k):
    """Kuhn cubes: the Galerkin stars (FEEC) converge in every degree, with absolute boundary
    conditions (Neumann for functions, Dirichlet for densities)."""
    coarse, fine = (errors(*kuhn_cube(n), "whitney", k, 8)["eigenvalue_relative_error_max"] for n in (3, 5))
    assert fine < 0.16 and coarse > 1.5 * fine, (coarse, fine)


@pytest.mark.parametrize("k, star", [(1, "whitney"), (2, "whitney")])
def test_unit_square_absolute_spectrum_for_one_and_two_forms(k, star):
    """(The jittered square's circumcentric ⋆1 is negative on 137 edges: refused for k = 1,
    see test_indefinite_mass_is_refused_naming_the_operator_that_works, and for k = 2, see
    test_negative_stiffness_star_is_refused_naming_the_operator_that_works.)"""
    got = errors(*grid_triangles(16, jitter=0.2), star, k)
    assert got["eigenvalue_relative_error_max"] < 0.06


@pytest.mark.parametrize("star", ["circumcentric", "whitney"])
def test_flat_torus_has_two_harmonic_one_forms(star):
    K = SimplicialComplex(*flat_torus(16), orient="fix")
    values = laplacian_eigenpairs(DEC(K, star=star), 1, 6).values
    assert np.abs(values[:2]).max() < 1e-9 and values[2] > 0.9
    assert errors(*flat_torus(16), star, 1)["eigenvalue_relative_error_max"] < 0.05


def test_eigenvectors_are_star_orthonormal_and_solve_the_pencil():
    dec = DEC(SimplicialComplex(*kuhn_cube(4)), star="whitney")
    pairs = laplacian_eigenpairs(dec, 1, 6)
    M, A = dec.star(1), dec.laplacian_symmetric(1)
    np.testing.assert_allclose(pairs.vectors.T @ (M @ pairs.vectors), np.eye(6), atol=1e-9)
    for value, u in zip(pairs.values, pairs.vectors.T, strict=True):
        assert np.linalg.norm(A @ u - value * (M @ u)) < 1e-7 * value * np.linalg.norm(M @ u)


def test_sparse_and_dense_paths_agree(monkeypatch):
    dec = DEC(SimplicialComplex(*icosphere(2)), star="whitney")
    sparse = laplacian_eigenpairs(dec, 1, 8).values
    monkeypatch.setattr(spectrum, "DENSE_MAX", 10**6)
    np.testing.assert_allclose(laplacian_eigenpairs(dec, 1, 8).values, sparse, rtol=1e-8)


def test_indefinite_mass_is_refused_naming_the_operator_that_works():
    """Issue 25 item 4: a mass ⋆_k with negative entries made the pencil indefinite, and the
    eigenvalues came back negative (−17.0, −4.6 on a jittered box, degree 1) with no error.
    Refused now, naming the operator whose mass is positive on that mesh and degree; that
    operator converges (checked residual and orthonormality)."""
    vertices, tets = kuhn_cube(4)
    inner = np.all((vertices > 1e-9) & (vertices < 1 - 1e-9), axis=1)
    vertices[inner] += np.random.default_rng(0).uniform(-0.025, 0.025, (inner.sum(), 3))
    dec = DEC(SimplicialComplex(vertices, tets), star="barycentric")
    assert dec.star_diagonal(0).min() > 0 and dec.star_diagonal(1).min() < 0
    assert spectrum.needs_indefinite_solve(dec, 1) and not spectrum.needs_indefinite_solve(dec, 0)
    assert laplacian_eigenpairs(dec, 0, 4).converged  # ⋆0 > 0: functions are fine
    with pytest.raises(MeshError, match=r"positive mass ⋆_1.*negative on \d+ of .*`operator=whitney`"):
        laplacian_eigenpairs(dec, 1, 4)
    pairs = laplacian_eigenpairs(DEC(SimplicialComplex(vertices, tets), star="whitney"), 1, 4)
    assert pairs.converged and pairs.values.min() > 0 and pairs.residual_max < 1e-10
    square = SimplicialComplex(*grid_triangles(16, jitter=0.2), orient="fix")
    with pytest.raises(MeshError, match=r"positive mass ⋆_1.*`operator=whitney`"):
        laplacian_eigenpairs(DEC(square, star="circumcentric"), 1, 4)
    surface = SimplicialComplex(*flat_torus(6), orient="fix")
    dec = DEC(surface, star="circumcentric")
    monkeypatched = dec.star_diagonal(0).copy()
    monkeypatched[3] = -monkeypatched[3]
    dec.star_diagonal = lambda j, _real=dec.star_diagonal: monkeypatched if j == 0 else _real(j)
    dec.star_diagonal_or_none = dec.star_diagonal
    with pytest.raises(MeshError, match=r"positive mass ⋆_0.*`operator=mixed_area`"):
        spectrum.check_stars(dec, 0)


def test_every_eigenpair_is_checked_and_a_bad_one_is_not_converged(monkeypatch):
    """The residual ‖A u − λ M u‖ / (‖A‖ ‖u‖) and the M-orthonormality of every returned pair
    are measured; eigenvectors that do not solve the pencil are not ``converged``."""
    dec = DEC(SimplicialComplex(*icosphere(3)), star="whitney")  # 642 vertices: the sparse (ARPACK) path
    good = laplacian_eigenpairs(dec, 0, 6)
    assert good.converged and good.residual_max < 1e-12 and good.orthonormality_error < 1e-10
    real = spla.eigsh

    def perturbed(*args, **kwargs):  # an eigen-solve that stops short: 1e-3 of noise in every vector
        values, vectors = real(*args, **kwargs)
        return values, vectors + 1e-3 * np.random.default_rng(0).standard_normal(vectors.shape)

    monkeypatch.setattr(spla, "eigsh", perturbed)
    bad = laplacian_eigenpairs(dec, 0, 6)
    assert not bad.converged and bad.residual_max > 1e-6


def test_degenerate_star_is_refused_with_the_galerkin_hint():
    dec = DEC(SimplicialComplex(*kuhn_cube(6)))
    laplacian_eigenpairs(dec, 0, 4)  # ⋆0 > 0 and Δ0 never divides by ⋆1
    with pytest.raises(MeshError, match=r"⋆_1 of operator=circumcentric is zero.*`operator=whitney`"):
        laplacian_eigenpairs(dec, 2, 4)  # Δ2 contains ⋆1⁻¹
    with pytest.raises(MeshError, match=r"singular: ⋆_1 .*`operator=whitney`"):
        laplacian_eigenpairs(dec, 1, 4)  # zero ⋆1 rows that Δ1 does not reach


@pytest.mark.parametrize("star", ["circumcentric", "barycentric", "mixed_area"])
def test_negative_stiffness_star_is_refused_naming_the_operator_that_works(star):
    """Issue 34 item 7: Δ2 on a surface contains ⋆1⁻¹ (⋆2 d1 ⋆1⁻¹ d1ᵀ ⋆2), and the cot ⋆1 of
    the jittered square is negative on 137 of 800 edges. ⋆2Δ2 then has exactly as many
    negative eigenvalues (Sylvester), down to −6.8e5; the app returned either those (4 × 4 grid,
    dense solve: −864.5 as "the lowest eigenvalue") or the non-negative part with the 137
    skipped (16 × 16, shift-invert: 19.66 first), converged both times. Refused now before
    any work, naming `operator=whitney`, whose spectrum is the analytic one."""
    import scipy.linalg as la

    for n in (4, 16):
        K = SimplicialComplex(*grid_triangles(n, jitter=0.2), orient="fix")
        dec = DEC(K, star=star)
        negative = int(np.sum(dec.star_diagonal(1) < 0))
        A, M = dec.laplacian_symmetric(2), dec.star(2)
        A, M = (x.toarray() if hasattr(x, "toarray") else np.asarray(x) for x in (A, M))
        assert np.sum(la.eigh(0.5 * (A + A.T), M, eigvals_only=True) < -1e-6) == negative > 0  # indefinite
        with pytest.raises(MeshError, match=rf"contains ⋆_2 d ⋆_1⁻¹ dᵀ ⋆_2, but ⋆_1 of operator={star} is negative "
                                            rf"on {negative} of .*indefinite.*`operator=whitney`"):
            laplacian_eigenpairs(dec, 2, 10)
    got = errors(*grid_triangles(16, jitter=0.2), "whitney", 2)  # the override: the analytic spectrum
    assert got["eigenvalue_relative_error_max"] < 0.02


def test_stiffness_degrees_are_the_stars_whose_signs_matter():
    """⋆_{k-1} (inverted) and ⋆_{k+1} between two derivatives; not ⋆1 in Δ0 (the cot weights'
    P1 stiffness: semi-definite whatever their signs — the jittered square's Δ0 with 137
    negative ⋆1 entries has no negative eigenvalue) and not ⋆_n."""
    assert spectrum.stiffness_degrees(2, 0) == () and spectrum.stiffness_degrees(2, 1) == (0,)
    assert spectrum.stiffness_degrees(2, 2) == (1,) and spectrum.stiffness_degrees(3, 1) == (0, 2)
    assert spectrum.stiffness_degrees(3, 2) == (1,) and spectrum.stiffness_degrees(3, 3) == (2,)
    dec = DEC(SimplicialComplex(*grid_triangles(16, jitter=0.2), orient="fix"), star="mixed_area")
    values = laplacian_eigenpairs(dec, 0, 6).values
    assert values[0] > -1e-9 and abs(values[1] - PI2) < 0.05 * PI2


def test_negative_eigenvalues_the_checks_miss_are_refused_after_the_solve(monkeypatch):
    """The last guard: an indefinite operator that check_stars does not foresee (here: the
    check switched off) is refused when its eigenvalues come out negative, not returned."""
    monkeypatch.setattr(spectrum, "check_stars", lambda dec, k: None)
    dec = DEC(SimplicialComplex(*grid_triangles(4, jitter=0.2), orient="fix"), star="circumcentric")
    with pytest.raises(MeshError, match=r"Δ_2 with operator=circumcentric is indefinite.*negative \(down to "
                                        r"-864.5\).*`operator=whitney`"):
        laplacian_eigenpairs(dec, 2, 10)


def test_several_pieces_have_one_kernel_dimension_each():
    """Issue 34 item 8: the spectrum of a mesh of several pieces is the union of the pieces'
    spectra; Δ0's kernel is the 22 piecewise constants. One Lanczos run about σ found 17 of
    the 22 zero eigenvalues and listed 9.86, 9.86, 19.7, 39.3, … (the big square's) as the
    lowest, converged. Each piece is solved on its own now."""
    K = SimplicialComplex(*pieces_mesh())
    assert K.connected_components()[0] == 22 and K.betti_numbers()[0] == 22
    dec = DEC(K, star="mixed_area")
    pairs = laplacian_eigenpairs(dec, 0, 25)
    assert pairs.converged and pairs.orthonormality_error < 1e-10
    np.testing.assert_allclose(pairs.values[:22], 0, atol=1e-9)
    kernel = pairs.vectors[:, :22]  # piecewise constant, spanning the 22 pieces' constants
    _, top_label = K.connected_components()
    vertex_piece = np.zeros(K.num_simplices(0), dtype=np.int64)
    vertex_piece[K.simplices(2)] = top_label[:, None]
    indicator = np.eye(22)[vertex_piece]  # (n0, 22)
    coefficients = np.linalg.lstsq(indicator, kernel, rcond=None)[0]
    np.testing.assert_allclose(indicator @ coefficients, kernel, atol=1e-9)
    assert np.linalg.matrix_rank(coefficients) == 22
    big = SimplicialComplex(*grid_triangles(30))  # the rest: the big square's own lowest nonzero eigenvalues
    alone = laplacian_eigenpairs(DEC(big, star="mixed_area"), 0, 4).values
    np.testing.assert_allclose(pairs.values[22:], alone[1:4], rtol=1e-9)
    np.testing.assert_allclose(alone[1:3], PI2, rtol=0.01)
    one_forms = laplacian_eigenpairs(dec, 1, 4)  # Betti_1 = 0: no kernel, the big square's π²
    assert one_forms.converged and one_forms.values[0] == pytest.approx(PI2, rel=0.01)
