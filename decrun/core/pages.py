"""The complex's and the operators' arrays in 4 KiB pages: numpy's huge-page advice set aside.

On Linux numpy advises the kernel to back every array of 4 MiB or more with 2 MiB transparent
huge pages (``madvise(MADV_HUGEPAGE)``, numpy's default). A process touches most of a mesh's
complex and operators for the first time when it builds them (a fresh process, or a sweep worker
whose previous mesh's memory went back to the system), so the build pays the first touch of that
memory: zeroed pages, one fault each. On this project's machine (a virtual machine) the first
touch of huge pages cost several times more in some processes than in others, while 4 KiB pages
cost the same in every process; C++ libraries that allocate with ``malloc`` (libigl's Eigen)
never ask for huge pages either.

:func:`small_pages` sets numpy's advice aside while the complex and its operators are built,
and restores the setting it found (nested and concurrent blocks share one setting: the first
to enter sets it aside, the last to leave restores it; another thread allocating meanwhile
gets 4 KiB pages too). Nothing else changes: the arrays, their values and the computation are
the same.
"""

from __future__ import annotations

import threading
from contextlib import contextmanager
from typing import Callable, Iterator

__all__ = ["small_pages", "huge_page_advice"]

_lock = threading.Lock()
_depth = 0
_saved: bool | None = None


def _switch() -> Callable[[bool], bool] | None:
    """numpy's ``_set_madvise_hugepage(enabled) -> previous`` (numpy 2's location, then 1.x's),
    or None where numpy has none (not Linux, or another numpy)."""
    try:
        from numpy._core.multiarray import _set_madvise_hugepage  # type: ignore[attr-defined]
    except ImportError:
        try:
            from numpy.core.multiarray import _set_madvise_hugepage  # type: ignore[attr-defined,no-redef]
        except ImportError:
            return None
    return _set_madvise_hugepage


def huge_page_advice() -> bool | None:
    """Whether numpy now advises huge pages for its large arrays (None: numpy has no such switch);
    read by setting it and putting it back, numpy's only way to read it."""
    switch = _switch()
    if switch is None:
        return None
    current = switch(True)
    switch(current)
    return current


@contextmanager
def small_pages() -> Iterator[None]:
    """Within the block numpy allocates without huge-page advice (see the module docstring);
    the setting found on entry is restored when the outermost block exits."""
    global _depth, _saved
    switch = _switch()
    if switch is None:
        yield
        return
    with _lock:
        if _depth == 0:
            _saved = switch(False)
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                switch(bool(_saved))
                _saved = None
