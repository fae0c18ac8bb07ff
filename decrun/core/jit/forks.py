"""One parallel region at a time in the process (:data:`PARALLEL`), and fork safety: a child
forked after parallel kernels ran on GNU OpenMP runs their serial versions (:func:`forked`)."""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass

__all__ = ["PARALLEL", "state", "forked"]

#: numba's workqueue thread pool must not be entered by two threads at once (it aborts the process:
#: "not threadsafe ... concurrent access"); a sweep run by a thread pool (joblib's threading backend)
#: would, where OpenMP is not found. Python callers of the parallel kernels take this lock, so such
#: calls wait for each other (on OpenMP too: two regions at once would only share the cores).
PARALLEL = threading.Lock()


@dataclass
class ForkState:
    """What a fork needs to know of this process's parallel kernels."""

    #: a parallel kernel ran in this process (numba's threads started)
    parallel_ran: bool = False
    #: this process was forked after a parallel region on OpenMP
    child_of_openmp: bool = False


state = ForkState()


def forked() -> None:
    """In a forked child: when the parent ran a parallel kernel on GNU OpenMP, numba terminates a
    child that enters OpenMP ("fork() called from a process already using GNU OpenMP, this is
    unsafe"); the child then calls the kernels' serial versions (:meth:`.kernels.LazyKernel.serial_dispatcher`),
    which give the same bits. (Forking before any parallel kernel ran, or after workqueue ran, is safe.)"""
    if state.parallel_ran and not state.child_of_openmp:
        import sys

        numba = sys.modules.get("numba")
        try:
            layer = numba.threading_layer() if numba is not None else None
        except ValueError:  # no layer started
            layer = None
        state.child_of_openmp = layer == "omp"


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=forked)
