"""A sweep tracked with ``tracker=mlflow`` read back from its store against its own files, for
the launcher tests (``from tracked_sweeps import check_tracked_sweep``; ``tests/`` is on
``sys.path``): whatever launcher ran the jobs, the runs are the table's."""

from __future__ import annotations

import json
import math
from pathlib import Path

import h5py
import pandas as pd


def check_tracked_sweep(sweep: Path, uri: str, stdout: str) -> None:
    """The sweep in ``sweep`` (every job ok) is one MLflow run in ``uri`` with one nested run
    per row of its ``metrics.csv``: the run ids are the ones kept in ``tracking.json``, each
    job's metrics are its ``metrics.json`` numbers exactly, its params its resolved options,
    its series the ``series/<name>`` histories, its ``config.yaml`` an artifact."""
    from mlflow.tracking import MlflowClient

    table = pd.read_csv(sweep / "metrics.csv")
    assert list(table["status"]) == ["ok"] * len(table), table
    assert f"decrun: tracker=mlflow: {len(table)} jobs under run" in stdout, stdout
    client = MlflowClient(tracking_uri=uri)
    experiment = client.get_experiment_by_name("decrun")
    runs = client.search_runs([experiment.experiment_id], max_results=100)
    assert len(runs) == len(table) + 1, [r.info.run_name for r in runs]
    (parent,) = [r for r in runs if "mlflow.parentRunId" not in r.data.tags]
    assert parent.info.run_id == json.loads((sweep / "tracking.json").read_text())[uri]["run_id"]
    assert parent.info.status == "FINISHED" and parent.data.metrics["jobs_ok"] == len(table)
    jobs = {r.data.tags["decrun.job"]: r for r in runs if r is not parent}
    for row in table.to_dict("records"):
        job_dir = sweep / str(row["job"])
        run = jobs[str(row["job"])]
        assert run.info.run_id == json.loads((job_dir / "tracking.json").read_text())[uri]["run_id"]
        assert run.data.tags["mlflow.parentRunId"] == parent.info.run_id and run.info.status == "FINISHED"
        assert float(run.data.params["app.dt"]) == row["app.dt"]
        metrics = json.loads((job_dir / "metrics.json").read_text())
        numbers = {k: float(v) for k, v in metrics.items() if isinstance(v, (int, float))}
        assert numbers and all(_same(run.data.metrics[k], v) for k, v in numbers.items()), (numbers, run.data.metrics)
        with h5py.File(job_dir / "result.h5", "r") as f:
            steps = f["series/step"][()].tolist()
            series = {name: f["series"][name][()].tolist() for name in f["series"]
                      if name != "step" and f["series"][name].ndim == 1}
        assert steps and series
        for name, values in series.items():  # every series of one number per step, as its metric history
            history = client.get_metric_history(run.info.run_id, f"series/{name}")
            assert [m.step for m in history] == steps, name
            assert all(_same(m.value, v) for m, v in zip(history, values, strict=True)), name
        assert "config.yaml" in {a.path for a in client.list_artifacts(run.info.run_id)}


def _same(a: float, b: float) -> bool:
    """Equal, NaN equal to NaN (a metric that is NaN in metrics.json is NaN in MLflow)."""
    return a == b or (math.isnan(a) and math.isnan(b))
