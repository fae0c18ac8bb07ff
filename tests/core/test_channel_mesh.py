"""Channel meshes for the vorticity fluid: no obtuse triangles, graded, correct borders."""

from __future__ import annotations

import numpy as np
import pytest

from decrun.complex import SimplicialComplex
from decrun.core.channel_mesh import channel_mesh
from decrun.core.geometry import obtuse_triangle_count as obtuse_count


def edge_lengths_near(mesh, center, inner, outer):
    v, f = mesh.vertices, mesh.faces
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    mid = 0.5 * (v[e[:, 0]] + v[e[:, 1]])
    r = np.linalg.norm(mid - center, axis=1)
    length = np.linalg.norm(v[e[:, 1]] - v[e[:, 0]], axis=1)
    return length[(r > inner) & (r < outer)].mean()


def test_default_channel_has_no_obtuse_triangle_and_a_graded_valid_mesh():
    mesh = channel_mesh(target_faces=1400)
    assert abs(mesh.faces.shape[0] / 1400 - 1) < 0.05
    assert mesh.obtuse == 0 == obtuse_count(mesh.vertices, mesh.faces)
    assert mesh.max_angle_deg <= 90.0 + 1e-9
    K = SimplicialComplex(mesh.vertices, mesh.faces)  # valid, consistently oriented manifold
    assert K.betti_numbers() == [1, 1, 0]  # a disk with one hole
    p = mesh.vertices[mesh.faces]
    a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    signed = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    assert np.all(signed > 0)  # counter-clockwise
    # border loops: the rectangle and the circle of radius 0.1 round (0.5, 0.5)
    outer, hole = mesh.loops
    assert mesh.loop_labels == ["outer", "obstacle 0"]
    x, y = mesh.vertices[outer].T
    on_rectangle = np.isclose(x, 0) | np.isclose(x, 2) | np.isclose(y, 0) | np.isclose(y, 1)
    assert on_rectangle.all()
    np.testing.assert_allclose(np.linalg.norm(mesh.vertices[hole] - [0.5, 0.5], axis=1), 0.1, rtol=1e-12)
    assert set(np.flatnonzero(K.border_vertices())) == set(outer) | set(hole)
    loops = K.border_loops()
    assert {frozenset(loop.tolist()) for loop in loops} == {frozenset(outer.tolist()), frozenset(hole.tolist())}
    # graded: edges at the obstacle are markedly shorter than far away
    near = edge_lengths_near(mesh, np.array([0.5, 0.5]), 0.1, 0.13)
    far = edge_lengths_near(mesh, np.array([0.5, 0.5]), 1.2, 5.0)
    assert far > 2.0 * near


def test_several_obstacles_circle_and_polygon():
    square = np.array([[1.3, 0.3], [1.5, 0.3], [1.5, 0.5], [1.3, 0.5]])
    mesh = channel_mesh(target_faces=1500, obstacles=[("circle", (0.5, 0.6), 0.1), square])
    K = SimplicialComplex(mesh.vertices, mesh.faces)
    assert K.betti_numbers() == [1, 2, 0]
    assert mesh.loop_labels == ["outer", "obstacle 0", "obstacle 1"]
    assert len(mesh.obstacle_loops) == 2
    on_square = mesh.vertices[mesh.obstacle_loops[1]]
    assert {tuple(p) for p in square} <= {tuple(p) for p in on_square.round(12)}
    x, y = on_square.T
    side = (np.isclose(x, 1.3) | np.isclose(x, 1.5)) & (y > 0.3 - 1e-12) & (y < 0.5 + 1e-12)
    side |= (np.isclose(y, 0.3) | np.isclose(y, 0.5)) & (x > 1.3 - 1e-12) & (x < 1.5 + 1e-12)
    assert side.all()
    # the square's corners (270° on the fluid side) force a few obtuse triangles at most
    assert mesh.obtuse <= 0.01 * mesh.faces.shape[0]


@pytest.mark.slow
@pytest.mark.parametrize("target", [2800, 5300, 12000])
def test_finer_channels_have_no_obtuse_triangles(target):
    mesh = channel_mesh(target_faces=target)
    assert abs(mesh.faces.shape[0] / target - 1) < 0.05
    assert mesh.obtuse == 0
