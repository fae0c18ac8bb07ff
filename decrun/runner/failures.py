"""How a run that cannot go on ends: one line, a status on disk where there is a directory.

The ``decrun`` command turns every way a run can stop early into one message on stderr and
an exit code, never a traceback (``-v`` shows it):

==========================================  ======================================  ====
what happened                               message                                 exit
==========================================  ======================================  ====
bad input (:class:`DecrunError`)            ``error: <key or file>: <cause>``       1
an OS error writing the output (full disk,  ``error: cannot write <path>: <cause>;``  1
read-only or forbidden directory, a file    ``choose another with hydra.run.dir=…``
where the run directory should be)
Ctrl-C (SIGINT)                             ``decrun: interrupted (Ctrl-C) …``      130
SIGTERM (a scheduler, ``kill``)             ``decrun: interrupted (SIGTERM) …``     143
==========================================  ======================================  ====

SIGTERM is turned into :class:`Terminated`, a ``KeyboardInterrupt``, so it takes the path
of Ctrl-C everywhere: the recorder keeps the steps recorded so far in ``result.h5``
marked ``status: interrupted``, and the run directory's ``metrics.json`` says
``interrupted`` (:func:`record_status`; ``failed`` with the error for the others).
"""

from __future__ import annotations

import errno
import os
import signal
import sys
from pathlib import Path
from typing import NoReturn

from decrun.errors import DecrunError
from decrun.runner.paths import NEW_OUTPUT

__all__ = ["stop", "Terminated", "install_sigterm", "interrupt_cause", "exit_code", "os_error_message", "record_status"]


class Terminated(KeyboardInterrupt):
    """Raised in the main thread when the process receives SIGTERM."""


def _raise_terminated(signum, frame):  # a signal handler
    raise Terminated("SIGTERM")


def install_sigterm() -> None:
    """Make SIGTERM raise :class:`Terminated` (main thread only; a no-op elsewhere)."""
    try:
        signal.signal(signal.SIGTERM, _raise_terminated)
    except ValueError:  # not the main thread
        pass


def interrupt_cause(exc: KeyboardInterrupt) -> str:
    """``"SIGTERM"`` or ``"Ctrl-C"``."""
    return "SIGTERM" if isinstance(exc, Terminated) else "Ctrl-C"


def exit_code(exc: KeyboardInterrupt) -> int:
    """128 + the signal number: 143 for SIGTERM, 130 for Ctrl-C."""
    return 128 + (signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT)


def find_os_error(exc: BaseException) -> OSError | None:
    """``exc`` or the first OSError in its chain of causes (logging wraps the one of its
    file handler in a ValueError), skipping decrun's own errors, which say it already."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, OSError) and not isinstance(exc, DecrunError):
            return exc
        exc = exc.__cause__ or exc.__context__
    return None


def os_error_message(exc: OSError) -> str:
    """``cannot write <path>: <cause>; choose another …`` for an OS error met while writing
    a run's output; names the path and says why in words."""
    path = exc.filename
    code = exc.errno
    cause = os.strerror(code) if isinstance(code, int) else str(exc)
    if code in (errno.EEXIST, errno.ENOTDIR) and path is not None:
        blocking = next((p for p in [Path(path), *Path(path).parents] if p.exists() and not p.is_dir()), None)
        if blocking is not None:
            path, cause = blocking, "a file is in the way where a directory is needed"
    where = f"{path}" if path is not None else "the run's output"
    hint = ""
    if code in (errno.EROFS, errno.EACCES, errno.EPERM, errno.EEXIST, errno.ENOTDIR, errno.ENOSPC, errno.EDQUOT):
        hint = f"; {NEW_OUTPUT}"
    return f"cannot write {where}: {cause}{hint}"


def stop(message: str) -> NoReturn:
    """Print the one-line ``message`` on stderr and exit 1 — also from a Hydra callback,
    where Hydra would turn an exception into a warning and go on."""
    print(message, file=sys.stderr)
    sys.exit(1)


def record_status(out: Path, status: str, error: str, extra: dict | None = None) -> str:
    """Write ``{"status": status, "error": error, **extra}`` to ``out/metrics.json`` if ``out``
    is a directory; returns "" or, when that is impossible, a note saying why (for the message)."""
    # lazy: the decrun command imports this module first, before numpy (start-up speed)
    from decrun.runner.results.provenance import write_metrics_json

    if not Path(out).is_dir():
        return ""
    try:
        write_metrics_json(Path(out) / "metrics.json", {"status": status, "error": error, **(extra or {})})
    except OSError as exc:
        cause = os.strerror(exc.errno) if exc.errno else str(exc)
        return "" if cause in error else f" (metrics.json could not be written either: {cause})"
    return ""
