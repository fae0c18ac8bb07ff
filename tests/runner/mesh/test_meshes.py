"""Mesh sources and post-processing steps (decrun.runner.mesh)."""

from __future__ import annotations

import numpy as np
import pytest

from decrun.core.complex import SimplicialComplex
from decrun.core.geometry import mean_edge_length, vertex_normals
from decrun.errors import ConfigError, MeshError
from decrun.runner.mesh import mesh_hash
from decrun.runner.mesh.sources.files import SAMPLE_MESHES, sample_mesh_dir

from meshes_for_tests import mesh


@pytest.mark.parametrize("subdiv", [0, 1, 2, 3])
def test_icosphere_counts_topology_and_radius(subdiv):
    m = mesh(source="icosphere", subdiv=subdiv, radius=2.0)
    assert len(m.vertices) == 10 * 4**subdiv + 2 and len(m.faces) == 20 * 4**subdiv
    np.testing.assert_allclose(np.linalg.norm(m.vertices, axis=1), 2.0, rtol=1e-6)
    K = SimplicialComplex(m.vertices, m.faces)
    assert K.euler_characteristic == 2 and K.betti_numbers() == [1, 0, 1]


@pytest.mark.parametrize(
    "kw, betti",
    [
        (dict(source="torus"), [1, 2, 1]),
        (dict(source="sphere_cap"), [1, 0, 0]),
        (dict(source="annulus", refine="midpoint"), [1, 1, 0]),
        (dict(source="grid", nx=5, ny=4), [1, 0, 0]),
        (dict(source="cube", refine="loop", refine_iterations=1), [1, 0, 1]),
        (dict(source="planar", holes=[[[0.3, 0.3], [0.6, 0.3], [0.6, 0.6], [0.3, 0.6]]]), [1, 1, 0]),
    ],
)
def test_sources_have_the_expected_topology(kw, betti):
    m = mesh(**kw)
    assert SimplicialComplex(m.vertices, m.faces).betti_numbers() == betti


def test_torus_and_grid_geometry():
    t = mesh(source="torus", major_radius=1.0, minor_radius=0.25, major_segments=24, minor_segments=12)
    assert len(t.vertices) == 24 * 12
    ring = np.hypot(t.vertices[:, 0], t.vertices[:, 1])
    np.testing.assert_allclose(np.hypot(ring - 1.0, t.vertices[:, 2]), 0.25, rtol=1e-5)
    g = mesh(source="grid", nx=5, ny=4, width=2.0, height=3.0)
    assert len(g.vertices) == 20 and len(g.faces) == 2 * 4 * 3
    np.testing.assert_allclose(np.ptp(g.vertices, axis=0), [2.0, 3.0, 0.0], atol=1e-6)


@pytest.mark.parametrize("nx, ny, width, height", [(5, 4, 2.0, 3.0), (31, 51, 60000.0, 100000.0), (16, 26, 60000.0, 100000.0)])
def test_the_grid_is_centred_on_the_origin_with_pymeshlabs_triangulation(nx, ny, width, height):
    """The grid is a lattice of spacing width/(nx−1) × height/(ny−1) whose bounding box is centred
    on the origin (with odd nx, ny a vertex is the origin: the Halfar benchmark's dome centre).
    pymeshlab's create_grid(center=True), whose triangulation and vertex order it keeps, is off
    centre by (−width/(2nx), height/(2ny))."""
    import pymeshlab

    g = mesh(source="grid", nx=nx, ny=ny, width=width, height=height)
    V = g.vertices
    np.testing.assert_array_equal(V.min(axis=0) + V.max(axis=0), 0.0)
    xs, ys = np.unique(V[:, 0]), np.unique(V[:, 1])
    np.testing.assert_allclose(xs, np.linspace(-width / 2, width / 2, nx), rtol=0, atol=1e-12 * width)
    np.testing.assert_allclose(ys, np.linspace(-height / 2, height / 2, ny), rtol=0, atol=1e-12 * height)
    if nx % 2 and ny % 2:
        assert np.any(np.all(V == 0.0, axis=1))
    ms = pymeshlab.MeshSet()
    ms.create_grid(numvertx=nx, numverty=ny, absscalex=width, absscaley=height, center=True)
    theirs = ms.current_mesh()
    np.testing.assert_array_equal(g.faces, theirs.face_matrix())
    offset = theirs.vertex_matrix() - V
    np.testing.assert_allclose(offset, np.broadcast_to([-width / (2 * nx), height / (2 * ny), 0.0], V.shape),
                               rtol=0, atol=1e-6 * max(width, height))


def test_planar_domain_area_quality_and_holes():
    hole = [[0.3, 0.3], [0.6, 0.3], [0.6, 0.6], [0.3, 0.6]]
    m = mesh(source="planar", holes=[hole], min_angle_deg=28.0, max_area=0.004)
    assert m.vertices.shape[1] == 2
    p = m.vertices[m.faces]
    a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    area = 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    assert np.all(area > 0)  # counter-clockwise
    assert area.sum() == pytest.approx(1.0 - 0.09, rel=1e-12)  # the polygon is meshed exactly
    assert area.max() <= 0.004 * (1 + 1e-9)
    angles = []
    for i in range(3):
        u, v = p[:, (i + 1) % 3] - p[:, i], p[:, (i + 2) % 3] - p[:, i]
        angles.append(np.degrees(np.arccos(np.sum(u * v, 1) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1))))
    assert np.min(angles) >= 28.0 - 1e-6
    centroids = p.mean(axis=1)
    assert not np.any(np.all((centroids > 0.3) & (centroids < 0.6), axis=1))  # nothing inside the hole


def test_noise_is_seeded_normal_and_relative_to_the_edge_length():
    clean = mesh(source="icosphere", subdiv=3)
    a = mesh(source="icosphere", subdiv=3, noise=0.2, seed=7)
    b = mesh(source="icosphere", subdiv=3, noise=0.2, seed=7)
    c = mesh(source="icosphere", subdiv=3, noise=0.2, seed=8)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    assert not np.allclose(a.vertices, c.vertices)
    np.testing.assert_array_equal(a.meta["clean_vertices"], clean.vertices)
    displacement = a.vertices - clean.vertices
    normals = vertex_normals(clean.vertices, clean.faces)
    # along the normals: no tangential part
    tangential = displacement - np.sum(displacement * normals, axis=1, keepdims=True) * normals
    assert np.abs(tangential).max() < 1e-12
    h = mean_edge_length(clean.vertices, clean.faces)
    assert a.meta["noise_amplitude"] == pytest.approx(0.2 * h)
    rms = np.sqrt(np.mean(np.sum(displacement**2, axis=1)))
    assert rms == pytest.approx(0.2 * h, rel=0.1)  # 642 samples of N(0, 1)
    assert a.meta["hash"] != clean.meta["hash"] == mesh_hash(clean.vertices, clean.faces)


def test_vertex_normals_of_a_sphere_point_outwards():
    m = mesh(source="icosphere", subdiv=2)
    n = vertex_normals(m.vertices, m.faces)
    np.testing.assert_allclose(np.sum(n * m.vertices, axis=1), 1.0, atol=2e-2)  # outwards: no abs()
    flipped = vertex_normals(m.vertices, m.faces[:, ::-1])
    np.testing.assert_allclose(np.sum(flipped * m.vertices, axis=1), -1.0, atol=2e-2)


def test_normalize_and_noise_keep_the_clean_copy_consistent():
    m = mesh(source="torus", normalize=True, noise=0.1, post=["normalize", "noise"])
    lo, hi = m.meta["clean_vertices"].min(0), m.meta["clean_vertices"].max(0)
    assert np.linalg.norm(hi - lo) == pytest.approx(1.0)
    np.testing.assert_allclose((hi + lo) / 2, 0.0, atol=1e-12)
    m2 = mesh(source="torus", normalize=True, noise=0.1, post=["noise", "normalize"])
    lo, hi = m2.vertices.min(0), m2.vertices.max(0)
    assert np.linalg.norm(hi - lo) == pytest.approx(1.0)
    assert m2.meta["steps"] == ["noise", "normalize"]


def test_refine_loop_quadruples_faces():
    m = mesh(source="icosphere", subdiv=1, refine="loop", refine_iterations=2)
    assert len(m.faces) == 80 * 16 and len(m.vertices) == 642
    assert "refine" in m.meta["steps"]


def test_clean_keeps_the_largest_component(tmp_path):
    # a cube (12 triangles) plus a separate triangle and an unreferenced vertex
    cube = mesh(source="cube")
    V = np.vstack([cube.vertices, [[5, 5, 5], [6, 5, 5], [5, 6, 5], [9, 9, 9]]])
    F = np.vstack([cube.faces, [[8, 9, 10]]])
    path = tmp_path / "two.obj"
    path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in V) + "".join(f"f {a+1} {b+1} {c+1}\n" for a, b, c in F))
    raw = mesh(source="file", path=str(path))
    assert len(raw.faces) == 13
    cleaned = mesh(source="file", path=str(path), clean=True)
    assert len(cleaned.faces) == 12 and len(cleaned.vertices) == 8
    assert cleaned.meta["dropped_faces"] == 1 and cleaned.meta["dropped_vertices"] == len(raw.vertices) - 8
    assert SimplicialComplex(cleaned.vertices, cleaned.faces).betti_numbers() == [1, 0, 1]


def test_file_round_trip(tmp_path):
    src = mesh(source="icosphere", subdiv=1)
    path = tmp_path / "ico.obj"
    path.write_text("".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in src.vertices)
                    + "".join(f"f {a+1} {b+1} {c+1}\n" for a, b, c in src.faces))
    m = mesh(source="file", path=str(path))
    np.testing.assert_allclose(m.vertices, src.vertices, rtol=1e-6)
    np.testing.assert_array_equal(m.faces, src.faces)
    assert m.meta["path"] == str(path)


@pytest.mark.parametrize("name", ["bone", "cow", "bunny10k_textured"])
def test_sample_meshes_shipped_with_pymeshlab(name):
    assert (sample_mesh_dir() / SAMPLE_MESHES[name]).is_file()
    m = mesh(source="sample", sample=name)
    assert len(m.faces) > 1000 and m.meta["label"] == name


def test_every_sample_name_points_to_a_file():
    for name, rel in SAMPLE_MESHES.items():
        assert (sample_mesh_dir() / rel).is_file(), name


@pytest.mark.parametrize(
    "kw, error, words",
    [
        (dict(source="file", path="/nonexistent/mesh.obj"), MeshError, ["mesh.path", "not found"]),
        (dict(source="file", path=""), ConfigError, ["mesh.path"]),
        (dict(source="sample", sample="dragon"), ConfigError, ["mesh.sample", "dragon"]),
        (dict(source="icosphere", subdiv=-1), ConfigError, ["mesh.subdiv"]),
        (dict(source="icosphere", noise=-0.1), ConfigError, ["mesh.noise"]),
        (dict(source="torus", major_radius=0.1, minor_radius=0.4), ConfigError, ["mesh.minor_radius"]),
        (dict(source="planar", min_angle_deg=40), ConfigError, ["mesh.min_angle_deg"]),
        (dict(source="planar", outer=[[0, 0], [1, 1]]), ConfigError, ["mesh.outer"]),
        (dict(source="icosphere", post=["noise", "smooth"]), ConfigError, ["mesh.post", "smooth"]),
        (dict(source="icosphere", refine="magic"), ConfigError, ["mesh.refine", "magic"]),
    ],
)
def test_bad_options_name_the_key(kw, error, words):
    with pytest.raises(error) as info:
        mesh(**kw)
    for word in words:
        assert word in str(info.value)


def test_empty_unreadable_and_faceless_files(tmp_path):
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    with pytest.raises(MeshError, match="empty"):
        mesh(source="file", path=str(empty))
    garbage = tmp_path / "garbage.ply"
    garbage.write_bytes(b"ply\nthis is not a ply file\x00\x01")
    with pytest.raises(MeshError, match="garbage.ply"):
        mesh(source="file", path=str(garbage))
    points = tmp_path / "points.obj"
    points.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(MeshError, match="no faces"):
        mesh(source="file", path=str(points))
    with pytest.raises(MeshError, match="not a file"):
        mesh(source="file", path=str(tmp_path))


def test_each_source_has_only_its_own_options():
    """Per-source schemas: a torus key on an icosphere is an error naming the key and the
    options the source has; an unknown source option is not silently ignored."""
    with pytest.raises(ConfigError, match=r"mesh.major_radius: unknown option of mesh=icosphere; it has \[.*'subdiv'"):
        mesh(source="icosphere", major_radius=2.0)


def test_int_lists_are_accepted_where_floats_are_expected():
    """`'mesh.hole_balls=[[1,0,0,0.5]]'` (ints) is used as given, widened to floats — through
    the plugin builder and through the full CLI composition (experiment keys, app lists)."""
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    ints = mesh(source="icosphere", subdiv=2, hole_balls=[[1, 0, 0, 1]])
    floats = mesh(source="icosphere", subdiv=2, hole_balls=[[1.0, 0.0, 0.0, 1.0]])
    np.testing.assert_array_equal(ints.vertices, floats.vertices)
    result = run_experiment(compose_config([
        "app=vector_field", "mesh.subdiv=2", "mesh.hole_balls=[[1,0,0,1]]", "mesh.hole_boxes=[[-2,-2,-2,0,0,0]]",
        "app.sources=[{point: [0, 0, 1], divergence: 1}]", "app.region_normal=[0,0,1]",
        "app.strokes=[{points: [[0,1,0],[0,0,1]]}]"])).result
    assert result.metrics["status"] == "ok" and result.metrics["sources"] == 1


def test_holes_are_split_along_the_ball_by_default_and_whole_triangles_on_request():
    ball = [0.0, 0.0, 1.0, 0.6]
    split = mesh(source="icosphere", subdiv=3, hole_balls=[ball], noise=0.1)
    whole = mesh(source="icosphere", subdiv=3, hole_balls=[ball], noise=0.1, hole_cut="whole_triangles")
    K = SimplicialComplex(split.vertices, split.faces)
    border = np.unique(np.concatenate(K.border_loops()))
    # the smooth border lies on the ball's sphere (before noise, which moves the vertices after)
    clean = split.meta["clean_vertices"]
    np.testing.assert_allclose(np.linalg.norm(clean[border] - ball[:3], axis=1), ball[3], rtol=1e-9)
    assert clean.shape == split.vertices.shape  # carried through the cut
    Kw = SimplicialComplex(whole.vertices, whole.faces)
    border_w = np.unique(np.concatenate(Kw.border_loops()))
    off = np.abs(np.linalg.norm(whole.meta["clean_vertices"][border_w] - ball[:3], axis=1) - ball[3])
    assert off.max() > 0.05  # the sawtooth border of whole triangles is off the sphere
    assert split.meta["holes"]["split_faces"] > 0 and "removed_faces" in whole.meta["holes"]


def test_post_processing_yaml_equals_the_mesh_source_defaults():
    """conf/mesh/_post_processing.yaml declares exactly MeshSource's post-processing fields with
    the same defaults (the dataclass is the schema, the YAML what --help shows)."""
    import dataclasses

    from omegaconf import OmegaConf

    from decrun.runner.job.config import config_dir
    from decrun.runner.mesh import MeshSource

    yaml_values = OmegaConf.to_container(OmegaConf.load(config_dir() / "mesh" / "_post_processing.yaml"))
    fields = {f.name: (f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default)
              for f in dataclasses.fields(MeshSource)}
    assert yaml_values == fields


def test_samples_are_repaired_cleaned_and_turned_z_up_by_default_files_are_not(tmp_path):
    from decrun.runner.mesh.repair import UP_AXIS

    face = mesh(source="sample", sample="face")
    assert face.meta["repair"]["non_manifold_vertices_split"] == 6 and "repair" in face.meta["steps"]
    SimplicialComplex(face.vertices, face.faces)  # valid as loaded
    cow = mesh(source="sample", sample="cow")
    raw = mesh(source="sample", sample="cow", up_axis="z", repair=False, clean=False)
    assert UP_AXIS["cow"] == "y" and cow.meta["up_axis"] == "y"
    np.testing.assert_allclose(np.ptp(cow.vertices, axis=0), np.ptp(raw.vertices, axis=0)[[0, 2, 1]], rtol=1e-12)
    as_file = mesh(source="file", path=str(sample_mesh_dir() / SAMPLE_MESHES["face"]))
    assert "repair" not in as_file.meta and as_file.meta["steps"] == []


def test_up_axis_on_a_planar_mesh_is_an_error_naming_the_fix():
    with pytest.raises(ConfigError, match="`mesh.up_axis=z`"):
        mesh(source="planar", up_axis="y")


def test_up_axis_is_one_of_its_choices_checked_when_the_source_is_made_and_negative_axes_rotate():
    """mesh.up_axis is a closed choice (UpAxis): an unknown axis is refused before any mesh is
    built, naming every choice and the override; ``-y`` (no Python name) is the rotation of
    up_axis_to_z, and ``auto`` on a source that is not a sample is ``z`` (nothing turned)."""
    from decrun.runner.mesh.repair import up_axis_to_z

    with pytest.raises(ConfigError, match=r"^mesh.up_axis: must be one of auto \| x \| y \| z \| -x \| -y \| -z, "
                                          r"got 'w' \(e.g. mesh.up_axis=auto\)$"):
        mesh(source="icosphere", subdiv=1, up_axis="w")
    raw = mesh(source="icosphere", subdiv=1, up_axis="auto", noise=0.0)
    assert "up_axis" not in raw.meta
    turned = mesh(source="icosphere", subdiv=1, up_axis="-y", noise=0.0)
    assert turned.meta["up_axis"] == "-y" and type(turned.meta["up_axis"]) is str
    np.testing.assert_array_equal(turned.vertices, up_axis_to_z(raw.vertices, "-y"))
    assert np.allclose(up_axis_to_z(np.array([[0.0, -1.0, 0.0]]), "-y"), [[0.0, 0.0, 1.0]])


@pytest.mark.parametrize("name, sample", [("bunny", "bunny10k_textured"), ("cow", "cow")])
def test_mesh_bunny_and_cow_are_upright_like_mesh_sample(name, sample, decrun_cli, tmp_path):
    """``mesh=bunny`` / ``mesh=cow`` turn the Y-up samples Z-up (up_axis: auto) as
    ``mesh=sample`` does: the stored mesh's z extent is the raw model's y extent."""
    from decrun.runner.results.reading import read_mesh

    proc = decrun_cli(f"mesh={name}", "app.steps=0", "figures=false", f"hydra.run.dir={tmp_path / 'run'}")
    assert proc.returncode == 0, proc.stderr
    vertices, _ = read_mesh(tmp_path / "run" / "result.h5")
    raw = mesh(source="sample", sample=sample, up_axis="z", repair=False, clean=False)
    np.testing.assert_allclose(np.ptp(vertices, axis=0), np.ptp(raw.vertices, axis=0)[[0, 2, 1]], rtol=1e-9)
