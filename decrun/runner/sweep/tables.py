"""Sweep → one pandas table: one row per job, one column per overridden parameter and
per metric.

A sweep directory (``outputs/sweeps/<stamp>/``) holds one sub-directory per job with
Hydra's ``.hydra/overrides.yaml`` and (when the job got that far) ``metrics.json``. With
a manifest (:mod:`decrun.runner.sweep.manifest`, written by the ``decrun`` sweeper) the table has
one row per *planned* job — ``ok``, ``failed``, ``killed``, ``missing`` (never started or
no metrics), ``stale`` or ``corrupt`` (a result that is not the one its metrics.json
records, or a job file that is not what decrun writes: the error names the file) — so a
killed sweep never looks complete; without one (another sweeper, an older sweep,
``outputs/runs``) one row per job directory. A corrupt manifest.json is a ``corrupt`` row
of its own above one row per job directory.

Columns: ``job``, the overridden keys as written (``app.dt``, ``boundary``), ``status``,
``error``, the metrics (in the order the jobs wrote them; ``metric.<name>`` for a metric
named like a config root key or group, e.g. vector_field's ``metric.boundary``:
:func:`metric_column`), ``result`` (the job's ``result.h5`` — or its journal
``result.h5.partial`` when it was killed — relative to the sweep directory; empty when
there is none), and — only when some job repeats another's — ``same_as``: for a job whose
result is exactly that of an earlier job (the same ``content_sha256``: every number equal),
that job (a swept key that does not change the result, e.g. a stroke length under
precomputed magnitudes). Integer metrics stay integers when a row lacks them (pandas ``Int64``).

:func:`load_sweep` returns exactly the frame ``pandas.read_csv(<sweep>/metrics.csv)``
gives; :func:`stack` puts several sweeps under each other with a ``sweep`` column.
"""

from __future__ import annotations

import io
import math
import os
from pathlib import Path
from typing import Any, Collection, Iterable, Sequence

import numpy as np
import pandas as pd
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException

from decrun.errors import CorruptFileError
from decrun.runner.io.atomic import write_text_atomic
from decrun.runner.io.files import RunFiles, SweepFiles
from decrun.runner.results.checked import load_yaml
from decrun.runner.results.provenance import SAME_AS, mark_duplicates
from decrun.runner.sweep.manifest import MANIFEST, job_dir_name, job_state, read_manifest

__all__ = ["SAME_AS", "mark_duplicates", "sweep_table", "load_sweep", "stack", "swept_keys", "select", "headline_metrics", "to_markdown", "write_sweep_table", "failed_jobs",
           "is_sweep_dir"]

LEADING = ("job", "status", "error")
_PARSER = OverridesParser.create()
#: columns :func:`select` never drops as constant
KEPT = ("sweep", "job", "status")


def is_sweep_dir(path: str | os.PathLike) -> bool:
    """A directory a sweep wrote (``multirun.yaml`` or ``manifest.json`` at its root): the
    only kind :func:`write_sweep_table` writes into."""
    path = Path(path)
    return SweepFiles(path).multirun.is_file() or SweepFiles(path).manifest.is_file()


def _job_dirs(sweep_dir: Path) -> list[Path]:
    jobs = [p for p in sweep_dir.iterdir() if p.is_dir() and (p / RunFiles.HYDRA).is_dir()]

    def order(p: Path):
        head = p.name.split("_", 1)[0]
        return (0, int(head), p.name) if head.isdigit() else (1, 0, p.name)

    return sorted(jobs, key=order)


def parse_overrides(items: Iterable[str]) -> dict[str, Any]:
    """``["app.dt=1e-3", "+x=a", "hydra.foo=1"]`` → ``{"app.dt": 0.001, "x": "a"}``: each
    override read by Hydra's own parser (values typed as Hydra types them; lists and dicts
    kept as the text written), Hydra's own keys left out, a deletion ``~key`` → None."""
    out: dict[str, Any] = {}
    for override in _PARSER.parse_overrides([str(item) for item in items]):
        if override.is_hydra_override():
            continue
        value = override.value() if override.value_type is not None else None
        if isinstance(value, (list, dict)):
            value = override.input_line.partition("=")[2]
        out[override.key_or_group] = value
    return out


def metric_column(name: str, reserved: Collection[str]) -> str:
    """The column of a metric: its name, or ``metric.<name>`` when the name is ``reserved``
    (:func:`reserved_names`: a possible override column, e.g. ``boundary`` — vector_field
    reports the boundary adaptation it used — or one of the table's own columns). Override
    columns are the config keys as written (``app.dt``, ``boundary``), so the two never
    share a column."""
    return f"metric.{name}" if name in reserved else name


def reserved_names(sweep_dir: Path, override_keys: Iterable[str] = ()) -> frozenset[str]:
    """Names a metric column must not take in this sweep's table: the table's own columns,
    the sweep's override columns, and every root key and chosen config group of the sweep's
    config (from its ``multirun.yaml``: the same in every decrun sweep, so a metric keeps its
    column from one sweep to the next)."""
    names = {"job", "sweep", "result", *override_keys}
    path = SweepFiles(sweep_dir).multirun
    if path.is_file():
        try:
            config = load_yaml(path) or {}
        except (OSError, CorruptFileError):  # only the naming of metric columns depends on it
            config = {}
        config = config if isinstance(config, dict) else {}
        hydra = config.get("hydra") if isinstance(config.get("hydra"), dict) else {}
        runtime = hydra.get("runtime") if isinstance(hydra.get("runtime"), dict) else {}
        choices = runtime.get("choices") if isinstance(runtime.get("choices"), dict) else {}
        names.update(str(key) for key in [*config, *choices] if key != "hydra" and not str(key).startswith("hydra/"))
    return frozenset(names)


def _overrides(job: Path) -> tuple[dict[str, Any], str]:
    """The overrides of a job directory from its ``.hydra/overrides.yaml``, and "" or the
    one-line error naming the file when it is not a list of overrides Hydra parses (read
    with ``yaml.safe_load``: a ``!!python/object`` tag is refused, never built)."""
    path = job / RunFiles.HYDRA / "overrides.yaml"
    if not path.is_file():
        return {}, ""
    try:
        items = load_yaml(path) or []
        if not isinstance(items, list) or not all(isinstance(item, str) for item in items):
            raise CorruptFileError(f"{path}: not a list of overrides (got a {type(items).__name__})")
        return parse_overrides(items), ""
    except CorruptFileError as exc:
        return {}, str(exc)
    except OSError as exc:
        return {}, f"{path}: unreadable ({exc})"
    except HydraException as exc:  # Hydra's parser refuses an override (OverrideParseException)
        return {}, f"{path}: an override Hydra cannot parse ({str(exc).strip().splitlines()[0]})"


def _result_path(sweep_dir: Path, job_dir: str) -> str:
    for name in (RunFiles.RESULT, RunFiles.JOURNAL):
        if (sweep_dir / job_dir / name).is_file():
            return f"{Path(job_dir).as_posix()}/{name}"
    return ""


def sweep_table(sweep_dir: str | os.PathLike) -> pd.DataFrame:
    """Table of a sweep: columns ``job, <overridden keys...>, status, error, <metrics...>,
    result`` (module docstring); nullable ``Int64`` for integer columns."""
    sweep_dir = Path(sweep_dir)
    if not sweep_dir.is_dir():
        raise FileNotFoundError(f"sweep directory {str(sweep_dir)!r} does not exist")
    planned, broken = _planned(sweep_dir)
    known = {os.path.normpath(where) for _, where, _, _ in planned}
    unplanned = {p.name: _overrides(p) for p in _job_dirs(sweep_dir) if p.name not in known}
    planned += [(name, name, overrides, None) for name, (overrides, _) in unplanned.items()]
    override_keys = list(dict.fromkeys(key for _, _, overrides, _ in planned for key in overrides))
    reserved = reserved_names(sweep_dir, override_keys)
    rows, metric_keys = [], []
    if broken:  # the plan is unknown: one row says so, the job directories follow
        rows.append({"job": MANIFEST, "status": "corrupt", "error": broken, "result": ""})
    for name, where, overrides, expected in planned:
        job_dir = sweep_dir / where
        metrics = job_state(job_dir, expected)
        if expected is None and name in unplanned and unplanned[name][1]:
            metrics = {**metrics, "status": "corrupt", "error": unplanned[name][1]}
        for key in overrides:
            if key not in override_keys:
                override_keys.append(key)
        metrics = {key if key in LEADING else metric_column(key, reserved): value for key, value in metrics.items()}
        for key in metrics:
            if key not in metric_keys and key not in LEADING:
                metric_keys.append(key)
        rows.append({"job": int(name) if name.isdigit() else name, **overrides, **metrics, "result": _result_path(sweep_dir, where)})
    duplicates = mark_duplicates(rows)
    columns = ["job", *override_keys, "status", "error", *metric_keys, *([SAME_AS] if duplicates else []), "result"]
    return _typed(pd.DataFrame(rows, columns=columns), rows)


def _planned(sweep_dir: Path) -> tuple[list[tuple[str, str, dict, str | None]], str]:
    """The manifest's jobs ``(job, its directory, overrides, config hash)`` and "" — or no
    jobs and the one-line error naming manifest.json when it is corrupt (the table then
    lists the job directories, under a ``corrupt`` row for the manifest)."""
    try:
        manifest = read_manifest(sweep_dir)
        if manifest is None:
            return [], ""
        return [(j["job"], job_dir_name(j), parse_overrides(j["overrides"]), j["config_hash"])
                for j in manifest["jobs"]], ""
    except CorruptFileError as exc:
        return [], str(exc)
    except OSError as exc:
        return [], f"{sweep_dir / MANIFEST}: unreadable ({exc})"
    except HydraException as exc:  # Hydra's parser refuses an override of the manifest
        return [], f"{sweep_dir / MANIFEST}: an override Hydra cannot parse ({str(exc).strip().splitlines()[0]})"


def _typed(table: pd.DataFrame, rows: list[dict]) -> pd.DataFrame:
    """Integer columns with a missing row → ``Int64`` (not float), booleans → ``boolean``."""
    for column in table.columns:
        values = [row[column] for row in rows if column in row and row[column] is not None]
        if not values or len(values) == len(rows):
            continue
        if all(isinstance(v, bool) for v in values):
            table[column] = table[column].astype("boolean")
        elif all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            table[column] = table[column].astype("Int64")
    return table


def load_sweep(sweep_dir: str | os.PathLike) -> pd.DataFrame:
    """The sweep's table as ``pandas.read_csv(<sweep_dir>/metrics.csv)`` returns it (the
    same dtypes), built from the job directories without writing anything."""
    return pd.read_csv(io.StringIO(sweep_table(sweep_dir).to_csv(index=False)))


def stack(sweep_dirs: Sequence[str | os.PathLike]) -> pd.DataFrame:
    """Several sweeps under each other: a first column ``sweep`` (the directory as given),
    the union of their columns (empty where a sweep lacks one) — every sweep's swept keys before
``status``, so a row of any of them can be told apart by its keys."""
    tables = [sweep_table(d).assign(sweep=str(d)) for d in sweep_dirs]
    table = pd.concat(tables, ignore_index=True) if len(tables) > 1 else tables[0]
    keys = list(dict.fromkeys(key for t in tables for key in swept_keys(t)))
    rest = [c for c in table.columns if c not in ("sweep", "job", *keys)]  # status, error, metrics, …, result
    return table[["sweep", "job", *keys, *rest]]


def swept_keys(table: pd.DataFrame) -> list[str]:
    """The override columns of a sweep table (between ``job``/``sweep`` and ``status``), in order."""
    columns = list(table.columns)
    return [c for c in columns[:columns.index("status")] if c not in ("sweep", "job")]


#: a metric naming, comma-separated, further metrics of its run that a table shows by default
#: (a model's declared metrics: their names are the model's, not the app's)
HEADLINE_COLUMN = "headline_metrics"


def headline_metrics() -> tuple[str, ...]:
    """The metrics a table shows by default: every app's ``headline_metrics`` and ``total_seconds``."""
    import importlib
    import pkgutil

    import decrun.apps
    from decrun.apps.base import App

    for module in pkgutil.iter_modules(decrun.apps.__path__):
        importlib.import_module(f"decrun.apps.{module.name}")
    names = [name for cls in App.__subclasses__() for name in cls.headline_metrics]
    return tuple(dict.fromkeys([*names, "total_seconds"]))


def select(table: pd.DataFrame, metrics: Sequence[str] | None = None, sort: Sequence[str] | None = None,
           descending: bool = False, drop_constant: bool = False, narrow: bool = False) -> pd.DataFrame:
    """A view for reading: only the metric columns ``metrics``, in the order given (the
    ``sweep``/``job``/override/``status``/``error``/``result`` columns stay) — with ``narrow`` and no
    ``metrics``, the apps' :func:`headline_metrics` — rows sorted by ``sort``, constant
    columns dropped (except ``sweep``, ``job``, ``status`` and the ``metrics`` asked for). An
    unknown column is a ``KeyError`` naming the columns there are."""
    for key in [*(metrics or []), *(sort or [])]:
        if key not in table.columns:
            raise KeyError(f"no column {key!r}; the columns are {', '.join(map(str, table.columns))}")
    keep = list(metrics or (headline_metrics() if narrow else []))
    if narrow and not metrics and HEADLINE_COLUMN in table.columns:  # a run's own (a model's declared metrics)
        named = table[HEADLINE_COLUMN].dropna().astype(str)
        keep += [name for text in named for name in text.split(",") if name and name in table.columns]
        table = table.drop(columns=[HEADLINE_COLUMN])
    if keep:
        status_at = list(table.columns).index("status")
        leading = list(table.columns[:status_at + 2])
        wanted = [*keep, *(sort or [])] if metrics else [c for c in table.columns if c in keep or c in (sort or [])]
        chosen = list(dict.fromkeys(c for c in wanted  # metrics asked for: in the order asked
                                    if c in table.columns and c not in leading and c not in (SAME_AS, "result")))
        trailing = [c for c in (SAME_AS, "result") if c in table.columns and c not in chosen]
        table = table[leading + chosen + trailing]
    if sort:
        table = table.sort_values(list(sort), ascending=not descending, kind="stable", na_position="last")
    if drop_constant and len(table) > 1:
        constant = [c for c in table.columns if c not in KEPT and c not in (metrics or [])
                    and table[c].astype(str).nunique(dropna=False) <= 1]
        table = table.drop(columns=constant)
    return table


def _cell(value: Any) -> str:
    if value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, (bool, np.bool_)):
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


def write_sweep_table(sweep_dir: str | os.PathLike, *, sweep: bool | None = None) -> pd.DataFrame:
    """Write ``metrics.csv`` and ``metrics.md`` (atomically) at the sweep root; return the
    table. Refuses (``NotADirectoryError``) a directory no sweep wrote, e.g. ``outputs/runs``
    (``sweep=True``: the caller knows it is one, e.g. the end-of-sweep callback)."""
    sweep_dir = Path(sweep_dir)
    table = sweep_table(sweep_dir)
    if not (is_sweep_dir(sweep_dir) if sweep is None else sweep):
        raise NotADirectoryError(f"{sweep_dir} is not a sweep directory (no {SweepFiles.MULTIRUN} or "
                                 f"{SweepFiles.MANIFEST})")
    for name, text in ((SweepFiles.TABLE_CSV, table.to_csv(index=False)), (SweepFiles.TABLE_MD, to_markdown(table))):
        write_text_atomic(sweep_dir / name, text)
    return table


def failed_jobs(table: pd.DataFrame) -> pd.DataFrame:
    """Rows whose status is not ``ok``."""
    return table[table["status"] != "ok"]
