"""The boundary adaptations of the operators (decrun.core.boundary): eq. 6.10 and its matrices."""

from __future__ import annotations

import numpy as np
import pytest

from decrun.core.boundary.flux import border_flux_matrix, border_vertex_matrix
from decrun.core.dec import DEC
from decrun.core.forms import sample_vector_field
from decrun.errors import ConfigError
from decrun.methods.vector_design import adjointness_defect

from meshes_for_tests import complex_of


@pytest.fixture(scope="module")
def sphere():
    return complex_of(source="icosphere", subdiv=3)


@pytest.fixture(scope="module")
def square():
    return complex_of(source="planar", outer=[[0, 0], [1, 0], [1, 1], [0, 1]], holes=[], max_area=0.004)


def test_border_flux_matrix_is_exact_for_constant_fields(square):
    """Eq. 6.10 (zero curl) is exact for a constant field: F w = |e| (u · n_out) on border
    edges, and the flux-adapted δ of a constant field vanishes everywhere (closed dual cells),
    while the unadapted δ does not on the border."""
    dec = DEC(square)
    u = np.array([0.7, 0.3])
    w = sample_vector_field(square, u)
    edges, _ = square.border_faces()
    ends = square.vertices[square.simplices(1)[edges]]
    mid = ends.mean(axis=1)
    outward = np.zeros_like(mid)
    outward[np.isclose(mid[:, 0], 0)] = [-1, 0]
    outward[np.isclose(mid[:, 0], 1)] = [1, 0]
    outward[np.isclose(mid[:, 1], 0)] = [0, -1]
    outward[np.isclose(mid[:, 1], 1)] = [0, 1]
    length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    F = border_flux_matrix(dec)
    assert np.allclose((F @ w)[edges], length * (outward @ u), atol=1e-13)
    interior_rows = np.setdiff1d(np.arange(square.num_simplices(1)), edges)
    assert F[interior_rows].nnz == 0
    scale = np.abs(dec.codifferential(1) @ w).max()
    assert np.abs(DEC(square, boundary="flux").codifferential(1) @ w).max() < 1e-12 * scale
    border = square.border_vertices()
    assert np.abs((dec.codifferential(1) @ w)[border]).min() > 1e-3 * scale
    assert np.abs((dec.codifferential(1) @ w)[~border]).max() < 1e-10 * scale


def test_flux_adaptation_breaks_adjointness_only_with_a_border(square, sphere):
    """§6.4.4: the adapted δ is no longer the adjoint of d0 (Theorem 5 fails); on a closed
    mesh both modes coincide."""
    dec = DEC(square)
    flux = DEC(square, boundary="flux").codifferential(1)
    assert adjointness_defect(dec, dec.codifferential(1)) < 1e-14
    # the defect is exactly the border term: ⟨d0 a, w⟩_⋆1 − ⟨a, δ_flux w⟩_⋆0 = aᵀ M_border F w
    rng = np.random.default_rng(5)
    a, w = rng.standard_normal(square.num_simplices(0)), rng.standard_normal(square.num_simplices(1))
    border_term = a @ (border_vertex_matrix(square) @ (border_flux_matrix(dec) @ w))
    defect = dec.inner(1, dec.d(0) @ a, w) - dec.inner(0, a, flux @ w)
    assert abs(border_term) > 1e-3 * abs(dec.inner(1, dec.d(0) @ a, w))
    assert defect == pytest.approx(border_term, rel=1e-10)
    dec_s = DEC(sphere)
    assert (DEC(sphere, boundary="flux").codifferential(1) - dec_s.codifferential(1)).nnz == 0
    with pytest.raises(ConfigError, match="boundary=dirichlet: unknown BoundaryAdaptation; choose one of boundary=flux | boundary=none"):
        DEC(square, boundary="dirichlet")
