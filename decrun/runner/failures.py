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

A run that fails in a directory where an earlier run left a ``result.h5`` renames that
file ``result.h5.stale`` (:func:`set_aside_stale`, said in the message), so no earlier
result sits beside this run's ``status: failed``.

SIGTERM is turned into :class:`Terminated`, a ``KeyboardInterrupt``, so it takes the path
of Ctrl-C everywhere: the recorder keeps the steps recorded so far in ``result.h5``
marked ``status: interrupted``, and the run directory's ``metrics.json`` says
``interrupted`` (:func:`record_status`; ``failed`` with the error for the others).
"""

from __future__ import annotations

import errno
import os
import signal
from pathlib import Path

from decrun.errors import DecrunError

__all__ = ["Terminated", "install_sigterm", "interrupt_cause", "exit_code", "os_error_message", "record_status",
           "file_identity", "set_aside_stale"]


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
        hint = "; choose another output directory with hydra.run.dir=DIR (hydra.sweep.dir=DIR with -m)"
    return f"cannot write {where}: {cause}{hint}"


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
        return f" (metrics.json could not be written either: {os.strerror(exc.errno) if exc.errno else exc})"
    return ""


def file_identity(path: str | os.PathLike) -> tuple[int, int, int, int] | None:
    """``(device, inode, mtime_ns, size)`` of ``path``, None when absent: an atomic
    rewrite (a new inode) changes it."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino, st.st_mtime_ns, st.st_size


def set_aside_stale(out: Path, before: tuple[int, int, int, int] | None) -> str:
    """After a failed or interrupted run in ``out``: rename ``out/result.h5`` to
    ``result.h5.stale`` when it is still the file that was there before the run started
    (``before``: its :func:`file_identity` then), i.e. an earlier run's result. Returns the
    note for the message ("" when there was none; a result this run wrote, marked failed,
    stays)."""
    path = Path(out) / "result.h5"
    if before is None or file_identity(path) != before:
        return ""
    stale = path.with_name("result.h5.stale")
    try:
        os.replace(path, stale)
    except OSError as exc:
        return f" (the earlier run's {path} could not be renamed {stale.name}: {os.strerror(exc.errno or 0)})"
    return f" (the earlier run's result.h5 is now {stale})"
