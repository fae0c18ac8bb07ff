"""What the ``decrun`` sweeper knows of a Hydra task beyond Hydra's contract, registered per
task function: the check it runs on every planned job before the first starts (decrun's
task registers the type checks of :func:`decrun.runner.job.experiment.validate`; other Hydra apps get
none) and the modules a joblib worker imports while the sweep is planned (a worker's first
import of decrun's stack is ~1.5 s; the workers are reused for the jobs that follow).
Imports nothing: the ``decrun`` command registers its task at start-up."""

from __future__ import annotations

from typing import Any, Callable

__all__ = ["CHECKS", "WARM", "register_check", "import_modules"]

#: task function → the check run on every planned job's config before the first job starts
CHECKS: dict[Callable, Callable[..., Any]] = {}
#: task function → the modules its jobs import (imported ahead in joblib's workers)
WARM: dict[Callable, tuple[str, ...]] = {}


def register_check(task_function: Callable, check: Callable[..., Any], warm: tuple[str, ...] = ()) -> None:
    """Run ``check(job_config)`` on each planned job of ``task_function`` (the function
    ``@hydra.main`` wraps) before any job starts; a :class:`~decrun.errors.DecrunError` it
    raises stops the sweep in one line naming the job. With ``hydra.sweeper.fast`` the
    sweeper calls ``check(job_config, memo=<dict>)``, the dict shared by the sweep's jobs,
    and adds ``delta=JobDelta(...)`` for a job derived from its group's composition
    (:class:`decrun.runner.sweep.fast.JobDelta`), so the check may redo only what the
    changed keys touch. ``warm``: modules its jobs import, which joblib's workers import
    while the sweep is planned."""
    CHECKS[task_function] = check
    WARM[task_function] = tuple(warm)


def import_modules(names: tuple[str, ...]) -> int:
    """Import ``names`` (in a launcher's worker process); returns the worker's pid."""
    import importlib
    import os

    for name in names:
        importlib.import_module(name)
    return os.getpid()
