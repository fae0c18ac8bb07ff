"""``tracker=mlflow``: a sweep as one MLflow run with one nested run per job, through
MLflow's own client (``mlflow.tracking.MlflowClient``) — any store MLflow has: a tracking
server (``http://host:5000``), a database (``sqlite:///path/mlflow.db``), a directory.

What a run holds, when it is logged and how a resumed sweep updates its runs:
:mod:`decrun.runner.tracking`. Here: the calls. A new run is ``create_run`` (its tags, and
``mlflow.parentRunId`` for a job), then ``log_batch`` in MLflow's batch limits (params, the
metrics at step 0, each series as a metric history at its steps), one ``log_artifacts`` of a
temporary directory holding hard links to exactly the run's files (:func:`_staged`; into the
run's local artifact directory through MLflow's artifact repository of the ``artifact_uri`` the
run came with — the client would look the run up once more for it),
``set_terminated`` with ``FINISHED`` / ``FAILED`` / ``KILLED`` for ``ok`` / ``failed`` /
``killed``. A new run is tagged ``decrun.run_key`` (:func:`run_key`) so that a run made by a
process killed before it wrote ``tracking.json`` is found again (``search_runs``) and
logged into, never doubled. An existing run (a resumed sweep) gets the params it lacks, the new metric values,
tags, artifacts and status. A param value longer than MLflow takes (6000 characters) is not
cut: it goes to the tag ``param.<key>`` (up to 8000), and one longer still is named in the tag
``decrun.params_in_config_yaml`` (the artifact ``config.yaml`` holds every value).

The HTTP client is told not to retry (``MLFLOW_HTTP_REQUEST_MAX_RETRIES=0``) and to give up
after ``timeout_seconds`` (``MLFLOW_HTTP_REQUEST_TIMEOUT``) unless those are set already, so an
unreachable server is one warning line within seconds, not minutes of retries; MLflow's
telemetry is off unless ``MLFLOW_DISABLE_TELEMETRY`` says otherwise, and so is its printing of
each run's URL (``MLFLOW_SUPPRESS_PRINTING_URL_TO_STDOUT``), for which ``set_terminated`` on a
server would fetch the whole run once more.
"""

from __future__ import annotations

import logging
import os
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Iterator, Optional

from decrun.runner.tracking import RunRecord, Tracker, require

__all__ = ["MlflowTracker"]

#: ``status`` tag → MLflow's run status
RUN_STATUS = {"ok": "FINISHED", "failed": "FAILED", "killed": "KILLED"}
#: the tag naming what a run logs (:func:`run_key`), set when the run is made
RUN_KEY = "decrun.run_key"


def run_key(record: RunRecord) -> str:
    """32 hex digits of sha256 over the absolute directory a run logs (a sweep's, a job's, a single
    run's): one key per job for as long as its directory is where it is. Tagged at ``create_run``,
    it finds the run again when a kill came between ``create_run`` and ``tracking.json``, so a
    resume logs into that run instead of making a second one (docs/tracking.md)."""
    from decrun.core.digest import text_sha256

    return text_sha256(str(Path(record.dir).resolve()))[:32]


#: MLflow's limits (mlflow.utils.validation)
MAX_PARAMS_TAGS_PER_BATCH = 100
MAX_ENTITIES_PER_BATCH = 1000
MAX_PARAM_VALUE = 6000
MAX_TAG_VALUE = 8000


@dataclass
class MlflowTracker(Tracker):
    """``tracker=mlflow`` (module docstring). ``uri``: the tracking URI (None:
    ``MLFLOW_TRACKING_URI``, else MLflow's default); ``experiment``: the MLflow experiment the
    runs go to (made when absent); ``result_h5``: upload each job's result.h5 as an artifact
    too; ``timeout_seconds``: how long one HTTP request to a tracking server may take."""

    name: ClassVar[str] = "mlflow"
    uri: Optional[str] = None
    experiment: str = "decrun"
    result_h5: bool = False
    timeout_seconds: float = 10.0

    def __post_init__(self):
        from decrun.errors import ConfigError

        if not self.timeout_seconds > 0:
            raise ConfigError(f"tracker.timeout_seconds: must be > 0, got {self.timeout_seconds}; e.g. "
                              "tracker.timeout_seconds=10")
        if not str(self.experiment).strip():
            raise ConfigError("tracker.experiment: empty; name the MLflow experiment, e.g. tracker.experiment=decrun")
        self._client = None
        self._experiment_id = None
        self._keyed: dict[str, dict[str, Any]] = {}  # parent run id → run key → run (:meth:`_made_before`)

    def check(self) -> None:
        require("mlflow", "mlflow", "'decrun[mlflow]'")

    def store(self) -> str:
        """The tracking URI (``uri``, ``MLFLOW_TRACKING_URI``, MLflow's default), a relative
        ``sqlite:///`` path made absolute: the same database from any working directory."""
        if self.uri:
            uri = str(self.uri)
        elif os.environ.get("MLFLOW_TRACKING_URI"):
            uri = os.environ["MLFLOW_TRACKING_URI"]
        elif self._client is not None:
            uri = str(self._client.tracking_uri)
        else:
            from mlflow.tracking import get_tracking_uri

            uri = str(get_tracking_uri())
        prefix = "sqlite:///"
        if uri.startswith(prefix) and not uri[len(prefix):].startswith("/") and uri[len(prefix):] != ":memory:":
            uri = prefix + os.path.abspath(uri[len(prefix):])
        return uri

    def client(self):
        """The ``MlflowClient`` of :meth:`store` and the id of :attr:`experiment` (made once)."""
        if self._client is None:
            os.environ.setdefault("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "0")
            os.environ.setdefault("MLFLOW_HTTP_REQUEST_TIMEOUT", str(max(1, int(round(self.timeout_seconds)))))
            os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")
            # set_terminated on a server fetches the whole run again to print its URL: once a job
            os.environ.setdefault("MLFLOW_SUPPRESS_PRINTING_URL_TO_STDOUT", "true")
            from mlflow.tracking import MlflowClient

            for name in ("mlflow", "alembic"):  # MLflow's INFO lines (a new sqlite store's tables) are not decrun's
                if logging.getLogger(name).level in (logging.NOTSET, logging.INFO):
                    logging.getLogger(name).setLevel(logging.WARNING)

            client = MlflowClient(tracking_uri=self.store())
            found = client.get_experiment_by_name(self.experiment)
            if found is None:
                try:
                    experiment_id = client.create_experiment(self.experiment)
                except Exception:  # noqa: BLE001 — made meanwhile by another process: take that one
                    found = client.get_experiment_by_name(self.experiment)
                    if found is None:
                        raise
                    experiment_id = found.experiment_id
            else:
                experiment_id = found.experiment_id
            self._client, self._experiment_id = client, experiment_id
        return self._client

    def log_run(self, record: RunRecord, run_id: str | None) -> str:
        from mlflow.entities import Metric, Param, RunTag

        client = self.client()
        identity = run_key(record)
        existing = self._existing(run_id) or self._made_before(record, identity)
        tags = dict(record.tags)
        params, too_long = {}, []
        for key, value in record.params.items():
            if len(value) <= MAX_PARAM_VALUE:
                params[key] = value
            elif len(value) <= MAX_TAG_VALUE:
                tags[f"param.{key}"] = value
            else:
                too_long.append(key)
        if too_long:
            tags["decrun.params_in_config_yaml"] = ", ".join(too_long)
        if existing is None:
            run_tags = {**tags, RUN_KEY: identity, **({"mlflow.parentRunId": record.parent} if record.parent else {})}
            run = client.create_run(self._experiment_id, run_name=record.name, tags=run_tags)
            run_id, artifact_uri, tags = run.info.run_id, run.info.artifact_uri, {}
        else:
            run_id, artifact_uri, logged = existing.info.run_id, existing.info.artifact_uri, existing.data.params
            changed = [k for k, v in params.items() if k in logged and logged[k] != v]
            if changed:  # MLflow keeps a param's first value: the new one goes to a tag
                tags.update({f"param.{k}": params[k] for k in changed})
            params = {k: v for k, v in params.items() if k not in logged}
        stamp = int(time.time() * 1000)
        metrics = [Metric(k, v, stamp, 0) for k, v in record.metrics.items()]
        for key, (steps, values) in record.series.items():
            metrics += [Metric(key, float(v), stamp, int(s))
                        for s, v in zip(steps.tolist(), values.tolist(), strict=True)]
        for batch in _batches([Param(k, v) for k, v in params.items()], [RunTag(k, str(v)) for k, v in tags.items()],
                              metrics):
            client.log_batch(run_id, **batch)
        if record.artifacts:
            with _staged(record.artifacts) as staged:
                repository = _local_artifacts(artifact_uri)
                if repository is not None:
                    repository.log_artifacts(staged)
                else:
                    client.log_artifacts(run_id, staged)
        client.set_terminated(run_id, status=RUN_STATUS.get(record.status, "FAILED"))
        return run_id

    def _existing(self, run_id: str | None) -> Any:
        """The run ``run_id`` when the store has it (not deleted), else None."""
        if not run_id:
            return None
        from mlflow.exceptions import MlflowException

        try:
            run = self.client().get_run(run_id)
        except MlflowException as exc:
            if getattr(exc, "error_code", "") in ("RESOURCE_DOES_NOT_EXIST", "INVALID_PARAMETER_VALUE"):
                return None
            raise
        return run if run.info.lifecycle_stage == "active" else None

    def _made_before(self, record: RunRecord, key: str) -> Any:
        """The active run tagged :data:`RUN_KEY` ``key`` in the experiment — the run a process
        made for this record before it was killed, ahead of writing ``tracking.json`` — or None.
        A job's runs are looked up once per sweep run (every run under ``record.parent``, through
        MLflow's public ``search_runs``), so a sweep of n jobs costs n/1000 searches, not n."""
        parent = record.parent or ""
        if parent not in self._keyed:
            found: dict[str, Any] = {}
            where = f"tags.`mlflow.parentRunId` = '{parent}'" if parent else f"tags.`{RUN_KEY}` = '{key}'"
            token = None
            while True:
                page = self.client().search_runs([self._experiment_id], filter_string=where, max_results=1000,
                                                 order_by=["attributes.start_time ASC"], page_token=token)
                for run in page:  # the latest of several (made by older versions) wins
                    if RUN_KEY in run.data.tags:
                        found[run.data.tags[RUN_KEY]] = run
                token = page.token
                if not token:
                    break
            if not parent:
                return found.get(key)
            self._keyed[parent] = found
        return self._keyed[parent].get(key)

    def close(self) -> None:
        self._client = None
        self._keyed = {}


def _local_artifacts(artifact_uri: str | None) -> Any:
    """MLflow's artifact repository of a run whose artifacts live in a local directory
    (``file:`` URI or a plain path): the repository ``MlflowClient.log_artifact`` would use,
    made from the URI ``create_run`` / ``get_run`` returned instead of looking the run up
    again for it. None for any other store (a server, a cloud bucket): those go through
    ``MlflowClient.log_artifact``."""
    from urllib.parse import urlparse

    if not artifact_uri or urlparse(artifact_uri).scheme not in ("", "file"):
        return None
    from mlflow.store.artifact.artifact_repository_registry import get_artifact_repository

    return get_artifact_repository(artifact_uri)


@contextmanager
def _staged(paths: list) -> Iterator[str]:
    """A temporary directory holding exactly ``paths`` under their names (of two paths with
    one name the later, as one upload per file would leave it), each a hard link to the file
    (a symbolic link where the directory is on another filesystem): one ``log_artifacts``
    call uploads them all — MLflow's path checks and the run's directory done once, not once
    per file — and staging them copies nothing. Removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="decrun-artifacts-") as directory:
        for name, path in {Path(p).name: Path(p) for p in paths}.items():
            target = os.path.join(directory, name)
            try:
                os.link(path, target)
            except FileNotFoundError:  # a file gone since the record was read: the upload's error
                raise
            except OSError:  # another filesystem, or hard links not allowed there
                os.symlink(path.resolve(), target)
        yield directory


def _batches(params: list, tags: list, metrics: list) -> list[dict[str, list]]:
    """``params``, ``tags`` and ``metrics`` cut into ``log_batch`` calls within MLflow's limits
    (100 params, 100 tags, 1000 entities a call); at least one call when there is anything."""
    out: list[dict[str, list]] = []
    while params or tags or metrics or not out:
        p, params = params[:MAX_PARAMS_TAGS_PER_BATCH], params[MAX_PARAMS_TAGS_PER_BATCH:]
        t, tags = tags[:MAX_PARAMS_TAGS_PER_BATCH], tags[MAX_PARAMS_TAGS_PER_BATCH:]
        room = MAX_ENTITIES_PER_BATCH - len(p) - len(t)
        m, metrics = metrics[:room], metrics[room:]
        out.append({"params": p, "tags": t, "metrics": m})
        if not (params or tags or metrics):
            break
    return [b for b in out if b["params"] or b["tags"] or b["metrics"]]

