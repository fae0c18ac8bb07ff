"""Distortion metrics on hand-made maps with known answers (decrun.methods.parametrization_metrics)."""

import numpy as np
import pytest

from decrun.core.primitives import grid_triangles
from decrun.methods.parametrization_metrics import (
    angle_distortion,
    area_distortion_std,
    border_self_intersections,
    border_turning_numbers,
    border_vertex_uv_angles,
    degenerate_triangles,
    flipped_triangles,
    is_embedding,
    map_singular_values,
    parametrization_metrics,
)

from meshes_for_tests import spiral_strip

RIGHT_TRIANGLE = (np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), np.array([[0, 1, 2]]))


@pytest.mark.parametrize("s", [0.3, 1.0, 2.5])
def test_shear_has_known_singular_values(s):
    # J = [[1, s], [0, 1]]: σ1σ2 = det = 1, σ1² + σ2² = tr JᵀJ = 2 + s².
    vertices, faces = RIGHT_TRIANGLE
    uv = vertices[:, :2] @ np.array([[1.0, s], [0.0, 1.0]]).T
    sigma = map_singular_values(vertices, uv, faces)[0]
    expected_ratio = (2 + s**2 + s * np.sqrt(4 + s**2)) / 2  # σ1/σ2 = σ1² when σ1σ2 = 1
    assert sigma[0] * sigma[1] == pytest.approx(1.0, rel=1e-12)
    assert sigma[0] / sigma[1] == pytest.approx(expected_ratio, rel=1e-12)


def test_shear_by_one_has_known_angle_errors():
    # (0,0),(1,0),(0,1) -> (0,0),(1,0),(1,1): angles 90,45,45 -> 45,90,45 degrees.
    vertices, faces = RIGHT_TRIANGLE
    uv = vertices[:, :2] @ np.array([[1.0, 1.0], [0.0, 1.0]]).T
    error = np.degrees(angle_distortion(vertices, uv, faces))[0]
    np.testing.assert_allclose(error, [45.0, 45.0, 0.0], atol=1e-12)
    metrics = parametrization_metrics(vertices, uv, faces, [np.array([0, 1, 2])])
    assert metrics["angle_distortion_mean_deg"] == pytest.approx(30.0)
    assert metrics["angle_distortion_max_deg"] == pytest.approx(45.0)
    assert metrics["area_distortion_std"] == pytest.approx(0.0, abs=1e-12)  # a shear keeps area


def test_similarity_of_a_3d_triangle_has_no_distortion():
    rng = np.random.default_rng(1)
    vertices = rng.normal(size=(3, 3))
    faces = np.array([[0, 1, 2]])
    # isometric layout of the triangle in the plane, then rotate + scale
    a, b, c = vertices
    e1 = (b - a) / np.linalg.norm(b - a)
    normal = np.cross(b - a, c - a)
    e2 = np.cross(normal / np.linalg.norm(normal), e1)
    flat = np.stack([(vertices - a) @ e1, (vertices - a) @ e2], axis=1)
    rotation = np.array([[np.cos(0.7), -np.sin(0.7)], [np.sin(0.7), np.cos(0.7)]])
    uv = 3.0 * flat @ rotation.T + 5.0
    sigma = map_singular_values(vertices, uv, faces)[0]
    np.testing.assert_allclose(sigma, [3.0, 3.0], rtol=1e-12)
    assert angle_distortion(vertices, uv, faces).max() < 1e-12


def test_area_distortion_of_two_triangles():
    # unit square split in two; uv moves vertex 2 so the two areas become 1/2·(1+t) and 1/2
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    t = 0.6
    uv = vertices[:, :2].copy()
    uv[1] = [1 + t, 0]  # only triangle 0 changes: area (1+t)/2
    area_uv = np.array([(1 + t) / 2, 0.5])
    log_ratio = np.log(area_uv / area_uv.sum()) - np.log([0.5, 0.5])
    expected = np.std(log_ratio)  # equal weights
    assert area_distortion_std(vertices, uv, faces) == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(0.5 * np.log(1 + t))


def test_reflection_is_not_a_flip_and_a_folded_vertex_is():
    vertices, faces = grid_triangles(4, 4)
    uv = vertices.copy()
    assert flipped_triangles(uv, faces) == 0
    reflected = uv * [-1.0, 1.0]
    assert flipped_triangles(reflected, faces) == 0
    # push interior vertex (1, 1)·h across its neighbours: its triangles flip
    h = 0.25
    index = int(np.flatnonzero(np.all(np.isclose(vertices, [h, h]), axis=1))[0])
    folded = uv.copy()
    folded[index] = [3 * h, 3 * h]
    incident = np.any(faces == index, axis=1)
    e1, e2 = folded[faces[:, 1]] - folded[faces[:, 0]], folded[faces[:, 2]] - folded[faces[:, 0]]
    signed = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    assert flipped_triangles(folded, faces) == int(np.sum(signed[incident] < 0)) > 0
    assert not is_embedding(folded, faces, _square_loops(vertices, faces))


def _square_loops(vertices, faces):
    from decrun.core.complex import SimplicialComplex

    return SimplicialComplex(vertices, faces).border_loops()


def test_border_self_intersections_and_turning_numbers():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    loop = np.arange(4)
    assert border_self_intersections(square, [loop]) == 0
    np.testing.assert_allclose(border_turning_numbers(square, [loop, loop[::-1]]), [1.0, -1.0])
    bowtie = np.array([[0, 0], [1, 1], [1, 0], [0, 1]], dtype=float)
    assert border_self_intersections(bowtie, [loop]) == 1  # segments 0-1 and 2-3 cross
    assert border_turning_numbers(bowtie, [loop])[0] == pytest.approx(0.0, abs=1e-12)
    # a hole that pokes out of the exterior square: two crossings
    hole = np.array([[0.5, 0.5], [0.5, 1.5], [0.6, 1.5], [0.6, 0.5]])
    points = np.concatenate([square, hole])
    assert border_self_intersections(points, [loop, 4 + np.arange(4)]) == 2
    # a vertex lying exactly on a non-adjacent segment counts (touching)
    touching = np.array([[0, 0], [2, 0], [1, 0], [1, 1]], dtype=float)
    assert border_self_intersections(touching, [np.arange(4)]) >= 1


def test_uv_vertex_angles_and_winding_of_a_flat_map():
    vertices, faces = grid_triangles(3, 3)
    loops = _square_loops(vertices, faces)
    angles = border_vertex_uv_angles(vertices, faces, len(vertices))
    corners = [0, 3, 12, 15]
    np.testing.assert_allclose(angles[corners], np.pi / 2)
    interior = [5, 6, 9, 10]
    np.testing.assert_allclose(angles[interior], 2 * np.pi)
    metrics = parametrization_metrics(np.column_stack([vertices, np.zeros(16)]), vertices, faces, loops)
    assert metrics["is_embedding"] and metrics["border_winding_ok"]
    assert metrics["border_winding_exterior_turns"] == pytest.approx(1.0)
    assert metrics["reflex_border_vertices_uv"] == 0
    assert metrics["qc_distortion_max"] == pytest.approx(1.0)


def test_overlapping_map_without_flips_is_not_an_embedding():
    """A 1.5-turn strip laid flat: every triangle counter-clockwise (0 flips, none degenerate),
    the border turns exactly once — only the border crossing itself shows that the map is
    not injective (Gortler's condition: disjoint simple border curves)."""
    vertices, faces = spiral_strip(turns=1.5)
    uv = vertices[:, :2]
    loops = _square_loops(uv, faces)
    assert len(loops) == 1
    assert flipped_triangles(uv, faces) == 0 and degenerate_triangles(uv, faces) == 0
    assert border_turning_numbers(uv, loops)[0] == pytest.approx(1.0, abs=1e-12)
    assert border_self_intersections(uv, loops) > 0
    assert not is_embedding(uv, faces, loops)
    metrics = parametrization_metrics(vertices, uv, faces, loops)
    assert metrics["border_winding_ok"] and metrics["flipped_triangles"] == 0
    assert metrics["is_embedding"] is False
    # one turn less and the same strip is an embedding: the test above is not vacuous
    vertices, faces = spiral_strip(turns=0.75)
    loops = _square_loops(vertices[:, :2], faces)
    assert is_embedding(vertices[:, :2], faces, loops)
    assert parametrization_metrics(vertices, vertices[:, :2], faces, loops)["is_embedding"] is True


def test_degenerate_uv_triangles_are_counted_and_are_no_embedding():
    """Move interior vertex (h, h) of a grid onto its neighbour (2h, h): the two triangles of
    the collapsed edge have zero area — counted as degenerate (not as flips), no embedding."""
    vertices, faces = grid_triangles(4, 4)
    h = 0.25
    index = int(np.flatnonzero(np.all(np.isclose(vertices, [h, h]), axis=1))[0])
    neighbour = int(np.flatnonzero(np.all(np.isclose(vertices, [2 * h, h]), axis=1))[0])
    uv = vertices.copy()
    uv[index] = vertices[neighbour]
    on_edge = np.sum(np.isin(faces, [index, neighbour]), axis=1) == 2
    assert on_edge.sum() == 2
    assert degenerate_triangles(uv, faces) == 2 and degenerate_triangles(vertices, faces) == 0
    loops = _square_loops(vertices, faces)
    assert not is_embedding(uv, faces, loops)
    metrics = parametrization_metrics(np.column_stack([vertices, np.zeros(len(vertices))]), uv, faces, loops)
    assert metrics["degenerate_triangles"] == 2 and metrics["is_embedding"] is False


def test_a_map_onto_a_line_is_all_degenerate_and_no_flip():
    """Every triangle of a map onto a line has zero area: all counted degenerate, none
    flipped (no orientation), infinite quasi-conformal distortion, no embedding — even
    though the border of the image does not cross itself transversally."""
    vertices, faces = grid_triangles(3, 3)
    uv = np.column_stack([vertices[:, 0] + 0.5 * vertices[:, 1], np.zeros(len(vertices))])
    metrics = parametrization_metrics(np.column_stack([vertices, np.zeros(len(vertices))]), uv, faces,
                                      _square_loops(vertices, faces))
    assert metrics["degenerate_triangles"] == len(faces) and metrics["flipped_triangles"] == 0
    assert metrics["qc_distortion_max"] == np.inf
    assert metrics["is_embedding"] is False
