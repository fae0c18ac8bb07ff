"""Lazy kernels: ``@njit`` makes a function a kernel compiled by ``numba.njit(cache=True,
**options)`` on its first call (package docstring); a ``parallel=True`` kernel runs one
parallel region at a time in the process, and its serial version in a child forked after
parallel regions ran on GNU OpenMP (:mod:`.forks`). A call marks numba started in the process
(:func:`.switch.mark_started`); a kernel numba must compile is announced as it starts compiling
(:func:`listen_for_compiles`, on numba's public event API ``numba.core.event``)."""

from __future__ import annotations

from functools import update_wrapper
from typing import Any, Callable

from decrun.core.jit import forks
from decrun.core.jit.signals import handler_exception
from decrun.core.jit.switch import mark_started
from decrun.core.jit.threads import threading_layer

__all__ = ["njit", "prange", "KERNELS", "LazyKernel", "listen_for_compiles"]

#: ``for i in prange(n)`` in a kernel: numba's parallel loop once the kernel is compiled with
#: ``parallel=True`` (the dispatcher swaps it in), the plain ``range`` everywhere else
prange = range

#: every kernel made by :func:`njit`, in definition order (modules that were imported)
KERNELS: list = []

_noticed = False  # the package's compile_notice was called in this process (it is said once)
_compiling: dict[int, "LazyKernel"] = {}  # id of each dispatcher made here: its kernel (what a compile event names)
_listening = False  # the compile listener is registered with numba


class LazyKernel:
    """A Python function compiled with ``numba.njit(cache=True, **options)`` on its first call."""

    def __init__(self, function: Callable, options: dict):
        self.function = function
        self.options = options
        self.compiled: Any = None  # numba dispatchers, made on the first call
        self.serial: Any = None
        update_wrapper(self, function)
        KERNELS.append(self)

    @property
    def name(self) -> str:
        return f"{self.function.__module__}.{self.function.__name__}"

    def dispatcher(self):
        """The numba dispatcher (created once; it compiles per argument types when called).

        Kernels called from this one must be numba functions when it is compiled: every
        lazy kernel among the module's globals this one names is replaced by its dispatcher
        (the others stay lazy kernels) — but a
        ``parallel=True`` kernel, which only Python calls (through :meth:`__call__` and its lock;
        numba cannot nest its parallel regions anyway)."""
        if self.compiled is None:
            import numba

            namespace = self.function.__globals__
            if namespace.get("prange") is range:
                namespace["prange"] = numba.prange
            if self.options.get("parallel"):
                threading_layer(numba)
            listen_for_compiles(numba)
            self.compiled = numba.njit(cache=True, **self.options)(self.function)
            _compiling[id(self.compiled)] = self
            for name in _global_names(self.function.__code__):
                value = namespace.get(name)
                # a parallel kernel stays this object (its callers are Python's, through __call__'s lock)
                if isinstance(value, LazyKernel) and not value.options.get("parallel"):
                    namespace[name] = value.dispatcher()
        return self.compiled

    def used(self) -> bool:
        """Whether this kernel ran as machine code in this process (called, or compiled into a
        caller): its dispatcher holds a compiled or cache-loaded signature."""
        return self.compiled is not None and bool(self.compiled.signatures)

    def serial_dispatcher(self):
        """A ``parallel=True`` kernel compiled without ``parallel`` (``prange`` runs as ``range``:
        the same blocks, one after the other, the same bits): what a process forked from one whose
        parallel kernels ran on GNU OpenMP calls instead (see :func:`.forks.forked`). Compiled from a
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
            _compiling[id(self.serial)] = self
        return self.serial

    def __call__(self, *args: Any) -> Any:
        try:
            if self.options.get("parallel"):
                if forks.state.child_of_openmp:
                    return self.serial_dispatcher()(*args)
                with forks.PARALLEL:  # one parallel region at a time in the process (see forks.PARALLEL)
                    result = self.dispatcher()(*args)
                forks.state.parallel_ran = True
                mark_started()
                return result
            result = self.dispatcher()(*args)
            mark_started()
            return result
        except SystemError as exc:
            cause = handler_exception(exc)
            if cause is None:
                raise
            raise cause from None


def _global_names(code) -> set:
    """The global names a function's code (and the code nested in it) refers to."""
    names = set(code.co_names)
    for constant in code.co_consts:
        if hasattr(constant, "co_names"):
            names |= _global_names(constant)
    return names


def listen_for_compiles(numba) -> None:
    """Register (once per process) a listener for numba's ``numba:compile`` event (its public
    event API, ``numba.core.event``), which numba broadcasts when a dispatcher starts compiling:
    its disk cache held no machine code valid for the kernel's current source (the first run of an
    install, or after the source changed). The first such event for one of these kernels calls
    the package's :data:`decrun.core.jit.compile_notice` with the kernel's name, once per process.
    A kernel loaded from the cache, or never called, compiles nothing and is not announced."""
    global _listening
    if _listening:
        return
    from numba.core import event

    class CompileNotice(event.Listener):
        def on_start(self, started) -> None:
            kernel = _compiling.get(id(started.data.get("dispatcher"))) if isinstance(started.data, dict) else None
            if kernel is not None:
                announce_compile(kernel)

        def on_end(self, ended) -> None:
            pass

    event.register("numba:compile", CompileNotice())
    _listening = True


def announce_compile(kernel: LazyKernel) -> None:
    """The package's :data:`decrun.core.jit.compile_notice` with ``kernel``'s name, once per
    process (numba is compiling it). The notice is read from the package, where callers set it."""
    global _noticed
    from decrun.core import jit  # the package (initialised by now): its compile_notice is the setting

    notice = jit.compile_notice
    if _noticed or notice is None:
        return
    _noticed = True
    notice(kernel.name)


def njit(function: Callable | None = None, **options: Any) -> Any:
    """Decorator: ``function`` becomes a kernel compiled (and disk-cached) at first call;
    ``@njit(error_model="numpy", ...)`` passes numba options."""
    if function is None:
        return lambda f: LazyKernel(f, options)
    return LazyKernel(function, options)
