"""Progress for every wait longer than ~2 s, shown only when stderr is a terminal.

- :func:`make_progress` — the ``ctx.progress`` of a run: ``progress(iterable, total=…,
  desc=…)`` wraps loops (time steps) in a tqdm bar, and ``progress.task(desc)`` is a context
  manager for one long call that cannot report steps (an eigen-solve, a factorization and
  solve): a line with the elapsed seconds, refreshed from a thread until the call returns.
- :class:`SweepProgress` — jobs done / total and the ETA of a sweep, in the submitting
  process, counted from the ``metrics.json`` files the jobs write (so it works with every
  launcher: in-process, joblib workers, SLURM); :func:`sweep_size` counts the jobs from the
  sweep's overrides the way Hydra's basic sweeper expands them.

Everything is a no-op when disabled (``progress=false``), when stderr is not a terminal,
or under pytest.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from contextlib import contextmanager, nullcontext
from pathlib import Path
from typing import Iterator

from decrun.runner.io.files import RunFiles, SweepFiles

__all__ = ["terminal", "make_progress", "Progress", "SweepProgress", "sweep_size"]


def terminal(enabled: bool = True) -> bool:
    """True when bars should be drawn: enabled, stderr a terminal, not under pytest."""
    return bool(enabled) and sys.stderr.isatty() and "PYTEST_CURRENT_TEST" not in os.environ


class Progress:
    """``ctx.progress``: a tqdm factory with :meth:`task` for single long calls."""

    def __init__(self, enabled: bool = True):
        self.enabled = enabled

    def __call__(self, iterable, total=None, desc=None, **kwargs):
        if not self.enabled:
            return iterable
        from tqdm import tqdm

        return tqdm(iterable, total=total, desc=desc, leave=False, dynamic_ncols=True, **kwargs)

    @contextmanager
    def task(self, desc: str, refresh: float = 0.5) -> Iterator[None]:
        """Show ``desc`` with the elapsed seconds while the block runs (a thread refreshes it)."""
        if not self.enabled:
            yield
            return
        from tqdm import tqdm

        bar = tqdm(total=None, desc=desc, leave=False, dynamic_ncols=True, bar_format="{desc}: {elapsed}")
        stop = threading.Event()

        def refresh_loop():
            while not stop.wait(refresh):
                bar.refresh()

        thread = threading.Thread(target=refresh_loop, daemon=True)
        thread.start()
        try:
            yield
        finally:
            stop.set()
            thread.join()
            bar.close()


def make_progress(enabled: bool = True) -> Progress:
    """The run's progress factory: bars only when :func:`terminal` (``enabled`` and a tty)."""
    return Progress(terminal(enabled))


def task(progress, desc: str):
    """``progress.task(desc)`` when the factory has one (else a null context)."""
    method = getattr(progress, "task", None)
    return method(desc) if method is not None else nullcontext()


def sweep_size(overrides: list[str], params: dict | None = None) -> int | None:
    """Number of jobs ``decrun -m <overrides>`` runs, ``hydra.sweeper.params`` (``params``)
    included, expanded as Hydra's basic sweeper does; None when it cannot be told."""
    try:
        from hydra.core.override_parser.overrides_parser import OverridesParser

        from decrun.runner.sweep.grid import grid_size  # counted, not made: a grid may be huge

        arguments = [f"{k}={v}" for k, v in (params or {}).items()] + list(overrides)
        return grid_size(OverridesParser.create().parse_overrides(arguments))[0]
    except Exception:  # an unusual sweeper or syntax: show a bar without a total
        return None


class SweepProgress:
    """Jobs done / total with ETA for a sweep, polled from ``sweep_dir`` in a thread.

    A job is done when its ``<job dir>/metrics.json`` exists (written at the end of every job,
    ok or failed). ``start()`` / ``stop()``; a no-op unless ``enabled``. The bar appears once
    the sweep's ``manifest.json`` is written (while the sweep is planned, the decrun sweeper
    shows its own line: :class:`~decrun.runner.sweep.sweeper.PlanningProgress`); a sweeper
    that writes none gets it at once.
    """

    def __init__(self, sweep_dir: Path, total: int | None, enabled: bool = True, poll: float = 0.5):
        self.sweep_dir, self.total, self.enabled, self.poll = Path(sweep_dir), total, enabled, poll
        self._stop = threading.Event()
        self._thread = None
        self._bar = None

    def done(self) -> int:
        """Jobs that have written their metrics.json (in job directories at any depth: any
        ``hydra.sweep.subdir`` pattern)."""
        if not self.sweep_dir.is_dir():
            return 0
        return sum(1 for _ in self.sweep_dir.glob("**/" + RunFiles.METRICS))

    def start(self, planned: bool = False) -> "SweepProgress":
        """Start polling; ``planned``: the sweeper plans the sweep and writes its manifest
        first (the bar waits for it)."""
        if not self.enabled:
            return self
        self._since = time.time() - 1  # a resumed sweep's old manifest is not this plan (mtime: 1 s granularity)
        if not planned:
            self._open()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()
        return self

    def _open(self) -> None:
        from tqdm import tqdm

        self._bar = tqdm(total=self.total, desc="sweep jobs", unit="job", dynamic_ncols=True, file=sys.stderr)

    def _written(self) -> bool:
        """Whether this sweep's plan is written (its manifest.json, new since :meth:`start`)."""
        try:
            return SweepFiles(self.sweep_dir).manifest.stat().st_mtime >= self._since
        except OSError:
            return False

    def _loop(self) -> None:
        while not self._stop.wait(self.poll):
            if self._bar is None and self._written():
                self._open()
            self._update()

    def _update(self) -> None:
        if self._bar is None:
            return
        count = self.done()
        if count > self._bar.n:
            self._bar.update(count - self._bar.n)

    def stop(self) -> None:
        if self._thread is None:
            return
        self._stop.set()
        self._thread.join()
        self._thread = None
        if self._bar is None:
            return
        self._update()
        self._bar.close()
        self._bar = None
