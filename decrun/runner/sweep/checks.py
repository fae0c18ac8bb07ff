"""The checks the ``decrun`` sweeper runs on every planned job before the first starts,
registered per Hydra task function (decrun's task registers the type checks of
:func:`decrun.runner.run.validate`; other Hydra apps get none). Imports nothing: the
``decrun`` command registers its check at start-up."""

from __future__ import annotations

from typing import Any, Callable

__all__ = ["CHECKS", "register_check"]

#: task function → the check run on every planned job's config before the first job starts
CHECKS: dict[Callable, Callable[[Any], Any]] = {}


def register_check(task_function: Callable, check: Callable[[Any], Any]) -> None:
    """Run ``check(job_config)`` on each planned job of ``task_function`` (the function
    ``@hydra.main`` wraps) before any job starts; a :class:`~decrun.errors.DecrunError` it
    raises stops the sweep in one line naming the job."""
    CHECKS[task_function] = check
