"""The complex and its operators are built in 4 KiB pages (numpy's huge-page advice set aside and
restored), and the diagonal ⋆ matrices hold their diagonals without copies."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import scipy.sparse as sp

from decrun.core import pages
from decrun.core.complex import SimplicialComplex, checks
from decrun.core.dec import DEC, diagonal_matrix
from decrun.core.primitives import grid_triangles

pytestmark = pytest.mark.skipif(pages.huge_page_advice() is None, reason="this numpy has no huge-page switch")


@pytest.fixture
def advice():
    """numpy's advice as found, restored after the test whatever it set."""
    switch = pages._switch()
    found = switch(True)
    switch(found)
    yield switch
    switch(found)


@pytest.mark.parametrize("initial", [True, False])
def test_small_pages_sets_the_advice_aside_and_restores_it(advice, initial):
    advice(initial)
    with pages.small_pages():
        assert pages.huge_page_advice() is False
        with pages.small_pages():  # nested: the inner exit does not restore yet
            assert pages.huge_page_advice() is False
        assert pages.huge_page_advice() is False
    assert pages.huge_page_advice() is initial


def test_small_pages_restores_after_an_exception(advice):
    advice(True)
    with pytest.raises(ValueError):
        with pages.small_pages():
            raise ValueError("inside")
    assert pages.huge_page_advice() is True


def test_concurrent_blocks_restore_once_the_last_leaves(advice):
    advice(True)
    entered, release = threading.Barrier(2), threading.Event()
    seen = []

    def worker():
        with pages.small_pages():
            entered.wait()
            release.wait()
            seen.append(pages.huge_page_advice())

    thread = threading.Thread(target=worker)
    thread.start()
    with pages.small_pages():
        entered.wait()
    assert pages.huge_page_advice() is False  # the other block is still inside
    release.set()
    thread.join()
    assert seen == [False]
    assert pages.huge_page_advice() is True


def test_the_build_and_the_operators_run_without_huge_page_advice(advice, monkeypatch):
    """Inside the complex's build and the computation of d and ⋆ the advice is off; after them
    it is what it was."""
    advice(True)
    during = []
    for module, name in ((checks, "facet_pairs"), (checks, "check_degenerate")):
        original = getattr(module, name)

        def spy(*args, _original=original, **kwargs):
            during.append(pages.huge_page_advice())
            return _original(*args, **kwargs)

        monkeypatch.setattr(module, name, spy)
    V, F = grid_triangles(6, 5, jitter=0.2)
    K = SimplicialComplex(V, F)
    assert during == [False, False] and pages.huge_page_advice() is True
    dec = DEC(K)
    monkeypatch.setattr(DEC, "dual_volumes", lambda self, k: during.append(pages.huge_page_advice())
                        or np.ones(K.num_simplices(k)))
    dec.star(1)
    dec.d(0)
    assert during == [False, False, False] and pages.huge_page_advice() is True


def test_diagonal_matrix_holds_its_diagonal_without_copies():
    diagonal = np.array([2.0, -0.5, 3.0, 1e-3])
    M = diagonal_matrix(diagonal)
    assert np.shares_memory(M.data, diagonal)  # the data is the diagonal itself
    assert np.shares_memory(M.indices, M.indptr)  # one 0..n array: row pointers and column indices
    assert M.indices.dtype == M.indptr.dtype == np.int32
    np.testing.assert_array_equal(M.toarray(), np.diag(diagonal))
    x = np.array([1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(M @ x, diagonal * x)
    np.testing.assert_array_equal((M + M.T).toarray(), 2 * np.diag(diagonal))
    M.sort_indices()
    M.sum_duplicates()
    assert M.has_canonical_format and (M != sp.diags(diagonal)).nnz == 0
    # a zero on the diagonal is left out, as sp.diags(...).tocsr() leaves it
    Z = diagonal_matrix(np.array([1.0, 0.0, 2.0]))
    assert Z.nnz == 2 and not np.shares_memory(Z.data, diagonal)


def test_star_matrix_data_is_the_cached_diagonal():
    V, F = grid_triangles(5, 4, jitter=0.2)
    dec = DEC(SimplicialComplex(V, F))
    for k in range(3):
        star = dec.star(k)
        assert np.shares_memory(star.data, dec.star_diagonal(k))
        np.testing.assert_array_equal(star.diagonal(), dec.dual_volumes(k) / dec.primal_volumes(k))


def test_the_shared_diagonal_is_read_only_so_no_caller_changes_the_other():
    """``star(k)`` and ``star_diagonal(k)`` are one array: writing into either must fail loudly
    rather than change the other (and every later use of the cached operator)."""
    V, F = grid_triangles(5, 4, jitter=0.2)
    dec = DEC(SimplicialComplex(V, F))
    for k in range(3):
        diagonal = dec.star_diagonal(k)
        before = diagonal.copy()
        with pytest.raises(ValueError, match="read-only"):
            diagonal[0] = 7.0
        with pytest.raises(ValueError, match="read-only"):
            dec.star(k).data[0] = 7.0
        np.testing.assert_array_equal(dec.star_diagonal(k), before)
        scaled = 2.0 * dec.star(k)  # arithmetic makes new matrices, as before
        np.testing.assert_array_equal(scaled.diagonal(), 2.0 * before)
