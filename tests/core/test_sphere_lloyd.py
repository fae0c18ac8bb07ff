"""Lloyd's iteration on the sphere (decrun.core.sphere_lloyd): it converges to a centroidal Voronoi
tessellation on the same sphere with the same triangles, and there TRiSK's perpendicular flux, which
is inconsistent on the plain icosphere (tests/core/test_trisk.py), converges at second order in rms."""

from __future__ import annotations

import numpy as np
import pytest

import tests.core.test_trisk as trisk_tests
from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.sphere_lloyd import lloyd_sphere, subdivide_sphere
from decrun.core.trisk import TRiSK
from decrun.errors import MeshError
from tests.meshes_for_tests import icosphere


def test_lloyd_converges_to_a_centroidal_tessellation_on_the_same_sphere():
    vertices, faces = icosphere(3)
    radius = 6.37122e6
    moved, info = lloyd_sphere(radius * vertices, faces, 500, tolerance=1e-12)
    assert info["last_move"] < 1e-12 and info["iterations"] < 500
    np.testing.assert_allclose(np.linalg.norm(moved, axis=1), radius, rtol=1e-14)
    assert np.linalg.norm(moved - radius * vertices, axis=1).max() > 1e-3 * radius  # it did move the grid
    again, one = lloyd_sphere(moved, faces, 1)  # a fixed point: every generator is its cell's centroid
    assert one["last_move"] < 1e-12
    TRiSK(DEC(SimplicialComplex(moved, faces, orient="fix")))  # still Delaunay


def test_subdividing_the_icosphere_gives_the_next_icosphere():
    """pymeshlab's icosphere of subdiv 3 is that of subdiv 2 refined 1-to-4 at projected midpoints."""
    from scipy.spatial import cKDTree

    coarse, faces = icosphere(2)
    fine, fine_faces = subdivide_sphere(coarse, faces)
    expected, expected_faces = icosphere(3)
    distance, match = cKDTree(expected).query(fine)
    assert distance.max() < 1e-12 and np.unique(match).size == expected.shape[0]
    as_expected = np.sort(np.sort(match[fine_faces], axis=1), axis=0)
    np.testing.assert_array_equal(np.unique(np.sort(match[fine_faces], axis=1), axis=0),
                                  np.unique(np.sort(expected_faces, axis=1), axis=0))
    assert as_expected.shape == expected_faces.shape
    K = SimplicialComplex(fine, fine_faces)  # consistently oriented as it is (orient="check")
    assert K.euler_characteristic == 2


def test_lloyd_refuses_a_mesh_off_the_sphere():
    vertices, faces = icosphere(1)
    with pytest.raises(MeshError, match="not a sphere centred at the origin"):
        lloyd_sphere(vertices + 0.1, faces, 3)


@pytest.mark.slow
def test_on_the_centroidal_grid_the_perpendicular_flux_converges_at_second_order():
    """Measured over subdiv 3 → 4 → 5: perp rms order 1.9, 1.9 (plain icosphere 0.5, 0.5); divergence
    rms 1.8, 1.6; kinetic energy rms 1.9, 1.7; gradient 2.0."""

    def centroidal(subdiv):
        vertices, faces = icosphere(subdiv)
        moved, _ = lloyd_sphere(vertices, faces, 3000, tolerance=1e-11)
        return TRiSK(DEC(SimplicialComplex(moved, faces, orient="fix")))

    errors = [trisk_tests.errors(subdiv, centroidal) for subdiv in (3, 4)]
    for operator, order in (("perp", 1.8), ("divergence", 1.7), ("kinetic energy", 1.7)):
        assert np.log2(errors[0][operator][1] / errors[1][operator][1]) >= order, operator
