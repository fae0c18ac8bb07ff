"""decrun.core.connectivity: the shared edge table, edge owners, pieces and unused vertices."""

from __future__ import annotations

import numpy as np

from decrun.core.complex import SimplicialComplex
from decrun.core.connectivity import drop_unreferenced, edge_owners, edge_table, largest_component

from meshes_for_tests import icosphere

BOWTIE = np.array([[0, 1, 2], [0, 3, 4], [3, 4, 5]])  # two pieces touching at vertex 0


def test_edge_table_matches_the_complex_and_the_corners():
    vertices, faces = icosphere(2)
    edges, corner_edges = edge_table(faces)
    K = SimplicialComplex(vertices, faces)
    np.testing.assert_array_equal(edges, K.simplices(1))  # same lexicographic order
    start, end = faces, np.roll(faces, -1, axis=1)
    np.testing.assert_array_equal(np.sort(edges[corner_edges], axis=2),
                                  np.sort(np.stack([start, end], axis=2), axis=2))


def test_edge_owners_point_back_at_the_edge():
    vertices, faces = icosphere(1)
    K = SimplicialComplex(vertices, faces)
    owner, slot = edge_owners(K.facet_indices(2), K.num_simplices(1))
    assert (owner >= 0).all()
    np.testing.assert_array_equal(K.facet_indices(2)[owner, slot], np.arange(K.num_simplices(1)))


def test_largest_component_through_edges_or_vertices():
    assert largest_component(BOWTIE).tolist() == [False, True, True]  # the 2-triangle piece
    assert largest_component(BOWTIE, through="vertices").tolist() == [True, True, True]


def test_drop_unreferenced_keeps_order():
    vertices = np.arange(7.0)[:, None] * [1.0, 0.0]
    kept, simplices, used = drop_unreferenced(vertices, BOWTIE[1:] + 1)
    assert used.tolist() == [False, True, False, False, True, True, True]
    np.testing.assert_array_equal(kept[simplices], vertices[BOWTIE[1:] + 1])
