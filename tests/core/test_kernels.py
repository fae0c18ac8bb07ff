"""Every kernel of the compiled extension (:mod:`decrun.core.extension`) equals its numpy twin
(``DECRUN_NUMBA=0``), bit for bit, kernel by kernel (the whole complex and its operators:
``tests/core/test_extension.py``).

The kernels repeat the twins' arithmetic in the same order, so floats are compared with
``array_equal``, not a tolerance. Meshes: closed and bordered surfaces, planar (2-D) and
obtuse triangulations, tetrahedra, curves, and the inputs the checks reject.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from decrun import errors
from decrun.core import extension, jit
from decrun.core.complex import SimplicialComplex, checks
from decrun.core.complex.construction import enumerate_faces
from decrun.core.dec import DEC
from decrun.core.simplex_arrays import (
    FaceRows,
    group_rows,
    group_rows_numpy,
    inversion_parity,
    sort_rows,
    sorted_rows_and_parity,
    vertex_volumes,
    vertex_volumes_numpy,
)
from tests.meshes_for_tests import (
    annulus,
    icosphere,
    kuhn_cube,
    planar_domain,
    random_planar,
    random_tets,
    spiral_strip,
)


def _polyline(count: int = 40):
    angle = np.linspace(0, 3 * np.pi, count)
    return np.stack([np.cos(angle), np.sin(angle), 0.1 * angle], axis=1), np.stack(
        [np.arange(count - 1), np.arange(1, count)], axis=1)


MESHES = {
    "icosphere": lambda: icosphere(3),
    "planar with holes": lambda: planar_domain(2, max_area=0.01),
    "annulus": lambda: annulus(max_area=0.01),
    "random planar (obtuse)": lambda: random_planar(150),
    "spiral strip": lambda: spiral_strip(),
    "random tets": lambda: random_tets(60),
    "kuhn cube": lambda: kuhn_cube(4),
    "polyline": _polyline,
}


needs_extension = pytest.mark.skipif(extension.built() is None,
                                     reason="the compiled extension is not built (no C compiler at install)")


def _both(monkeypatch, build):
    """(result with the compiled kernels, result with the numpy twins)."""
    monkeypatch.setenv("DECRUN_NUMBA", "1")
    compiled = build()
    monkeypatch.setenv("DECRUN_NUMBA", "0")
    reference = build()
    monkeypatch.delenv("DECRUN_NUMBA")
    return compiled, reference


def _assert_same(a, b):
    assert type(a) is type(b)
    if isinstance(a, (tuple, list)):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            _assert_same(x, y)
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape
        assert np.array_equal(a, b)
    else:
        assert a == b


def _everything(vertices, simplices):
    K = SimplicialComplex(vertices, simplices, orient="fix")
    n = K.dim
    out = [K.orientation, K.top_volumes, K.edge_lengths()]
    for j in range(n + 1):
        out += [K.simplices(j), K.top_face_indices(j)]
    for j in range(1, n + 1):
        D = K.incidence(j)
        out += [D.data, D.indices, D.indptr, K.facet_indices(j), K.facet_signs(j)]
    if n >= 2:
        dec = DEC(K, star="circumcentric")
        for k in range(n + 1):
            S = dec.star(k)
            out += [dec.primal_volumes(k), dec.dual_volumes(k), S.data, S.indices, S.indptr]
    return out


REJECTED = {
    "index out of range": (np.eye(3), [[0, 1, 2], [0, 2, 7]]),
    "repeated vertex": (np.eye(3), [[0, 1, 2], [0, 2, 2]]),
    "duplicate": (np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]]), [[0, 1, 2], [2, 3, 0], [1, 2, 0]]),
    "fin (edge in three triangles)": (np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [.5, .5, 1]]),
                                      [[0, 1, 2], [0, 2, 3], [0, 2, 4]]),
    "bowtie": (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0.]]), [[0, 1, 2], [0, 3, 4]]),
    "inconsistent orientation": (np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]]), [[0, 1, 2], [0, 2, 3][::-1]]),
    "pinched tets": (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1.]]),
                     [[0, 1, 2, 3], [0, 5, 4, 6]]),
}


@needs_extension
def test_group_rows_kernel_on_wide_buckets_and_duplicates(monkeypatch):
    rng = np.random.default_rng(3)
    # a fan: vertex 0 leads 300 rows (the merge-sorted bucket), plus many duplicates
    fan = np.stack([np.zeros(300, dtype=np.int64), rng.integers(1, 50, 300), rng.integers(50, 90, 300)], axis=1)
    rows = np.vstack([fan, rng.integers(0, 90, (2000, 3)), fan[:40]])
    monkeypatch.setenv("DECRUN_NUMBA", "1")
    for table in (rows, FaceRows(sort_rows(rows), [(0, 1), (0, 2), (1, 2)])):
        _assert_same(group_rows(table), group_rows_numpy(table))


@needs_extension
def test_sorted_rows_and_parity_kernel(monkeypatch):
    rng = np.random.default_rng(4)
    rows = rng.integers(0, 6, (3000, 4))  # repeats and every permutation
    triangles = rng.integers(-2, 12, (500, 3))  # entries out of range on both sides
    for table, n_vertices in ((rows, 6), (rows, 9), (triangles, 10), (triangles[triangles.min(axis=1) >= 0], 12)):
        compiled, reference = _both(monkeypatch, lambda t=table, n=n_vertices: sorted_rows_and_parity(t, n))
        _assert_same(compiled, reference)
        inside = table[(table >= 0) & (table < n_vertices)]
        assert np.array_equal(np.flatnonzero(compiled[5]), np.unique(inside))  # the used vertices


@needs_extension
@pytest.mark.parametrize("dimension", [2, 3])
def test_volume_kernel(dimension, monkeypatch):
    monkeypatch.setenv("DECRUN_NUMBA", "1")
    vertices, faces = icosphere(2)
    vertices = vertices[:, :dimension].copy()
    edges = np.unique(np.sort(faces[:, :2], axis=1), axis=0)
    for simplices in (faces, edges):
        _assert_same(vertex_volumes(vertices, simplices), vertex_volumes_numpy(vertices, simplices))


@needs_extension
@pytest.mark.parametrize("name", ["icosphere", "planar with holes", "random planar (obtuse)"])
def test_edge_lengths_found_by_the_dual_volume_kernel_equal_the_numpy_twins(name, monkeypatch):
    """⋆1 asked first: the triangle dual-volume kernel hands the complex its edge lengths (the
    volume kernel does not run for the edges), and they equal vertex_volumes' numpy twin bit for bit."""
    from decrun.core import simplex_arrays

    vertices, simplices = MESHES[name]()

    def stars_first():
        K = SimplicialComplex(vertices, simplices, orient="fix")
        dec = DEC(K)
        star1 = dec.star(1).diagonal().copy()
        return star1, K.edge_lengths(), dec.primal_volumes(1)

    edge_calls = []

    compiled_module = extension.built()

    class Counting:  # the extension, the volume kernel's calls' corner counts recorded
        def __getattr__(self, name):
            return getattr(compiled_module, name)

        def small_volumes(self, points, corners):
            edge_calls.append(corners.shape[1])
            return compiled_module.small_volumes(points, corners)

    monkeypatch.setattr(simplex_arrays.extension, "kernels",
                        lambda: Counting() if jit.mode() != "numpy" else None)
    compiled, reference = _both(monkeypatch, stars_first)
    assert edge_calls == [3]  # the triangles' areas only: the kernel path measured no edge on its own
    _assert_same(compiled, reference)
    K = SimplicialComplex(vertices, simplices, orient="fix")
    _assert_same(compiled[1], vertex_volumes_numpy(K.vertices, K.simplices(1)))
    assert compiled[2] is not None and np.array_equal(compiled[1], compiled[2])


@needs_extension
@pytest.mark.parametrize("name", ["icosphere", "planar with holes", "spiral strip", "random tets", "kuhn cube"])
def test_fans_kernel_equals_both_numpy_twins(name):
    vertices, simplices = MESHES[name]()
    K = SimplicialComplex(vertices, simplices, orient="fix")
    top, n, nv = K.simplices(K.dim), K.dim, K.num_simplices(0)
    faces = enumerate_faces(top, nv)
    pairs = checks.facet_pairs(faces.facet_order, faces.facet_starts, top, faces.lists[n - 1], True)
    compiled_module = extension.built()
    compiled = compiled_module.fans(top, *pairs[1:], nv)
    _assert_same(compiled, checks.fans_per_vertex_general(top, faces.lists[n - 1], pairs, nv))
    roots, consistent = compiled_module.fan_roots(top, *pairs[1:], K.orientation)
    assert roots == compiled.sum() == nv and consistent  # one fan each, oriented ("fix")
    flipped = K.orientation.copy()
    flipped[pairs.first[0]] *= -1  # one simplex against its neighbours
    assert compiled_module.fan_roots(top, *pairs[1:], flipped) == (nv, False)
    assert compiled_module.consistent(*pairs[1:], flipped) is False
    pairs_numpy, _ = checks.facet_pairs_numpy(faces.facet_order, faces.facet_starts, top)
    _assert_same(tuple(pairs), tuple(pairs_numpy))


@needs_extension
def test_bowtie_fans_counted_alike():
    top = sort_rows(np.array([[0, 1, 2], [0, 3, 4]]))
    faces = enumerate_faces(top, 5)
    pairs = checks.facet_pairs(faces.facet_order, faces.facet_starts, top, faces.lists[1], True)
    orientation = np.ones(2, dtype=np.int8)
    compiled = extension.built().fans(top, *pairs[1:], 5)
    assert compiled[0] == 2
    assert extension.built().fan_roots(top, *pairs[1:], orientation) == (6, True)  # more roots than vertices: name vertex 0
    _assert_same(compiled, checks.fans_per_vertex_general(top, faces.lists[1], pairs, 5))


def _glued_at_vertex_zero(first, second):
    """Two oriented triangle meshes (vertices, faces) with their vertex 0 made one vertex."""
    (v1, f1), (v2, f2) = first, second
    f2 = np.where(f2 == 0, 0, f2 + v1.shape[0] - 1)
    return np.vstack([v1, v2[1:] + [5.0, 0.0, 0.0][:v2.shape[1]]]), np.vstack([f1, f2])


def test_the_numpy_fan_count_finds_every_kind_of_pinched_vertex():
    """A vertex in a closed fan and a border fan, in two closed fans, in two border fans: the
    numpy twin counts two fans there and one everywhere else, and the complex names it."""
    from decrun.core.primitives import grid_triangles

    sphere = icosphere(1)
    disk = grid_triangles(3, 3)
    disk = (np.column_stack([disk[0], np.zeros(len(disk[0]))]), disk[1])
    cases = {"closed + border": _glued_at_vertex_zero(sphere, disk),
             "closed + closed": _glued_at_vertex_zero(sphere, sphere),
             "border + border": _glued_at_vertex_zero(disk, disk)}
    for name, (vertices, faces) in cases.items():
        top = sort_rows(faces)
        parity = inversion_parity(faces)
        built = enumerate_faces(top, vertices.shape[0])
        pairs = checks.facet_pairs(built.facet_order, built.facet_starts, top, built.lists[1], True)
        checks.orient(pairs, parity, "fix", 2)  # orientable: only the vertex is pinched
        counts = checks.fans_per_vertex_general(top, built.lists[1], pairs, vertices.shape[0])
        assert counts[0] == 2 and (counts[1:] == 1).all(), name
        with pytest.raises(errors.NonManifoldError, match="vertex 0: .* 2 separate fans"):
            with jit.use("numpy"):
                SimplicialComplex(vertices, faces, orient="fix")


def test_config_composition_does_not_import_numba():
    code = ("import sys, contextlib, io; from decrun.__main__ import console_main\n"
            "sys.argv = ['decrun', '--cfg', 'job']; shown = io.StringIO()\n"
            "with contextlib.redirect_stdout(shown):\n"
            "    try: console_main()\n"
            "    except SystemExit: pass\n"
            "print('app:' in shown.getvalue(), 'numba' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "True False"  # composed, and numba not imported


FLIP_CASES = {
    "stretched sphere (many rounds)": (lambda: icosphere(3), {"border": "tufted"}, 4.0),
    "planar obtuse, tufted border": (lambda: random_planar(150), {"border": "tufted"}, 4.0),
    "planar obtuse, fixed border": (lambda: random_planar(150), {"border": "fixed"}, 4.0),
    "annulus, mollified": (lambda: annulus(max_area=0.01), {"border": "tufted", "mollify": 1e-5}, 3.0),
    "spiral strip": (lambda: spiral_strip(), {"border": "tufted"}, 3.0),
}


@needs_extension
@pytest.mark.parametrize("name", FLIP_CASES)
def test_flip_rounds_kernel_equals_the_numpy_rounds(name, monkeypatch):
    from decrun.core.intrinsic_delaunay import intrinsic_delaunay

    build, options, stretch = FLIP_CASES[name]
    vertices, faces = build()
    vertices = np.asarray(vertices, dtype=np.float64).copy()
    vertices[:, -1] *= stretch

    def flipped():
        T = intrinsic_delaunay(vertices, faces, **options)
        return [T.faces, T.face_edges, T.edge_lengths, T.edge_sides, T.flips, T.rounds]

    compiled, reference = _both(monkeypatch, flipped)
    assert reference[4] > 0  # the case flips
    _assert_same(compiled, reference)
