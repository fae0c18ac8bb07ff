"""Ctrl-C and SIGTERM while an interrupt is being handled: the ``decrun`` command
ends after its first interrupt, so a second one — while the sweep counts its jobs, while the
interrupted jobs are marked and the message printed, while the process exits — is
ignored instead of breaking off the message with a traceback. Imports only ``signal``
(the command imports it at start-up)."""

from __future__ import annotations

import signal

__all__ = ["INTERRUPTS", "ignore_interrupts", "restore_interrupts"]

#: the signals that stop a run or a sweep (SIGTERM takes Ctrl-C's path: decrun.runner.job.failures)
INTERRUPTS = (signal.SIGINT, signal.SIGTERM)


def ignore_interrupts() -> dict:
    """Ignore Ctrl-C and SIGTERM from now on; the handlers they had, for
    :func:`restore_interrupts`. A no-op ({}) outside the main thread."""
    previous = {}
    for signum in INTERRUPTS:
        try:
            previous[signum] = signal.signal(signum, signal.SIG_IGN)
        except ValueError:  # not the main thread
            break
    return previous


def restore_interrupts(previous: dict) -> None:
    """Give the signals of :func:`ignore_interrupts` back their handlers."""
    for signum, handler in previous.items():
        if handler is not None:
            signal.signal(signum, handler)
