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
out of memory (MemoryError; a native        ``error: <where>: could not allocate``  1
library's bad_alloc)                        ``<size> for an array of shape (…) …;``
                                            ``use `<smaller setting>```
a config Hydra cannot read: a YAML error     ``error: <file>, line <n>: <cause>``    1
(a python tag ``!!python/...``, never run)
an override nested deeper than              ``error: <key>=<value…>: nested <n>``   1
:data:`MAX_NESTING` (refused before Hydra   ``levels deep …``
parses it), a config file Python's stack
cannot load                                 ``error: <file>: nested too deeply …``  1
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
import sys
from pathlib import Path
from typing import NoReturn

from decrun.errors import LONG_WORD, DecrunError, shorten_words
from decrun.runner.io.files import RunFiles
from decrun.runner.io.paths import NEW_OUTPUT

__all__ = ["stop", "Stopped", "shorten_words", "LONG_WORD", "Terminated", "install_sigterm", "interrupt_cause", "exit_code",
           "os_error_message", "record_status", "file_identity", "set_aside_stale", "MAX_NESTING", "nesting_depth",
           "override_nesting_error", "config_error_message", "find_memory_error", "memory_error_text"]


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


def find_in_chain(exc: BaseException | None, kinds) -> BaseException | None:
    """``exc`` or the first exception of type ``kinds`` in its chain of causes (Hydra and
    logging wrap the original error), skipping decrun's own errors, which say it already."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, kinds) and not isinstance(exc, DecrunError):
            return exc
        exc = exc.__cause__ or exc.__context__
    return None


def find_os_error(exc: BaseException) -> OSError | None:
    """``exc`` or the first OSError in its chain of causes (logging wraps the one of its
    file handler in a ValueError), skipping decrun's own errors, which say it already."""
    return find_in_chain(exc, OSError)


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
    if code == errno.ENAMETOOLONG:  # met reading as often as writing (a mesh.path, a config group name)
        return f"cannot use {where}: {cause} (a file or directory name has at most 255 bytes)"
    hint = ""
    if code in (errno.EROFS, errno.EACCES, errno.EPERM, errno.EEXIST, errno.ENOTDIR, errno.ENOSPC, errno.EDQUOT):
        hint = f"; {NEW_OUTPUT}"
    return f"cannot write {where}: {cause}{hint}"


class Stopped(SystemExit):
    """``sys.exit(code)`` once the one line ``message`` has been said (printed or logged): the
    ``decrun`` command exits with ``code`` as before; :func:`decrun.run` and :func:`decrun.sweep`,
    in the caller's process, raise ``message`` instead (:mod:`decrun.runner.api`)."""

    #: the run failed on bad input (a config value, a mesh), not a full disk: its attempt leaves
    #: nothing behind (set by :mod:`decrun.runner.job.run`)
    refused: bool = False
    #: the run directory :mod:`decrun.runner.job.run` removes once its lock is dropped, and the
    #: outermost of its parents made with it (removed while empty), or None
    leave_nothing: tuple[Path, Path] | None = None

    def __init__(self, message: str, code: int = 1):
        super().__init__(code)
        self.message = message


def stop(message: str) -> NoReturn:
    """Print the one-line ``message`` on stderr (:func:`shorten_words`) and exit 1
    (:class:`Stopped`) — also from a Hydra callback, where Hydra would turn an exception into a
    warning and go on."""
    message = shorten_words(message)
    print(message, file=sys.stderr)
    raise Stopped(message)


def record_status(out: Path, status: str, error: str, extra: dict | None = None) -> str:
    """Write ``{"status": status, "error": error, **extra}`` to ``out/metrics.json`` if ``out``
    is a directory; returns "" or, when that is impossible, a note saying why (for the message)."""
    # lazy: the decrun command imports this module first, before numpy (start-up speed)
    from decrun.runner.results.provenance import write_metrics_json

    if not Path(out).is_dir():
        return ""
    try:
        write_metrics_json(RunFiles(out).metrics, {"status": status, "error": error, **(extra or {})})
    except OSError as exc:
        cause = os.strerror(exc.errno) if exc.errno else str(exc)
        return "" if cause in error else f" ({RunFiles.METRICS} could not be written either: {cause})"
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
    path, stale = RunFiles(out).result, RunFiles(out).stale
    if before is None or file_identity(path) != before:
        return ""
    try:
        os.replace(path, stale)
    except OSError as exc:
        return f" (the earlier run's {path} could not be renamed {stale.name}: {os.strerror(exc.errno or 0)})"
    return f" (the earlier run's {path.name} is now {stale})"


_NATIVE_OUT_OF_MEMORY = ("out of memory", "bad_alloc", "cannot allocate", "unable to allocate", "failed to allocate")


def find_memory_error(exc: BaseException) -> BaseException | None:
    """``exc`` or the first exception in its chain that says the process ran out of memory:
    a MemoryError (numpy's has the array's ``shape`` and ``dtype``; pybind11 turns a native
    ``std::bad_alloc`` into one) or a RuntimeError of a native library saying so."""
    found = find_in_chain(exc, MemoryError)
    if found is not None:
        return found
    native = find_in_chain(exc, RuntimeError)
    if native is not None and any(words in str(native).lower() for words in _NATIVE_OUT_OF_MEMORY):
        return native
    return None


def _bytes(count: float) -> str:
    """``71.1 PiB``: a byte count in binary units, as numpy's message writes it."""
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if count < 1024 or unit == "PiB":
            return f"{count:.0f} {unit}" if unit == "bytes" else f"{count:.3g} {unit}"
        count /= 1024
    return ""  # pragma: no cover


def memory_error_text(exc: BaseException) -> str:
    """``could not allocate 49.3 MiB for an array of shape (717602, 3, 3) float64`` for
    numpy's MemoryError (its ``shape`` and ``dtype``), ``ran out of memory (<cause>)`` for
    the others."""
    import math

    shape, dtype = getattr(exc, "shape", None), getattr(exc, "dtype", None)
    if shape is not None and dtype is not None:
        size = math.prod(int(d) for d in shape) * dtype.itemsize
        return f"could not allocate {_bytes(size)} for an array of shape {tuple(int(d) for d in shape)} {dtype}"
    cause = " ".join(str(exc).split())
    return f"ran out of memory ({cause})" if cause else "ran out of memory"


#: the deepest nesting of ``[…]`` / ``{…}`` an override may have. OmegaConf recurses once
#: per level and exhausts Python's stack near 150 levels (measured: 100 compose, 150 do
#: not); a real config nests a few levels (``mesh.hole_balls=[[x,y,z,r]]``: 2)
MAX_NESTING = 64


def nesting_depth(text: str) -> int:
    """The deepest nesting of ``[`` / ``{`` in an override value, outside quoted strings
    (``'[['`` is a string); unclosed brackets count, so ``[[[`` is 3 deep."""
    depth = deepest = 0
    quote = None
    escaped = False
    for char in text:
        if quote is not None:
            if escaped:
                escaped = False
            elif char == "\\":
                escaped = True
            elif char == quote:
                quote = None
        elif char in "'\"":
            quote = char
        elif char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth = max(depth - 1, 0)
    return deepest


def _shorten(text: str, keep: int = 24) -> str:
    return text if len(text) <= keep else f"{text[:keep]}… ({len(text)} characters)"


def override_nesting_error(args: list[str]) -> str | None:
    """``error: <override>: nested <n> levels deep …`` for the first command-line override
    whose value nests deeper than :data:`MAX_NESTING` (checked before Hydra parses it, which
    would overflow Python's stack); None when every override is within it."""
    for arg in args:
        key, sep, value = arg.partition("=")
        if arg.startswith("-") or not sep:
            continue
        depth = nesting_depth(value)
        if depth > MAX_NESTING:
            return (f"error: {_shorten(arg, len(key) + 1 + 24)}: the value is nested {depth} levels deep; an "
                    f"override may nest lists and dicts ([…], {{…}}) at most {MAX_NESTING} levels")
    return None


def _yaml_message(exc) -> str:
    """``<file>, line <n>: <cause>`` for a PyYAML error (a tag that would build a Python
    object is named as such: OmegaConf's loader refuses it, nothing is run)."""
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    where = f"{mark.name}, line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "a config file"
    problem = " ".join(str(getattr(exc, "problem", None) or exc).split())
    tag = problem.partition("for the tag ")[2].strip("'")
    if tag:
        short = tag.replace("tag:yaml.org,2002:", "!!")
        return (f"{where}: the YAML tag {short} is refused: decrun configs are plain YAML, tags that build "
                f"Python objects are never run; remove the tag")
    context = " ".join(str(getattr(exc, "context", None) or "").split())
    return f"{where}: invalid YAML: {context + ': ' if context else ''}{problem}"


def _config_file(args: list[str], matches) -> tuple[Path, bytes] | None:
    """The first config file of the search path for ``args``
    (:func:`~decrun.runner.io.config_files.config_files`) whose bytes ``matches``, with its
    bytes; None when none does. Read once Hydra failed to load a config: the file is found by
    its content."""
    from decrun.runner.io.config_files import config_files
    from decrun.runner.job.config import config_dir

    for path in config_files(args, config_dir()):
        try:
            data = path.read_bytes()
        except OSError:
            continue
        if matches(data):
            return path, data
    return None


def _utf8_error(data: bytes) -> UnicodeDecodeError | None:
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as exc:
        return exc
    return None


def _unreadable_config(exc: BaseException, args: list[str]) -> str | None:
    """``<file>: …`` for a config file that cannot be read: a byte that is not UTF-8 (a Latin-1
    ``é`` in a comment: the file and the byte's offset), or an OS error on a file or directory of
    the config search path (unreadable, a directory where a file is expected: the path and the
    cause, never "cannot write"). None for any other error."""
    undecodable = find_in_chain(exc, UnicodeDecodeError)
    # the file that holds the bytes Hydra could not decode (Hydra may have read a chunk of it)
    found = _config_file(args, lambda data: bytes(undecodable.object) in data and _utf8_error(data) is not None) \
        if isinstance(undecodable, UnicodeDecodeError) else None
    if found is not None:
        path, data = found
        offset = _utf8_error(data).start  # type: ignore[union-attr]
        return (f"{path}: byte 0x{data[offset]:02x} at offset {offset} is not UTF-8 (config files are UTF-8 text, "
                "comments too); save the file as UTF-8 (e.g. iconv -f latin1 -t utf-8)")
    os_error = find_in_chain(exc, OSError)
    if not isinstance(os_error, OSError) or os_error.filename is None:
        return None
    if os_error.errno == errno.ENAMETOOLONG:  # a name from the command line, not a file: the override is named
        return None  # by decrun.runner.command.errors (and Path.is_dir would raise the same error again)
    from decrun.runner.io.config_files import search_roots
    from decrun.runner.job.config import config_dir

    where = Path(os.path.abspath(os_error.filename))
    if not any(where == root or root in where.parents for root in search_roots(args, config_dir())):
        return None
    cause = os.strerror(os_error.errno) if isinstance(os_error.errno, int) else str(os_error)
    fix = "make it readable (chmod u+r" + (",u+x" if where.is_dir() else "") + f" {where})" \
        if os_error.errno in (errno.EACCES, errno.EPERM) else "fix or remove it"
    return f"cannot read the config {'directory' if where.is_dir() else 'file'} {where}: {cause}; {fix}"


def config_error_message(exc: BaseException, args: list[str] | None = None) -> str | None:
    """``error: …`` (one line) for a config Hydra could not read: a YAML error in a config
    file (naming the file and line), or one nested too deeply for Python's stack (naming
    the file, or else the deepest override of ``args``). None for any other error."""
    import yaml  # lazy: only when something failed

    if isinstance(exc, DecrunError):  # decrun's own one-line message (a hostile file it read) says it already
        return None
    yaml_error = find_in_chain(exc, yaml.YAMLError)
    if yaml_error is not None:
        return f"error: {_yaml_message(yaml_error)}"
    unreadable = _unreadable_config(exc, args or [])
    if unreadable is not None:
        return f"error: {unreadable}"
    recursion = find_in_chain(exc, RecursionError)
    if recursion is None:
        return None
    from decrun.runner.io.config_files import yaml_depth

    found = _config_file(args or [], lambda data: yaml_depth(data) > MAX_NESTING)
    if found is not None:
        return (f"error: {found[0]}: nested too deeply to load (Python's recursion limit); a config may nest lists "
                f"and dicts at most {MAX_NESTING} levels")
    deepest = max(args or [""], key=lambda a: nesting_depth(a.partition("=")[2]))
    culprit = f"{_shorten(deepest)}: " if "=" in deepest else ""
    return (f"error: {culprit}the config is nested too deeply to compose (Python's recursion limit); lists and "
            f"dicts may nest at most {MAX_NESTING} levels")
