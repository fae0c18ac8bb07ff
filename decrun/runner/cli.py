"""The ``decrun`` command (a Hydra app) and ``decrun-table``.

``decrun [-v] [overrides...]`` composes ``conf/config.yaml`` (defaults: mesh, operator,
app, solver), runs one experiment into ``outputs/runs/<stamp>/`` and prints what it
wrote. ``decrun -m key=a,b ...`` runs a sweep into ``outputs/sweeps/<stamp>/<job>/`` and
writes ``metrics.csv`` / ``metrics.md`` at the sweep root (one row per job, also for
jobs that failed); it exits non-zero when a job failed.

This module is the thin Hydra layer: the task hands the composed config and the run
directory to :func:`decrun.runner.run.run` (the data flow of one run is there).

Errors: a :class:`decrun.errors.DecrunError` (bad input) prints one line
``error: <message>`` and exits 1 with no ``result.h5``; ``-v``/``--verbose`` or
``hydra.verbose=true`` show the traceback. Config keys Hydra cannot compose (a misspelt
key, a wrong type, an unknown option) are reported by Hydra before anything runs.
"""

from __future__ import annotations

import logging
import os
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Any, cast

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.experimental.callback import Callback
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf, open_dict, read_write

from decrun.core.choices import Choice, choice_error
from decrun.errors import DecrunError
from decrun.runner.config import config_dir, load_option, register_configs
from decrun.runner.failures import (
    config_error_message,
    exit_code,
    find_memory_error,
    find_os_error,
    install_sigterm,
    interrupt_cause,
    memory_error_text,
    os_error_message,
    override_nesting_error,
    record_status,
    shorten_words,
    stop,
)
from decrun.runner.files import SweepFiles
from decrun.runner.interrupts import ignore_interrupts
from decrun.runner.locks import LockedError, acquire, release
from decrun.runner.paths import OutsideError, hydra_files, inside
from decrun.runner.progress import SweepProgress, sweep_size, terminal
from decrun.runner.sweep.checks import register_check

register_configs()

# ----------------------------------------------------------------------------------
# the Hydra task
# ----------------------------------------------------------------------------------

_VERBOSE = False


def _is_multirun() -> bool:
    return HydraConfig.get().mode == RunMode.MULTIRUN


def _verbose() -> bool:
    return _VERBOSE or bool(HydraConfig.get().verbose)


def _hydra_task(cfg: DictConfig) -> int | float:
    """The Hydra task: :func:`decrun.runner.run.run` in the directory Hydra made."""
    # lazy: the numerical stack loads only once a run starts, not for --help or a bad override (start-up speed)
    from decrun.runner.run import run

    hydra_cfg = HydraConfig.get()
    if _is_multirun() or not cfg.get("figures", True):  # a sweep's jobs draw their own figures
        from decrun.runner import figure_process

        figure_process.dismiss()
    out = Path(hydra_cfg.runtime.output_dir)
    made = OutputGuard.made  # (run directory, outermost directory made with it), when this process made it
    outermost = made[1] if made is not None and made[0].absolute() == out.absolute() else None
    return run(cfg, out, multirun=_is_multirun(), verbose=_verbose(), log_name=hydra_cfg.job.name, made=outermost)


def _check_job(cfg: DictConfig, memo: dict | None = None, delta: Any = None) -> None:
    """The sweeper's check of each planned job: :func:`decrun.runner.experiment.validate`;
    with the sweeper's ``memo`` each distinct plugin node is built once per sweep, and with
    a ``delta`` only a derived job's changed leaves are checked anew."""
    from decrun.runner.experiment import validate  # lazy: the numerical stack (start-up speed)

    validate(cfg, memo=memo, delta=delta)


_hydra_main = hydra.main(version_base="1.3", config_path=str(config_dir()), config_name="config")(_hydra_task)
# every job of a sweep is type-checked before the first starts; joblib's workers import the
# numerical stack while the sweep is planned
register_check(_hydra_task, _check_job, warm=("decrun.runner.run", "decrun.runner.results.recorder"))


class OutputGuard(Callback):
    """Hydra callback (``hydra.callbacks.output_guard`` in conf/config.yaml, listed first):
    before a single run — before Hydra creates its directory, saves ``.hydra/`` and opens
    the log — refuses a ``.hydra/`` file or log that resolves out of the run directory
    (:func:`decrun.runner.paths.inside`) and takes the run directory's lock
    (:mod:`decrun.runner.locks`) until the run ends; ``made`` says whether it made the
    directory (a run refused as bad input removes it again). After a sweep, once
    :class:`SweepTable` has written the table, drops the sweep directory's lock (the
    ``decrun`` sweeper takes it). A refusal is one line and exit 1, nothing written.
    ``run_dir``: the directory of the last single run this process started (for
    :func:`decrun.run`)."""

    run_dir: Path | None = None
    #: when this process made the run directory (it did not exist before the run): the run
    #: directory and the outermost directory made with it (``outputs`` of a first
    #: ``outputs/runs/<stamp>``; the run directory itself when its parent existed), else None
    made: tuple[Path, Path] | None = None

    def on_run_start(self, config: DictConfig, **kwargs) -> None:
        try:
            self._guard(config)
        except Exception as exc:  # hydra.run.dir=${oc.env:UNSET}: one line naming the key, not Hydra's warning
            from decrun.runner.hints import resolution_message

            unresolved = None if isinstance(exc, DecrunError) else resolution_message(exc)
            if unresolved is None:
                raise
            stop(f"error: {unresolved}")

    def _guard(self, config: DictConfig) -> None:
        out = Path(str(config.hydra.run.dir))
        OutputGuard.run_dir = out
        OutputGuard.made = None if os.path.lexists(out) else (out, _outermost_missing(out.absolute()))
        try:
            for name in hydra_files(config.hydra):
                inside(out, out / name, fix="remove the link, or choose another run directory with hydra.run.dir=DIR")
            try:
                out.mkdir(parents=True, exist_ok=True)  # as Hydra does next; its error (if any) is reported then
            except OSError:
                return
            acquire(out, "run", fix="choose another run directory with hydra.run.dir=DIR")
        except (OutsideError, LockedError) as exc:
            stop(f"error: {exc}")  # Hydra turns a callback's exception into a warning: exit here

    def on_run_end(self, config: DictConfig, **kwargs) -> None:
        run_dir = Path(str(config.hydra.run.dir))
        try:
            track(config, run_dir, sweep=False)
        finally:
            release(run_dir)

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        release(Path(str(config.hydra.sweep.dir)))


def _outermost_missing(path: Path) -> Path:
    """The outermost of ``path`` and its parents that does not exist (``path`` must not):
    the first directory ``path.mkdir(parents=True)`` makes."""
    outermost = path
    for parent in path.parents:
        if os.path.lexists(parent):
            break
        outermost = parent
    return outermost


class SweepTable(Callback):
    """Hydra callback (``hydra.callbacks.sweep_table`` in conf/config.yaml): before a sweep,
    refuses a non-empty ``hydra.sweep.dir`` for sweepers without resume (the ``decrun``
    sweeper checks it itself, see :mod:`decrun.runner.sweep.sweeper`); at its end writes
    ``metrics.csv`` and ``metrics.md`` at the sweep root and prints the table. ``sweep_dir``:
    the directory of the last sweep this process started (for :func:`decrun.sweep`)."""

    failed = 0
    sweep_dir: Path | None = None
    _progress: Any = None

    def on_multirun_start(self, config: DictConfig, **kwargs) -> None:
        """Refuse a non-empty sweep dir for sweepers without resume; then show jobs done /
        total with ETA in the submitting process (a terminal only)."""
        sweep_dir = SweepTable.sweep_dir = Path(str(config.hydra.sweep.dir))
        target = str(config.hydra.sweeper.get("_target_", ""))
        if not target.startswith("hydra_plugins.decrun_sweeper.") and sweep_dir.is_dir() and any(sweep_dir.iterdir()):
            from decrun.runner.sweep.sweeper import (  # lazy: Hydra's sweeper machinery (start-up speed)
                SweepError,
                refuse,
            )

            refuse(SweepError(f"error: hydra.sweep.dir={sweep_dir} is not empty; its old jobs would mix into the "
                             f"new table: choose a new hydra.sweep.dir (only hydra/sweeper=decrun resumes)"))
        try:
            shown = bool(config.progress) if "progress" in config else True
        except Exception:  # noqa: BLE001 — an interpolation that does not resolve: the job checks name its key
            shown = False
        if not terminal(shown):
            return
        params = config.hydra.sweeper.get("params") or {}
        params = cast(dict, OmegaConf.to_container(params, resolve=False)) if isinstance(params, DictConfig) else dict(params)
        total = sweep_size(list(config.hydra.overrides.task), params)
        SweepTable._progress = SweepProgress(sweep_dir, total, enabled=True).start(
            planned=target.startswith("hydra_plugins.decrun_sweeper."))

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        from decrun.runner.sweep.tables import (  # lazy: pandas (start-up speed)
            SAME_AS,
            failed_jobs,
            select,
            to_markdown,
            write_sweep_table,
        )

        if SweepTable._progress is not None:
            SweepTable._progress.stop()
            SweepTable._progress = None
        sweep_dir = Path(str(config.hydra.sweep.dir))
        table = write_sweep_table(sweep_dir, sweep=True)
        bad = failed_jobs(table)
        # jobs that ran (status ok, metrics kept) but whose export or figures failed after the run
        exports = [(job, f"{what} failed: {error}") for column, what in (("export_error", "export"),
                                                                          ("figures_error", "figures"))
                   if column in table
                   for job, error in zip(table["job"], table[column].fillna("").astype(str), strict=True) if error]
        SweepTable.failed = len(bad) + len(exports)
        shown = select(table, drop_constant=True, narrow=True)
        print(to_markdown(shown), end="")
        hidden = len(select(table, drop_constant=True).columns) - len(shown.columns)
        if hidden:
            print(f"decrun: {hidden} more column{'s' if hidden > 1 else ''} in {SweepFiles.TABLE_MD} "
                  f"(`decrun-table --all {sweep_dir}`)")
        if SAME_AS in table:
            repeats = table[table[SAME_AS].notna()]
            repeat = "jobs repeat" if len(repeats) > 1 else "job repeats"
            print(f"decrun: {len(repeats)} {repeat} an earlier job's result exactly (column {SAME_AS}: "
                  f"{', '.join(f'{j} = {s}' for j, s in zip(repeats['job'], repeats[SAME_AS], strict=True))}); the keys they differ "
                  f"in do not change the result")
        failed_exports = "".join(f", {n} {what} failed" for what in ("export", "figures")
                                 if (n := sum(error.startswith(what) for _, error in exports)))
        print(f"decrun: sweep of {len(table)} jobs ({len(bad)} not ok{failed_exports}) → "
              f"{SweepFiles(sweep_dir).table_csv}, {SweepFiles.TABLE_MD}")
        for row in bad.itertuples(index=False):
            print(f"decrun: job {row.job} {row.status}: {row.error}", file=sys.stderr)
        for job, error in exports:
            print(f"decrun: job {job} {error}", file=sys.stderr)
        track(config, sweep_dir, sweep=True)


def track(config: DictConfig, where: Path, *, sweep: bool) -> None:
    """Log the sweep (or single run) in ``where`` to ``config.tracker``
    (:mod:`decrun.runner.tracking`) once its own files are written, and say so in one line;
    nothing for ``tracker=none``. Whatever goes wrong is one warning line naming the command
    that logs the files later (``decrun-track``): the run's files are never touched by it."""
    if "tracker" not in config or config.tracker is None:
        return
    from decrun.runner.plugins import build
    from decrun.runner.tracking import Tracker, track_run, track_sweep, warning_line

    tracker = build(config.tracker, "tracker", Tracker)
    try:
        tracker.check()
    except DecrunError:  # the run's own checks reported it already (Experiment), before any work
        return
    if not tracker.active():
        return
    try:
        if sweep:
            tracked = track_sweep(tracker, where)
            print(f"decrun: tracker={tracker.name}: {len(tracked.runs)} jobs under run {tracked.sweep_run} "
                  f"({tracked.sent} sent) in {tracker.store()}")
        else:
            run_id = track_run(tracker, where)
            print(f"decrun: tracker={tracker.name}: run {run_id} in {tracker.store()}")
    except Exception as exc:  # noqa: BLE001 — an unreachable or refusing tracker: one line, the files stay
        print(warning_line(tracker, exc, where, track_command(where, config)), file=sys.stderr)


def track_command(where: Path, config: DictConfig) -> str:
    """``decrun-track <where> tracker=<name> tracker.<option>=<value> ...``: the command that
    logs ``where`` with the tracker options of ``config``."""
    import shlex

    from decrun.runner.config import load_option

    node = cast(dict, OmegaConf.to_container(config.tracker, resolve=False))
    target = node.get("_target_", "")
    choice = next((p.stem for p in (config_dir() / "tracker").glob("*.yaml")
                   if load_option("tracker", p.stem).get("_target_") == target), None)
    defaults = cast(dict, OmegaConf.to_container(load_option("tracker", choice), resolve=False)) if choice else {}
    words = ["decrun-track", str(where), f"tracker={choice}" if choice else f"tracker._target_={target}"]
    words += [f"tracker.{k}={'null' if v is None else v}" for k, v in node.items()
              if k != "_target_" and defaults.get(k, object()) != v]
    return shlex.join(words)


def fast_help() -> str:
    """``decrun --help`` without composing through Hydra (which deep-copies its whole config
    store once per config group): the header, the options of each config group (the YAML
    files of ``conf/``) and the default config (``config.yaml``'s defaults merged in order).
    With overrides (``decrun app=hodge --help``) Hydra's own help runs."""
    root = config_dir()
    main_cfg = OmegaConf.load(root / "config.yaml")
    lines = [str(main_cfg.hydra.help.header).rstrip(), "", "== Configuration groups ==",
             "Compose your configuration from those groups (group=option)", ""]
    for group in sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith((".", "_"))):
        options = sorted(f.stem for f in (root / group).glob("*.yaml") if not f.stem.startswith("_"))
        if options:
            lines.append(f"{group}: {', '.join(options)}")
    merged = OmegaConf.create()
    for entry in main_cfg.defaults:
        if isinstance(entry, str) or entry is None:
            continue
        for group, option in entry.items():
            if not group.startswith(("override ", "hydra/")):  # Hydra's own groups are not the task's
                merged[group] = load_option(group, option)
    body = {k: v for k, v in cast(dict, OmegaConf.to_container(main_cfg)).items() if k not in ("defaults", "hydra")}
    merged = cast(DictConfig, OmegaConf.merge(merged, body))
    lines += ["", "", "== Config ==", "Override anything in the config (foo.bar=value)", "",
              OmegaConf.to_yaml(merged).rstrip(), "", str(main_cfg.hydra.help.footer).rstrip(), ""]
    return "\n".join(lines)


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
    if any(a.startswith("query=") for a in args) and any(a in ("-sc", "--shell-completion") for a in args):
        _completion()
        return
    nested = override_nesting_error(args)  # before Hydra's parser, which would overflow the stack
    if nested:
        print(nested, file=sys.stderr)
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
        print(f"decrun: interrupted ({interrupt_cause(exc)}) {_interrupted_where(exc)}", file=sys.stderr)
        sys.exit(exit_code(exc))
    if SweepTable.failed:
        sys.exit(1)


def hydra_command(args: list[str]) -> None:
    """The ``decrun`` command's Hydra app for the command line ``args`` (``sys.argv[1:]``, set
    by the caller): a single run composes its config once (:func:`_composed_once`); a sweep, a
    config that sets ``hydra.mode`` or a composition error goes Hydra's own way. What the app
    raises, Hydra's exit included, reaches the caller (:func:`main`, :func:`decrun.run`). The
    search path's config files are checked first (:func:`~decrun.runner.config_files.check_config_files`)."""
    from decrun.runner.config_files import check_config_files

    check_config_files(args, config_dir())
    try:
        with _composed_once(args):
            _hydra_main()
    except _ComposeAgain:  # a config that asks for another mode, or an error: Hydra's own way says it
        _hydra_main()


class _ComposeAgain(Exception):
    """The single composition of :func:`_composed_once` did not give a run's config."""


@contextmanager
def _composed_once(args: list[str]):
    """While the block runs, a single run (no ``-m``/``--multirun``, no ``hydra.mode``
    override) composes its config once. Hydra's command line composes it twice: first (in
    MULTIRUN mode) only to read ``hydra.mode``, which no decrun config sets, then for the run.
    Here the first is skipped (``Hydra.get_mode`` answers RUN) and the run's composition
    records ``hydra.mode=RUN`` among its Hydra overrides as Hydra's way does; when that
    composition fails or finds ``hydra.mode`` set to MULTIRUN by a config, it raises
    :class:`_ComposeAgain` before anything ran, and the caller runs the command Hydra's way
    (which then reports the error, or sweeps)."""
    if any(a in ("-m", "--multirun") or a.lstrip("+").startswith("hydra.mode=") for a in args):
        yield
        return
    from hydra._internal.hydra import Hydra

    get_mode, compose_config = Hydra.get_mode, Hydra.compose_config

    def run_mode(self, config_name, overrides):
        return RunMode.RUN

    def compose_for_run(self, config_name, overrides, run_mode, **kwargs):
        if run_mode != RunMode.RUN:
            return compose_config(self, config_name, overrides, run_mode, **kwargs)
        try:
            cfg = compose_config(self, config_name, overrides, run_mode, **kwargs)
        except Exception as exc:
            raise _ComposeAgain() from exc
        if cfg.hydra.mode is not None:  # a config chose the mode: Hydra's way decides
            raise _ComposeAgain()
        with open_dict(cfg), read_write(cfg):  # what Hydra's way records: hydra.mode=RUN, an override
            cfg.hydra.mode = RunMode.RUN
            cfg.hydra.overrides.hydra.append("hydra.mode=RUN")
        return cfg

    setattr(Hydra, "get_mode", run_mode)  # noqa: B010 — assigning a method, which mypy refuses
    setattr(Hydra, "compose_config", compose_for_run)  # noqa: B010
    try:
        yield
    finally:
        setattr(Hydra, "get_mode", get_mode)  # noqa: B010
        setattr(Hydra, "compose_config", compose_config)  # noqa: B010


def _interrupted_where(exc: KeyboardInterrupt) -> str:
    """Where an interrupt that reached :func:`main` stopped: ``before the run started``, or
    for a sweep interrupted while its jobs ran (the sweeper's
    :class:`~decrun.runner.sweep.stops.Stock` on ``exc.sweep_stock``) which jobs finished
    and which were interrupted — the latter marked ``interrupted`` in their metrics.json
    (:func:`~decrun.runner.failures.record_status`) — and the command that resumes the rest."""
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


def error_message(exc: Exception) -> str | None:
    """What the ``decrun`` command prints for an exception Hydra let through (one line; two
    for a Hydra error with an OmegaConf cause, as Hydra prints it), or None for a bug (the
    command shows its traceback). Overrides are read from ``sys.argv`` (the command line)."""
    from hydra.errors import CompactHydraException
    from omegaconf.errors import OmegaConfBaseException

    message = config_error_message(exc, sys.argv[1:]) or typo_message(exc) or missing_plugin_message(exc) or \
        part_missing_message(exc) or group_typo_message(exc) or root_value_message(exc) or append_message(exc)
    if not message and not isinstance(exc, DecrunError):  # hydra.run.dir=${oc.env:UNSET}: Hydra's own keys
        from decrun.runner.hints import resolution_message

        unresolved = resolution_message(exc)
        message = f"error: {unresolved}" if unresolved else None
    if message:
        return message
    if isinstance(exc, CompactHydraException):  # what Hydra's run_and_report prints
        cause: Any = exc.__cause__  # an OmegaConf validation error when choices is not None
        choices = _choices_of(cause)
        if choices is not None:  # a schema field with a closed set of values (optimize.direction)
            return f"error: {choice_error(cause.full_key, cause.value, choices)}"
        if isinstance(exc.__cause__, OmegaConfBaseException):
            return f"{exc}\n{exc.__cause__}"
        return str(exc)
    if isinstance(exc, DecrunError):
        return f"error: {exc}"
    os_error = find_os_error(exc)
    if os_error is not None:
        return f"error: {_name_too_long(os_error) or os_error_message(os_error)}"
    memory = find_memory_error(exc)  # outside a run (composing a sweep): no run config to name
    if memory is not None:
        return f"error: {memory_error_text(memory)}"
    return None


def _say(message: str) -> None:
    """One line on stderr, its over-long words cut (:func:`~decrun.runner.failures.shorten_words`)."""
    print(shorten_words(message), file=sys.stderr)


def _name_too_long(exc: OSError) -> str | None:
    """For a name too long for the file system (``mesh=<120 kB>``, ``+app.<120 kB>=1``: Hydra
    looks the name up as a config file or group), the command-line override it came from —
    the longest one — as the culprit; None for any other OS error."""
    import errno

    if exc.errno != errno.ENAMETOOLONG:
        return None
    args = [a for a in sys.argv[1:] if not a.startswith("-")]
    if not args:
        return None
    culprit = max(args, key=len)
    return f"{culprit}: a name too long for the file system ({os.strerror(exc.errno)}: a file or directory " \
           f"name has at most 255 bytes); shorten it"


def typo_message(exc: Exception) -> str | None:
    """For an option of a plugin group Hydra refuses to override (``app.stpes=3``: not in
    the group's config), the decrun message of its ``+`` form — the group's options and the
    closest one — instead of Hydra's advice to append it; also for a plugin whose config
    directory the command adds with ``hydra.searchpath``. None for any other error."""
    import re

    from omegaconf.errors import ConfigAttributeError, ConfigKeyError

    from decrun.runner.config import PLUGIN_GROUPS

    match = re.match(r"Could not override '([^']+)'", str(exc))
    if match is None or not isinstance(exc.__cause__, (ConfigAttributeError, ConfigKeyError)):
        return None
    key = match.group(1)
    if key.split(".", 1)[0] not in PLUGIN_GROUPS:
        return None
    overrides = []  # the group choices and experiments of the command, the key in its + form
    for arg in sys.argv[1:]:
        name, sep, value = arg.partition("=")
        bare = name.lstrip("+~")
        if sep and bare == "hydra.searchpath":  # where a plugin's config directory is
            overrides.append(arg)
            continue
        if not sep or bare.startswith(("hydra.", "hydra/")):
            continue
        if bare == key:
            overrides.append(f"+{key}={value.split(',')[0]}")  # a sweep: its first value
        elif "." not in bare:
            overrides.append(f"{name}={value.split(',')[0]}")
    from decrun.runner.config import compose_config
    from decrun.runner.experiment import validate  # lazy: the numerical stack (start-up speed)

    try:
        validate(compose_config(overrides))
    except DecrunError as error:
        return f"error: {error}"
    except Exception:  # the command cannot be recomposed this way: Hydra's message stands
        return None
    return None


def missing_plugin_message(exc: Exception) -> str | None:
    """For a Hydra launcher or sweeper whose plugin is not installed (``hydra/launcher=ray``
    without the extra), the pip line that installs it (:data:`decrun.runner.hints.PLUGIN_EXTRAS`)."""
    import re

    from hydra.errors import MissingConfigException

    from decrun.runner.hints import PLUGIN_EXTRAS

    if not isinstance(exc, MissingConfigException):
        return None
    match = re.search(r"Could not (?:find|load) '(hydra/(?:launcher|sweeper))/([^']+)'", str(exc))
    if match is None or match.group(2) not in PLUGIN_EXTRAS.get(match.group(1), {}):
        return None
    group, name = match.groups()
    plugin, extra = PLUGIN_EXTRAS[group][name]
    return f'error: {group}={name}: {plugin} is not installed; pip install "decrun[{extra}]"'


def part_missing_message(exc: Exception) -> str | None:
    """For a part a composed model names that no config directory has (``- parts@_here_:
    [halfar_dynamics, glen_lw]`` in ``app/halfar``): one line naming the model and the part,
    with the closest part and every part of the search path's ``<group>/parts/`` directories
    (decrun's and those added with ``hydra.searchpath``). None for any other error."""
    import difflib
    import re

    from hydra.errors import MissingConfigException

    if not isinstance(exc, MissingConfigException):
        return None
    text = str(exc)
    match = re.search(r"In '([^'/]+)/([^']+)': Could not (?:find|load) '([^']+?)/parts/([^']*)'", text)
    if match is None or match.group(1) != match.group(3):
        return None
    group, model, _, part = match.groups()
    named = part and "/" not in part and part not in (".", "..")  # `parts=[/etc/passwd]`, `parts=['']`: no name
    options: set[str] = set()
    for root in re.findall(r"path=file://(\S+)", text):
        directory = Path(root) / group / "parts"
        if directory.is_dir():
            options.update(p.stem for p in directory.glob("*.yaml") if not p.stem.startswith("_"))
    close = difflib.get_close_matches(part, sorted(options), n=1)
    hint = f"; did you mean {close[0]}?" if close else ""
    listing = f" (the parts: {' | '.join(sorted(options))})" if options else " (there are none)"
    if not named:
        return f"error: {group}={model}: {shorten_words(repr(part))} is not a part's name (a file in {group}/parts/, " \
               f"no path){listing}"
    return (f"error: {group}={model}: no part {part} ({group}/parts/{part}.yaml is in no config directory of the "
            f"search path){hint}{listing}")


def group_typo_message(exc: Exception) -> str | None:
    """For a config-group option that does not exist (``app=smooth``, ``mesh=icosahedron``,
    ``hydra/launcher=nonexistent``): one line with the closest option and every option of the
    group (not the files that are shared pieces of one, ``_``-prefixed), instead of Hydra's
    listing with the config search path. None for any other error."""
    import difflib
    import re

    from hydra.errors import MissingConfigException

    if not isinstance(exc, MissingConfigException):
        return None
    match = re.search(r"Could not (?:find|load) '([^']+)/([^'/]+)'", str(exc))
    if match is None:
        return None
    group, name = match.groups()
    options = sorted(option for option in (exc.options or []) if not option.startswith("_"))
    if not options:
        return None
    close = difflib.get_close_matches(name, options, n=1) or _same_stem(name, options)
    # as the command line gave it: a group outside the defaults list is added with + (+experiment=...)
    plus = next((arg[:len(arg) - len(arg.lstrip("+"))] for arg in sys.argv[1:]
                 if arg.lstrip("+") == f"{group}={name}"), "")
    hint = f"; did you mean `{plus}{group}={close[0]}`?" if close else ""
    return f"error: {plus}{group}={name}: no such option{hint} (the options: {' | '.join(options)})"


def append_message(exc: Exception) -> str | None:
    """For a group outside the config's defaults list chosen without ``+``
    (``experiment=fig5_8_t_hole``): one line with the ``+`` form Hydra advises, instead of
    its two. None for any other error."""
    import re

    from hydra.errors import ConfigCompositionException

    if not isinstance(exc, ConfigCompositionException):
        return None
    match = re.match(r"Could not override '([^']+)'\. No match in the defaults list\.\s+"
                     r"To append to your default list use (\S+)", str(exc))
    if match is None:
        return None
    key, fix = match.groups()
    return f"error: {fix.lstrip('+')}: {key} is not in the config's defaults list, it is added with +; use `{fix}`"


def _same_stem(name: str, options: list[str], least: int = 4) -> list[str]:
    """The option sharing the longest start with ``name``, of at least ``least`` characters
    (``cholesky`` → ``cholmod``), as a one-item list; empty when none shares that much. For
    names a spelling distance misses because they are another word of the same stem."""
    import os.path

    shared = {option: len(os.path.commonprefix([name.lower(), option.lower()])) for option in options}
    best = max(shared, key=lambda option: shared[option], default=None)
    return [best] if best is not None and shared[best] >= least else []


def root_value_message(exc: Exception) -> str | None:
    """For a root option given a value of the wrong type (``progress=maybe``): one line naming
    the option, the value and what it takes, instead of Hydra's merge report."""
    import re

    from omegaconf.errors import ValidationError

    cause = exc.__cause__ if isinstance(exc.__cause__, ValidationError) else None
    match = re.match(r"Error merging override (\S+)=(.*)", str(exc))
    if cause is None or match is None:
        return None
    key, value = match.groups()
    if "not a valid bool" not in str(cause):  # other types keep their own handling (closed choices)
        return None
    return f"error: {key}={value}: not a boolean; use `{key}=true` or `{key}=false`"


def _choices_of(cause: BaseException | None) -> type[Choice] | None:
    """The :class:`~decrun.core.choices.Choice` type of the schema field an OmegaConf
    ValidationError is about, or None (another error, or a field of another type)."""
    import typing

    from omegaconf.errors import ValidationError

    owner, key = getattr(cause, "object_type", None), getattr(cause, "key", None)
    if not (isinstance(cause, ValidationError) and isinstance(owner, type) and isinstance(key, str)):
        return None
    try:
        hint = typing.get_type_hints(owner).get(key)
    except Exception:  # an owner whose annotations cannot be resolved
        return None
    return hint if isinstance(hint, type) and issubclass(hint, Choice) else None


# ----------------------------------------------------------------------------------
# decrun-table
# ----------------------------------------------------------------------------------


def table_main(argv: list[str] | None = None) -> int:
    """Console script ``decrun-table SWEEP [SWEEP ...]``: rebuild each sweep's ``metrics.csv``
    / ``metrics.md`` (only in directories a sweep wrote) and print the table — several
    sweeps stacked with a ``sweep`` column; one line on stderr for each ``corrupt`` job,
    naming the file, and for each sweep directory the table could not be saved in (read-only:
    the table is printed all the same). Exit 1 when a job is not ok, 2 on an error."""
    import argparse

    # lazy: pandas, only for decrun-table (start-up speed)
    from decrun.runner.sweep.tables import failed_jobs, is_sweep_dir, select, stack, to_markdown, write_sweep_table

    parser = argparse.ArgumentParser(prog="decrun-table", description=table_main.__doc__)
    parser.add_argument("sweep_dirs", nargs="+", metavar="SWEEP", help="a sweep directory, e.g. outputs/sweeps/<stamp>")
    parser.add_argument("--csv", action="store_true", help="print CSV instead of markdown")
    parser.add_argument("--metrics", help="comma-separated metric columns to show (default: the apps' headline "
                                          "metrics in markdown, all in --csv)")
    parser.add_argument("--all", action="store_true", help="show every column, constant ones included")
    parser.add_argument("--sort", help="comma-separated columns to sort the rows by")
    parser.add_argument("--descending", action="store_true", help="sort in descending order")
    parser.add_argument("--drop-constant", action=argparse.BooleanOptionalAction, default=None,
                        help="drop columns with one value in every row (default: on for markdown, off for --csv and --all)")
    args = parser.parse_args(argv)

    def split(text: str | None) -> list[str] | None:
        return [k.strip() for k in text.split(",") if k.strip()] if text else None

    unsaved = []  # a sweep directory the table cannot be written into (read-only): printed, not saved
    try:
        for sweep_dir in args.sweep_dirs:
            if not Path(sweep_dir).is_dir():
                raise FileNotFoundError(f"sweep directory {sweep_dir!r} does not exist")
            if is_sweep_dir(sweep_dir):
                try:
                    write_sweep_table(sweep_dir)
                except OSError as exc:
                    cause = os.strerror(exc.errno) if exc.errno else str(exc)
                    unsaved.append(f"decrun-table: the table above could not be saved in {sweep_dir} "
                                   f"({SweepFiles.TABLE_CSV}, {SweepFiles.TABLE_MD}: {cause}); it is printed only "
                                   f"(`decrun-table --csv {sweep_dir} > FILE` saves it elsewhere)")
        table = stack(args.sweep_dirs)
        if len(args.sweep_dirs) == 1:
            table = table.drop(columns="sweep")
        drop = not (args.csv or args.all) if args.drop_constant is None else args.drop_constant
        shown = select(table, split(args.metrics), split(args.sort), args.descending, drop,
                       narrow=not (args.all or args.csv))
    except (FileNotFoundError, KeyError, DecrunError) as exc:
        print(shorten_words(f"decrun-table: error: {exc.args[0] if isinstance(exc, KeyError) else exc}"),
              file=sys.stderr)
        return 2
    if table.empty:
        print(f"decrun-table: error: no jobs (no manifest.json, no job directories with .hydra/) in "
              f"{', '.join(args.sweep_dirs)}", file=sys.stderr)
        return 2
    print(shown.to_csv(index=False) if args.csv else to_markdown(shown), end="")
    for row in table[table["status"] == "corrupt"].itertuples(index=False):  # one line each, naming the file
        print(f"decrun-table: job {row.job} corrupt: {row.error}", file=sys.stderr)
    for line in unsaved:
        print(line, file=sys.stderr)
    return 1 if len(failed_jobs(table)) else 0


# ----------------------------------------------------------------------------------
# decrun-track
# ----------------------------------------------------------------------------------


def track_main(argv: list[str] | None = None) -> int:
    """Console script ``decrun-track DIR [tracker=mlflow tracker.uri=URI ...]``: log the sweep
    (a directory with ``manifest.json`` or ``multirun.yaml``) or the single run in ``DIR`` to
    the tracker the overrides compose (:mod:`decrun.runner.tracking`) — a sweep that ran
    with ``tracker=none``, or whose tracker could not be reached. Runs it logged before go
    into the same tracker runs (their ids are kept in the directories). Exit 2 on an error."""
    import argparse

    parser = argparse.ArgumentParser(prog="decrun-track", description=track_main.__doc__)
    parser.add_argument("dir", metavar="DIR", help="a sweep directory (outputs/sweeps/<stamp>) or a run directory")
    parser.add_argument("overrides", nargs="*", help="tracker=mlflow and tracker.<option>=<value> overrides")
    args = parser.parse_args(argv)
    from decrun.runner.config import compose_config
    from decrun.runner.plugins import build
    from decrun.runner.sweep.tables import is_sweep_dir
    from decrun.runner.tracking import Tracker, track_run, track_sweep

    where = Path(args.dir)
    try:
        outside = [o for o in args.overrides if not o.startswith("tracker")]
        if outside:
            raise DecrunError(f"{outside[0]}: decrun-track takes only tracker overrides (tracker=mlflow "
                              "tracker.uri=URI ...)")
        if not where.is_dir():
            raise DecrunError(f"{where}: no such directory; give a sweep or run directory")
        tracker = build(compose_config(args.overrides).tracker, "tracker", Tracker)
        tracker.check()
        if not tracker.active():
            raise DecrunError("tracker=none logs nothing; choose one, e.g. decrun-track DIR tracker=mlflow")
        if is_sweep_dir(where):
            tracked = track_sweep(tracker, where)
            print(f"decrun-track: tracker={tracker.name}: {len(tracked.runs)} jobs under run {tracked.sweep_run} "
                  f"({tracked.sent} sent) in {tracker.store()}")
        else:
            print(f"decrun-track: tracker={tracker.name}: run {track_run(tracker, where)} in {tracker.store()}")
    except DecrunError as exc:
        print(shorten_words(f"decrun-track: error: {exc}"), file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 — the tracker's own errors (unreachable server): one line
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        print(shorten_words(f"decrun-track: error: {type(exc).__name__}: {text}"), file=sys.stderr)
        return 2
    return 0
