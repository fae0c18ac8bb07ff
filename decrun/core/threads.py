"""One BLAS thread inside a step: the fluid's parallel kernels and the BLAS do not share the cores.

numpy's and scipy's BLAS (OpenBLAS here; MKL or BLIS elsewhere) thread their level-1 calls — the
inner products ⟨⋆0 w, w⟩, ⟨u, ⋆1 u⟩ of every step — from about 10,000 entries on, and their
threads then spin for a while after each call. Next to numba's parallel kernels (two threads on a
2-core machine) the spinning threads took the cores: a 20,480-face sphere step took 157 ms instead
of 22 ms (and 31 ms instead of 24 ms with one numba thread). Inner products of mesh vectors gain
nothing from threads, so a step runs them on one (``threadpoolctl``, the scientific-Python standard
for this; the limit is restored after the block, so nothing else in the process changes).

And short spins for idle threads, set by the ``decrun`` command before the libraries load: GNU
OpenMP's (:func:`bound_openmp_spin`) and OpenBLAS's (:func:`bound_blas_spin`).
"""

from __future__ import annotations

import os
from contextlib import contextmanager

__all__ = ["one_blas_thread", "bound_openmp_spin", "OPENMP_SPIN", "bound_blas_spin", "BLAS_SPIN"]

#: GNU OpenMP's ``GOMP_SPINCOUNT`` decrun sets when the environment sets no wait policy
OPENMP_SPIN = "10000"
#: OpenBLAS's ``OPENBLAS_THREAD_TIMEOUT`` decrun sets: an idle thread spins 2**20 cycles
#: (under a millisecond) before it sleeps, against OpenBLAS's default 2**28 (about 0.1 s)
BLAS_SPIN = "20"


def bound_openmp_spin() -> None:
    """``GOMP_SPINCOUNT=10000`` unless the environment sets ``GOMP_SPINCOUNT`` or ``OMP_WAIT_POLICY``.

    The fluid's parallel kernels run on OpenMP (:func:`decrun.core.jit.threading_layer`); after a
    region GNU OpenMP's idle threads spin 300,000 rounds (its default) before they sleep. On idle
    cores that keeps them awake between a step's regions, but where processes outnumber the cores
    they spin on cores others need: the fluid tests on four pytest workers over two cores took 40 s
    instead of 30 s. 10,000 rounds (tens of µs) kept the single run's speed (the 20,480-face sphere
    113 against 115 steps/s, the channel 58 against 58, within noise) and the four workers' 32 s.
    libgomp reads it once, when first loaded — by pymeshlab, which bundles it, on importing it — so
    this runs at ``import decrun``; a process that loaded libgomp before keeps its setting."""
    if "GOMP_SPINCOUNT" not in os.environ and "OMP_WAIT_POLICY" not in os.environ:
        os.environ["GOMP_SPINCOUNT"] = OPENMP_SPIN


def bound_blas_spin() -> None:
    """``OPENBLAS_THREAD_TIMEOUT=20`` unless the environment sets it.

    OpenBLAS starts its worker threads when it loads (with numpy, and again with scipy, which
    bundles its own), and an idle worker spins 2**28 cycles (its default, about 0.1 s) before it
    sleeps: at ``import numpy, scipy`` the two workers spun 0.07-0.09 s of CPU between them that
    nothing asked for, taken from the other processes on a busy machine (the small run's imports
    used more CPU than wall time). 2**20 cycles still keeps the workers awake between BLAS calls
    that follow each other within a fraction of a millisecond. Only the wait changes: the number
    of threads and every result stay the same. OpenBLAS reads the variable when it loads, so the
    command sets it before numpy is imported; a process that loaded OpenBLAS before keeps its
    setting."""
    if "OPENBLAS_THREAD_TIMEOUT" not in os.environ:
        os.environ["OPENBLAS_THREAD_TIMEOUT"] = BLAS_SPIN


_controller = None


@contextmanager
def one_blas_thread():
    """Within the block every BLAS library loaded in the process runs one thread (restored after).

    The libraries are looked up once per process, on the first call (~3 ms); later calls cost ~7 µs.
    """
    global _controller
    if _controller is None:
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController()
    with _controller.limit(limits=1, user_api="blas"):
        yield
