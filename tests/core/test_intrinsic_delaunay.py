"""Intrinsic Delaunay Laplacian: against robust_laplacian (Sharp & Crane 2020), against the
planar Delaunay triangulation (scipy/Qhull), and its M-matrix property."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pymeshlab
import pytest
import scipy.sparse as sp
import scipy.spatial

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.intrinsic_delaunay import intrinsic_delaunay, intrinsic_delaunay_operators
from decrun.core.primitives import grid_triangles
from decrun.errors import DegenerateSimplexError, NonManifoldError, OrientationError

from meshes_for_tests import icosphere  # noqa: E402


def robust_laplacian():
    return pytest.importorskip("robust_laplacian", reason="robust_laplacian is not installed: reference skipped")


# ---------------------------------------------------------------- meshes
def bunny():
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(Path(pymeshlab.__file__).parent / "tests/sample_meshes/bunny10k_textured.obj"))
    mesh = ms.current_mesh()
    return mesh.vertex_matrix().astype(np.float64), mesh.face_matrix().astype(np.int64)


def split_square(n_points: int = 60, seed: int = 0):
    """Random points in the unit square, triangulated by inserting each point with a 1→3
    split of the triangle containing it: a valid planar triangulation, far from Delaunay."""
    rng = np.random.default_rng(seed)
    points = np.concatenate([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], rng.uniform(0.05, 0.95, (n_points, 2))])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    for i in range(4, points.shape[0]):
        a, b, c = (points[faces[:, j]] for j in range(3))
        cross = lambda u, v: u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]  # noqa: E731
        p = points[i][None, :]
        inside = (cross(b - a, p - a) > 0) & (cross(c - b, p - b) > 0) & (cross(a - c, p - c) > 0)
        t = int(np.flatnonzero(inside)[0])
        x, y, z = faces[t]
        faces = np.concatenate([np.delete(faces, t, axis=0), [[x, y, i], [y, z, i], [z, x, i]]])
    return points, faces


def mobius(nu: int = 40, nv: int = 6, noise: float = 0.04):
    """A Möbius strip (non-orientable, one border loop), vertices moved by seeded noise."""
    u = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    v = np.linspace(-1, 1, nv + 1)
    U, W = np.meshgrid(u, v, indexing="ij")
    r = 1 + 0.4 * W * np.cos(U / 2)
    vertices = np.stack([r * np.cos(U), r * np.sin(U), 0.4 * W * np.sin(U / 2)], -1).reshape(-1, 3)
    vertices += noise * np.random.default_rng(0).uniform(-1, 1, vertices.shape)
    index = np.arange(nu * (nv + 1)).reshape(nu, nv + 1)
    following = np.concatenate([index[1:], index[:1, ::-1]])  # the twist: v → −v across u = 2π
    a, b = index[:, :-1].ravel(), following[:, :-1].ravel()
    c, d = following[:, 1:].ravel(), index[:, 1:].ravel()
    return vertices, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def stretched_sphere():
    V, F = icosphere(3)
    return V * np.array([1.0, 1.0, 6.0]), F


def as3(points):
    return np.c_[points, np.zeros(points.shape[0])] if points.shape[1] == 2 else np.ascontiguousarray(points)


def relative_difference(A, B) -> float:
    return abs(A - B).max() / abs(B).max()


# ---------------------------------------------------------------- against robust_laplacian
@pytest.mark.parametrize("mollify", [0.0, 1e-5, 1e-3])
def test_bunny_matches_robust_laplacian(mollify):
    rl = robust_laplacian()
    V, F = bunny()
    L, M = rl.mesh_laplacian(V, F, mollify_factor=mollify)
    T = intrinsic_delaunay(V, F, mollify=mollify)
    assert T.flips > 1000 and T.rounds < T.flips // 100  # many flips, done in few vectorized rounds
    assert relative_difference(T.stiffness(), L) <= 1e-10
    np.testing.assert_allclose(T.star0(), M.diagonal(), rtol=1e-10)


@pytest.mark.parametrize("name", ["split square", "mobius", "stretched sphere", "jittered grid"])
def test_tufted_cover_matches_robust_laplacian(name):
    """The tufted cover reproduces robust_laplacian on borders, on non-orientable meshes and
    when cocircular quads make the Delaunay triangulation non-unique (the Laplacian is still
    unique: Bobenko & Springborn 2007, Prop. 10)."""
    rl = robust_laplacian()
    V, F = {"split square": split_square, "mobius": mobius, "stretched sphere": stretched_sphere,
            "jittered grid": lambda: grid_triangles(10, jitter=0.35, seed=2)}[name]()
    L, _ = rl.mesh_laplacian(as3(V), F, mollify_factor=0.0)
    ours = intrinsic_delaunay_operators(V, F)
    assert ours.flips > 0
    assert relative_difference(ours.stiffness, L) <= 1e-10


def test_degenerate_triangle_needs_mollification():
    rl = robust_laplacian()
    V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    F = np.array([[0, 1, 3], [1, 2, 3], [0, 2, 1]])  # the last triangle has zero area
    with pytest.raises(DegenerateSimplexError, match="mollify"):
        intrinsic_delaunay(V, F)
    L, M = rl.mesh_laplacian(V, F, mollify_factor=1e-3)
    T = intrinsic_delaunay(V, F, mollify=1e-3)
    assert T.mollify_epsilon > 0
    assert relative_difference(T.stiffness(), L) <= 1e-10
    np.testing.assert_allclose(T.star0(), M.diagonal(), rtol=1e-10)


# ---------------------------------------------------------------- borders: tufted vs fixed
def test_border_conventions():
    """What matches on borders, and why.

    robust_laplacian flips on the tufted cover, where a border edge is glued to its own
    back copy: its weight is ½(cot α + cot α), so it is flipped iff α > 90°. ``border="fixed"``
    never flips border edges. Hence: fixed == tufted == robust_laplacian when every angle
    opposite a border edge of the fixed result is ≤ 90° (the jittered grid), and they differ
    exactly when one is obtuse (the bunny: the fixed result keeps negative border weights,
    i.e. positive off-diagonal entries; the tufted one has none).
    """
    for make, obtuse_expected in ((lambda: grid_triangles(10, jitter=0.35, seed=2), False), (bunny, True)):
        V, F = make()
        fixed = intrinsic_delaunay(V, F, border="fixed")
        tufted = intrinsic_delaunay(V, F, border="tufted")
        border = fixed.edge_sides[:, 1] < 0
        has_obtuse = bool((fixed.cotan_weights()[border] < 0).any())
        assert has_obtuse == obtuse_expected
        difference = relative_difference(fixed.stiffness(), tufted.stiffness())
        if obtuse_expected:
            assert difference > 1e-3
            off_diagonal = sp.triu(fixed.stiffness(), k=1)
            assert off_diagonal.max() > 0
        else:
            assert difference <= 1e-12


def test_fixed_border_on_a_flat_square_is_the_planar_delaunay_triangulation():
    """In a flat convex domain, intrinsic flips are Lawson's planar flips: the result is the
    Delaunay triangulation of the points (computed here by Qhull), whose cot Laplacian DEC
    builds independently."""
    V, F = split_square()
    K = SimplicialComplex(V, scipy.spatial.Delaunay(V).simplices, orient="fix")
    reference = DEC(K).laplacian_symmetric(0)
    assert (DEC(SimplicialComplex(V, F)).star_diagonal(1) < 0).any()  # the input is not Delaunay
    T = intrinsic_delaunay(V, F, border="fixed")
    assert T.flips > 0
    assert relative_difference(T.stiffness(), reference) <= 1e-10
    np.testing.assert_allclose(T.star0(), DEC(K, star="barycentric").star_diagonal(0), rtol=1e-10)


# ---------------------------------------------------------------- properties
@pytest.mark.parametrize("make", [bunny, split_square, mobius, stretched_sphere])
def test_stiffness_is_an_m_matrix(make):
    V, F = make()
    ours = intrinsic_delaunay_operators(V, F)
    S = ours.stiffness
    assert abs(S - S.T).max() <= 1e-15 * S.diagonal().max()
    assert sp.triu(S, k=1).max() <= 0.0  # off-diagonal entries ≤ 0
    assert np.abs(np.asarray(S.sum(axis=1)).ravel()).max() <= 1e-12 * S.diagonal().max()
    assert ours.star0.min() > 0


@pytest.mark.parametrize("make", [bunny, split_square, stretched_sphere])
def test_flips_preserve_total_area(make):
    V, F = make()
    area = 0.5 * np.linalg.norm(np.cross(*(as3(V)[F[:, i]] - as3(V)[F[:, 0]] for i in (1, 2))), axis=1).sum()
    assert intrinsic_delaunay_operators(V, F).star0.sum() == pytest.approx(area, rel=1e-12)


def test_delaunay_icosphere_is_the_cotan_laplacian_with_no_flips():
    V, F = icosphere(3)
    K = SimplicialComplex(V, F, orient="fix")
    assert DEC(K).star_diagonal(1).min() > 0  # already Delaunay
    ours = intrinsic_delaunay_operators(V, F)
    assert ours.flips == 0 and ours.rounds == 0
    assert relative_difference(ours.stiffness, DEC(K).laplacian_symmetric(0)) <= 1e-13
    np.testing.assert_allclose(ours.star0, DEC(K, star="barycentric").star_diagonal(0), rtol=1e-13)


def test_orientation_does_not_matter_on_the_tufted_cover():
    V, F = bunny()
    reference = intrinsic_delaunay_operators(V, F).stiffness
    flipped = F.copy()
    flip = np.random.default_rng(1).random(F.shape[0]) < 0.3
    flipped[flip] = flipped[flip][:, ::-1]
    assert relative_difference(intrinsic_delaunay_operators(V, flipped).stiffness, reference) <= 1e-12
    with pytest.raises(OrientationError):
        intrinsic_delaunay(V, flipped, border="fixed")


def test_non_manifold_edge_is_reported():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]])
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    with pytest.raises(NonManifoldError, match="more than two"):
        intrinsic_delaunay(V, F)
