"""A signal handler's exception out of a kernel call (Ctrl-C, SIGTERM, submitit's USR2)."""

from __future__ import annotations

__all__ = ["handler_exception"]


def handler_exception(exc: SystemError) -> BaseException | None:
    """The exception a signal handler raised during a kernel call, or None.

    A kernel that returns a new array runs one Python function at its end (numba unpickles the
    ndarray class to box the array), where Python runs pending signal handlers; an exception they
    raise — Ctrl-C's KeyboardInterrupt, SIGTERM's (:mod:`decrun.runner.job.failures`), submitit's
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
