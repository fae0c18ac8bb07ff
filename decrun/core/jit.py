"""Compiled kernels without paying for numba at import time.

``@njit`` marks a kernel written in numba's subset of Python; it is compiled by
``numba.njit(cache=True)`` on its **first call** (a kernel may call the other kernels of its
module) (so ``import decrun`` and ``decrun --help``
never import numba) and the machine code is cached next to the module (``__pycache__``): a
sweep compiles once per install, not once per job.

Every kernel lives next to its numpy twin, which stays the reference the tests compare it
with, and both give the same bits. A caller takes the kernel when :func:`enabled` says so for
the size of its input: by default from :data:`MIN_SIZE` items on, where the time saved
outweighs what a fresh process pays once to import numba and load the cached kernels
(~0.7 s on an idle 2-core machine; ``benchmarks/bench_operators.py --jit``). The environment
variable ``DECRUN_NUMBA`` overrides it: ``1`` always the kernels, ``0`` always numpy (to rule
out a kernel when chasing a bug).
"""

from __future__ import annotations

import os
from functools import update_wrapper

__all__ = ["njit", "enabled", "MIN_SIZE"]

#: inputs from this many items (simplices, faces, rows) on take the compiled kernels
MIN_SIZE = 500_000


def enabled(size: int | None = None) -> bool:
    """Whether to run the kernel for an input of ``size`` items (None: any size):
    ``DECRUN_NUMBA=1`` always, ``0`` never, unset from :data:`MIN_SIZE` items on."""
    setting = os.environ.get("DECRUN_NUMBA", "")
    if setting in ("0", "1"):
        return setting == "1"
    return size is None or size >= MIN_SIZE


class _LazyKernel:
    """A Python function compiled with ``numba.njit(cache=True)`` on its first call."""

    def __init__(self, function):
        self.function = function
        self.compiled = None
        update_wrapper(self, function)

    def dispatcher(self):
        """The numba dispatcher (created once; it compiles per argument types when called).

        Kernels called from this one must be numba functions when it is compiled: every
        lazy kernel among the module's globals is replaced by its dispatcher first."""
        if self.compiled is None:
            import numba

            namespace = self.function.__globals__
            self.compiled = numba.njit(cache=True)(self.function)
            for name, value in list(namespace.items()):
                if isinstance(value, _LazyKernel):
                    namespace[name] = value.dispatcher()
        return self.compiled

    def __call__(self, *args):
        return self.dispatcher()(*args)


def njit(function):
    """Decorator: ``function`` becomes a kernel compiled (and disk-cached) at first call."""
    return _LazyKernel(function)
