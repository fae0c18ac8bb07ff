"""Experiment trackers (the ``tracker`` config group): a sweep's jobs, as runs of a tracking
server, from the files decrun already wrote.

``tracker=none`` (the default) logs nothing; ``tracker=mlflow``
(:mod:`decrun.runner.tracking.mlflow_tracker`) logs each job of a sweep as one MLflow run
nested under one run for the sweep. What a job's run holds is read from its directory, the
same files ``metrics.csv`` is made of, once the sweep's table is written:

- params: the job's resolved options as flattened keys (``app.dt``, ``mesh.subdiv``; from the
  resolved config stored in ``result.h5``, else ``.hydra/config.yaml``) and the option chosen in
  each config group (``operator: barycentric``); the job's overrides as written in the tag
  ``decrun.overrides``;
- metrics: the numbers of ``metrics.json`` (booleans as 0/1); its strings as tags
  ``metric.<name>``; each recorded series of ``result.h5`` (or of the journal of a killed job)
  with one value per step as the metric history ``series/<name>`` at its ``step``;
- artifacts: the figures (``*.png``, ``*.gif``), ``.hydra/config.yaml`` and ``overrides.yaml``, and with
  ``tracker.result_h5=true`` the ``result.h5`` itself;
- tags: ``decrun.config_hash``, ``status`` (``ok`` | ``failed`` | ``killed``; the table's own
  word in ``decrun.status``, its error in ``decrun.error``) and the git commit the job ran
  (``mlflow.source.git.commit``).

The jobs are logged by the process that ran the sweep, at its end, from the sweep's manifest
and job directories (:func:`track_sweep`): the same on every launcher (local, joblib, SLURM,
Ray — a job on a node never needs to reach the tracking server, and one writer at a time is
what a sqlite store wants). Each logged run's id is kept in its directory
(``tracking.json``, keyed by the tracker's store, with a fingerprint of what was logged):
``hydra.sweeper.resume=true`` updates the runs it finds there — a job rerun since is logged
into its old run, an unchanged one is not touched — and never makes a second run for a job.
A tracker that cannot be reached is one warning line: the sweep's own files are written
before any tracking starts and are never touched by it.

A second tracker is one module and one YAML file: a dataclass subclass of :class:`Tracker`
implementing :meth:`Tracker.log_run` (and :meth:`Tracker.check`, :meth:`Tracker.store`)
named by ``conf/tracker/<name>.yaml``'s ``_target_`` (on ``hydra.searchpath`` for one outside
decrun).
"""

from __future__ import annotations

import io
import json
import logging
import os
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, cast

from decrun.core.digest import Digest
from decrun.errors import ConfigError, CorruptFileError
from decrun.runner.io.config_files import check_aliases

__all__ = ["Tracker", "NoTracker", "RunRecord", "STATUS", "track_sweep", "track_run",
           "job_record", "read_series", "flatten", "read_state"]

log = logging.getLogger("decrun")

#: a decrun job status (:mod:`decrun.runner.sweep.tables`) → the tracker's ``status`` tag
STATUS = {"ok": "ok", "failed": "failed", "corrupt": "failed", "stale": "failed", "killed": "killed",
          "interrupted": "killed", "missing": "killed"}


@dataclass
class RunRecord:
    """What one run (a sweep job, a single run, or the sweep itself) gives its tracker.

    ``name``: the run's name (``job 3``, the sweep directory's name); ``dir``: its directory;
    ``status``: ``ok`` | ``failed`` | ``killed`` (:data:`STATUS`); ``params``: flattened
    option → value as text; ``metrics``: name → float; ``series``: name → ``(steps, values)``,
    two 1-D arrays of one length; ``tags``: name → text; ``artifacts``: files to upload;
    ``parent``: the sweep's run id for a job (None otherwise)."""

    name: str
    dir: Path
    status: str
    params: dict[str, str] = field(default_factory=dict)
    metrics: dict[str, float] = field(default_factory=dict)
    series: dict[str, tuple[Any, Any]] = field(default_factory=dict)
    tags: dict[str, str] = field(default_factory=dict)
    artifacts: list[Path] = field(default_factory=list)
    parent: str | None = None

    def fingerprint(self) -> str:
        """16 hex digits of sha256 over everything logged (params, metrics, series, tags, the
        artifacts' names and sizes): equal when a resumed sweep finds the job as it was."""
        h = Digest().json([self.name, self.status, self.params, self.metrics, self.tags, self.parent])
        for name, (steps, values) in sorted(self.series.items()):
            h.text(name).array(steps, header=False).array(values, header=False)
        for path in self.artifacts:
            h.text(f"{path.name}:{path.stat().st_size}:{path.stat().st_mtime_ns}")
        return h.hexdigest(16)


@dataclass
class Tracker:
    """Base of the trackers (``tracker=<name>``). A subclass's fields are its options
    (``conf/tracker/<name>.yaml``); it implements :meth:`log_run`, and :meth:`check` and
    :meth:`store` where it has a package to import or a store to name."""

    name: ClassVar[str] = ""

    def active(self) -> bool:
        """Whether this tracker logs anything (False for ``tracker=none``)."""
        return True

    def check(self) -> None:
        """ConfigError before a sweep's first job when the tracker cannot work here (its
        package not installed), naming the key and the override that fixes it."""

    def store(self) -> str:
        """Where runs go (a tracking URI, a project): a run id kept in a run directory
        belongs to this store only."""
        return self.name

    def log_run(self, record: RunRecord, run_id: str | None) -> str:  # pragma: no cover - abstract
        """Log ``record`` as one run — a new one when ``run_id`` is None or unknown to the
        store, else into the run ``run_id`` (a resumed sweep: params unchanged, new metric
        values, tags, artifacts and status) — and return its id. A job's run is nested under
        ``record.parent``. Raises :class:`TrackingFailed` (or any error) when it cannot."""
        raise NotImplementedError

    def close(self) -> None:
        """Flush and let go of the connection after the last run of a sweep."""


@dataclass
class NoTracker(Tracker):
    """``tracker=none``: nothing is logged."""

    name: ClassVar[str] = "none"

    def active(self) -> bool:
        return False

    def log_run(self, record: RunRecord, run_id: str | None) -> str:
        return ""


# ----------------------------------------------------------------------------------
# what a run directory holds, as a RunRecord
# ----------------------------------------------------------------------------------


def flatten(values: Any, prefix: str = "") -> dict[str, str]:
    """A resolved config as ``{"app.dt": "0.001", "mesh.hole_balls": "[[0, 0, 1, 0.5]]"}``:
    every leaf under its dotted key, its value as text (lists as JSON, null as ``None``);
    an empty mapping is a leaf ``{}``."""
    out: dict[str, str] = {}
    if isinstance(values, dict) and values:
        for key, value in values.items():
            out.update(flatten(value, f"{prefix}{key}."))
        return out
    key = prefix[:-1]
    out[key] = json.dumps(values) if isinstance(values, (list, dict)) else str(values)
    return out


def read_series(job_dir: Path) -> tuple[dict[str, tuple[Any, Any]], dict[str, str], list[str]]:
    """The recorded series of a run directory: ``name → (steps, values)`` for each series with
    one number per step (from ``result.h5``'s ``series`` group, read through the checked
    readers of :mod:`decrun.runner.results.checked`; a killed job's from its journal), the
    result's root attributes a record uses (:data:`RECORD_ATTRS`; a journal's all), and the
    names of the series that are not one number per step (arrays per step: they stay in
    result.h5, unread, and the run's tag ``decrun.series_not_logged`` names them)."""
    import numpy as np

    from decrun.runner.io.files import RunFiles
    from decrun.runner.results.checked import checked_members, open_h5
    from decrun.runner.results.provenance import decrun_attrs

    path = RunFiles(job_dir).result
    if path.is_file():
        with open_h5(path) as f:
            attrs = decrun_attrs(f, path, RECORD_ATTRS)
            group = f.get("series")
            arrays, skipped = {}, []
            if group is not None:  # every member checked (check_dataset) before it is read
                for name, member in checked_members(group, path):
                    if _one_per_step(member):
                        arrays[name] = member[()]
                    else:  # an array per step is named, not read: it can be the bulk
                        skipped.append(name)
    elif RunFiles(job_dir).journal.is_file():
        from decrun.runner.results.reading import read_result

        stored = read_result(path)
        attrs, skipped = stored.provenance, []
        arrays = {name: np.asarray(values) for name, values in stored.series.items()}
    else:
        return {}, {}, []
    steps = np.asarray(arrays.get("step", np.arange(max((len(a) for a in arrays.values()), default=0))))
    series = {}
    for name, values in arrays.items():
        if name == "step":
            continue
        if _one_per_step(values) and len(values) == len(steps):
            series[name] = (steps.astype(np.int64), np.asarray(values, dtype=np.float64))
        else:
            skipped.append(name)
    return series, attrs, skipped


#: the root attributes of result.h5 a run's record uses (:func:`job_record`)
RECORD_ATTRS = ("config_yaml", "git_commit")


def _one_per_step(values: Any) -> bool:
    """Whether an array (or an h5py dataset, from its metadata) is one number per step."""
    return len(values.shape) == 1 and values.dtype.kind in "biuf"


def _params(job_dir: Path, attrs: dict, shared: dict | None = None) -> dict[str, str]:
    """The job's resolved config as flattened params (:func:`flatten`, ``hydra`` left out):
    from the YAML stored in result.h5, else ``.hydra/config.yaml`` resolved here (an
    interpolation that does not resolve here stays as written).

    ``shared``: a dict kept across the jobs of one sweep, whose configs differ in a few
    sections: a top-level section whose YAML text an earlier job had is taken flattened from
    there instead of being built again (a section with an anchor or alias, whose meaning can
    lie outside its text, or a text that is not ASCII is always built)."""
    import yaml
    from omegaconf import OmegaConf

    from decrun.runner.io.files import RunFiles

    text = attrs.get("config_yaml")
    if isinstance(text, str) and text:
        where = f"{job_dir}/{RunFiles.RESULT}: attribute config_yaml"
        shared = {} if shared is None else shared
        params: dict[str, str] = {}
        with _composed(text, where) as (loader, root):
            if not isinstance(root, yaml.MappingNode):
                return {}
            for key_node, node in root.value:
                key = loader.construct_object(key_node, deep=True)
                if key == "hydra":
                    continue
                section = text[node.start_mark.index:node.end_mark.index] if text.isascii() else ""
                cacheable = section and "&" not in section and "*" not in section
                flat = shared.get((key, section)) if cacheable else None
                if flat is None:
                    flat = flatten(loader.construct_object(node, deep=True), f"{key}.")
                    if cacheable:
                        shared[(key, section)] = flat
                params.update(flat)
        return params
    path = job_dir / RunFiles.HYDRA / "config.yaml"
    if not path.is_file():
        return {}
    text = path.read_text()
    check_aliases(text, path)
    cfg = OmegaConf.load(io.StringIO(text))
    try:
        config = cast(dict, OmegaConf.to_container(cfg, resolve=True))  # a config.yaml is a mapping
    except Exception:  # noqa: BLE001 — e.g. ${oc.env:X} unset in this process: the text as written
        config = cast(dict, OmegaConf.to_container(cfg, resolve=False))
    return flatten({k: v for k, v in config.items() if k != "hydra"}) if config else {}


@contextmanager
def _composed(text: str, where: str):
    """``(loader, root node)`` of the YAML ``text``: libyaml's parse into nodes, none of them
    built into Python objects yet (``loader.construct_object(node, deep=True)`` builds one, as
    ``yaml.safe_load`` would); CorruptFileError naming ``where``."""
    import yaml

    check_aliases(text, where)  # an alias bomb, before construct_object and flatten walk its expansion
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)(text)
    try:
        yield loader, loader.get_single_node()
    except (yaml.YAMLError, RecursionError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise CorruptFileError(f"{where}: not YAML decrun reads ({first})") from None
    finally:
        loader.dispose()


def _choices(job_dir: Path) -> dict[str, str]:
    """The option chosen in each of the job's config groups (``.hydra/hydra.yaml``'s
    ``runtime.choices``, Hydra's own groups left out)."""
    import yaml

    from decrun.runner.io.files import RunFiles

    path = job_dir / RunFiles.HYDRA / "hydra.yaml"
    if not path.is_file():
        return {}
    with _composed(path.read_text(), str(path)) as (loader, node):  # 4 KB, of which only the choices are built
        for key in ("hydra", "runtime", "choices"):
            found = [v for k, v in node.value if isinstance(k, yaml.ScalarNode) and k.value == key] \
                if isinstance(node, yaml.MappingNode) else []
            if not found:
                return {}
            node = found[-1]  # as yaml.safe_load: a repeated key's last value
        choices = loader.construct_object(node, deep=True)
    return {str(k): str(v) for k, v in (choices if isinstance(choices, dict) else {}).items()
            if not str(k).startswith("hydra/")}


def _overrides(job_dir: Path) -> list[str]:
    from decrun.runner.io.files import RunFiles

    path = job_dir / RunFiles.HYDRA / "overrides.yaml"
    if not path.is_file():
        return []
    with _composed(path.read_text(), str(path)) as (loader, node):
        items = loader.construct_object(node, deep=True) if node is not None else []
    return [str(item) for item in items] if isinstance(items, list) else []


def job_record(job_dir: Path, name: str, state: dict[str, Any], *, result_h5: bool = False,
               parent: str | None = None, shared: dict | None = None) -> RunRecord:
    """The :class:`RunRecord` of one run directory: ``name`` is the job's (the run is named
    ``job <name>`` under a ``parent``) or the single run's. ``state``: its status, error and metrics
    as the sweep's table has them (:func:`decrun.runner.sweep.manifest.job_state`); the
    numbers among the metrics become metrics (booleans 0/1), the other values tags
    ``metric.<name>``. ``shared``: one dict for the jobs of a sweep, the config sections
    they share flattened once (:func:`_params`)."""
    from decrun.runner.io.files import RunFiles
    from decrun.runner.results.provenance import git_commit

    job_dir = Path(job_dir)
    try:
        series, attrs, skipped = read_series(job_dir)
    except (OSError, CorruptFileError) as exc:  # the table says corrupt already; the run says why
        series, attrs, skipped = {}, {}, []
        state = {**state, "error": state.get("error") or str(exc)}
    status = str(state.get("status", "ok"))
    from decrun.runner.sweep.manifest import read_metrics

    written = read_metrics(job_dir) or {}
    if isinstance(written.get("config_hash"), str):  # job_state keeps it out of the metrics
        state = {**state, "config_hash": written["config_hash"]}
    params = _params(job_dir, attrs, shared)
    params.update(_choices(job_dir))
    overrides = _overrides(job_dir)
    tags = {"status": STATUS.get(status, "failed"), "decrun.status": status, "decrun.job": name,
            "decrun.overrides": " ".join(overrides)}
    if state.get("error"):
        tags["decrun.error"] = str(state["error"])
    commit = attrs.get("git_commit") or git_commit()
    if commit:
        tags["mlflow.source.git.commit"] = str(commit)
    metrics: dict[str, float] = {}
    for key, value in state.items():
        if key in ("status", "error"):
            continue
        if key == "config_hash":
            tags["decrun.config_hash"] = str(value)
        elif isinstance(value, (bool, int, float)):
            metrics[key] = float(value)
        elif value is not None:
            tags[f"metric.{key}"] = value if isinstance(value, str) else json.dumps(value, default=str)
    if skipped:
        tags["decrun.series_not_logged"] = f"{', '.join(skipped)} (arrays per step: in {RunFiles.RESULT})"
    artifacts = sorted([*job_dir.glob(RunFiles.FIGURES), *job_dir.glob(RunFiles.ANIMATIONS)])
    artifacts += [p for p in (job_dir / RunFiles.HYDRA / "config.yaml", job_dir / RunFiles.HYDRA / "overrides.yaml")
                  if p.is_file()]
    if result_h5 and RunFiles(job_dir).result.is_file():
        artifacts.append(RunFiles(job_dir).result)
    return RunRecord(name=f"job {name}" if parent else name, dir=job_dir, status=tags["status"], params=params, metrics=metrics,
                     series={f"series/{k}": v for k, v in series.items()}, tags=tags, artifacts=artifacts,
                     parent=parent)


# ----------------------------------------------------------------------------------
# the state kept in a run directory: which run of which store it is
# ----------------------------------------------------------------------------------


def read_state(path: Path) -> dict[str, dict]:
    """``tracking.json`` of a run or sweep directory: store → ``{"run_id", "fingerprint"}``;
    empty when absent or not what :func:`_write_state` writes (the run is then logged anew)."""
    try:
        state = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return state if isinstance(state, dict) and all(isinstance(v, dict) for v in state.values()) else {}


def _write_state(path: Path, store: str, run_id: str, fingerprint: str) -> None:
    from decrun.runner.io.atomic import write_text_atomic

    state = read_state(path)
    state[store] = {"run_id": run_id, "fingerprint": fingerprint}
    write_text_atomic(path, json.dumps(state, indent=1) + "\n")


def _log(tracker: Tracker, record: RunRecord, state_path: Path) -> tuple[str, bool]:
    """Log ``record`` unless ``state_path`` says this store has it as it is; returns the run
    id and whether anything was sent."""
    store = tracker.store()
    known = read_state(state_path).get(store, {})
    fingerprint = record.fingerprint()
    if known.get("run_id") and known.get("fingerprint") == fingerprint:
        return str(known["run_id"]), False
    run_id = tracker.log_run(record, known.get("run_id"))
    _write_state(state_path, store, run_id, fingerprint)
    return run_id, True


@dataclass
class Tracked:
    """What :func:`track_sweep` did: the sweep's run id, the jobs' run ids (job → id) and how
    many runs it sent (a resumed sweep whose jobs are unchanged sends none)."""

    sweep_run: str = ""
    runs: dict[str, str] = field(default_factory=dict)
    sent: int = 0


def track_sweep(tracker: Tracker, sweep_dir: str | os.PathLike) -> Tracked:
    """Log the sweep in ``sweep_dir`` (its table written: every planned job has its status):
    one run for the sweep, one nested run per job (module docstring); returns :class:`Tracked`.

    The jobs are the manifest's (every planned one, as rows of ``metrics.csv``), or the job
    directories of a sweep without one. The sweep's run has status ``ok`` when every job is,
    ``killed`` when one was killed, else ``failed``; its params are the sweep's own overrides."""
    from decrun.runner.io.files import RunFiles, SweepFiles
    from decrun.runner.sweep.manifest import job_dir_name, job_state, read_manifest

    sweep_dir = Path(sweep_dir)
    tracked = Tracked()
    if not tracker.active():
        return tracked
    manifest = read_manifest(sweep_dir)
    if manifest is not None:
        jobs = [(str(j["job"]), sweep_dir / job_dir_name(j), j["config_hash"]) for j in manifest["jobs"]]
        common = [str(o) for o in manifest.get("overrides", [])]
    else:
        jobs = [(p.name, p, None) for p in sorted(sweep_dir.iterdir()) if (p / RunFiles.HYDRA).is_dir()]
        common = []
    states = [(name, where, job_state(where, expected)) for name, where, expected in jobs]
    statuses = {STATUS.get(str(s.get("status")), "failed") for _, _, s in states}
    status = "ok" if statuses <= {"ok"} else "killed" if "killed" in statuses else "failed"
    sweep_params = {key.lstrip("+~"): value for key, _, value in (o.partition("=") for o in common)
                    if not key.lstrip("+~").startswith("hydra.")}  # as typed: `app.dt` → `1e-3,2e-3`
    sweep_record = RunRecord(name=sweep_dir.name, dir=sweep_dir, status=status, params=sweep_params,
                             metrics={"jobs": float(len(jobs)),
                                      "jobs_ok": float(sum(STATUS.get(str(s.get("status"))) == "ok"
                                                           for _, _, s in states))},
                             tags={"status": status, "decrun.sweep_dir": str(sweep_dir.resolve()),
                                   "decrun.overrides": " ".join(common)})
    shared: dict = {}
    try:
        tracked.sweep_run, sent = _log(tracker, sweep_record, SweepFiles(sweep_dir).dir / SweepFiles.TRACKING)
        tracked.sent += sent
        for name, where, state in states:
            record = job_record(where, name, state, result_h5=bool(getattr(tracker, "result_h5", False)),
                                parent=tracked.sweep_run, shared=shared)
            tracked.runs[name], sent = _log(tracker, record, RunFiles(where).tracking)
            tracked.sent += sent
    finally:
        tracker.close()
    return tracked


def track_run(tracker: Tracker, run_dir: str | os.PathLike) -> str:
    """Log the single run in ``run_dir`` (not a sweep: no parent run); its run id ("" for
    ``tracker=none``)."""
    from decrun.runner.io.files import RunFiles
    from decrun.runner.sweep.manifest import job_state

    run_dir = Path(run_dir)
    if not tracker.active():
        return ""
    try:
        record = job_record(run_dir, run_dir.name, job_state(run_dir), result_h5=bool(getattr(tracker, "result_h5",
                                                                                            False)))
        return _log(tracker, record, RunFiles(run_dir).tracking)[0]
    finally:
        tracker.close()


def warning_line(tracker: Tracker, exc: BaseException, where: Path, fix: str) -> str:
    """The one line an error of the tracker becomes: the tracker, its store, the first line of
    the error, that the run's files are complete, and ``fix`` (the command that logs them)."""
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    if len(text) > 200:
        text = text[:200] + " …"
    return (f"decrun: warning: tracker={tracker.name} could not log to {tracker.store()} ({type(exc).__name__}: "
            f"{text}); the files in {where} are complete; to log them: {fix}")


def require(module: str, key: str, install: str) -> None:
    """ConfigError ``tracker=<key>: needs the package <module> …`` when ``module`` cannot be
    imported here, with ``pip install <install>`` and the override that turns tracking off."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise ConfigError(f"tracker={key}: needs the package {module!r}, not installed here; "
                          f"pip install {install}, or run without it: tracker=none")

