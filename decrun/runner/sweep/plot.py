"""A metric against a swept key, from a sweep's table, as a PNG (``decrun-table SWEEP --plot
METRIC --x KEY [-o FILE]``).

One line per combination of the other swept keys that vary (and per sweep when several are
stacked), labelled by their values; only ``ok`` rows are drawn, each line sorted by the key. An
axis is logarithmic when its positive values span more than a decade (a convergence study:
error against ``mesh.subdiv``'s h, or ``app.dt``), linear otherwise; a key that is not numeric
is drawn as categories in the table's order.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from decrun.runner.sweep.tables import swept_keys

__all__ = ["plot_metric", "draw_metric", "default_plot_path"]


def default_plot_path(sweep_dir: str | os.PathLike, metric: str, x: str) -> Path:
    """``<sweep>/<metric>_vs_<key>.png`` (a ``.`` or ``/`` of the names becomes ``_``)."""
    def safe(name: str) -> str:
        return name.replace("/", "_").replace(".", "_")
    return Path(sweep_dir) / f"{safe(metric)}_vs_{safe(x)}.png"


def _spans_decades(values: np.ndarray) -> bool:
    positive = values[np.isfinite(values) & (values > 0)]
    return positive.size == values[np.isfinite(values)].size > 1 and positive.max() > 10 * positive.min()


def plot_metric(table: pd.DataFrame, metric: str, x: str, path: str | os.PathLike) -> Path:
    """Draw ``metric`` against the swept key ``x`` of a sweep table (:func:`stack` or
    :func:`sweep_table`'s), grouped by the other swept keys, into the PNG ``path``; returns it.
    Raises ``KeyError`` naming the columns there are when ``metric`` or ``x`` is not one, and
    ``ValueError`` when no ``ok`` row has a finite numeric value of ``metric``."""
    import matplotlib.pyplot as plt

    figure = draw_metric(table, metric, x)
    path = Path(path)
    try:
        figure.savefig(path, dpi=120)
    finally:
        plt.close(figure)
    return path


def draw_metric(table: pd.DataFrame, metric: str, x: str):
    """The matplotlib Figure of :func:`plot_metric` (one Axes; not saved, not closed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    keys = swept_keys(table)
    for name, what in ((x, "swept key"), (metric, "metric")):
        choices = keys if what == "swept key" else [c for c in table.columns if c not in (*keys, "sweep", "job")]
        if name not in choices:
            raise KeyError(f"no {what} {name!r}; the {what}s are {', '.join(map(str, choices))}")
    rows = table[table["status"] == "ok"].copy()
    rows[metric] = pd.to_numeric(rows[metric], errors="coerce")
    rows = rows[np.isfinite(rows[metric].to_numpy(dtype=float, na_value=np.nan))]
    if rows.empty:
        raise ValueError(f"no ok job has a finite number for {metric!r}: nothing to plot")
    groups = [k for k in [*(["sweep"] if "sweep" in rows and rows["sweep"].nunique() > 1 else []), *keys]
              if k != x and rows[k].astype(str).nunique() > 1]
    numeric_x = pd.to_numeric(rows[x], errors="coerce").notna().all()
    if numeric_x:
        rows[x] = pd.to_numeric(rows[x])
    else:
        order = {value: i for i, value in enumerate(dict.fromkeys(rows[x].astype(str)))}
        rows["_position"] = rows[x].astype(str).map(order)
    figure, axes = plt.subplots(figsize=(6.4, 4.4), constrained_layout=True)
    for label, group in (rows.groupby(groups, sort=False, dropna=False) if groups else [((), rows)]):
        group = group.sort_values(x if numeric_x else "_position")
        values = label if isinstance(label, tuple) else (label,)
        name = ", ".join(f"{k}={v}" for k, v in zip(groups, values, strict=True) if not pd.isna(v)) or metric
        axes.plot(group[x] if numeric_x else group["_position"], group[metric], marker="o", label=name)
    if numeric_x and _spans_decades(rows[x].to_numpy(dtype=float)):
        axes.set_xscale("log")
    if _spans_decades(rows[metric].to_numpy(dtype=float)):
        axes.set_yscale("log")
    if not numeric_x:
        axes.set_xticks(list(order.values()), list(order.keys()))
    axes.set_xlabel(x)
    axes.set_ylabel(metric)
    axes.set_title(f"{metric} against {x}")
    axes.grid(True, which="both", alpha=0.3)
    if numeric_x and axes.get_xscale() == "linear" and (rows[x] == np.round(rows[x])).all():
        axes.xaxis.set_major_locator(MaxNLocator(integer=True))  # mesh.subdiv, steps: whole numbers
    if groups:
        axes.legend(fontsize="small")
    return figure
