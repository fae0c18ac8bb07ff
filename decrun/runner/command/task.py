"""The ``decrun`` command (a Hydra app): the Hydra task, the command line and its one-line errors.

``decrun [-v] [overrides...]`` composes ``conf/config.yaml`` (defaults: mesh, operator,
app, solver), runs one experiment into ``outputs/runs/<stamp>/`` and prints what it
wrote. ``decrun -m key=a,b ...`` runs a sweep into ``outputs/sweeps/<stamp>/<job>/`` and
writes ``metrics.csv`` / ``metrics.md`` at the sweep root (one row per job, also for
jobs that failed); it exits non-zero when a job failed.

This module is the thin Hydra layer: the task hands the composed config and the run
directory to :func:`decrun.runner.job.run.run` (the data flow of one run is there).

Errors: a :class:`decrun.errors.DecrunError` (bad input) prints one line
``error: <message>`` and exits 1 with no ``result.h5``; ``-v``/``--verbose`` or
``hydra.verbose=true`` show the traceback. Config keys Hydra cannot compose (a misspelt
key, a wrong type, an unknown option) are reported by Hydra before anything runs, in the
one line of :mod:`decrun.runner.command.errors`.
"""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path
from typing import Any

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig

from decrun.errors import DecrunError
from decrun.runner.command.callbacks import OutputGuard, SweepTable
from decrun.runner.command.errors import error_message
from decrun.runner.command.help import fast_help
from decrun.runner.command.model_keys import refuse_unread_constants, with_model_options
from decrun.runner.io.interrupts import ignore_interrupts
from decrun.runner.job.config import config_dir, register_configs
from decrun.runner.job.failures import (
    exit_code,
    install_sigterm,
    interrupt_cause,
    override_nesting_error,
    record_status,
    shorten_words,
)
from decrun.runner.sweep.checks import register_check

register_configs()

_VERBOSE = False


def _hydra_task(cfg: DictConfig) -> int | float:
    """The Hydra task: :func:`decrun.runner.job.run.run` in the directory Hydra made."""
    # lazy: the numerical stack loads only once a run starts, not for --help or a bad override (start-up speed)
    from decrun.runner.job.run import run

    hydra_cfg = HydraConfig.get()
    out = Path(hydra_cfg.runtime.output_dir)
    made = OutputGuard.made  # (run directory, outermost directory made with it), when this process made it
    outermost = made[1] if made is not None and made[0].absolute() == out.absolute() else None
    return run(cfg, out, multirun=hydra_cfg.mode == RunMode.MULTIRUN, verbose=_VERBOSE or bool(hydra_cfg.verbose),
               log_name=hydra_cfg.job.name, made=outermost)


def _check_job(cfg: DictConfig, memo: dict | None = None, delta: Any = None) -> None:
    """The sweeper's check of each planned job: :func:`decrun.runner.job.experiment.validate`;
    with the sweeper's ``memo`` each distinct plugin node is built once per sweep, and with
    a ``delta`` only a derived job's changed leaves are checked anew."""
    from decrun.runner.job.experiment import validate  # lazy: the numerical stack (start-up speed)

    validate(cfg, memo=memo, delta=delta)


_hydra_main = hydra.main(version_base="1.3", config_path=str(config_dir()), config_name="config")(_hydra_task)
# every job of a sweep is type-checked before the first starts; joblib's workers import the
# numerical stack while the sweep is planned
register_check(_hydra_task, _check_job, warm=("decrun.runner.job.run", "decrun.runner.results.recorder"))


def main() -> None:
    """Console script ``decrun``: ``-v``/``--verbose`` shows tracebacks; everything else is
    Hydra's command line (overrides, ``-m``, ``--cfg job``, ``--help``...)."""
    global _VERBOSE
    args = [a for a in sys.argv[1:] if a not in ("-v", "--verbose")]
    _VERBOSE = len(args) != len(sys.argv) - 1
    if _VERBOSE:
        os.environ["HYDRA_FULL_ERROR"] = "1"
    sys.argv = [sys.argv[0], *args]
    if args in (["--help"], ["-h"]):
        print(fast_help(), end="")
        return
    if "--version" in args:  # decrun's version, not Hydra's (Hydra's argument parser prints its own)
        import decrun

        print(f"decrun {decrun.__version__}")
        return
    if any(a.startswith("query=") for a in args) and any(a in ("-sc", "--shell-completion") for a in args):
        _completion()
        return
    nested = override_nesting_error(args)  # before Hydra's parser, which would overflow the stack
    if nested:
        print(nested, file=sys.stderr)
        sys.exit(1)
    args = with_model_options(args)  # app.steps=… in a model file without `- _model`
    sys.argv = [sys.argv[0], *args]
    try:
        refuse_unread_constants(args)  # +app.constants.epz=… that nothing reads
    except DecrunError as exc:
        _say(f"error: {exc}")
        sys.exit(1)
    SweepTable.failed = 0
    install_sigterm()
    # a log file that cannot be written (full disk) must not print logging's tracebacks;
    # the error itself is reported on the console
    logging.raiseExceptions = False
    # Hydra prints a traceback for an exception outside the task (creating the run
    # directory, saving .hydra/, Ctrl-C while composing); let them reach _report instead
    os.environ["HYDRA_FULL_ERROR"] = "1"
    try:
        hydra_command(args)
    except Exception as exc:
        sys.exit(_report(exc))
    except KeyboardInterrupt as exc:
        # the command ends here: a second Ctrl-C (or SIGTERM) while the interrupted jobs are
        # marked and the message is printed, or while the process exits, is ignored
        ignore_interrupts()
        print(f"decrun: interrupted ({interrupt_cause(exc)}) {interrupted_where(exc)}", file=sys.stderr)
        sys.exit(exit_code(exc))
    if SweepTable.failed:
        sys.exit(1)


def hydra_command(args: list[str]) -> None:
    """The ``decrun`` command's Hydra app for the command line ``args`` (``sys.argv[1:]``, set
    by the caller), run Hydra's own way. What the app raises, Hydra's exit included, reaches
    the caller (:func:`main`, :func:`decrun.run`). The search path's config files are checked
    first (:func:`~decrun.runner.io.config_files.check_config_files`)."""
    from decrun.runner.io.config_files import check_config_files

    check_config_files(args, config_dir())
    _hydra_main()


def interrupted_where(exc: KeyboardInterrupt) -> str:
    """Where an interrupt that reached :func:`main` stopped: ``before the run started``, or
    for a sweep interrupted while its jobs ran (the sweeper's
    :class:`~decrun.runner.sweep.stops.Stock` on ``exc.sweep_stock``) which jobs finished
    and which were interrupted — the latter marked ``interrupted`` in their metrics.json
    (:func:`~decrun.runner.job.failures.record_status`) — and the command that resumes the rest."""
    stock = getattr(exc, "sweep_stock", None)
    if stock is None:
        return getattr(exc, "sweep_where", None) or "before the run started"
    from decrun.runner.sweep.stops import resume_command  # lazy: only for an interrupted sweep

    cause = f"interrupted ({interrupt_cause(exc)})"
    for job in stock.running:
        record_status(stock.sweep_dir / job["dir"], "interrupted", cause, {"config_hash": job["config_hash"]})
    return f"during the sweep: {stock.describe('interrupted')}; resume with: {resume_command(stock.sweep_dir)}"


def _completion() -> None:
    """Hydra's shell completion, without the files that are shared pieces of a group rather
    than options (names starting with ``_``, e.g. ``mesh/_post_processing``)."""
    import contextlib
    import io
    import re

    captured = io.StringIO()
    with contextlib.redirect_stdout(captured):
        try:
            _hydra_main()
        except SystemExit:
            pass
    words = [w for w in captured.getvalue().split() if not re.search(r"[=/]_[^/=]*$", w)]
    print(" ".join(words))


def _say(message: str) -> None:
    """One line on stderr, its over-long words cut (:func:`~decrun.runner.job.failures.shorten_words`)."""
    print(shorten_words(message), file=sys.stderr)


def _report(exc: Exception) -> int:
    """Print an exception Hydra let through (see :func:`main`) as one line, as Hydra itself
    would for its own errors; returns the exit code. With -v: the traceback."""
    if _VERBOSE:
        raise exc
    message = error_message(exc)
    if message is None:
        raise exc  # a bug: show it
    for line in message.splitlines():
        _say(line)
    return 1
