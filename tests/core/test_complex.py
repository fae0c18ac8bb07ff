"""SimplicialComplex: the thesis' worked examples, δδ = 0, topology, border loops, validation."""

import numpy as np
import pytest

from decrun import errors
from decrun.core.complex import SimplicialComplex, inversion_parity, unique_rows
from decrun.core.complex.topology import betti_by_rank

from meshes_for_tests import (
    annulus,
    icosphere,
    kuhn_cells,
    kuhn_cube,
    planar_domain,
    random_planar,
    random_tets,
    remeshed_torus,
)


def thesis_matrix(K, j, thesis_simplices):
    """Map the thesis' enumeration (with its reference orientations) to ours.

    Returns P (ours -> thesis index) and the sign of each thesis simplex relative to our
    reference orientation (sorted tuple, times K.orientation for top simplices).
    """
    ours = K.find_simplices(thesis_simplices)
    sign = inversion_parity(np.asarray(thesis_simplices))
    if j == K.dim:
        sign = sign * K.orientation[ours]
    return ours, sign


def to_thesis(K, j, matrix, rows_thesis, cols_thesis):
    """Express δ_j (our basis) in the thesis' bases: D_thesis[r, c] = s_r s_c D[ours_r, ours_c]."""
    r, sr = thesis_matrix(K, j - 1, rows_thesis) if j - 1 > 0 else (np.array([v[0] for v in rows_thesis]), 1)
    c, sc = thesis_matrix(K, j, cols_thesis)
    dense = matrix.toarray()[np.ix_(r, c)]
    return np.asarray(sr).reshape(-1, 1) * dense * np.asarray(sc).reshape(1, -1)


def test_figure_2_15_border_matrices():
    # Fig. 2.15: vertices v0..v3, edges e0..e4, faces f0 = {v0, v2, v1}, f1 = {v2, v3, v1}.
    vertices = np.array([[0, 0], [1, 0], [0, 1], [1, 1.0]])
    faces = np.array([[0, 2, 1], [2, 3, 1]])
    K = SimplicialComplex(vertices, faces)
    edges = [[0, 2], [0, 1], [2, 1], [3, 1], [3, 2]]
    delta2 = to_thesis(K, 2, K.boundary(2), edges, faces.tolist())
    delta1 = to_thesis(K, 1, K.boundary(1), [[0], [1], [2], [3]], edges)
    np.testing.assert_array_equal(delta2, np.array([[1, -1, 1, 0, 0], [0, 0, -1, 1, -1]]).T)
    np.testing.assert_array_equal(
        delta1, [[-1, -1, 0, 0, 0], [0, 1, 1, 1, 0], [1, 0, -1, 0, 1], [0, 0, 0, -1, -1]])
    # the border of e0 - e4 + e3 is -v0 + v1 (§2.2.4)
    chain = np.array([1, 0, 0, 1, -1])
    np.testing.assert_array_equal(delta1 @ chain, [-1, 1, 0, 0])


def regular_tetrahedron_surface():
    vertices = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1.0]]) / np.sqrt(8)
    faces = np.array([[0, 1, 2], [1, 3, 2], [0, 2, 3], [0, 3, 1]])
    return vertices, faces


def test_section_4_5_5_tetrahedron_border_matrices():
    vertices, faces = regular_tetrahedron_surface()
    K = SimplicialComplex(vertices, faces)
    edges = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    delta1 = to_thesis(K, 1, K.boundary(1), [[0], [1], [2], [3]], edges)
    delta2 = to_thesis(K, 2, K.boundary(2), edges, faces.tolist())
    np.testing.assert_array_equal(delta1, [[-1, -1, -1, 0, 0, 0], [1, 0, 0, -1, -1, 0],
                                           [0, 1, 0, 1, 0, -1], [0, 0, 1, 0, 1, 1]])
    # The thesis prints δ2 transposed (4 × 6, one row per face).
    np.testing.assert_array_equal(delta2.T, [[1, -1, 0, 1, 0, 0], [0, 0, 0, -1, 1, -1],
                                             [0, 1, -1, 0, 0, 1], [-1, 0, 1, 0, -1, 0]])


def test_inversion_table_example():
    # §2.3.3: (3, 2, 5, 4, 1) has 6 inversions -> even
    assert inversion_parity(np.array([[3, 2, 5, 4, 1], [2, 1, 3, 4, 5]])).tolist() == [1, -1]


def test_unique_rows_lexicographic_wide_values():
    rows = np.array([[5, 2**40, 1, 0], [1, 2, 3, 4], [5, 2**40, 1, 0], [1, 2, 3, 3]])
    unique, inverse = unique_rows(rows)
    assert unique.tolist() == [[1, 2, 3, 3], [1, 2, 3, 4], [5, 2**40, 1, 0]]
    np.testing.assert_array_equal(unique[inverse], rows)


@pytest.mark.parametrize("mesh", [random_planar, random_tets, lambda: icosphere(2), lambda: kuhn_cube(3)])
def test_border_of_border_is_zero(mesh):
    K = SimplicialComplex(*mesh(), orient="fix")
    for j in range(2, K.dim + 1):
        product = K.boundary(j - 1) @ K.boundary(j)
        assert abs(product).max() == 0
    # every j-simplex list is sorted rows, lexicographic for j < n
    for j in range(1, K.dim):
        s = K.simplices(j)
        assert (np.diff(s, axis=1) > 0).all()
        order = np.lexsort(s.T[::-1])
        np.testing.assert_array_equal(order, np.arange(len(s)))


def test_orientation_of_top_simplices_matches_input():
    vertices, faces = icosphere(1)
    K = SimplicialComplex(vertices, faces)
    np.testing.assert_array_equal(K.orientation, inversion_parity(faces))
    oriented = K.oriented_simplices()
    np.testing.assert_array_equal(inversion_parity(oriented), inversion_parity(faces))
    # closed surface: δ2·1 = 0 (no border), outward normals preserved
    assert K.border_faces()[0].size == 0


@pytest.mark.parametrize("mesh, betti", [
    (lambda: icosphere(2), [1, 0, 1]),
    (remeshed_torus, [1, 2, 1]),
    (lambda: planar_domain(0), [1, 0, 0]),
    (annulus, [1, 1, 0]),
    (lambda: planar_domain(3), [1, 3, 0]),
    (lambda: kuhn_cube(4), [1, 0, 0, 0]),
    (lambda: kuhn_cube(5, keep_cell=lambda c: ~((abs(c[:, 0] - .5) < .2) & (abs(c[:, 1] - .5) < .2))), [1, 1, 0, 0]),
    (lambda: kuhn_cube(5, keep_cell=lambda c: ~(abs(c - .5) < .2).all(1)), [1, 0, 1, 0]),
])
def test_betti_numbers_and_euler_characteristic(mesh, betti):
    K = SimplicialComplex(*mesh())
    assert K.betti_numbers() == betti
    assert K.euler_characteristic == sum((-1) ** j * b for j, b in enumerate(betti))


def test_betti_by_dense_rank_agrees_on_small_complexes():
    for mesh in [lambda: icosphere(1), lambda: planar_domain(2, max_area=0.02), lambda: kuhn_cube(3)]:
        K = SimplicialComplex(*mesh())
        assert betti_by_rank(K) == K.betti_numbers()


@pytest.mark.parametrize("mesh, betti", [
    # two cavity cells meeting along an edge: one connected border inside, two regions (b2 = 2);
    # the surface count gave [1, -1, 1, 0]
    (lambda: kuhn_cells(5, removed={(1, 1, 2), (2, 2, 2)}), [1, 0, 2, 0]),
    # two cavity cells meeting at a vertex only
    (lambda: kuhn_cells(5, removed={(1, 1, 1), (2, 2, 2)}), [1, 0, 2, 0]),
    # two cells meeting along an edge: contractible
    (lambda: kuhn_cells(2, kept={(0, 0, 0), (1, 1, 0)}), [1, 0, 0, 0]),
    # four cells in a ring, each meeting the next along an edge: one loop
    (lambda: kuhn_cells(3, kept={(0, 1, 0), (1, 0, 0), (2, 1, 0), (1, 2, 0)}), [1, 1, 0, 0]),
], ids=["cavities_along_an_edge", "cavities_at_a_vertex", "cells_along_an_edge", "ring_of_cells"])
def test_betti_numbers_of_solids_with_a_pinched_border(mesh, betti):
    """A border that is not a 2-manifold (cells touching along an edge or at a vertex) is not
    counted by surfaces: the Betti numbers come from the ranks, and match them exactly. (Solids
    that are not manifolds themselves — cells meeting along an edge — need check_manifold=False.)"""
    K = SimplicialComplex(*mesh(), check_manifold=False)
    assert K.betti_numbers() == betti == betti_by_rank(K)
    assert K.euler_characteristic == sum((-1) ** j * b for j, b in enumerate(betti))


def test_betti_numbers_of_a_large_pinched_solid_say_why_they_cannot_be_counted():
    K = SimplicialComplex(*kuhn_cells(12, removed={(3, 3, 6), (4, 4, 6)}))
    with pytest.raises(NotImplementedError, match="its border surface is pinched"):
        K.betti_numbers()


def test_boundary_loops_orientation_and_order():
    vertices, faces = planar_domain(3)
    # make every triangle counter-clockwise
    p = vertices[faces]
    u, v = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    cross = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    faces[cross < 0] = faces[cross < 0][:, ::-1]
    K = SimplicialComplex(vertices, faces)
    loops = K.border_loops()
    assert len(loops) == 4

    def signed_area(loop):
        x, y = vertices[loop, 0], vertices[loop, 1]
        return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)

    assert signed_area(loops[0]) > 3.0  # outer unit circle, counter-clockwise
    assert all(signed_area(loop) < 0 for loop in loops[1:])  # holes clockwise
    # every consecutive pair is a border edge
    border = set(map(tuple, np.sort(K.simplices(1)[K.border_faces()[0]], axis=1).tolist()))
    for loop in loops:
        pairs = np.sort(np.stack([loop, np.roll(loop, -1)], 1), axis=1)
        assert set(map(tuple, pairs.tolist())) <= border
    assert sum(len(loop) for loop in loops) == len(border)


def test_boundary_complex_is_closed():
    K = SimplicialComplex(*kuhn_cube(3))
    border = K.border_complex()
    assert border.dim == 2
    assert border.betti_numbers() == [1, 0, 1]
    assert border.border_faces()[0].size == 0


def test_orientation_fix_keeps_majority_and_makes_consistent():
    vertices, faces = icosphere(2)
    flipped = faces.copy()
    flipped[:5] = flipped[:5, ::-1]
    with pytest.raises(errors.OrientationError, match="orient='fix'"):
        SimplicialComplex(vertices, flipped)
    K = SimplicialComplex(vertices, flipped, orient="fix")
    np.testing.assert_array_equal(K.orientation, inversion_parity(faces))


def test_unreferenced_vertices_error_or_drop():
    vertices, faces = icosphere(1)
    extra = np.vstack([vertices, [[5.0, 5.0, 5.0]]])
    with pytest.raises(errors.UnreferencedVertexError, match=f"vertex {len(vertices)}"):
        SimplicialComplex(extra, faces)
    K = SimplicialComplex(extra, faces, unreferenced="drop")
    assert K.num_simplices(0) == len(vertices)
    np.testing.assert_array_equal(K.original_vertex_index, np.arange(len(vertices)))


SQUARE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1.0]])


@pytest.mark.parametrize("vertices, simplices, error, named", [
    (SQUARE, [[0, 1, 2], [0, 2, 7]], errors.IndexOutOfRangeError, "triangle 1"),
    (SQUARE, [[0, 1, 2], [0, 2, 2]], errors.RepeatedVertexError, "triangle 1"),
    (SQUARE, [[0, 1, 2], [2, 3, 0], [1, 2, 0]], errors.DuplicateSimplexError, "triangles 0, 2"),
    (np.vstack([SQUARE[:4], [[np.nan, 0, 0]]]), [[0, 1, 2], [0, 2, 4]], errors.NonFiniteCoordinateError, "vertex 4"),
    (np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0.]]), [[0, 1, 3], [0, 1, 2]], errors.DegenerateSimplexError,
     "triangle 1"),
    # an edge in three triangles (a "dangling" fin, Fig. 2.11)
    (SQUARE, [[0, 1, 2], [0, 2, 3], [0, 2, 4]], errors.NonManifoldError, "edge"),
    # two triangles touching at one vertex: a bowtie (Fig. 2.11/2.12)
    (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0.]]), [[0, 1, 2], [0, 3, 4]],
     errors.NonManifoldError, "vertex 0"),
    (SQUARE, [[0, 1, 2], [0, 2, 3], [5, 1, 2]], errors.IndexOutOfRangeError, "triangle 2"),
])
def test_validation_errors_name_the_simplex(vertices, simplices, error, named):
    with pytest.raises(error, match=named):
        SimplicialComplex(vertices, np.array(simplices), unreferenced="drop")


def test_two_closed_fans_at_one_vertex_are_non_manifold():
    # two tetrahedron surfaces touching at vertex 0: each fan around it is a closed cycle
    vertices, faces = regular_tetrahedron_surface()
    second = vertices.copy()
    second[1:] = 2 * vertices[0] - vertices[1:]  # point reflection through vertex 0
    all_vertices = np.vstack([vertices, second[1:]])
    second_faces = faces.copy()
    second_faces[second_faces > 0] += 3
    second_faces = second_faces[:, ::-1]  # the reflection flips orientation back
    with pytest.raises(errors.NonManifoldError, match="vertex 0: .* 2 separate fans"):
        SimplicialComplex(all_vertices, np.vstack([faces, second_faces]), orient="fix")
    # each half alone is fine
    SimplicialComplex(vertices, faces)


def test_unreferenced_error_names_vertex():
    with pytest.raises(errors.UnreferencedVertexError, match="vertices 3, 4"):
        SimplicialComplex(SQUARE, np.array([[0, 1, 2]]))


def test_moebius_strip_is_not_orientable():
    count = 8
    angle = np.linspace(0, 2 * np.pi, count, endpoint=False)
    vertices = []
    for a in angle:
        for w in (-0.3, 0.3):
            r = 1 + w * np.cos(a / 2)
            vertices.append([r * np.cos(a), r * np.sin(a), w * np.sin(a / 2)])
    faces = []
    for i in range(count):
        a0, a1 = 2 * i, 2 * i + 1
        if i < count - 1:
            b0, b1 = 2 * i + 2, 2 * i + 3
        else:
            b0, b1 = 1, 0  # the half twist glues the strip to itself reversed
        faces += [[a0, b0, b1], [a0, b1, a1]]
    for orient in ("check", "fix"):
        with pytest.raises(errors.NonOrientableError, match="not orientable"):
            SimplicialComplex(np.array(vertices), np.array(faces), orient=orient)


def test_tetrahedral_orientation_check():
    vertices, tets = kuhn_cube(2)
    bad = tets.copy()
    bad[3] = bad[3][[1, 0, 2, 3]]
    with pytest.raises(errors.OrientationError, match="tetrahedron"):
        SimplicialComplex(vertices, bad)
    K = SimplicialComplex(vertices, bad, orient="fix")
    assert abs(K.boundary(2) @ K.boundary(3)).max() == 0
    assert np.all(np.abs(np.asarray(K.boundary(3).sum(axis=1)).ravel()) <= 1)


def test_find_simplices_any_order():
    K = SimplicialComplex(*random_tets(30), orient="fix")
    tets = K.simplices(3)[[4, 0, 7]]
    assert K.find_simplices(tets[:, ::-1]).tolist() == [4, 0, 7]
    edges = K.simplices(1)[[10, 3]]
    assert K.find_simplices(np.vstack([edges[:, ::-1], [[0, 0]]])).tolist() == [10, 3, -1]
