"""The ``decrun`` command's Hydra callbacks (``hydra.callbacks`` in conf/config.yaml): the run
directory guarded and locked (:class:`OutputGuard`), the sweep table written at a sweep's end
(:class:`SweepTable`), and the run or sweep logged to the configured tracker (:func:`track`)."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any, cast

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from decrun.errors import DecrunError
from decrun.runner.io.files import SweepFiles
from decrun.runner.io.locks import LockedError, acquire, release
from decrun.runner.io.paths import OutsideError, hydra_files, inside
from decrun.runner.job.config import config_dir, load_option
from decrun.runner.job.failures import (
    stop,
)
from decrun.runner.job.progress import SweepProgress, sweep_size, terminal


class OutputGuard(Callback):
    """Hydra callback (``hydra.callbacks.output_guard`` in conf/config.yaml, listed first):
    before a single run — before Hydra creates its directory, saves ``.hydra/`` and opens
    the log — refuses a ``.hydra/`` file or log that resolves out of the run directory
    (:func:`decrun.runner.io.paths.inside`) and takes the run directory's lock
    (:mod:`decrun.runner.io.locks`) until the run ends; ``made`` says whether it made the
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
            from decrun.runner.job.hints import resolution_message

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
    from decrun.runner.job.plugins import build
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


    node = cast(dict, OmegaConf.to_container(config.tracker, resolve=False))
    target = node.get("_target_", "")
    choice = next((p.stem for p in (config_dir() / "tracker").glob("*.yaml")
                   if load_option("tracker", p.stem).get("_target_") == target), None)
    defaults = cast(dict, OmegaConf.to_container(load_option("tracker", choice), resolve=False)) if choice else {}
    words = ["decrun-track", str(where), f"tracker={choice}" if choice else f"tracker._target_={target}"]
    words += [f"tracker.{k}={'null' if v is None else v}" for k, v in node.items()
              if k != "_target_" and defaults.get(k, object()) != v]
    return shlex.join(words)
