"""Conformal parametrization (thesis ch. 5): exact reproduction of flat and developable meshes,
Tutte's conditions 5.5–5.7 row by row, eq. 5.8–5.9, topology errors, the T-hole failure."""

import numpy as np
import pytest
import scipy.sparse as sp

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.solvers import make_solver
from decrun.errors import TopologyError
from decrun.methods.parametrization import (
    conformal_border,
    conformal_border_rows,
    harmonic_matrix,
    parametrize,
    target_border_angles,
)
from decrun.methods.parametrization_metrics import parametrization_metrics
from decrun.runner.mesh.holes import cut_holes

from meshes_for_tests import icosphere, planar_domain, random_planar

# a T on the front (y > 0) of the unit sphere: bar 1.0 × 0.2, stem 0.24 wide (thesis Fig. 5.8)
T_HOLE = [[-0.5, 0.0, 0.35, 0.5, 1.5, 0.55], [-0.12, 0.0, -0.4, 0.12, 1.5, 0.36]]


def similarity_residual(points: np.ndarray, uv: np.ndarray) -> float:
    """max |uv − S(points)| / extent for the best similarity S (complex least squares)."""
    z = points[:, 0] + 1j * points[:, 1]
    w = uv[:, 0] + 1j * uv[:, 1]
    zc, wc = z - z.mean(), w - w.mean()
    a = np.vdot(zc, wc) / np.vdot(zc, zc)
    return float(np.abs(a * zc - wc).max() / np.ptp(uv, axis=0).max())


def wavy_disk():
    """A planar domain with a non-convex, wavy outer border and one hole (reflex border vertices)."""
    import triangle

    t = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    outer = np.c_[1.3 * np.cos(t), 0.8 * np.sin(t) + 0.2 * np.sin(3 * t)]
    s = np.linspace(0, 2 * np.pi, 14, endpoint=False)
    inner = np.c_[0.3 + 0.25 * np.cos(s), 0.1 + 0.2 * np.sin(s)]
    segments = np.r_[np.c_[np.arange(48), (np.arange(48) + 1) % 48], 48 + np.c_[np.arange(14), (np.arange(14) + 1) % 14]]
    mesh = triangle.triangulate({"vertices": np.r_[outer, inner], "segments": segments, "holes": [[0.3, 0.1]]}, "pq25a0.01")
    return mesh["vertices"], mesh["triangles"].astype(np.int64)


def bent_rectangle(nx=12, ny=8, radius=0.6, seed=0):
    """A rectangle rolled onto a cylinder: vertices on rulings, so the triangulated surface is
    developable exactly (each ruling strip is a planar quad). Returns (3-D vertices, faces, flat layout)."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.5, nx + 1)
    y = np.linspace(0.0, 1.0, ny + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    Y = Y + np.where((Y > 0) & (Y < 1), rng.uniform(-0.3, 0.3, Y.shape) / ny, 0.0)  # jitter along rulings only
    theta = X / radius
    vertices = np.stack([radius * np.sin(theta), Y, radius * (1 - np.cos(theta))], axis=-1).reshape(-1, 3)
    # flat development: ruling k sits at the accumulated chord length
    chord = 2 * radius * np.sin(np.diff(x) / (2 * radius))
    flat_x = np.concatenate([[0.0], np.cumsum(chord)])
    flat = np.stack([np.broadcast_to(flat_x[:, None], X.shape), Y], axis=-1).reshape(-1, 2)
    index = np.arange((nx + 1) * (ny + 1)).reshape(nx + 1, ny + 1)
    a, b, c, d = index[:-1, :-1].ravel(), index[1:, :-1].ravel(), index[1:, 1:].ravel(), index[:-1, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return vertices, faces, flat


def complex_and_dec(vertices, faces, star="circumcentric"):
    K = SimplicialComplex(vertices, faces, orient="fix")
    return K, DEC(K, star=star)


# ---------------------------------------------------------------------------- eq. 5.5–5.7
@pytest.mark.parametrize("weights", ["uniform", "mean_value", "dec"])
def test_weights_meet_tutte_conditions_row_by_row(weights):
    K, dec = complex_and_dec(*random_planar(150, seed=3))
    A = harmonic_matrix(dec, weights).tocsr()
    adjacency = abs(dec.d(0).T @ dec.d(0)).tocsr()  # nonzero exactly on neighbours and the diagonal
    # eq. 5.5: a_ij = 0 unless i, j are neighbours (or i = j)
    outside = A - A.multiply(adjacency != 0)
    assert abs(outside).max() == 0
    # eq. 5.6: zero row sums
    row_sum = np.asarray(A.sum(axis=1)).ravel()
    assert np.abs(row_sum).max() <= 1e-12 * abs(A).max()
    # eq. 5.7: a_ii < 0, a_ij >= 0 — holds for uniform and mean value on every row (border too)
    off = A - sp.diags(A.diagonal())
    if weights == "dec":
        # cot weights of a random Delaunay mesh with obtuse triangles: 5.7 can fail at border
        # edges (one obtuse angle, no second triangle); this is what the thesis warns about.
        negative = off.data < -1e-12
        assert negative.any()
    else:
        assert np.all(A.diagonal() < 0)
        assert off.data.min() > 0  # strictly convex combinations of all neighbours
        assert off.nnz == adjacency.nnz - K.num_simplices(0)


def test_mean_value_weights_reproduce_linear_functions_inside():
    # Floater's coordinates have linear precision at interior vertices
    K, dec = complex_and_dec(*planar_domain(holes=0, max_area=0.01))
    A = harmonic_matrix(dec, "mean_value")
    interior = ~K.border_vertices()
    residual = A @ K.vertices[:, :2]
    assert np.abs(residual[interior]).max() < 1e-10 * abs(A).max()


# ---------------------------------------------------------------------------- eq. 5.8–5.9
def test_planar_border_satisfies_conformal_border_rows_and_angle_sums():
    K, _ = complex_and_dec(*wavy_disk())
    loops = K.border_loops()
    exterior, hole = loops
    alpha = target_border_angles(K, exterior, exterior=True)
    assert alpha.sum() == pytest.approx((len(exterior) - 2) * np.pi)
    alpha_hole = target_border_angles(K, hole, exterior=False)
    assert alpha_hole.sum() == pytest.approx((len(hole) + 2) * np.pi)
    z = np.concatenate([K.vertices[:, 0], K.vertices[:, 1]])
    for loop, a in ((exterior, alpha), (hole, alpha_hole)):
        rows = conformal_border_rows(K, loop, a)
        assert np.abs(rows @ z).max() < 1e-12  # the flat border meets eq. 5.9 exactly
    b = conformal_border(K, exterior, make_solver("direct"))
    assert similarity_residual(K.vertices[exterior], b) < 1e-10
    assert b.min() == pytest.approx(0.0, abs=1e-14) and b.max() == pytest.approx(1.0)


# ---------------------------------------------------------------------------- exact reproduction
@pytest.mark.parametrize("border,weights", [("free", "dec"), ("free", "mean_value"),
                                            ("conformal", "dec"), ("conformal", "mean_value")])
def test_flat_mesh_with_hole_is_reproduced_up_to_similarity(border, weights, new_solver):
    K, dec = complex_and_dec(*wavy_disk())
    result = parametrize(dec, new_solver, border=border, weights=weights, reflex_rows="cauchy_riemann")
    assert similarity_residual(K.vertices, result.uv) < 1e-9
    metrics = parametrization_metrics(K.vertices, result.uv, K.oriented_simplices(), result.loops)
    assert metrics["angle_distortion_max_deg"] < 1e-6 and metrics["is_embedding"]
    assert metrics["uv_orientation"] == 1  # the map keeps the complex's orientation


def test_thesis_reflex_rows_distort_a_flat_mesh_with_reflex_border_vertices(new_solver):
    # The thesis gives reflex border vertices the one-sided harmonic row, which a similarity does
    # not satisfy: measurable distortion on a flat mesh (unlike reflex_rows=cauchy_riemann).
    K, dec = complex_and_dec(*wavy_disk())
    result = parametrize(dec, new_solver, border="conformal", weights="dec", reflex_rows="harmonic")
    assert result.reflex_predicted > 0
    metrics = parametrization_metrics(K.vertices, result.uv, K.oriented_simplices(), result.loops)
    assert metrics["angle_distortion_mean_deg"] > 1.0 and metrics["is_embedding"]


def test_convex_flat_disk_is_reproduced_by_the_thesis_conformal_border(new_solver):
    K, dec = complex_and_dec(*planar_domain(holes=0, max_area=0.01))
    result = parametrize(dec, new_solver, border="conformal", weights="dec")
    assert result.reflex_predicted == 0
    assert similarity_residual(K.vertices, result.uv) < 1e-9


@pytest.mark.parametrize("border", ["free", "conformal"])
def test_bent_rectangle_is_developed_isometrically(border, new_solver):
    vertices, faces, flat = bent_rectangle()
    K, dec = complex_and_dec(vertices, faces)
    result = parametrize(dec, new_solver, border=border, weights="dec")
    assert similarity_residual(flat, result.uv) < 1e-9
    metrics = parametrization_metrics(K.vertices, result.uv, K.oriented_simplices(), result.loops)
    assert metrics["qc_distortion_max"] == pytest.approx(1.0, abs=1e-8)
    assert metrics["area_distortion_std"] < 1e-8


def test_star_variant_does_not_change_the_map(new_solver):
    # ⋆0 scales each harmonic row, whose right-hand side is 0: the solution is the same.
    vertices, faces = wavy_disk()
    maps = []
    for star in ("circumcentric", "mixed_area", "barycentric"):
        _, dec = complex_and_dec(vertices, faces, star=star)
        maps.append(parametrize(dec, new_solver, border="circle", weights="dec").uv)
    assert np.abs(maps[0] - maps[1]).max() < 1e-12 and np.abs(maps[0] - maps[2]).max() < 1e-12


# ---------------------------------------------------------------------------- topology
class ExplodingSolver:
    name = "exploding"

    def factorize(self, A):
        raise AssertionError("the topology check must come before any solve")


def test_closed_surface_is_rejected_before_solving():
    K, dec = complex_and_dec(*icosphere(1))
    with pytest.raises(TopologyError, match="closed"):
        parametrize(dec, ExplodingSolver)


def test_two_components_are_rejected():
    v, f = planar_domain(max_area=0.05)
    vertices = np.concatenate([v, v + [3.0, 0.0]])
    faces = np.concatenate([f, f + len(v)])
    _, dec = complex_and_dec(vertices, faces)
    with pytest.raises(TopologyError, match="2 connected components"):
        parametrize(dec, ExplodingSolver)


def test_torus_with_a_hole_has_genus_one():
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.create_torus(hradius=1.0, vradius=0.4, hsubdiv=24, vsubdiv=12)
    m = ms.current_mesh()
    vertices, faces, _ = cut_holes(m.vertex_matrix(), m.face_matrix(), balls=[[1.4, 0.0, 0.0, 0.25]])
    _, dec = complex_and_dec(vertices, faces)
    with pytest.raises(TopologyError, match="genus 1"):
        parametrize(dec, ExplodingSolver)


# ---------------------------------------------------------------------------- thesis Fig. 5.8
def test_t_hole_sphere_circle_embeds_conformal_does_not(new_solver):
    v, f = icosphere(4)
    vertices, faces, _ = cut_holes(v, f, boxes=T_HOLE)
    K, dec = complex_and_dec(vertices, faces)
    assert len(K.border_loops()) == 1
    outcome = {}
    for border, weights in [("circle", "uniform"), ("circle", "mean_value"), ("conformal", "dec"), ("free", "dec")]:
        result = parametrize(dec, new_solver, border=border, weights=weights)
        outcome[border, weights] = parametrization_metrics(K.vertices, result.uv, K.oriented_simplices(), result.loops)
    assert outcome["circle", "uniform"]["is_embedding"] and outcome["circle", "uniform"]["flipped_triangles"] == 0
    assert outcome["circle", "mean_value"]["is_embedding"]
    assert not outcome["conformal", "dec"]["is_embedding"]
    assert outcome["free", "dec"]["is_embedding"]
    assert outcome["free", "dec"]["angle_distortion_mean_deg"] < outcome["circle", "mean_value"]["angle_distortion_mean_deg"]


def test_cut_holes_keeps_a_manifold_and_removes_the_right_faces():
    v, f = icosphere(2)
    vertices, faces, kept = cut_holes(v, f, boxes=[[-2, -2, -2, 2, 2, 0.0]])
    centroid_z = vertices[faces].mean(axis=1)[:, 2]
    assert np.all(centroid_z > 0)
    K = SimplicialComplex(vertices, faces)  # manifold, oriented
    assert len(K.border_loops()) == 1 and K.euler_characteristic == 1
    np.testing.assert_array_equal(v[kept], vertices)


# The Tutte maps and the conformal / free borders of the experiment meshes (Fig. 5.5-5.8) have
# one home: tests/regression/parametrization.yaml pins their distortions, flips, border
# crossings and orientation through the same composition as `decrun`.


def test_app_run_returns_uv_metrics_and_figures(run_app):
    from decrun.apps.parametrization import Parametrization

    K, dec = complex_and_dec(*wavy_disk())
    result, _ = run_app(Parametrization(border="conformal", weights="dec", reflex_rows="cauchy_riemann"), K)
    assert result.fields["uv"].shape == (K.num_simplices(0), 2)
    assert result.metrics["angle_distortion_max_deg"] < 1e-6 and result.metrics["is_embedding"] is True
    assert result.metrics["cauchy_riemann_rows"] == result.metrics["reflex_border_vertices_predicted"] > 0
    assert set(result.figures) == {"uv_layout", "checkerboard"}


@pytest.mark.parametrize("border", ["circle", "circle_arclength"])
def test_circle_border_keeps_the_orientation_of_the_complex(border, new_solver):
    """§5.2.2 with (cos, sin): the border loop (surface on its left) runs counter-clockwise on
    the circle, so a counter-clockwise planar mesh keeps every triangle counter-clockwise
    (the thesis' (sin, cos) would mirror the map: all triangles clockwise)."""
    vertices, faces = planar_domain(0, max_area=0.01)
    K, dec = complex_and_dec(vertices, faces)
    result = parametrize(dec, new_solver, border=border, weights="uniform")
    loop = result.loops[0]
    x, y = result.uv[loop, 0], result.uv[loop, 1]
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0  # shoelace: counter-clockwise
    tri = K.oriented_simplices()

    def side(p):  # sign of each triangle's signed area
        u, v = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        return np.sign(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])

    np.testing.assert_array_equal(side(result.uv[tri]), side(vertices[tri]))
