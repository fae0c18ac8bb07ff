"""The jobs of a grid sweep, on Hydra's public override parser only: ``key=a,b`` and
``key=range(...)`` / ``glob(...)`` overrides expanded to their cartesian product, in the
order of Hydra's basic sweeper (``BasicSweeper.split_arguments``, which decrun no longer
imports: it is in ``hydra._internal``; ``tests/runner/test_sweep_grid.py`` compares the two)."""

from __future__ import annotations

import itertools
from hydra.core.override_parser.types import Override

__all__ = ["grid"]


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
            kind = override.value_type.name.lower().replace("_sweep", "")
            raise ValueError(f"{override.input_line}: the decrun sweeper runs a grid of values: give them as a "
                             f"list ({key}=a,b,c) or a range ({key}=range(start,stop,step)); an {kind} is for a "
                             "sampling sweeper's search")
    return [list(job) for job in itertools.product(*values.values())]

