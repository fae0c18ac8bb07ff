"""A sweep's manifest: the jobs planned at its start, so that its table always has one
row per planned job and a resumed sweep reruns exactly what is not done.

``<sweep dir>/manifest.json`` (written atomically by the ``decrun`` sweeper,
:mod:`hydra_plugins.decrun_sweeper`, before any job starts)::

    {"format": "decrun-sweep-1", "created": ISO time, "overrides": [command-line sweep overrides],
     "jobs": [{"job": "0", "dir": "0", "overrides": ["app.dt=0.1", ...], "config_hash": "<16 hex>"}, ...],
     "runs": [{"started": ISO, "jobs": ["0", "3"], "finished": ISO | null}, ...]}

``dir`` is the job's directory relative to the sweep directory (``hydra.sweep.subdir`` as
resolved when the sweep was planned; absent in older manifests: the job number). ``config_hash`` is :func:`config_hash` of the job's composed config (everything but the
``hydra`` node): two jobs with the same hash compute the same thing. A job writes its hash
into its ``metrics.json``, so a job directory left by another config is never taken for
this one's. ``runs`` has one entry per start or resume; a run whose ``finished`` is null
was killed (the sweep never looks complete).

A job's state (:func:`job_state`) is read from its directory only:

=========  ==========================================================================
``ok``      ``metrics.json`` with ``status: ok`` (and the manifest's hash, when it has one)
            beside the ``result.h5`` it records (size and sha256: ``result_h5``;
            :func:`~decrun.runner.results.reading.verify_result`)
``corrupt`` ``metrics.json`` ok but ``result.h5`` missing, truncated or altered; or a
            ``metrics.json`` / journal that is not what decrun writes (the error names
            the file)
``failed``  ``metrics.json`` with ``status: failed`` / ``interrupted`` (its ``error``)
``killed``  no ``metrics.json`` but the run's journal ``result.h5.partial``: the process
            died while recording (:func:`decrun.runner.results.recorder.recover_result` turns it
            into an incomplete ``result.h5``)
``missing`` no ``metrics.json`` and no journal: never started, killed before its first
            step, or still running
``stale``   ``metrics.json`` written by a different config (hash differs from the manifest)
=========  ==========================================================================
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from pathlib import Path
from typing import Any, Collection

import yaml
from omegaconf import DictConfig, OmegaConf

from decrun.core.digest import Digest
from decrun.errors import CorruptFileError
from decrun.runner.io.atomic import write_text_atomic
from decrun.runner.io.files import RunFiles, SweepFiles
from decrun.runner.io.yaml_text import PythonDumper as _Dumper
from decrun.runner.results.checked import CONTENT, RESULT_RECORD, load_json
from decrun.runner.results.journal import journal_path, read_journal
from decrun.runner.results.reading import verify_result

__all__ = ["MANIFEST", "config_hash", "read_manifest", "write_manifest", "job_state", "job_dir_name", "DONE"]

MANIFEST = SweepFiles.MANIFEST
FORMAT = "decrun-sweep-1"
#: states a resumed sweep does not rerun
DONE = ("ok",)
#: run options that do not change what a job computes (left out of its hash)
UNHASHED = ("progress", "checkpoint", "tracker")


def job_dir_name(job: dict[str, Any]) -> str:
    """A manifest job's directory, relative to the sweep directory."""
    return job.get("dir", job["job"])


def now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def config_hash(cfg: DictConfig, blocks: dict[str, str] | None = None, fresh: Collection[str] | None = None) -> str:
    """16 hex digits of sha256 over the resolved YAML of ``cfg`` without its ``hydra``
    node and the keys of :data:`UNHASHED`: equal for two compositions of the same job.

    The YAML of a mapping with sorted keys is its keys' blocks one after the other
    (:func:`yaml_block`), so a sweep's plan hashes its jobs from ``blocks`` (root key →
    block, filled as they are made) and makes anew only the blocks of the root keys in
    ``fresh`` (None: all), those whose value may differ from the previous job's."""
    h = Digest()
    keys = [key for key in sorted(str(k) for k in cfg) if key != "hydra" and key not in UNHASHED]
    if blocks is None and keys:  # the blocks in one dump: the same text, a tenth of the calls (~1.5 ms less)
        h.text(yaml_block(None, {key: _resolved(cfg[key]) for key in keys}))
        return h.hexdigest(16)
    for key in keys:
        if blocks is None or fresh is None or key in fresh or key not in blocks:
            block = yaml_block(key, cfg[key])
            if blocks is None:
                h.text(block)
                continue
            blocks[key] = block
        h.text(blocks[key])
    return h.hexdigest(16)


def yaml_block(key: str | None, value: Any) -> str:
    """``key: <value>`` as the resolved YAML of one root key of a config (sorted keys): the
    text of ``OmegaConf.to_yaml`` of it, made by :class:`_Dumper` directly on the resolved
    container (3× faster than making a config of it first). ``key`` None: ``value`` is a
    dict of resolved root keys, dumped as one mapping — the concatenation of their blocks
    (a block starts at column 0; :func:`_resolved` makes every container anew, so the
    dumper writes no anchor that spans two keys)."""
    data = value if key is None else {key: _resolved(value)}
    return yaml.dump(data, default_flow_style=False, allow_unicode=True, sort_keys=True, Dumper=_Dumper)


def _resolved(value: Any) -> Any:
    """A config node as resolved plain containers (enums as their names); any other value as it is."""
    return OmegaConf.to_container(value, resolve=True, enum_to_str=True) if OmegaConf.is_config(value) else value


def write_manifest(sweep_dir: Path, manifest: dict[str, Any]) -> Path:
    """Write ``manifest.json`` atomically (it is either the old or the new one)."""
    path = Path(sweep_dir) / MANIFEST
    write_text_atomic(path, json.dumps(manifest, indent=1) + "\n")
    return path


def read_manifest(sweep_dir: str | os.PathLike) -> dict[str, Any] | None:
    """The manifest of a sweep, or None when it has none (an older sweep, or one run by
    another sweeper such as optuna). A manifest that cannot be read or is not what the
    sweeper writes (not JSON, nested too deeply, not an object, a job without its
    ``job`` / ``overrides`` / ``config_hash``) is a :class:`CorruptFileError` naming the
    file and what is wrong."""
    path = Path(sweep_dir) / MANIFEST
    if not path.is_file():
        return None
    try:
        manifest = load_json(path)
    except FileNotFoundError:
        return None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        found = manifest.get("format") if isinstance(manifest, dict) else f"a JSON {type(manifest).__name__}"
        raise CorruptFileError(f"{path}: not a decrun sweep manifest (format {found!r})")
    jobs, overrides = manifest.get("jobs"), manifest.get("overrides", [])
    if not isinstance(jobs, list) or not _strings(overrides) or not isinstance(manifest.get("runs", []), list):
        raise CorruptFileError(f"{path}: malformed sweep manifest (jobs, overrides or runs is not a list)")
    for i, job in enumerate(jobs):
        if not (isinstance(job, dict) and isinstance(job.get("job"), str) and _strings(job.get("overrides"))
                and isinstance(job.get("config_hash"), str) and isinstance(job.get("dir", ""), str)):
            raise CorruptFileError(f"{path}: job {i} of the manifest lacks its job, overrides or config_hash "
                                   f"(got {str(job)[:80]})")
    return manifest


def _strings(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(item, str) for item in value)


def read_metrics(job_dir: Path) -> dict[str, Any] | None:
    """``metrics.json`` of a job, None when absent; one that cannot be read or is not a
    JSON object → a ``corrupt`` record naming the file."""
    path = RunFiles(job_dir).metrics
    if not path.is_file():
        return None
    try:
        metrics = load_json(path)
    except FileNotFoundError:
        return None
    except CorruptFileError as exc:
        return {"status": "corrupt", "error": str(exc)}
    if not isinstance(metrics, dict):
        return {"status": "corrupt", "error": f"{path}: a JSON {type(metrics).__name__}, not an object of metrics"}
    if not isinstance(metrics.get("status", "ok"), str) or not isinstance(metrics.get("error", ""), str):
        return {"status": "corrupt", "error": f"{path}: status and error must be strings"}
    return metrics


def job_state(job_dir: Path, expected_hash: str | None = None) -> dict[str, Any]:
    """``{"status", "error", **metrics}`` of one job directory (table in the module
    docstring). ``expected_hash``: the manifest's hash for this job."""
    metrics = read_metrics(job_dir)
    if metrics is None:
        journal = journal_path(RunFiles(job_dir).result)
        if journal.is_file():
            try:
                steps = read_journal(journal, verify=False).n_records
            except OSError as exc:
                return {"status": "killed", "error": f"{journal}: unreadable ({exc}); no {RunFiles.METRICS}"}
            except CorruptFileError as exc:
                return {"status": "corrupt", "error": f"{exc}; no {RunFiles.METRICS}"}
            return {"status": "killed", "error": f"killed after {steps} recorded steps ({RunFiles.JOURNAL}; "
                                                 f"no {RunFiles.METRICS})"}
        if not job_dir.is_dir():
            return {"status": "missing", "error": "never started"}
        return {"status": "missing", "error": f"no {RunFiles.METRICS} (killed before its first step, or still running)"}
    metrics = dict(metrics)
    found = metrics.pop("config_hash", None)
    record = metrics.pop(RESULT_RECORD, None)
    if expected_hash is not None and found is not None and found != expected_hash:
        return {"status": "stale", "error": f"{RunFiles.METRICS} is from another config (hash {found}, "
                                            f"the manifest plans {expected_hash})"}
    metrics.setdefault("status", "ok")
    metrics.setdefault("error", "")
    if metrics["status"] == "ok":
        try:
            verify_result(RunFiles(job_dir).result, record)
        except CorruptFileError as exc:
            metrics.update(status="corrupt", error=str(exc))
        else:  # what two runs of one config share (docs/running.md: "Reproducible records"); older records have none
            if isinstance(record, dict) and isinstance(record.get(CONTENT), str):
                metrics[CONTENT] = record[CONTENT]
    return metrics
