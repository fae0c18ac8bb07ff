"""decrun.runner.mesh.repair: every pymeshlab sample becomes a valid complex; exact repair counts."""

from __future__ import annotations

import numpy as np
import pymeshlab
import pytest

from decrun.complex import SimplicialComplex
from decrun.errors import NonOrientableError
from decrun.runner.mesh.repair import ROTATION_TO_Z_UP, UP_AXIS, repair_mesh, up_axis_to_z
from decrun.runner.mesh.sources.files import SAMPLE_MESHES as SAMPLES  # noqa: E402
from decrun.runner.mesh.sources.files import sample_mesh_dir  # noqa: E402

SAMPLE_DIR = sample_mesh_dir()


def load(name: str):
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(SAMPLE_DIR / SAMPLES[name]))
    mesh = ms.current_mesh()
    return mesh.vertex_matrix(), mesh.face_matrix().astype(np.int64)


def signed_volume(vertices, faces) -> float:
    """Σ det(p0, p1, p2)/6: the enclosed volume, negative when the faces point inwards."""
    p0, p1, p2 = (vertices[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", p0, np.cross(p1, p2)).sum() / 6)


@pytest.mark.parametrize("name", sorted(SAMPLES))
def test_every_sample_builds_a_consistently_oriented_complex(name):
    vertices, faces = load(name)
    v, f, report = repair_mesh(vertices, faces)
    # orient="check": the repaired faces are coherently oriented already
    K = SimplicialComplex(v, f, orient="check")
    assert report["manifold"] and report["orientable"]
    assert (report["vertices_out"], report["faces_out"]) == (K.num_simplices(0), K.num_simplices(2))
    # the vertex count is balanced by the reported changes (nothing dropped silently)
    assert report["vertices_out"] == (report["vertices_in"] - report["duplicate_vertices_merged"]
                                      - report["unreferenced_vertices_removed"]
                                      + report["non_manifold_vertices_split"])
    assert report["faces_out"] == (report["faces_in"] - report["duplicate_faces_removed"]
                                   - report["zero_area_faces_removed"] - report["degenerate_faces_removed"]
                                   - report["non_manifold_edge_faces_removed"])
    # every output vertex is an input position (repair moves nothing)
    index = {tuple(p) for p in np.asarray(vertices).tolist()}
    assert all(tuple(p) in index for p in v.tolist())


def test_known_unreferenced_and_bowtie_samples_are_counted():
    """The defects the raw files are known to have (counted independently with numpy)."""
    for name in ("airplane", "bone", "face"):
        vertices, faces = load(name)
        unused = len(vertices) - len(np.unique(faces))
        _, _, report = repair_mesh(vertices, faces)
        assert report["unreferenced_vertices_removed"] == unused > 0
    _, _, report = repair_mesh(*load("face"))
    assert report["non_manifold_vertices_split"] == 6  # pymeshlab's topological measure of the raw scan


def test_hand_made_mesh_counts_duplicate_face_unreferenced_vertex_and_bowtie():
    # two triangles touching only at vertex 0 (a bowtie), the first one repeated, vertex 5 unused
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [5, 5, 5.0]])
    faces = np.array([[0, 1, 2], [0, 3, 4], [2, 0, 1]])
    v, f, report = repair_mesh(vertices, faces)
    assert report["duplicate_faces_removed"] == 1
    assert report["unreferenced_vertices_removed"] == 1
    assert report["non_manifold_vertices_split"] == 1
    assert report["duplicate_vertices_merged"] == report["zero_area_faces_removed"] == 0
    assert report["non_manifold_edge_faces_removed"] == report["faces_reoriented"] == 0
    assert (report["vertices_out"], report["faces_out"]) == (6, 2)
    # the two copies of the bowtie vertex sit at the origin, one in each triangle
    at_origin = np.flatnonzero(np.all(v == 0, axis=1))
    assert len(at_origin) == 2
    assert sorted(int(np.isin(face, at_origin).sum()) for face in f) == [1, 1]
    assert not np.intersect1d(f[0], f[1]).size  # the triangles no longer share a vertex
    K = SimplicialComplex(v, f)
    assert K.num_simplices(0) == 6 and len(K.border_loops()) == 2


def test_non_manifold_edge_zero_area_face_and_flip_are_counted():
    # three triangles on edge (0, 1): one must go
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1.0]])
    v, f, report = repair_mesh(vertices, np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))
    assert report["non_manifold_edge_faces_removed"] == 1 and report["unreferenced_vertices_removed"] == 1
    SimplicialComplex(v, f, orient="check")
    # a collinear triangle hanging off vertex 1: removed with its two private vertices
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0.0]])
    v, f, report = repair_mesh(vertices, np.array([[0, 1, 2], [1, 3, 4]]))
    assert report["zero_area_faces_removed"] == 1 and report["unreferenced_vertices_removed"] == 2
    assert f.shape == (1, 3)
    # a square whose second triangle is flipped: exactly one face is re-oriented
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    v, f, report = repair_mesh(vertices, np.array([[0, 1, 2], [0, 3, 2]]))
    assert report["faces_reoriented"] == 1
    SimplicialComplex(v, f, orient="check")


def test_near_zero_area_face_is_removed_by_the_complex_criterion():
    # a sliver of relative area 1e-14 (not exactly zero) would fail SimplicialComplex
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 1e-14, 0], [3, 0, 0.0]])
    faces = np.array([[0, 1, 2], [1, 3, 4]])
    v, f, report = repair_mesh(vertices, faces)
    assert report["degenerate_faces_removed"] == 1 and report["zero_area_faces_removed"] == 0
    SimplicialComplex(v, f)


def test_moebius_strip_is_reported_non_orientable():
    n = 12
    u = 2 * np.pi * np.arange(n) / n
    rows = []
    for s in (-0.3, 0.3):
        rows.append(np.column_stack([(1 + s * np.cos(u / 2)) * np.cos(u), (1 + s * np.cos(u / 2)) * np.sin(u),
                                     s * np.sin(u / 2)]))
    vertices = np.concatenate(rows)  # bottom row 0..n-1, top row n..2n-1
    i = np.arange(n - 1)
    quads = np.column_stack([i, i + 1, n + i + 1, n + i])
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]],
                            [[n - 1, n, 0], [n - 1, 0, 2 * n - 1]]])  # the half twist: b_n = t_0
    v, f, report = repair_mesh(vertices, faces)
    assert report["orientable"] is False
    with pytest.raises(NonOrientableError):
        SimplicialComplex(v, f, orient="fix")


@pytest.mark.parametrize("up", sorted(ROTATION_TO_Z_UP))
def test_up_axis_rotation_is_proper_and_sends_up_to_z(up):
    R = ROTATION_TO_Z_UP[up]
    assert np.allclose(R @ R.T, np.eye(3), atol=0) and np.linalg.det(R) == pytest.approx(1.0, abs=1e-15)
    axis = np.zeros(3)
    axis["xyz".index(up[-1])] = -1.0 if up.startswith("-") else 1.0
    assert np.array_equal(up_axis_to_z(axis[None, :], up)[0], [0.0, 0.0, 1.0])


def test_up_axis_rotation_keeps_lengths_and_orientation_of_a_closed_mesh():
    v, f, _ = repair_mesh(*load("cow"))
    assert UP_AXIS["cow"] == "y"
    rotated = up_axis_to_z(v, "y")
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    length = lambda p: np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1)  # noqa: E731
    np.testing.assert_allclose(length(rotated), length(v), rtol=1e-13)
    # a reflection would flip the sign of the enclosed volume; a proper rotation keeps it
    assert signed_volume(rotated, f) == pytest.approx(signed_volume(v, f), rel=1e-12)
    assert signed_volume(v, f) != 0
    # the up axis y becomes z: the vertical extent after the turn is the old y extent
    np.testing.assert_allclose(np.ptp(rotated[:, 2]), np.ptp(v[:, 1]), rtol=1e-15)
    with pytest.raises(ValueError):
        up_axis_to_z(v, "up")
