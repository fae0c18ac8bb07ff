"""decrun.runner.mesh.cut: holes cut along the level set — exact borders, analytic areas/lengths."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pymeshlab
import pytest
import yaml

from decrun.complex import SimplicialComplex
from decrun.errors import ConfigError, MeshError

try:  # the old cut (whole triangles), for comparison; it moves to decrun.runner with the restructuring
    from decrun.runner.mesh.holes import cut_holes as cut_whole_triangles
except ImportError:
    from decrun.mesh_holes import cut_holes as cut_whole_triangles
from decrun.runner.mesh.cut import cut_holes, parse_regions, signed_distance

FIG5_7 = Path(__file__).resolve().parents[3] / "conf" / "experiment" / "fig5_7_half_sphere_holes.yaml"
BALL = np.array([0.3, 0.5, 0.8, 0.5])  # centre at distance 0.99 from the origin, radius 0.5


def icosphere(subdiv: int):
    ms = pymeshlab.MeshSet()
    ms.create_sphere(radius=1.0, subdiv=subdiv)
    mesh = ms.current_mesh()
    return mesh.vertex_matrix(), mesh.face_matrix().astype(np.int64)


def square_grid(nx: int):
    """[-1, 1]² with nx × nx vertices, every square split along its diagonal (2-D vertices)."""
    x = np.linspace(-1, 1, nx)
    X, Y = np.meshgrid(x, x)
    idx = np.arange(nx * nx).reshape(nx, nx)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return np.column_stack([X.ravel(), Y.ravel()]), faces


def area(vertices, faces) -> float:
    p = np.column_stack([vertices, np.zeros(len(vertices))]) if vertices.shape[1] == 2 else vertices
    p0, p1, p2 = (p[faces[:, i]] for i in range(3))
    return float(0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1).sum())


def loop_length(vertices, loop) -> float:
    q = vertices[loop]
    return float(np.linalg.norm(np.roll(q, -1, axis=0) - q, axis=1).sum())


def spherical_cap_area(ball) -> float:
    """Area of the unit sphere inside the ball: the cap x·ĉ ≥ z0, z0 = (1 + |c|² − r²)/(2|c|)."""
    d = np.linalg.norm(ball[:3])
    z0 = (1 + d * d - ball[3] ** 2) / (2 * d)
    return 2 * np.pi * (1 - z0)


# ------------------------------------------------------------------ a ball cut out of a sphere
def test_ball_cut_border_lies_on_the_ball_and_is_one_closed_loop():
    V, F = icosphere(4)
    v, f, info = cut_holes(V, F, balls=[BALL])
    K = SimplicialComplex(v, f, orient="check")  # valid, manifold, the input orientation kept
    loops = K.border_loops()
    assert len(loops) == 1
    border = info["on_border"]
    assert set(loops[0].tolist()) == set(np.flatnonzero(border).tolist())
    distance = np.linalg.norm(v[border] - BALL[:3], axis=1) - BALL[3]
    assert np.abs(distance).max() <= 1e-12
    assert np.all(info["region"][border] == 0) and np.all(info["region"][~border] == -1)
    # the kept vertices are outside the ball; the input vertices are reproduced or moved onto it
    assert np.all(np.linalg.norm(v[~border] - BALL[:3], axis=1) > BALL[3])
    assert info["new_vertices"] > 0 and info["snapped_vertices"] > 0
    assert info["new_vertices"] + info["snapped_vertices"] == border.sum()
    # shared crossing points: no two output vertices coincide (each cut edge got one new vertex)
    assert len(np.unique(v, axis=0)) == len(v)
    # every output vertex is P @ input vertices (a vertex or a point on an input edge)
    np.testing.assert_allclose(info["interpolation"] @ V, v, atol=1e-15)
    kept = info["source_vertex"] >= 0
    np.testing.assert_array_equal(v[kept & ~border], V[info["source_vertex"][kept & ~border]])


def test_removed_area_converges_to_the_spherical_cap():
    cap = spherical_cap_area(BALL)
    errors = []
    for subdiv in (2, 3, 4, 5):
        V, F = icosphere(subdiv)
        v, f, _ = cut_holes(V, F, balls=[BALL])
        errors.append(abs(area(V, F) - area(v, f) - cap) / cap)
    # second order: the error drops ~4× per subdivision (measured 4.3e-2, 1.0e-2, 2.6e-3, 6.4e-4)
    assert all(e1 < 0.3 * e0 for e0, e1 in zip(errors, errors[1:], strict=False))
    assert errors[-1] < 1e-3


def test_snapping_leaves_no_crossing_near_an_end_point():
    V, F = icosphere(4)
    lengths = np.linalg.norm(V[F] - V[np.roll(F, -1, axis=1)], axis=2)
    for snap in (0.0, 0.1, 0.25, 0.4):
        v, f, info = cut_holes(V, F, balls=[BALL], snap=snap)
        SimplicialComplex(v, f, orient="check")
        P = info["interpolation"].tocsr()
        new = np.flatnonzero(info["source_vertex"] < 0)
        weights = np.stack([P.data[P.indptr[i]:P.indptr[i + 1]] for i in new])  # (k, 2): 1 − t, t
        assert np.allclose(weights.sum(axis=1), 1.0)
        assert weights.min() > snap  # every remaining crossing lies in (snap, 1 − snap)
        assert info["max_snap_distance"] <= snap * lengths.max() + 1e-15
        assert (info["snapped_vertices"] == 0) == (snap == 0.0)
    # snapping trades new vertices for moved ones: the border has fewer, less crowded points
    _, _, none = cut_holes(V, F, balls=[BALL], snap=0.0)
    _, _, some = cut_holes(V, F, balls=[BALL], snap=0.25)
    assert some["new_vertices"] + some["snapped_vertices"] < none["new_vertices"]


# ------------------------------------------------------------------ planar: a disk out of a square
def test_planar_circular_hole_border_length_and_area_converge():
    centre, r = np.array([0.1, 0.05]), 0.3
    perimeter_errors, area_errors = [], []
    for nx in (21, 41, 81):
        P, F = square_grid(nx)
        v, f, info = cut_holes(P, F, balls=[[*centre, r]])
        K = SimplicialComplex(v, f, orient="check")
        loops = K.border_loops()
        assert len(loops) == 2  # the square and the hole
        hole = min(loops, key=lambda loop: np.linalg.norm(v[loop] - centre, axis=1).max())
        assert np.abs(np.linalg.norm(v[hole] - centre, axis=1) - r).max() <= 1e-12
        perimeter_errors.append(abs(loop_length(v, hole) - 2 * np.pi * r) / (2 * np.pi * r))
        area_errors.append(abs(area(v, f) - (4 - np.pi * r * r)) / (np.pi * r * r))
    # an inscribed polygon: both errors O(h²) (measured 2.8e-3, 1.0e-3, 2.4e-4 and 1.1e-2, 4.0e-3, 9.6e-4)
    assert all(e1 < 0.5 * e0 for e0, e1 in zip(perimeter_errors, perimeter_errors[1:], strict=False))
    assert all(e1 < 0.5 * e0 for e0, e1 in zip(area_errors, area_errors[1:], strict=False))
    assert perimeter_errors[-1] < 5e-4 and area_errors[-1] < 2e-3


def test_planar_box_cut_has_exact_sides_and_chamfered_corners():
    box = [-0.43, -0.61, 0.37, 0.29]
    lo, hi = np.array(box[:2]), np.array(box[2:])
    for nx in (16, 31, 61):
        P, F = square_grid(nx)
        h = 2 / (nx - 1)
        v, f, info = cut_holes(P, F, boxes=[box])
        SimplicialComplex(v, f, orient="check")
        on = v[info["on_border"]]
        # each border vertex lies exactly on a side of the box (that coordinate is set exactly)
        assert np.all(((on == lo) | (on == hi)).any(axis=1))
        assert np.all((on >= lo) & (on <= hi))
        # the sides are cut exactly; only the 4 corners, which lie inside triangles, are
        # chamfered (each by at most half a grid cell): error ≤ 2h² (measured ≈ 0.6–0.7 h²)
        error = abs(area(v, f) - (4 - np.prod(hi - lo)))
        assert 0 < error <= 2 * h * h


def test_two_holes_touching_at_a_vertex_split_the_pinch():
    # two disks touching at the grid vertex (0, 0): the kept triangles meet there in two fans
    # (snap=0: with snapping the neighbours (0, ±h) move onto the circles and the fans vanish)
    P, F = square_grid(21)
    v, f, info = cut_holes(P, F, balls=[[-0.3, 0.0, 0.3], [0.3, 0.0, 0.3]], snap=0.0)
    assert info["pinched_vertices_split"] == 1
    K = SimplicialComplex(v, f, orient="check")
    origin = np.flatnonzero(np.all(v == 0.0, axis=1))
    assert origin.size == 2  # two copies of the origin, one per fan
    # the figure-8 hole's border is now one simple loop passing through both copies
    loops = K.border_loops()
    assert len(loops) == 2 and all(np.isin(origin, loops[0]) | np.isin(origin, loops[1]))


# ------------------------------------------------------------------ the thesis' Fig. 5.7 half sphere
def _border_angles(K):
    """Σ of corner angles at each vertex on the surface (α_v at a border vertex, Fig. 5.4)."""
    faces = K.oriented_simplices()
    p = K.vertices[faces]
    a = np.roll(p, -1, axis=1) - p
    b = np.roll(p, 1, axis=1) - p
    angle = np.arctan2(np.linalg.norm(np.cross(a, b), axis=2), np.einsum("mkd,mkd->mk", a, b))
    return np.bincount(faces.ravel(), weights=angle.ravel(), minlength=K.num_simplices(0))


def reflex_counts(K):
    """Per loop (longest = exterior first): vertices reflex under the target angles of eq. 5.8."""
    alpha = _border_angles(K)
    counts = []
    for i, loop in enumerate(K.border_loops()):
        total = (len(loop) - 2) * np.pi if i == 0 else (len(loop) + 2) * np.pi
        counts.append(int((alpha[loop] * total / alpha[loop].sum() > np.pi + 1e-9).sum()))
    return counts


def test_fig5_7_half_sphere_borders_are_smooth():
    mesh = yaml.safe_load(FIG5_7.read_text())["mesh"]
    V, F = icosphere(mesh["subdiv"])
    old_v, old_f, _ = cut_whole_triangles(V, F, mesh["hole_balls"], mesh["hole_boxes"])
    v, f, info = cut_holes(V, F, mesh["hole_balls"], mesh["hole_boxes"])
    K_old, K = SimplicialComplex(old_v, old_f, orient="check"), SimplicialComplex(v, f, orient="check")
    assert reflex_counts(K_old) == [32, 24, 12, 12]  # 80: the sawtooth the old cut leaves
    loops = K.border_loops()
    assert len(loops) == 4  # the half-sphere rim with the ear notches, the smile, two eyes
    # the eyes are round holes: smooth borders turn one way only, so every vertex is reflex (the
    # surface wraps around the hole, Gortler's condition 5); the old sawtooth left ~half convex
    centres = np.array([loop_vertices[:, 0::2].mean(axis=0) for loop_vertices in (v[loop] for loop in loops)])
    eyes = [i for i, c in enumerate(centres) if min(np.linalg.norm(c - [0.35, 0.45]), np.linalg.norm(c + [0.35, -0.45])) < 0.1]
    assert len(eyes) == 2
    counts = reflex_counts(K)
    assert all(counts[i] == len(loops[i]) for i in eyes)
    assert reflex_counts(K_old)[2:] == [12, 12] and [len(x) for x in K_old.border_loops()][2:] == [22, 22]
    # the rim away from the ears follows the equator: α ≈ π (it is a geodesic) instead of the
    # ±72° zig-zag of whole triangles
    ears = np.array([b[:3] for b in mesh["hole_balls"][-2:]])
    for K_, max_mean_deviation_deg in ((K, 1.0), (K_old, None)):
        rim = K_.border_loops()[0]
        far = np.linalg.norm(K_.vertices[rim][:, None] - ears[None], axis=2).min(axis=1) > 0.35
        deviation = np.degrees(np.abs(np.pi - _border_angles(K_)[rim[far]])).mean()
        if max_mean_deviation_deg is None:
            assert deviation > 30
        else:
            assert deviation < max_mean_deviation_deg
    # the box's border vertices are exactly on the plane y = 0
    assert np.all(v[info["region"] == len(mesh["hole_balls"]), 1] == 0.0)


# ------------------------------------------------------------------ small contracts
def test_signed_distance_of_ball_and_box():
    balls, boxes = parse_regions([[0, 0, 0, 1.0]], [[2, -1, -1, 4, 1, 1.0]], 3)
    points = np.array([[0, 0, 0], [0.5, 0, 0], [1.5, 0, 0], [3, 0, 0], [5, 2, 0.0]])
    phi, region = signed_distance(points, balls, boxes)
    np.testing.assert_allclose(phi, [-1, -0.5, 0.5, -1, np.sqrt(2)])
    np.testing.assert_array_equal(region, [0, 0, 0, 1, 1])


def test_no_regions_is_the_identity_and_bad_input_is_named():
    V, F = icosphere(1)
    v, f, info = cut_holes(V, F)
    assert np.array_equal(v, V) and np.array_equal(f, F) and info["new_vertices"] == 0
    with pytest.raises(ConfigError, match=r"hole_balls\[0\]"):
        cut_holes(V, F, balls=[[0, 0, 1.0]])  # a 2-D ball on a 3-D mesh
    with pytest.raises(ConfigError, match=r"hole_boxes\[0\]"):
        cut_holes(V, F, boxes=[[1, 0, 0, 0, 1, 1]])  # min > max
    with pytest.raises(MeshError, match="every face"):
        cut_holes(V, F, balls=[[0, 0, 0, 2.0]])


def two_spheres_obj(tmp_path: Path) -> str:
    """A unit sphere (subdiv 3, 642 vertices) and, 3 units away, a small one (subdiv 1, 42)."""
    big, small = icosphere(3), icosphere(1)
    vertices = np.vstack([big[0], 0.5 * small[0] + [3.0, 0.0, 0.0]])
    faces = np.vstack([big[1], small[1] + len(big[0])])
    lines = [f"v {x} {y} {z}" for x, y, z in vertices] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    (tmp_path / "two_spheres.obj").write_text("\n".join(lines) + "\n")
    return str(tmp_path / "two_spheres.obj")


@pytest.mark.parametrize("cut", ["split", "whole_triangles"])
def test_a_cut_that_drops_pieces_says_so_and_hole_pieces_all_keeps_them(tmp_path, caplog, cut):
    """Issue 34 item 8: a hole in the big sphere of a two-sphere OBJ kept only the largest
    piece — the small sphere's 42 vertices gone — with no log line and no metric. Now the
    dropped piece is logged (one line naming `mesh.hole_pieces=all`) and counted in the
    metrics; `mesh.hole_pieces=all` keeps both, and the spectrum then finds one zero
    eigenvalue per piece."""
    import logging

    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    common = ["mesh=file", f"mesh.path={two_spheres_obj(tmp_path)}", "mesh.hole_balls=[[0.0,0.0,1.0,0.5]]",
              f"mesh.hole_cut={cut}", "app=spectrum", "app.count=4", "figures=false"]
    with caplog.at_level(logging.INFO, logger="decrun"):
        dropped = run_experiment(compose_config(common)).result.metrics
    lines = [r.getMessage() for r in caplog.records if "hole_pieces" in r.getMessage()]
    assert len(lines) == 1 and "the cut left 2 pieces" in lines[0] and "dropped 42 vertices, 80 simplices" in lines[0]
    assert lines[0].endswith("`mesh.hole_pieces=all` keeps every piece")
    assert dropped["holes_components"] == 2 and dropped["holes_dropped_vertices"] == 42
    assert dropped["holes_dropped_faces"] == 80 and dropped["betti_0"] == dropped["kernel_dimension"] == 1
    kept = run_experiment(compose_config(common + ["mesh.hole_pieces=all"])).result.metrics
    assert kept["n_vertices"] == dropped["n_vertices"] + 42 and kept["n_faces"] == dropped["n_faces"] + 80
    assert kept["betti_0"] == kept["kernel_dimension"] == 2 and kept["kernel_dimension_matches_betti"]
    assert "holes_components" not in kept  # nothing dropped, nothing kept out: no count to report


def test_clean_says_what_it_drops(tmp_path, caplog):
    """`mesh.clean` (on for samples) kept the largest piece silently too: a log line and
    metrics now, naming `mesh.clean=false`, which keeps every piece."""
    import logging

    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    common = ["mesh=file", f"mesh.path={two_spheres_obj(tmp_path)}", "app=spectrum", "app.count=4", "figures=false"]
    with caplog.at_level(logging.INFO, logger="decrun"):
        metrics = run_experiment(compose_config(common + ["mesh.clean=true"])).result.metrics
    lines = [r.getMessage() for r in caplog.records if "mesh.clean" in r.getMessage()]
    assert len(lines) == 1 and "left 2 pieces; kept the largest: 642 of 684 vertices" in lines[0]
    assert metrics["clean_components"] == 2 and metrics["clean_dropped_vertices"] == 42
    assert metrics["clean_dropped_faces"] == 80 and metrics["n_vertices"] == 642
    assert run_experiment(compose_config(common)).result.metrics["kernel_dimension"] == 2
