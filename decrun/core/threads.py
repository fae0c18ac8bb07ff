"""One BLAS thread inside a step: the fluid's parallel kernels and the BLAS do not share the cores.

numpy's and scipy's BLAS (OpenBLAS here; MKL or BLIS elsewhere) thread their level-1 calls — the
inner products ⟨⋆0 w, w⟩, ⟨u, ⋆1 u⟩ of every step — from about 10,000 entries on, and their
threads then spin for a while after each call. Next to numba's parallel kernels (two threads on a
2-core machine) the spinning threads took the cores: a 20,480-face sphere step took 157 ms instead
of 22 ms (and 31 ms instead of 24 ms with one numba thread). Inner products of mesh vectors gain
nothing from threads, so a step runs them on one (``threadpoolctl``, the scientific-Python standard
for this; the limit is restored after the block, so nothing else in the process changes).
"""

from __future__ import annotations

from contextlib import contextmanager

__all__ = ["one_blas_thread"]

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
