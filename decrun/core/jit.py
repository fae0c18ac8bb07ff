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
"""

from __future__ import annotations

import os
import threading
from contextlib import contextmanager
from functools import update_wrapper

from decrun.errors import ConfigError

__all__ = ["njit", "enabled", "started", "mode", "use", "check_mode", "threads", "prange", "MIN_SIZE", "WARM_MIN_SIZE",
           "AMORTIZE_SIZE", "MODES", "KERNELS"]

#: ``for i in prange(n)`` in a kernel: numba's parallel loop once the kernel is compiled with
#: ``parallel=True`` (the dispatcher swaps it in), the plain ``range`` everywhere else
prange = range

#: inputs from this many items (simplices, faces, rows) on take the compiled kernels under ``auto``
#: in a process where numba has not started: a triangle mesh's largest input is its 3·m edge
#: slots, and one build of its complex and operators saves numba's start from ~1M triangles on
#: (``benchmarks/bench_operators.py``, docs/performance.md)
MIN_SIZE = 3_000_000

#: under ``auto``, once a kernel ran in this process, inputs from this many items on take the kernels
WARM_MIN_SIZE = 10_000

#: under ``auto``, the items of numpy work (inputs of at least :data:`WARM_MIN_SIZE` items) after
#: which a process starts numba: a triangle mesh's complex and operators (d0, d1, ⋆0–⋆2) pass
#: 15.5·m items through :func:`enabled`, so 20M items ≈ 1.3M triangles of builds, whose saving
#: with the kernels is about what numba's start costs (docs/performance.md)
AMORTIZE_SIZE = 20_000_000

#: the switch's values
MODES = ("auto", "numba", "numpy")

_ENV = {"": "auto", "auto": "auto", "numba": "numba", "1": "numba", "numpy": "numpy", "0": "numpy"}

#: every kernel made by :func:`njit`, in definition order (modules that were imported)
KERNELS: list = []

_override: list[str] = []  # the modes :func:`use` set, innermost last
_started = False  # a kernel ran in this process: numba's one-time start is paid
_numpy_items = 0  # items auto sent to the numpy twins (inputs of >= WARM_MIN_SIZE items) before the start

#: called once per process, with the kernel's name, just before numba compiles a kernel its disk
#: cache has no machine code for (the first run of an install, or after the source changed), so
#: a caller can say why the first step waits; None: nothing is said (this layer prints nothing)
compile_notice = None
_noticed = False


def check_mode(value: str, where: str = "app.kernels") -> str:
    """``value`` if it is one of :data:`MODES`, else a ConfigError naming ``where``."""
    if value not in MODES:
        raise ConfigError(f"{where}: must be one of {list(MODES)}, got {value!r}; use {where}=auto")
    return value


def mode() -> str:
    """The switch in force: the innermost :func:`use` that is not ``auto``, else ``DECRUN_NUMBA``."""
    for value in reversed(_override):
        if value != "auto":
            return value
    setting = os.environ.get("DECRUN_NUMBA", "").strip().lower()
    if setting not in _ENV:
        raise ConfigError(f"DECRUN_NUMBA={setting!r}: must be one of auto, numba, numpy (or 1, 0); "
                          "use DECRUN_NUMBA=auto")
    return _ENV[setting]


@contextmanager
def use(value: str):
    """Within the block the switch is ``value`` (``auto`` defers to ``DECRUN_NUMBA``)."""
    _override.append(check_mode(str(value)))
    try:
        yield
    finally:
        _override.pop()


def enabled(size: int | None = None, min_size: int = MIN_SIZE, kernels: str = "auto") -> bool:
    """Whether to run the kernel for an input of ``size`` items (None: any size): ``kernels``
    (a caller's own setting) unless ``auto``, else :func:`mode`; under ``auto`` from ``min_size``
    items on, from ``min(min_size, WARM_MIN_SIZE)`` once a kernel ran in this process, and at
    any size from :data:`WARM_MIN_SIZE` on once the numpy work refused so far reaches
    :data:`AMORTIZE_SIZE` items."""
    global _numpy_items
    setting = check_mode(kernels, "kernels") if kernels != "auto" else mode()
    if setting != "auto":
        return setting == "numba"
    if size is None or size >= min_size:
        return True
    if _started:
        return size >= WARM_MIN_SIZE
    if size >= WARM_MIN_SIZE:
        _numpy_items += size
        return _numpy_items >= AMORTIZE_SIZE
    return False


def started() -> bool:
    """Whether a kernel ran in this process (numba imported and started: later kernels are cheap)."""
    return _started


class _LazyKernel:
    """A Python function compiled with ``numba.njit(cache=True, **options)`` on its first call."""

    def __init__(self, function, options: dict):
        self.function = function
        self.options = options
        self.compiled = self.serial = None
        update_wrapper(self, function)
        KERNELS.append(self)

    @property
    def name(self) -> str:
        return f"{self.function.__module__}.{self.function.__name__}"

    def dispatcher(self):
        """The numba dispatcher (created once; it compiles per argument types when called).

        Kernels called from this one must be numba functions when it is compiled: every
        lazy kernel among the module's globals is replaced by its dispatcher first — but a
        ``parallel=True`` kernel, which only Python calls (through :meth:`__call__` and its lock;
        numba cannot nest its parallel regions anyway)."""
        if self.compiled is None:
            import numba

            namespace = self.function.__globals__
            if namespace.get("prange") is range:
                namespace["prange"] = numba.prange
            if self.options.get("parallel"):
                _threading_layer(numba)
            self.compiled = numba.njit(cache=True, **self.options)(self.function)
            _announce_compile(self)
            for name, value in list(namespace.items()):
                # a parallel kernel stays this object (its callers are Python's, through __call__'s lock)
                if isinstance(value, _LazyKernel) and not value.options.get("parallel"):
                    namespace[name] = value.dispatcher()
        return self.compiled

    def used(self) -> bool:
        """Whether this kernel ran as machine code in this process (called, or compiled into a
        caller): its dispatcher holds a compiled or cache-loaded signature."""
        return self.compiled is not None and bool(self.compiled.signatures)

    def serial_dispatcher(self):
        """A ``parallel=True`` kernel compiled without ``parallel`` (``prange`` runs as ``range``:
        the same blocks, one after the other, the same bits): what a process forked from one whose
        parallel kernels ran on GNU OpenMP calls instead (see :func:`_forked`). Compiled from a
        copy of the function named ``<name>_serial``, so that numba's disk cache, whose index
        does not tell the options apart, keeps the two versions in files of their own."""
        if self.serial is None:
            import types

            import numba

            self.dispatcher()  # the module's helpers swapped for their dispatchers
            f = self.function
            copy = types.FunctionType(f.__code__, f.__globals__, f"{f.__name__}_serial", f.__defaults__,
                                      f.__closure__)
            copy.__qualname__, copy.__module__, copy.__doc__ = f"{f.__qualname__}_serial", f.__module__, f.__doc__
            options = {k: v for k, v in self.options.items() if k != "parallel"}
            self.serial = numba.njit(cache=True, **options)(copy)
        return self.serial

    def __call__(self, *args):
        try:
            if self.options.get("parallel"):
                if _fork_child_of_openmp:
                    return self.serial_dispatcher()(*args)
                with _PARALLEL:  # one parallel region at a time in the process (see _PARALLEL)
                    result = self.dispatcher()(*args)
                global _parallel_ran
                _parallel_ran = True
                _mark_started()
                return result
            result = self.dispatcher()(*args)
            _mark_started()
            return result
        except SystemError as exc:
            cause = _handler_exception(exc)
            if cause is None:
                raise
            raise cause from None


def _announce_compile(kernel: _LazyKernel) -> None:
    """:data:`compile_notice` (once per process) when ``kernel``'s disk cache holds no machine
    code valid for its current source: numba is about to compile it on this call."""
    global _noticed
    if _noticed or compile_notice is None:
        return
    try:
        cached = bool(kernel.compiled._cache._cache_file._load_index())  # numba's index: {} when absent or stale
    except Exception:  # noqa: BLE001 — another numba's internals: say nothing rather than guess
        return
    if not cached:
        _noticed = True
        compile_notice(kernel.name)


def _mark_started() -> None:
    global _started
    _started = True


def _handler_exception(exc: SystemError) -> BaseException | None:
    """The exception a signal handler raised during a kernel call, or None.

    A kernel that returns a new array runs one Python function at its end (numba unpickles the
    ndarray class to box the array), where Python runs pending signal handlers; an exception they
    raise — Ctrl-C's KeyboardInterrupt, SIGTERM's (:mod:`decrun.runner.failures`), submitit's
    SystemExit after a USR2 checkpoint — reached the caller as "SystemError: CPUDispatcher(...)
    returned a result with an exception set", with the handler's exception as its cause. The
    handler's exception is what the call should raise: the kernel's result is dropped with it."""
    mark = "returned a result with an exception set"
    if mark not in str(exc):
        return None
    cause = exc.__cause__  # (numba's own boxing call may wrap it once more)
    while isinstance(cause, SystemError) and mark in str(cause):
        cause = cause.__cause__
    return cause


#: numba's workqueue thread pool must not be entered by two threads at once (it aborts the process:
#: "not threadsafe ... concurrent access"); a sweep run by a thread pool (joblib's threading backend)
#: would, where OpenMP is not found. Python callers of the parallel kernels take this lock, so such
#: calls wait for each other (on OpenMP too: two regions at once would only share the cores).
_PARALLEL = threading.Lock()


def threads() -> int:
    """How many threads the parallel kernels (``parallel=True``, ``prange``) split their work into:
    numba's thread count — ``NUMBA_NUM_THREADS`` if set (joblib's workers set it to their share of
    the cores), else the cores this process may run on (its CPU affinity: a SLURM job's
    ``cpus_per_task``, ``taskset``), which numba's own default (every core of the machine) ignores.
    Their results do not depend on it: each thread takes a contiguous block of independent items.
    Imports numba: call it only where a kernel runs."""
    import numba

    _threading_layer(numba)
    global _affinity_applied
    if not _affinity_applied and "NUMBA_NUM_THREADS" not in os.environ and hasattr(os, "sched_getaffinity"):
        _affinity_applied = True
        usable = len(os.sched_getaffinity(0))
        if 0 < usable < numba.get_num_threads():
            numba.set_num_threads(usable)
    return int(numba.get_num_threads())


_affinity_applied = False  # the affinity cap is applied once per process (a later set_num_threads wins)


def _threading_layer(numba) -> None:
    """Before numba starts its threads: OpenMP where numba finds it (libgomp on Linux), else
    numba's own pool ``workqueue``, unless ``NUMBA_THREADING_LAYER`` or
    ``NUMBA_THREADING_LAYER_PRIORITY`` says otherwise; no TBB (an old TBB only warns).

    OpenMP, because the calling thread works one block itself and the other threads spin a
    moment after a region before they sleep, so the next region starts on cores that are awake.
    workqueue's threads sleep, and a region that follows a millisecond of serial Python (every
    step of the fluid) ran its two blocks one after the other on a 2-core machine: 3.5 ms instead
    of 1.7 ms for two 1.65 ms blocks; the fluid's 20,480-face sphere stepped 1.44× faster on
    OpenMP (``benchmarks/bench_fluid_kernels.py``). GNU OpenMP is not fork-safe: a forked child
    whose parent ran a parallel region runs the kernels' serial versions (:func:`_forked`)."""
    chosen = {"NUMBA_THREADING_LAYER", "NUMBA_THREADING_LAYER_PRIORITY"} & set(os.environ)
    if not chosen and numba.config.THREADING_LAYER == "default":
        numba.config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]


_parallel_ran = False  # a parallel kernel ran in this process (numba's threads started)
_fork_child_of_openmp = False  # this process was forked after a parallel region on OpenMP


def _forked() -> None:
    """In a forked child: when the parent ran a parallel kernel on GNU OpenMP, numba terminates a
    child that enters OpenMP ("fork() called from a process already using GNU OpenMP, this is
    unsafe"); the child then calls the kernels' serial versions (:meth:`_LazyKernel.serial_dispatcher`),
    which give the same bits. (Forking before any parallel kernel ran, or after workqueue ran, is safe.)"""
    global _fork_child_of_openmp
    if _parallel_ran and not _fork_child_of_openmp:
        import sys

        numba = sys.modules.get("numba")
        try:
            layer = numba.threading_layer() if numba is not None else None
        except ValueError:  # no layer started
            layer = None
        _fork_child_of_openmp = layer == "omp"


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forked)


def njit(function=None, **options):
    """Decorator: ``function`` becomes a kernel compiled (and disk-cached) at first call;
    ``@njit(error_model="numpy", ...)`` passes numba options."""
    if function is None:
        return lambda f: _LazyKernel(f, options)
    return _LazyKernel(function, options)
