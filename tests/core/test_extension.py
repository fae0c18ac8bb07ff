"""The compiled extension ``decrun.core._kernels`` (:mod:`decrun.core.extension`): the complex and
its operators built through it equal the numpy twins' bit for bit, ``auto`` and ``numba`` run it at
every size, ``numpy`` never, and a fresh process builds a complex and its operators through it
without importing numba.

The extension is optional (an install without a C compiler leaves it out): these tests skip
without it, except under ``CI=true``, where the install must have built it.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from decrun.core import extension, jit
from decrun.core.complex import SimplicialComplex
from decrun.core.simplex_arrays import FaceRows, group_rows, group_rows_numpy, sort_rows, sorted_rows_and_parity
from decrun.errors import NonManifoldError
from tests.core.test_kernels import MESHES, REJECTED, _assert_same, _everything

BUILT = extension.built() is not None
needs_extension = pytest.mark.skipif(not BUILT, reason="the compiled extension is not built (no C compiler at install)")


def test_the_install_built_the_extension_where_ci_requires_it():
    if not BUILT:
        ci = os.environ.get("CI") == "true"
        assert not ci, "decrun.core._kernels is not built: pip install -e . needs a C compiler and Python's headers"
        pytest.skip("the compiled extension is not built (no C compiler at install)")
    from importlib.machinery import EXTENSION_SUFFIXES

    from decrun.core import _kernels  # type: ignore[attr-defined]

    assert _kernels.__file__.endswith(tuple(EXTENSION_SUFFIXES))  # machine code, not a Python module


@pytest.fixture
def counted(monkeypatch):
    """{kernel name: calls}, the extension's kernels wrapped to count (auto, DECRUN_NUMBA unset)."""
    monkeypatch.delenv("DECRUN_NUMBA", raising=False)
    calls: dict = {}
    module = extension.built()

    class Counting:
        def __getattr__(self, name):
            kernel = getattr(module, name)

            def counting(*args):
                calls[name] = calls.get(name, 0) + 1
                return kernel(*args)
            return counting

    monkeypatch.setattr(extension, "_module", Counting() if module is not None else None)
    monkeypatch.setattr(extension, "_searched", True)
    return calls


@needs_extension
@pytest.mark.parametrize("name", MESHES)
def test_the_extension_equals_the_numpy_twins(name, counted):
    vertices, simplices = MESHES[name]()
    with jit.use("auto"):
        compiled = _everything(vertices, simplices)
    assert counted, "auto ran no twin"
    with jit.use("numpy"):
        reference = _everything(vertices, simplices)
    _assert_same(compiled, reference)


@needs_extension
def test_auto_runs_every_twin_on_a_triangle_mesh_at_any_size(counted):
    """A triangle mesh's edges are grouped and paired by the fused facet twin (the grouping and
    pairing twins run inside it); a tetrahedral mesh's edges take the grouping twin itself. The
    fans are counted per vertex only where the fans around all vertices outnumber them (a pinched
    vertex to name); the fan roots' twin tests the orientation too, so the orientation's own twin
    runs where the stars are not checked (a curve)."""
    vertices, simplices = MESHES["annulus"]()  # a few hundred triangles
    with jit.use("auto"):
        _everything(vertices, simplices)
    assert set(counted) == {"sorted_rows", "facet_groups", "fan_roots", "small_volumes", "triangle_dual", "incidence"}
    with jit.use("auto"):
        _everything(*MESHES["polyline"]())
    assert "consistent" in counted
    with jit.use("auto"), pytest.raises(NonManifoldError, match="vertex 0"):
        SimplicialComplex(*REJECTED["bowtie"])
    assert counted["fans"] == 1
    with jit.use("auto"):
        _everything(*MESHES["kuhn cube"]())
    assert "group_packed" in counted


@needs_extension
@pytest.mark.parametrize("name", REJECTED)
def test_rejected_inputs_fail_the_same_way_with_the_extension(name, counted):
    from decrun import errors

    vertices, simplices = REJECTED[name]

    def attempt(mode):
        with jit.use(mode):
            try:
                SimplicialComplex(vertices, np.array(simplices))
            except errors.MeshError as exc:
                return type(exc).__name__, str(exc)
        return None

    compiled = attempt("auto")
    assert compiled is not None and compiled == attempt("numpy")


@needs_extension
def test_group_rows_and_row_sorting_twins_on_wide_buckets_and_repeats(counted):
    rng = np.random.default_rng(3)
    fan = np.stack([np.zeros(300, dtype=np.int64), rng.integers(1, 50, 300), rng.integers(50, 90, 300)], axis=1)
    rows = np.vstack([fan, rng.integers(0, 90, (2000, 3)), fan[:40]])  # a merge-sorted bucket, duplicates
    for table in (rows, FaceRows(sort_rows(rows), [(0, 1), (0, 2), (1, 2)])):
        _assert_same(group_rows(table), group_rows_numpy(table))
    wide = rng.integers(0, 6, (3000, 4))  # repeated entries and every permutation
    with jit.use("auto"):
        compiled = sorted_rows_and_parity(wide, 8)  # two vertices unused
    with jit.use("numpy"):
        _assert_same(compiled, sorted_rows_and_parity(wide, 8))
    assert compiled[5].tolist() == [True] * 6 + [False] * 2
    assert counted["group_packed"] == 2
    assert counted["sorted_rows"] == 1


@needs_extension
def test_the_triangle_edge_grouping_equals_the_general_loops():
    """The extension groups a triangle mesh's edge slots with loops unrolled over the three slots
    (C-contiguous rows); other layouts take its general loops: both equal the numpy twin, also
    for rows that are not sorted (the leading entry is then not the smallest)."""
    from decrun.core import _kernels  # type: ignore[attr-defined]

    rng = np.random.default_rng(5)
    rows = np.vstack([rng.integers(0, 70, (2500, 3)), np.zeros((40, 3), dtype=np.int64) + [0, 1, 2]])
    columns = np.array([(0, 1), (0, 2), (1, 2)], dtype=np.int64)
    bits = max(1, int(np.ceil(np.log2(rows.max() + 2))))
    for top in (rows, sort_rows(rows), np.asfortranarray(sort_rows(rows)), np.asfortranarray(rows)):
        reference = group_rows_numpy(FaceRows(np.ascontiguousarray(top), [(0, 1), (0, 2), (1, 2)]))
        _assert_same(_kernels.group_packed(top, columns, bits), reference)


@needs_extension
def test_the_fused_triangle_edge_groups_and_pairs_equal_the_numpy_twins():
    """The fused twin of a triangle mesh's edge grouping and facet pairing (one counting sort,
    the pairs and their duplicate suspicion read off the sorted buckets) equals the numpy twins
    — on wide (merge-sorted) buckets, edges in one, two and three triangles, duplicates, rows
    that are not sorted, Fortran layout and sparse indices (the general loops)."""
    from decrun.core import _kernels  # type: ignore[attr-defined]
    from decrun.core.complex import checks

    rng = np.random.default_rng(11)
    fan = np.stack([np.zeros(300, dtype=np.int64), rng.integers(1, 50, 300), rng.integers(50, 90, 300)], axis=1)
    sphere = np.asarray(MESHES["icosphere"]()[1], dtype=np.int64) + 90
    rows = np.vstack([fan, rng.integers(0, 90, (2000, 3)), fan[:40], sphere])
    columns = np.array([(0, 1), (0, 2), (1, 2)], dtype=np.int64)
    cases = [(sort_rows(rows), np.int32), (rows, np.int32), (np.asfortranarray(sort_rows(rows)), np.int32),
             (sort_rows(rows), np.int64), (sort_rows(sphere), np.int32), (sort_rows(np.vstack([sphere, [[2, 0, 1], [0, 1, 2]]])), np.int32),
             (sort_rows(np.vstack([fan, fan[:3] * 5000])), np.int32)]  # sparse indices: the general loops
    suspicions = []
    for top, index_type in cases:
        bits = max(1, int(np.ceil(np.log2(top.max() + 2))))
        groups, pairs, suspect = _kernels.facet_groups(top, columns, bits, np.zeros(0, index_type))
        contiguous = np.ascontiguousarray(top)
        _assert_same(groups, group_rows_numpy(FaceRows(contiguous, [(0, 1), (0, 2), (1, 2)])))
        reference, reference_suspect = checks.facet_pairs_numpy(groups[2], groups[3], contiguous)
        _assert_same(tuple(a.astype(index_type) for a in pairs[1:]), tuple(a.astype(index_type) for a in reference[1:]))
        _assert_same(pairs[0], reference.facet)
        assert [a.dtype for a in pairs[1:]] == [np.dtype(index_type)] * 4
        assert suspect == reference_suspect
        suspicions.append(suspect)
    assert suspicions[-3:-1] == [False, True]  # a closed sphere has no duplicate; a triangle twice (beside it) is suspected


def test_without_the_extension_the_numpy_twins_build_the_same(monkeypatch):
    """An install without a C compiler: every switch value builds with the numpy twins, numba unused."""
    vertices, simplices = MESHES["annulus"]()
    with jit.use("numpy"):
        reference = _everything(vertices, simplices)
    monkeypatch.setattr(extension, "_searched", True)
    monkeypatch.setattr(extension, "_module", None)
    for mode in ("auto", "numba"):
        with jit.use(mode):
            _assert_same(_everything(vertices, simplices), reference)


@needs_extension
def test_numpy_mode_does_not_run_the_extension_and_numba_mode_does(counted):
    vertices, simplices = MESHES["icosphere"]()
    with jit.use("numpy"):
        _everything(vertices, simplices)
    assert not counted
    with jit.use("numba"):
        _everything(vertices, simplices)
    assert counted


@needs_extension
def test_a_fresh_process_builds_the_operators_without_starting_numba():
    code = ("import sys; from decrun.core.complex import SimplicialComplex; from decrun.core.dec import DEC; "
            "from decrun.core import jit; from tests.meshes_for_tests import icosphere; V, F = icosphere(4); "
            "dec = DEC(SimplicialComplex(V, F)); ops = [dec.d(0), dec.d(1)] + [dec.star(k) for k in range(3)]; "
            "print(float(dec.star(0).diagonal().sum()), 'numba' in sys.modules, jit.started())")
    env = {k: v for k, v in os.environ.items() if k != "DECRUN_NUMBA"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env,
                         cwd=os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    area, imported, started = out.stdout.split()
    assert abs(float(area) - 4 * np.pi) < 0.01 * 4 * np.pi  # ⋆0 sums to the sphere's area
    assert (imported, started) == ("False", "False")
