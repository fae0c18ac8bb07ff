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
  numba and load the cached kernels (~0.7 s on an idle 2-core machine;
  ``benchmarks/bench_operators.py --jit``); the fluid's kernels run at any size (a run steps
  hundreds of times).

``numpy`` never imports numba; ``numba`` runs every kernel on the path (``tests/core/test_jit.py``).

One module per concern: :mod:`.switch` (the switch), :mod:`.kernels` (lazy compilation),
:mod:`.signals` (a signal handler's exception out of a kernel call), :mod:`.threads` (how
many threads, on which threading layer), :mod:`.forks` (one parallel region at a time, and
fork safety on GNU OpenMP).
"""

from __future__ import annotations

from decrun.core.jit.kernels import KERNELS, njit, prange
from decrun.core.jit.switch import MIN_SIZE, MODES, check_mode, enabled, mode, use
from decrun.core.jit.threads import threading_layer, threads

__all__ = ["njit", "enabled", "mode", "use", "check_mode", "threads", "threading_layer", "prange", "MIN_SIZE",
           "MODES", "KERNELS"]
