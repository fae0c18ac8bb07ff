"""How many threads the parallel kernels use (:func:`threads`: the CPU affinity's count) and
on which threading layer (:func:`threading_layer`: OpenMP where numba finds it)."""

from __future__ import annotations

import os
from typing import Any

__all__ = ["threads", "threading_layer"]


def threads() -> int:
    """How many threads the parallel kernels (``parallel=True``, ``prange``) split their work into:
    numba's thread count — ``NUMBA_NUM_THREADS`` if set (joblib's workers set it to their share of
    the cores), else the cores this process may run on (its CPU affinity: a SLURM job's
    ``cpus_per_task``, ``taskset``), which numba's own default (every core of the machine) ignores.
    Their results do not depend on it: each thread takes a contiguous block of independent items.
    Imports numba: call it only where a kernel runs."""
    import numba

    threading_layer(numba)
    global _affinity_applied
    if not _affinity_applied and "NUMBA_NUM_THREADS" not in os.environ and hasattr(os, "sched_getaffinity"):
        _affinity_applied = True
        usable = len(os.sched_getaffinity(0))
        if 0 < usable < numba.get_num_threads():
            numba.set_num_threads(usable)
    return int(numba.get_num_threads())


_affinity_applied = False  # the affinity cap is applied once per process (a later set_num_threads wins)


def threading_layer(numba: Any) -> None:
    """Before numba starts its threads: OpenMP where numba finds it (libgomp on Linux), else
    numba's own pool ``workqueue``, unless ``NUMBA_THREADING_LAYER`` or
    ``NUMBA_THREADING_LAYER_PRIORITY`` says otherwise; no TBB (an old TBB only warns).

    OpenMP, because the calling thread works one block itself and the other threads spin a
    moment after a region before they sleep, so the next region starts on cores that are awake.
    workqueue's threads sleep, and a region that follows a millisecond of serial Python (every
    step of the fluid) ran its two blocks one after the other on a 2-core machine: 3.5 ms instead
    of 1.7 ms for two 1.65 ms blocks; the fluid's 20,480-face sphere stepped 1.44× faster on
    OpenMP (``benchmarks/bench_fluid_kernels.py``). GNU OpenMP is not fork-safe: a forked child
    whose parent ran a parallel region runs the kernels' serial versions (:func:`.forks.forked`)."""
    chosen = {"NUMBA_THREADING_LAYER", "NUMBA_THREADING_LAYER_PRIORITY"} & set(os.environ)
    if not chosen and numba.config.THREADING_LAYER == "default":
        numba.config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]
