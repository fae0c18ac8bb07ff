"""DEC of the intrinsic Delaunay triangulation (decrun.core.intrinsic_calculus): exact identities
on closed, bordered (tufted cover) and non-orientable meshes."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from test_intrinsic_delaunay import as3, mobius, split_square, stretched_sphere  # noqa: E402

from decrun.core.intrinsic_calculus import IntrinsicCalculus
from decrun.core.intrinsic_delaunay import intrinsic_delaunay

from meshes_for_tests import icosphere  # noqa: E402

MESHES = {"sphere": lambda: icosphere(3), "stretched sphere": stretched_sphere, "split square": split_square,
          "mobius": mobius}


@pytest.fixture(params=list(MESHES), scope="module")
def calculus(request):
    V, F = MESHES[request.param]()
    return IntrinsicCalculus(intrinsic_delaunay(as3(V), F)), as3(V)


def test_the_meshes_flip_and_two_are_tufted_covers(calculus):
    C, _ = calculus
    assert C.T.flips > 0 or C.n_faces == 1280  # the icosphere is Delaunay already
    assert C.n_edges * 2 == C.n_faces * 3  # a closed triangulation (the cover closes a bordered mesh)


def test_stiffness_is_d0_transpose_star1_d0(calculus):
    C, _ = calculus
    S = C.d0.T @ sp.diags(C.star1) @ C.d0
    assert abs(S - C.T.stiffness()).max() <= 1e-14 * abs(C.T.stiffness()).max()
    assert (C.star1 >= 0).all()  # Delaunay: non-negative cotan weights


def test_sharp_of_d0_is_the_gradient_and_d0_of_a_constant_is_zero(calculus):
    C, _ = calculus
    u = np.random.default_rng(0).normal(size=C.n_vertices)
    gradient = C.gradient(u)
    assert np.abs(C.sharp(C.d0 @ u) - gradient).max() <= 1e-12 * np.abs(gradient).max()
    assert np.abs(C.d0 @ np.ones(C.n_vertices)).max() == 0


def test_the_divergence_of_a_gradient_is_the_stiffness(calculus):
    """d0ᵀ ⋆1 (∇u)♭ = S u: the cotan divergence of a gradient is the cotan Laplacian (an exact
    identity of the flat's dual-edge weights)."""
    C, _ = calculus
    u = np.random.default_rng(1).normal(size=C.n_vertices)
    divergence = C.codifferential_weak() @ C.flat(C.gradient(u))
    expected = C.T.stiffness() @ u
    assert np.abs(divergence - expected).max() <= 1e-12 * np.abs(expected).max()


def test_the_gradient_of_a_linear_function_is_exact_on_a_planar_mesh():
    """Without the cover (border='fixed') every intrinsic triangle of a planar mesh is planar, so
    the gradient of 2x + y has length √5 in each, and ⟨∇u, ∇u⟩ = 5 × area."""
    V, F = split_square()
    C = IntrinsicCalculus(intrinsic_delaunay(as3(V), F, border="fixed"))
    u = 2 * V[:, 0] + V[:, 1]
    lengths = np.linalg.norm(C.gradient(u), axis=1)
    assert C.T.flips > 0 and np.abs(lengths - np.sqrt(5)).max() < 1e-12
    assert u @ C.T.stiffness() @ u == pytest.approx(5.0, rel=1e-12)  # ∫|∇u|² over the unit square


def test_frames_keep_lengths_and_areas(calculus):
    C, _ = calculus
    p = C.corners
    sides = np.linalg.norm(p[:, [2, 0, 1]] - p[:, [1, 2, 0]], axis=2)
    lengths = C.T.edge_lengths[C.T.face_edges]
    assert np.abs(sides - lengths).max() <= 1e-12 * lengths.max()
    assert (p[:, 2, 1] > 0).all()  # counter-clockwise frames
