"""``decrun.run`` and ``decrun.sweep``: the ``decrun`` command, called from Python.

``decrun.run(["app=heat", "mesh.subdiv=3"])`` is ``decrun app=heat mesh.subdiv=3`` and returns
the :class:`Run` it wrote; ``decrun.sweep(["app=heat", "app.constants.k=0.5,1"])`` is ``decrun -m
...`` and returns the sweep's table — the ``pandas.DataFrame`` that ``pandas.read_csv`` gives for
its ``metrics.csv``, the table ``decrun-table --csv`` prints
(:func:`decrun.runner.sweep.tables.load_sweep`).

How: each call runs the ``decrun`` command's own Hydra application in this process —
:data:`decrun.runner.command.task._hydra_main`, the ``@hydra.main`` function the console script calls,
with the overrides (and ``-m``) as its command line, through :func:`decrun.runner.command.task.hydra_command`
as the console script does (a single run composes its config once, not a second time only to read
``hydra.mode``). So a call composes, checks, plans, locks,
writes ``manifest.json``, launches, resumes and tabulates exactly as the command does: the same
config search path and callbacks (:class:`~decrun.runner.command.callbacks.OutputGuard`,
:class:`~decrun.runner.command.callbacks.SweepTable`), the ``decrun`` sweeper and any launcher, because it *is*
that code path. The alternatives re-implement part of it: Hydra's compose API runs no sweeper,
launcher or callback (it cannot run a multirun, hydra#2673), and calling the sweeper with a
composed config means rebuilding Hydra's ``multirun`` from its internals (its
``HydraContext``, config loader, callbacks), which is what ``hydra.main`` already does through
Hydra's public entry point.

What the command does to its process is done for the call and undone after it: ``sys.argv``
(Hydra reads the command line from it), ``HYDRA_FULL_ERROR=1`` in ``os.environ`` (errors reach
decrun's one-line messages instead of Hydra's printing), ``logging.raiseExceptions``, the root
logger's handlers and level (Hydra configures logging for each job: its log file handler is
closed after the call), and any directory lock the call took and still holds (a run or sweep
that stopped early; the command's exit drops them). The command's SIGTERM handler is not
installed: a library leaves the signals to its program. Calls are therefore one at a time in a
process: a call made while another runs (from another thread, or from inside it) is refused at
once with a :class:`RunError` naming the running one, and the running call goes on untouched;
any number of calls, one after the other.

Outputs go where the command puts them, relative to the working directory
(``outputs/runs/<stamp>/``, ``outputs/sweeps/<stamp>/``), or under ``root`` (``<root>/runs/<stamp>``,
``<root>/sweeps/<stamp>``), or into exactly ``dir`` (``hydra.run.dir`` / ``hydra.sweep.dir``:
what ``resume=True`` needs to find the sweep again). ``dir`` and ``root`` are paths, never
resolved: one holding ``${`` (which Hydra would read as an interpolation) is a :class:`RunError`.

Errors: whatever the command would end with a non-zero exit is a :class:`RunError` whose text is
the line the command prints (a bad override, a refused directory, a run that failed). A sweep
whose jobs failed is not an error: its table says which (``status``, ``error``), as the command
does with exit 1. Ctrl-C (a notebook's interrupt) is a ``KeyboardInterrupt``, after the sweep's
jobs were marked as the command marks them.
"""

from __future__ import annotations

import logging
import os
import shlex
import sys
import threading
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Iterator, Sequence

from decrun.errors import DecrunError

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["Run", "RunError", "run", "sweep"]


class RunError(DecrunError):
    """A run or sweep the ``decrun`` command would have ended with a non-zero exit: ``str(exc)``
    is the line the command prints, ``code`` its exit code, ``dir`` the run or sweep directory
    when one had been chosen (None when it stopped before)."""

    def __init__(self, message: str, code: int = 1, dir: Path | None = None):
        super().__init__(message)
        self.code, self.dir = code, dir


@dataclass(frozen=True)
class Run:
    """One finished run: its directory ``dir`` (absolute) and its ``metrics`` (``metrics.json``:
    the app's metrics, ``status``, ``result_h5``)."""

    dir: Path
    metrics: dict

    @property
    def status(self) -> str:
        """``ok`` for a finished run (a failed one is a :class:`RunError`)."""
        return str(self.metrics.get("status", ""))

    @property
    def result_path(self) -> Path:
        """The run's ``result.h5``."""
        from decrun.runner.io.files import RunFiles

        return RunFiles(self.dir).result

    def result(self):
        """The stored result — mesh, fields, series, metrics, provenance
        (:func:`decrun.runner.results.read_result`, checked on read)."""
        from decrun.runner.results import read_result

        return read_result(self.result_path)


def run(overrides: str | Sequence[str] = (), *, dir: str | os.PathLike | None = None,
        root: str | os.PathLike | None = None) -> Run:
    """``decrun <overrides>`` in this process (module docstring): one run, its :class:`Run`.

    ``overrides``: the command line's overrides (``["app=heat", "mesh.subdiv=3"]``, or one string
    split as a shell would); ``dir``: the run directory (``hydra.run.dir``); ``root``: the run goes
    to ``<root>/runs/<stamp>/`` (default: ``outputs/runs/<stamp>/`` in the working directory).
    ``dir`` and ``root`` are used as given, never resolved (one holding ``${`` is refused).
    Raises :class:`RunError` with the command's message when the run cannot start or fails, and
    at once when another call of :func:`run` or :func:`sweep` is running in this process (from
    another thread: calls are one at a time; the running one goes on untouched)."""
    from decrun.runner.command.callbacks import OutputGuard
    from decrun.runner.io.files import RunFiles
    from decrun.runner.results.checked import load_json

    args = _overrides(overrides, "run") + _directory("run", dir, root, overrides)
    with _one_call("run"):
        OutputGuard.run_dir = None
        _command(args, lambda: OutputGuard.run_dir)
        out = _made(OutputGuard.run_dir, "hydra.callbacks.output_guard")
        return Run(out, load_json(RunFiles(out).metrics))


def sweep(overrides: str | Sequence[str] = (), *, launcher: str | None = None, resume: bool = False,
          dir: str | os.PathLike | None = None, root: str | os.PathLike | None = None) -> "pd.DataFrame":
    """``decrun -m <overrides>`` in this process (module docstring): the sweep's table.

    ``launcher``: a Hydra launcher (``"joblib"``, ``"submitit_local"``, ``"ray"``...; its options
    as overrides, ``hydra.launcher.n_jobs=2``); ``resume``: rerun the jobs of ``dir`` that are not
    ok (``hydra.sweeper.resume=true``); ``dir``: the sweep directory (``hydra.sweep.dir``);
    ``root``: the sweep goes to ``<root>/sweeps/<stamp>/`` (default: ``outputs/sweeps/<stamp>/``).

    Returns the table ``pandas.read_csv(<sweep dir>/metrics.csv)`` gives (one row per planned
    job; ``status`` and ``error`` say which jobs failed), with the sweep directory (absolute) in
    ``table.attrs["sweep_dir"]``. Raises :class:`RunError` with the command's message when the
    sweep cannot start or its launcher stops it."""
    from decrun.runner.command.callbacks import SweepTable
    from decrun.runner.sweep.tables import load_sweep

    args = ["-m", *_overrides(overrides, "sweep")]
    if launcher is not None:
        _refuse_both(overrides, "hydra/launcher", "launcher")
        args.append(f"hydra/launcher={launcher}")
    if resume:
        _refuse_both(overrides, "hydra.sweeper.resume", "resume")
        args.append("hydra.sweeper.resume=true")
    args += _directory("sweep", dir, root, overrides)
    with _one_call("sweep"):
        SweepTable.sweep_dir = None
        _command(args, lambda: SweepTable.sweep_dir)
        sweep_dir = _made(SweepTable.sweep_dir, "hydra.callbacks.sweep_table")
        table = load_sweep(sweep_dir)
        table.attrs["sweep_dir"] = str(sweep_dir)
        return table


#: held by the call of :func:`run` / :func:`sweep` running in this process (:func:`_one_call`)
_CALL = threading.Lock()
_CALLER: list[str] = []


@contextmanager
def _one_call(what: str) -> Iterator[None]:
    """The block as this process's only call of the command: a second call while one runs (from
    another thread, or from inside the first) is refused at once with a :class:`RunError` —
    Hydra's state (its global config and search path, ``sys.argv``, the logging set-up) is the
    process's, and two runs composing at once would break each other, the valid one too."""
    if not _CALL.acquire(blocking=False):
        running = _CALLER[0] if _CALLER else "another call"
        raise RunError(f"error: decrun.{what}: {running} is running in this process (Hydra's state is global: calls "
                       f"are one at a time); call decrun.{what} after it returns, or from another process "
                       "(e.g. concurrent.futures.ProcessPoolExecutor)")
    _CALLER[:] = [f"decrun.{what} in thread {threading.current_thread().name!r}"]
    try:
        yield
    finally:
        _CALLER.clear()
        _CALL.release()


def _overrides(overrides: str | Sequence[str], what: str) -> list[str]:
    """The overrides as the command line's words; an option (``-m``, ``--cfg``) is refused."""
    words = shlex.split(overrides) if isinstance(overrides, str) else [str(o) for o in overrides]
    options = [w for w in words if w.startswith("-")]
    if options:
        raise ValueError(f"decrun.{what}: {', '.join(options)}: overrides only (key=value), no command-line "
                         f"options{'; a sweep is decrun.sweep(...)' if '-m' in options or '--multirun' in options else ''}")
    return words


def _refuse_both(overrides: str | Sequence[str], key: str, argument: str) -> None:
    words = shlex.split(overrides) if isinstance(overrides, str) else [str(o) for o in overrides]
    if key in {w.partition("=")[0].lstrip("+~") for w in words}:
        raise ValueError(f"{key} is set both by the overrides and by {argument}=...; give one")


def _directory(kind: str, dir: str | os.PathLike | None, root: str | os.PathLike | None,
               overrides: str | Sequence[str]) -> list[str]:
    """The ``hydra.<kind>.dir`` override for ``dir`` or ``root`` (none: the command's default)."""
    if dir is not None and root is not None:
        raise ValueError("give dir= (the directory itself) or root= (where its stamped directory goes), not both")
    if dir is None and root is None:
        return []
    _refuse_both(overrides, f"hydra.{kind}.dir", "dir" if dir is not None else "root")
    path = str(dir) if dir is not None else os.path.join(str(root), f"{kind}s")
    if "${" in path:  # Hydra resolves its output paths again where it uses them (its log file's name)
        argument = "dir" if dir is not None else "root"
        raise RunError(f"error: {argument}={path!r}: holds '${{', which Hydra would read as an interpolation (its own "
                       "output paths are resolved again where they are used), so the files would not go into exactly "
                       f"{argument}; give a path without '${{' (resolve it in Python, e.g. os.path.expandvars)")
    quoted = "'" + path.replace("\\", "\\\\").replace("'", "\\'") + "'"
    if dir is None:  # the command's stamp, made by Hydra's interpolation as for the default
        quoted = quoted[:-1] + "/${decrun.stamp:}'"
    return [f"hydra.{kind}.dir={quoted}"]


def _command(args: list[str], where) -> None:
    """Run the ``decrun`` command's Hydra app with the command line ``args`` in this process;
    raise what the command would exit with (module docstring). ``where()``: the directory
    chosen so far, for the error."""
    from decrun.runner.command import callbacks, errors, task
    from decrun.runner.io.locks import released_after
    from decrun.runner.job.failures import Stopped, interrupt_cause

    callbacks.SweepTable.failed = 0
    with _as_command(args), released_after():
        try:
            task.hydra_command(args)  # Hydra's command line, as the command's
        except Stopped as exc:
            if isinstance(exc.__cause__, KeyboardInterrupt):  # a single run, recorded as interrupted
                raise exc.__cause__ from None
            raise RunError(exc.message, _code(exc), _absolute(where())) from exc
        except SystemExit as exc:  # an exit decrun did not make (Hydra's argument parser)
            if _code(exc) == 0:
                return
            raise RunError(f"decrun {shlex.join(args)}: exit {exc.code}", _code(exc), _absolute(where())) from exc
        except KeyboardInterrupt as exc:  # a sweep: its running jobs marked interrupted, as the command does
            print(f"decrun: interrupted ({interrupt_cause(exc)}) {task.interrupted_where(exc)}", file=sys.stderr)
            raise
        except Exception as exc:
            message = errors.error_message(exc)
            if message is None:  # a bug: its traceback
                raise
            raise RunError(message, 1, _absolute(where())) from exc


def _made(directory: Path | None, callback: str) -> Path:
    """The directory the command's callback saw made (absolute)."""
    if directory is None:  # the config dropped the callback that notes it
        raise RunError(f"error: no directory was recorded: {callback} (conf/config.yaml) is not among the callbacks")
    return directory.absolute()


def _code(exc: SystemExit) -> int:
    return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)


def _absolute(path: Path | None) -> Path | None:
    """``path`` made absolute; None when there is none, or none any more (a run refused as bad
    input leaves no directory)."""
    return None if path is None or not path.exists() else path.absolute()


@contextmanager
def _as_command(args: list[str]) -> Iterator[None]:
    """The process as the ``decrun`` command sets it up for Hydra, restored after the block."""
    saved_argv, saved_error = sys.argv, os.environ.get("HYDRA_FULL_ERROR")
    saved_raise = logging.raiseExceptions
    root = logging.getLogger()
    saved_handlers, saved_level = list(root.handlers), root.level
    sys.argv = ["decrun", *args]
    os.environ["HYDRA_FULL_ERROR"] = "1"  # errors reach decrun's messages (the command's main does the same)
    logging.raiseExceptions = False
    try:
        yield
    finally:
        sys.argv = saved_argv
        if saved_error is None:
            os.environ.pop("HYDRA_FULL_ERROR", None)
        else:
            os.environ["HYDRA_FULL_ERROR"] = saved_error
        logging.raiseExceptions = saved_raise
        for handler in root.handlers:
            if handler not in saved_handlers:  # one that cannot flush (its file gone) is dropped all the same
                with suppress(Exception):
                    handler.flush()
                    handler.close()
        root.handlers[:] = saved_handlers
        root.setLevel(saved_level)
