"""One BLAS thread inside a step: the fluid's parallel kernels and the BLAS do not share the cores.

numpy's and scipy's BLAS (OpenBLAS here; MKL or BLIS elsewhere) thread their level-1 calls — the
inner products ⟨⋆0 w, w⟩, ⟨u, ⋆1 u⟩ of every step — from about 10,000 entries on, and their
threads then spin for a while after each call. Next to numba's parallel kernels (two threads on a
2-core machine) the spinning threads took the cores: a 20,480-face sphere step took 157 ms instead
of 22 ms (and 31 ms instead of 24 ms with one numba thread). Inner products of mesh vectors gain
nothing from threads, so a step runs them on one (``threadpoolctl``, the scientific-Python standard
for this; the limit is restored after the block, so nothing else in the process changes).

And a short spin for GNU OpenMP's idle threads (:func:`bound_openmp_spin`, at ``import decrun``).
"""

from __future__ import annotations

import os
from contextlib import contextmanager

__all__ = ["one_blas_thread", "bound_openmp_spin", "OPENMP_SPIN"]

#: GNU OpenMP's ``GOMP_SPINCOUNT`` decrun sets when the environment sets no wait policy
OPENMP_SPIN = "10000"


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
