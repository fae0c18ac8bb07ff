"""Sweep → one pandas table: one row per job, one column per overridden parameter and
per metric.

A sweep directory (``outputs/sweeps/<stamp>/``) holds one sub-directory per job with
Hydra's ``.hydra/overrides.yaml`` and (when the job got that far) ``metrics.json``. Every
job gets a row, also one that failed (``status: failed`` and its ``error``) or never
wrote its metrics (``status: missing``).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import pandas as pd
import yaml

LEADING = ("job", "status", "error")


def _job_dirs(sweep_dir: Path) -> list[Path]:
    jobs = [p for p in sweep_dir.iterdir() if p.is_dir() and (p / ".hydra").is_dir()]

    def order(p: Path):
        head = p.name.split("_", 1)[0]
        return (0, int(head), p.name) if head.isdigit() else (1, 0, p.name)

    return sorted(jobs, key=order)


def _overrides(job: Path) -> dict[str, Any]:
    path = job / ".hydra" / "overrides.yaml"
    if not path.is_file():
        return {}
    out: dict[str, Any] = {}
    for item in yaml.safe_load(path.read_text()) or []:
        key, _, value = str(item).partition("=")
        key = key.lstrip("+~")
        if key.startswith("hydra.") or key.startswith("hydra/"):
            continue
        try:
            out[key] = yaml.safe_load(value)
        except yaml.YAMLError:
            out[key] = value
        if isinstance(out[key], (list, dict)):
            out[key] = value
    return out


def _metrics(job: Path) -> dict[str, Any]:
    path = job / "metrics.json"
    if not path.is_file():
        return {"status": "missing", "error": "no metrics.json (job killed or still running)"}
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        return {"status": "missing", "error": f"unreadable metrics.json: {exc}"}


class NotASweepError(ValueError):
    """The directory is not a sweep root (no ``multirun.yaml``, which ``decrun -m`` writes)."""


def check_sweep_dir(sweep_dir: Path) -> None:
    """Raise :class:`FileNotFoundError` / :class:`NotASweepError` unless ``sweep_dir`` is the
    root of a sweep, so that a table is never written into ``outputs/runs`` or a run."""
    if not sweep_dir.is_dir():
        raise FileNotFoundError(f"sweep directory {str(sweep_dir)!r} does not exist")
    if not (sweep_dir / "multirun.yaml").is_file():
        if (sweep_dir / ".hydra").is_dir():
            raise NotASweepError(f"{str(sweep_dir)!r} is a single run, not a sweep: its metrics are in "
                                 f"{str(sweep_dir / 'metrics.json')!r}")
        raise NotASweepError(f"{str(sweep_dir)!r} is not a sweep directory (no multirun.yaml, which `decrun -m` "
                             "writes at the sweep root); give one of outputs/sweeps/<stamp>")


def sweep_table(sweep_dir: str | os.PathLike) -> pd.DataFrame:
    """Table of a sweep: columns ``job, <overridden keys...>, status, error, <metrics...>``.
    Raises :class:`NotASweepError` for a directory that is not a sweep root."""
    sweep_dir = Path(sweep_dir)
    check_sweep_dir(sweep_dir)
    rows, override_keys, metric_keys = [], [], []
    for job in _job_dirs(sweep_dir):
        overrides, metrics = _overrides(job), _metrics(job)
        metrics.setdefault("status", "ok")
        metrics.setdefault("error", "")
        for key in overrides:
            if key not in override_keys:
                override_keys.append(key)
        for key in metrics:
            if key not in metric_keys and key not in LEADING:
                metric_keys.append(key)
        rows.append({"job": job.name, **overrides, **metrics})
    columns = ["job", *override_keys, "status", "error", *metric_keys]
    return pd.DataFrame(rows, columns=columns)


def _cell(value: Any) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value).replace("|", "\\|").replace("\n", " ")


def to_markdown(table: pd.DataFrame) -> str:
    """GitHub markdown of the table (floats with 4 significant digits)."""
    header = "| " + " | ".join(map(str, table.columns)) + " |"
    rule = "|" + "|".join("---" for _ in table.columns) + "|"
    body = ["| " + " | ".join(_cell(v) for v in row) + " |" for row in table.itertuples(index=False)]
    return "\n".join([header, rule, *body]) + "\n"


def write_sweep_table(sweep_dir: str | os.PathLike) -> pd.DataFrame:
    """Write ``metrics.csv`` and ``metrics.md`` at the sweep root; return the table."""
    sweep_dir = Path(sweep_dir)
    table = sweep_table(sweep_dir)
    for name, text in (("metrics.csv", table.to_csv(index=False)), ("metrics.md", to_markdown(table))):
        tmp = sweep_dir / f".{name}.tmp-{os.getpid()}"
        tmp.write_text(text)
        os.replace(tmp, sweep_dir / name)
    return table


def failed_jobs(table: pd.DataFrame) -> pd.DataFrame:
    """Rows whose status is not ``ok``."""
    return table[table["status"] != "ok"]
