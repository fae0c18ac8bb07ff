"""``decrun-table --plot`` and ``decrun-table --compare``: what the command prints and its exit
code (the parsing stays in :func:`decrun.runner.command.table.table_main`)."""

from __future__ import annotations

import sys
from typing import Sequence

__all__ = ["plot_command", "compare_command"]


def plot_command(sweep_dirs: Sequence[str], metric: str, x: str | None, output: str | None) -> int:
    """Draw ``metric`` against the swept key ``x`` of the (stacked) sweeps into ``output``
    (default: :func:`decrun.runner.sweep.plot.default_plot_path` of the first sweep) and print
    where; exit 2 with one line on an error."""
    from decrun.runner.sweep.plot import default_plot_path, plot_metric
    from decrun.runner.sweep.tables import stack, swept_keys

    try:
        if not sweep_dirs:
            raise ValueError("--plot needs a sweep directory: decrun-table SWEEP --plot METRIC --x KEY")
        table = stack(sweep_dirs)
        if x is None:
            raise ValueError(f"--plot needs --x KEY, one of the swept keys: {', '.join(swept_keys(table))}")
        path = plot_metric(table, metric, x, output or default_plot_path(sweep_dirs[0], metric, x))
    except (FileNotFoundError, KeyError, ValueError, OSError) as exc:
        print(f"decrun-table: error: {exc.args[0] if isinstance(exc, KeyError) else exc}", file=sys.stderr)
        return 2
    print(f"decrun-table: wrote {path}")
    return 0


def compare_command(run_a: str, run_b: str, csv: bool) -> int:
    """Print :func:`decrun.runner.sweep.compare.compare_runs` of two runs (markdown, or CSV);
    exit 2 with one line when a run has no result."""
    from decrun.errors import DecrunError
    from decrun.runner.sweep.compare import compare_runs
    from decrun.runner.sweep.tables import to_markdown

    try:
        table = compare_runs(run_a, run_b)
    except (FileNotFoundError, DecrunError) as exc:
        print(f"decrun-table: error: {exc}", file=sys.stderr)
        return 2
    print(table.to_csv(index=False) if csv else to_markdown(table), end="")
    return 0
