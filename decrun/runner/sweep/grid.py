"""The jobs of a grid sweep, on Hydra's public override parser only: ``key=a,b`` and
``key=range(...)`` / ``glob(...)`` overrides expanded to their cartesian product, in the
order of Hydra's basic sweeper (``BasicSweeper.split_arguments``, which decrun does not
import: it is private to Hydra; ``tests/runner/sweep/test_sweep_grid.py`` compares the two).

:func:`grid_size` counts the jobs without making them (a ``range`` by arithmetic), so a
sweep beyond ``hydra.sweeper.max_jobs`` is refused at once, whatever its size."""

from __future__ import annotations

import itertools
import math

from hydra.core.override_parser.types import Override, RangeSweep

__all__ = ["grid", "grid_size", "MAX_JOBS"]

#: the jobs a sweep may plan unless ``hydra.sweeper.max_jobs`` says more (planning composes,
#: checks and hashes every job before the first starts: ~1-3 ms a job, 10 000 jobs in 10-30 s)
MAX_JOBS = 10_000


def _refuse_interval(override: Override) -> None:
    key = override.get_key_element()
    kind = (override.value_type.name if override.value_type is not None else "sweep").lower().replace("_sweep", "")
    raise ValueError(f"{override.input_line}: the decrun sweeper runs a grid of values: give them as a "
                     f"list ({key}=a,b,c) or a range ({key}=range(start,stop,step)); an {kind} is for a "
                     "sampling sweeper's search")


def grid(overrides: list[Override]) -> list[list[str]]:
    """The override lines of each job, in Hydra's basic-sweeper order.

    Each key contributes its values (a sweep: ``key=v`` for every value of
    ``sweep_string_iterator``; a plain override: its one line) and the jobs are
    ``itertools.product`` of those lists in the order the keys first appear (the last
    override of a key replaces its values in that place, as the basic sweeper's ordered
    dict does). The product of N lists of k values each is kᴺ jobs.

    Raises ValueError for a sweep that cannot be enumerated (``interval(...)``), naming it."""
    values: dict[str, list[str]] = {}
    for override in overrides:
        key = override.get_key_element()
        if not override.is_sweep_override():
            values[key] = [f"{key}={override.get_value_element_as_str()}"]
        elif override.is_discrete_sweep():
            values[key] = [f"{key}={value}" for value in override.sweep_string_iterator()]
        else:
            _refuse_interval(override)
    return [list(job) for job in itertools.product(*values.values())]


def _count(override: Override) -> int:
    """The number of values of a discrete sweep override, a range's by arithmetic."""
    value = override.value()
    if isinstance(value, RangeSweep) and value.start is not None and value.stop is not None:
        span = value.range()
        if isinstance(span, range):
            return len(span)
        return max(0, math.ceil((value.stop - value.start) / value.step))
    return sum(1 for _ in override.sweep_string_iterator())


def grid_size(overrides: list[Override]) -> tuple[int, list[tuple[str, int]]]:
    """``(jobs, [(key, number of values), ...])`` of :func:`grid` ``(overrides)`` — the swept
    keys only, in grid order — without making the jobs. ValueError as :func:`grid`."""
    counts: dict[str, int] = {}
    for override in overrides:
        key = override.get_key_element()
        if not override.is_sweep_override():
            counts[key] = 1
        elif override.is_discrete_sweep():
            counts[key] = _count(override)
        else:
            _refuse_interval(override)
    return math.prod(counts.values()), [(key, n) for key, n in counts.items() if n != 1]
