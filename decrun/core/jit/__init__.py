"""Compiled kernels without paying for numba at import time, and the one switch that picks them.

``@njit`` (or ``@njit(**numba_options)``) marks a kernel written in numba's subset of Python;
it is compiled by ``numba.njit(cache=True, **numba_options)`` on its **first call** (a kernel
may call the other kernels of its module), so ``import decrun`` and ``decrun --help`` never
import numba, and the machine code is cached next to the module (``__pycache__``): a sweep
compiles once per install, not once per job. Every kernel is listed in :data:`KERNELS`.

Every kernel lives next to its numpy twin, which stays the reference the tests compare it
with. A caller takes the kernel when :func:`enabled` says so. **The switch** (:func:`mode`) is
``auto`` | ``numba`` | ``numpy``, the same three words everywhere:

* the config key ``app.kernels`` (the runner applies it with :func:`use` around the whole job:
  mesh, complex, operators and app), when it is not ``auto``;
* else the environment variable ``DECRUN_NUMBA``: ``numba`` (or ``1``) always the kernels,
  ``numpy`` (or ``0``) never (to rule out a kernel when chasing a bug), ``auto`` or unset;
* ``auto``: a kernel runs from its caller's ``min_size`` items on — by default
  :data:`MIN_SIZE`, where the time saved outweighs what a fresh process pays once to import
  numba and start it (its typing registries, then each cached kernel's machine code;
  ``benchmarks/bench_operators.py --jit``); the fluid's kernels run at any size (a run steps
  hundreds of times). Once that price is paid — a kernel ran in this process — kernels
  run from :data:`WARM_MIN_SIZE` items on (loading one more cached kernel is cheap).
  A long-lived process (a sweep worker building one mesh after another) pays it when the numpy
  work it did on inputs of at least :data:`WARM_MIN_SIZE` items adds up to
  :data:`AMORTIZE_SIZE` items, about the time the start costs (rent until the rent paid equals
  the price, then buy: never more than twice the better choice in hindsight).

``numpy`` never imports numba; ``numba`` runs every kernel on the path (``tests/core/test_jit.py``).

**The compiled extension.** The kernels of the complex and its operators (row sorting and
grouping, facet pairs, orientation, vertex fans, volumes, dual volumes, incidence) also have
twins in ``decrun.core._kernels``, a Cython extension the install builds where a C compiler is
found (optional: without one it is left out). Under ``auto`` such a kernel runs as its twin at
every size (:meth:`.kernels.LazyKernel.runs`): machine code that loads with its module, so a
fresh process gets it without numba's start; ``numba`` and ``numpy`` keep their meaning.

A kernel numba must compile (its disk cache holds no machine code for it) calls
:data:`compile_notice` first, once per process, so a caller can say why the first step waits.

One module per concern: :mod:`.switch` (the switch, and whether numba started in this process),
:mod:`.kernels` (lazy compilation and the compile notice),
:mod:`.signals` (a signal handler's exception out of a kernel call), :mod:`.threads` (how
many threads, on which threading layer), :mod:`.forks` (one parallel region at a time, and
fork safety on GNU OpenMP).
"""

from __future__ import annotations

from typing import Callable

from decrun.core.jit.kernels import KERNELS, njit, prange
from decrun.core.jit.switch import (
    AMORTIZE_SIZE,
    MIN_SIZE,
    MODES,
    WARM_MIN_SIZE,
    check_mode,
    enabled,
    mode,
    started,
    use,
)
from decrun.core.jit.threads import threading_layer, threads

__all__ = ["njit", "enabled", "started", "mode", "use", "check_mode", "threads", "threading_layer", "prange",
           "MIN_SIZE", "WARM_MIN_SIZE", "AMORTIZE_SIZE", "MODES", "KERNELS", "compile_notice"]

#: called once per process, with the kernel's name, just before numba compiles a kernel its disk
#: cache has no machine code for (the first run of an install, or after the source changed), so
#: a caller can say why the first step waits; None: nothing is said (this layer prints nothing).
#: A setting of the package: callers assign ``jit.compile_notice = ...`` and
#: :func:`.kernels.announce_compile` reads it here at the moment of compiling.
compile_notice: Callable[[str], None] | None = None
