"""The TRiSK operators (decrun.core.trisk): exact identities (d∘d = 0 through the operators, the
antisymmetry of W, the Coriolis term doing no work, TRiSK's curl-of-perp = averaged divergence,
mass and energy conservation of the semi-discrete equations, to round-off, for random fields on a
jittered sphere) and the convergence orders of the operators on smooth fields over subdiv 3 → 4 → 5."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.forms import sample_vector_field
from decrun.core.trisk import TRiSK, corner_kite_areas, sphere_radius
from decrun.errors import MeshError
from tests.meshes_for_tests import icosphere

RADIUS = 6.37122e6
GRAVITY = 9.80616


def sphere_trisk(subdiv: int, jitter: float = 0.0, radius: float = 1.0, seed: int = 0) -> TRiSK:
    """TRiSK on the icosphere of ``radius``, its vertices moved by ``jitter`` mean edge lengths
    (random, tangentially) and projected back: a sphere mesh without the icosahedron's symmetries."""
    vertices, faces = icosphere(subdiv)
    if jitter:
        rng = np.random.default_rng(seed)
        step = jitter * 1.1 / 2 ** subdiv * rng.standard_normal(vertices.shape)
        vertices = vertices + step
        vertices /= np.linalg.norm(vertices, axis=1, keepdims=True)
    return TRiSK(DEC(SimplicialComplex(radius * vertices, faces, orient="fix")))


@pytest.fixture(scope="module")
def jittered():
    return sphere_trisk(3, jitter=0.05, radius=RADIUS)


def test_kite_areas_partition_the_cells_and_the_triangles(jittered):
    T = jittered
    kites = T.kite_areas()
    np.testing.assert_allclose(kites.sum(axis=1), T.triangle_areas, rtol=1e-12)
    per_cell = np.bincount(T.outward_triangles().ravel(), weights=kites.ravel(), minlength=T.K.num_simplices(0))
    np.testing.assert_allclose(per_cell, T.cell_areas, rtol=1e-12)
    # a right triangle: the circumcenter is the hypotenuse's midpoint, the right angle's kite is half
    right = corner_kite_areas(np.array([[[0.0, 0, 0], [2, 0, 0], [0, 2, 0]]]))
    np.testing.assert_allclose(right, [[1.0, 0.5, 0.5]])


def test_outward_triangles_point_out_of_the_sphere(jittered):
    p = jittered.K.vertices[jittered.outward_triangles()]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (np.einsum("md,md->m", normals, p.mean(axis=1)) > 0).all()


def test_curl_of_a_gradient_and_divergence_of_a_dual_curl_vanish(jittered):
    """d1 d0 = 0: ζ of ∇φ is zero; d0ᵀ d1ᵀ = 0: the flux of a stream function on the triangles
    (G = d1ᵀ ψ, a dual curl) has zero divergence in every cell — exactly."""
    rng = np.random.default_rng(1)
    T = jittered
    gradient = T.gradient(rng.standard_normal(T.K.num_simplices(0)))
    circulation = T.vorticity(gradient) * T.triangle_areas  # a sum of three differences: zero up to rounding
    assert np.abs(circulation).max() <= 4e-16 * np.abs(gradient).max()
    stream = rng.standard_normal(T.K.num_simplices(2))
    flux = T.dec.d(1).T @ stream
    assert np.abs(T.divergence(flux) * T.cell_areas).max() <= 8e-16 * np.abs(flux).max()


def test_divergence_conserves_mass(jittered):
    rng = np.random.default_rng(2)
    flux = rng.standard_normal(jittered.K.num_simplices(1))
    divergence = jittered.divergence(flux)
    assert abs(jittered.cell_areas @ divergence) <= 1e-14 * (jittered.cell_areas @ np.abs(divergence))


def test_W_is_antisymmetric_bit_for_bit_and_every_edge_couples_its_cells_edges(jittered):
    W = jittered.perp()
    assert abs(W + W.T).max() == 0.0
    assert W.diagonal().max() == 0.0
    # each edge sees the other edges of its two cells: Σ (degree − 1) over its two end vertices
    degree = np.bincount(jittered.K.simplices(1).ravel())
    expected = (degree[jittered.K.simplices(1)] - 1).sum(axis=1)
    np.testing.assert_array_equal(np.diff(W.indptr), expected)


def test_the_coriolis_term_does_no_work(jittered):
    """Σ_e G_e Q(q, G)_e = 0 to round-off for random fluxes and potential vorticities."""
    rng = np.random.default_rng(3)
    for _ in range(5):
        flux = rng.standard_normal(jittered.K.num_simplices(1))
        pv = rng.standard_normal(jittered.K.num_simplices(1))
        coriolis = jittered.coriolis_term(pv, flux)
        assert abs(flux @ coriolis) <= 1e-14 * (np.abs(flux) @ np.abs(coriolis))


def test_curl_of_the_perpendicular_flux_is_the_kite_averaged_divergence(jittered):
    """TRiSK's defining property (Thuburn et al. 2009): d1 (W G) = Σ_i (A_{i,v}/A_i) (net
    outflow of G from cell i), so a geostrophic flow on an f-plane is steady; exact."""
    T = jittered
    rng = np.random.default_rng(4)
    flux = rng.standard_normal(T.K.num_simplices(1))
    triangles = T.outward_triangles()
    share = sp.csr_matrix(((T.kite_areas() / T.cell_areas[triangles]).ravel(),
                           (np.repeat(np.arange(T.K.num_simplices(2)), 3), triangles.ravel())),
                          shape=(T.K.num_simplices(2), T.K.num_simplices(0)))
    outflow = -(T.dec.d(0).T @ flux)
    curl = T.dec.d(1) @ (T.perp() @ flux)
    np.testing.assert_allclose(curl, share @ outflow, atol=1e-13 * np.abs(outflow).max())


def tendencies(T: TRiSK, h, U, b, f):
    """The semi-discrete equations of the module doc, written from the operators."""
    flux = T.mass_flux(h, U)
    dh = -T.divergence(flux)
    pv = T.pv_on_edges(T.potential_vorticity(U, h, f))
    dU = -T.gradient(T.kinetic_energy(U) + GRAVITY * (h + b)) - T.coriolis_term(pv, flux)
    return dh, dU


def energy(T: TRiSK, h, U, b):
    return T.cell_areas @ (h * T.kinetic_energy(U) + GRAVITY * h * (0.5 * h + b))


def random_state(T: TRiSK, seed: int):
    rng = np.random.default_rng(seed)
    n0, n1, n2 = (T.K.num_simplices(j) for j in range(3))
    h = 1000.0 + 300.0 * rng.random(n0)
    U = 30.0 * T.primal_lengths * rng.standard_normal(n1)
    return h, U, 200.0 * rng.random(n0), 1e-4 * rng.standard_normal(n2)


def test_the_semi_discrete_equations_conserve_mass_and_energy(jittered):
    """dM/dt = Σ A ∂h/∂t = 0 and dE/dt = Σ_i A_i (K_i + g (h_i + b_i)) ∂h_i/∂t + Σ_e G_e ∂U_e/∂t = 0 to
    round-off for random states with topography; the chain rule used is checked against central
    differences of E."""
    T = jittered
    for seed in range(3):
        h, U, b, f = random_state(T, seed)
        dh, dU = tendencies(T, h, U, b, f)
        mass_rate = T.cell_areas @ dh
        assert abs(mass_rate) <= 1e-14 * (T.cell_areas @ np.abs(dh))
        bernoulli = T.kinetic_energy(U) + GRAVITY * (h + b)
        terms = np.concatenate([T.cell_areas * bernoulli * dh, T.mass_flux(h, U) * dU])
        assert abs(terms.sum()) <= 1e-13 * np.abs(terms).sum()
        epsilon = 1e-3
        finite = (energy(T, h + epsilon * dh, U + epsilon * dU, b)
                  - energy(T, h - epsilon * dh, U - epsilon * dU, b)) / (2 * epsilon)
        chain = (T.cell_areas * bernoulli) @ dh + T.mass_flux(h, U) @ dU
        scale = np.abs(terms).sum()
        assert abs(finite - chain) <= 1e-6 * scale


def test_the_depth_on_triangles_and_edges_reproduces_constants_and_the_kinetic_energy_of_rotation():
    T = sphere_trisk(3)
    ones = np.ones(T.K.num_simplices(0))
    np.testing.assert_allclose(T.cell_to_triangle() @ ones, 1.0, rtol=1e-13)
    np.testing.assert_allclose(T.edge_average() @ ones, 1.0, rtol=0)
    # Σ A_i K_i = Σ_e l_e d_e u_e²/2 for any U
    U = np.random.default_rng(5).standard_normal(T.K.num_simplices(1))
    np.testing.assert_allclose(T.cell_areas @ T.kinetic_energy(U), 0.5 * (T.star1 * U * U).sum(), rtol=1e-13)


def test_laplacian_bound_is_an_upper_bound_close_to_the_largest_eigenvalue():
    T = sphere_trisk(3, jitter=0.05)
    stiffness = (T.dec.d(0).T @ sp.diags(T.star1) @ T.dec.d(0)).tocsc()
    largest = spla.eigsh(stiffness, k=1, M=sp.diags(T.cell_areas).tocsc(), which="LA",
                         return_eigenvectors=False)[0]
    assert largest <= T.laplacian_bound() <= 1.6 * largest


def test_refuses_a_surface_with_a_border_and_a_non_delaunay_mesh():
    vertices, faces = icosphere(2)
    with pytest.raises(MeshError, match="closed surface"):
        TRiSK(DEC(SimplicialComplex(vertices, faces[1:], orient="fix")))
    squashed = vertices * np.array([1.0, 1.0, 0.05])
    with pytest.raises(MeshError, match="Delaunay"):
        TRiSK(DEC(SimplicialComplex(squashed, faces, orient="fix")))


def test_sphere_radius_refuses_a_noisy_or_shifted_sphere():
    vertices, _ = icosphere(2)
    assert sphere_radius(RADIUS * vertices) == pytest.approx(RADIUS, rel=1e-15)
    noisy = vertices.copy()
    noisy[7] *= 1.001
    with pytest.raises(MeshError, match=r"^mesh: not a sphere centred at the origin: vertex 7 .*mesh.noise=0\)$"):
        sphere_radius(noisy)
    with pytest.raises(MeshError, match="not a sphere centred at the origin"):
        sphere_radius(vertices + np.array([0.0, 0.0, 0.01]))


# -------------------------------------------------------------------- orders on smooth fields
def unit(x):
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def scalar(x):
    """φ = x̂ z² + sin(2 ŷ) on the unit sphere (radially constant)."""
    p = unit(x)
    return p[:, 0] * p[:, 2] ** 2 + np.sin(2 * p[:, 1])


def tangent_field(x):
    """A smooth tangent field with divergence and vorticity (the tangential part of a fixed field)."""
    p = unit(x)
    v = np.column_stack([np.sin(2 * p[:, 1]) + p[:, 2], np.cos(3 * p[:, 2]), p[:, 0] ** 2])
    return v - p * np.einsum("nd,nd->n", v, p)[:, None]


def surface_divergence_and_curl(x, h=1e-5):
    """(div, curl·n̂) of ``tangent_field`` at unit-sphere points by central differences of the
    3-D extension F(x) = tangent_field(x) (homogeneous of degree 0, tangent): div_S F = ∇·F − n̂·(∇F)n̂,
    curl_S F · n̂ = (∇ × F)·n̂."""
    p = unit(x)
    jac = np.empty((p.shape[0], 3, 3))
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = h
        jac[:, :, axis] = (tangent_field(p + step) - tangent_field(p - step)) / (2 * h)
    div = np.trace(jac, axis1=1, axis2=2) - np.einsum("ni,nij,nj->n", p, jac, p)
    curl = np.column_stack([jac[:, 2, 1] - jac[:, 1, 2], jac[:, 0, 2] - jac[:, 2, 0], jac[:, 1, 0] - jac[:, 0, 1]])
    return div, np.einsum("nd,nd->n", curl, p)


def errors(subdiv: int, build=sphere_trisk) -> dict[str, tuple[float, float]]:
    """(max, area-weighted rms) errors of each operator on the unit sphere mesh ``build(subdiv)``
    (default the icosphere of ``subdiv``)."""
    T = build(subdiv)
    K = T.K
    U = sample_vector_field(K, lambda x: tangent_field(unit(x)), order=4)
    d = T.primal_lengths
    exact_perp = sample_vector_field(K, lambda x: np.cross(unit(x), tangent_field(unit(x))), order=4)
    div, curl = surface_divergence_and_curl(K.vertices)
    _, curl_v = surface_divergence_and_curl(T.coriolis_points())
    midpoints = unit(K.vertices[K.simplices(1)].mean(axis=1))
    speed2 = np.einsum("nd,nd->n", tangent_field(K.vertices), tangent_field(K.vertices))

    def norms(err, weights):
        return float(np.abs(err).max()), float(np.sqrt(weights @ err ** 2 / weights.sum()))

    edge_weights = T.primal_lengths * T.dual_lengths
    tangent = (K.vertices[K.simplices(1)[:, 1]] - K.vertices[K.simplices(1)[:, 0]]) / d[:, None]
    exact_gradient = np.einsum("nd,nd->n", tangent, _gradient(midpoints))
    return {
        "gradient": norms(T.gradient(scalar(K.vertices)) / d - exact_gradient, edge_weights),
        "divergence": norms(T.divergence(T.star1 * U) - div, T.cell_areas),
        "vorticity": norms(T.vorticity(U) - curl_v, T.triangle_areas),
        "kinetic energy": norms(T.kinetic_energy(U) - 0.5 * speed2, T.cell_areas),
        "perp": norms((T.perp() @ (T.star1 * U) - exact_perp) / d, edge_weights),
    }


def _gradient(points, h=1e-6):
    grad = np.empty_like(points)
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = h
        grad[:, axis] = (scalar(points + step) - scalar(points - step)) / (2 * h)
    return grad - points * np.einsum("nd,nd->n", grad, points)[:, None]


@pytest.fixture(scope="module")
def convergence():
    return {subdiv: errors(subdiv) for subdiv in (3, 4, 5)}


@pytest.mark.parametrize("operator, norm, order", [
    ("gradient", 0, 1.9), ("gradient", 1, 1.9),
    ("divergence", 1, 1.1), ("vorticity", 0, 0.85), ("vorticity", 1, 0.95),
    ("kinetic energy", 1, 1.2), ("perp", 1, 0.45),
])
def test_observed_orders_on_smooth_fields(convergence, operator, norm, order):
    """Observed orders over subdiv 3 → 4 → 5 (h halves each time), norm 0 the maximum, 1 the
    area-weighted rms. Measured (max; rms): gradient 2.0; 2.0 — divergence 0.0; 1.4, 1.2 — vorticity
    (at the circumcenters) 0.9, 1.0; 1.0 — kinetic energy 0.1, 0.0; 1.6, 1.4 — perp 0.2, 0.1; 0.5, 0.5.
    The divergence, the kinetic energy and the perpendicular flux W are known to be inconsistent in
    the maximum norm on the non-optimized icosahedral grid, whose Voronoi edges are not bisected by
    their primal edges (Thuburn, Cotter & Dubos 2014; Peixoto 2016); TC2 converges anyway, at order
    1.5 (benchmarks/shallow_water_numpy.py)."""
    values = [convergence[s][operator][norm] for s in (3, 4, 5)]
    observed = np.log2(np.array(values[:-1]) / np.array(values[1:]))
    assert (observed >= order).all(), (operator, norm, values, observed)
