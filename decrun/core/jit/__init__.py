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
* else the environment variable ``DECRUN_NUMBA``: ``numba`` (or ``1``) the compiled kernels,
  ``numpy`` (or ``0``) never (to rule out a kernel when chasing a bug), ``auto`` or unset;
* ``auto`` and ``numba``: the compiled kernels — the fluid's numba kernels, and the core's
  compiled extension (:mod:`decrun.core.extension`, Cython, built by the install: the complex's,
  the operators' and the intrinsic Delaunay kernels; numba compiles none of the core's);
  ``numpy``: their numpy twins, and numba is never imported (``tests/core/test_jit.py``).

A kernel numba starts to compile (its disk cache holds no machine code for it) calls
:data:`compile_notice`, once per process, so a caller can say why the first step waits.

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
    MODES,
    check_mode,
    enabled,
    mode,
    started,
    use,
)
from decrun.core.jit.threads import threading_layer, threads

__all__ = ["njit", "enabled", "started", "mode", "use", "check_mode", "threads", "threading_layer", "prange",
           "MODES", "KERNELS", "compile_notice"]

#: called once per process, with the kernel's name, just before numba compiles a kernel its disk
#: cache has no machine code for (the first run of an install, or after the source changed), so
#: a caller can say why the first step waits; None: nothing is said (this layer prints nothing).
#: A setting of the package: callers assign ``jit.compile_notice = ...`` and
#: :func:`.kernels.announce_compile` reads it here at the moment numba starts compiling.
compile_notice: Callable[[str], None] | None = None
