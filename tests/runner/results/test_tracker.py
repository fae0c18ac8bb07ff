"""``tracker=mlflow``: a real 6-job sweep through the ``decrun`` command into an MLflow sqlite
store, read back with ``MlflowClient`` against ``metrics.csv`` row by row; a resumed sweep adds
no run; an unreachable server is one warning line and the command it names logs the sweep
later; a single run; the batching within MLflow's limits. Skipped where mlflow is not
installed (the ``mlflow`` extra; CI installs the ``test`` extra, which has it)."""

from __future__ import annotations

import json
import math
import shlex
import socket
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

from decrun.runner.tracking import STATUS, flatten, read_state

from cli_processes import decrun, env

mlflow = pytest.importorskip("mlflow", reason="tracker=mlflow needs the mlflow extra: pip install 'decrun[mlflow]'")

#: 6 jobs: 4 ok (40 or 20 explicit steps), 2 failed at run time (dt = 0.4 exceeds explicit Euler's stability
#: limit, about 0.1 on this mesh: refused when the job runs, not at planning)
SWEEP = ["app=heat", "mesh.subdiv=1", "app.t_end=0.8", "app.dt=2e-2,4e-2,4e-1", "app.integrator=explicit_euler",
         "operator=mixed_area,barycentric",
         "tracker=mlflow"]


def _client(uri: str):
    from mlflow.tracking import MlflowClient

    return MlflowClient(tracking_uri=uri)


def _runs(uri: str, experiment: str = "decrun") -> list:
    client = _client(uri)
    found = client.get_experiment_by_name(experiment)
    return client.search_runs([found.experiment_id], max_results=1000) if found else []


def track_command(*args: str, cwd) -> subprocess.CompletedProcess:
    """The console script ``decrun-track`` (:func:`decrun.runner.command.table.track_main`) as a child process."""
    code = "import sys; from decrun.runner.command.table import track_main; sys.exit(track_main())"
    return subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, env=env(), capture_output=True, text=True,
                          timeout=300)


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    """The 6-job sweep, run once for this module: (work dir, sweep dir, store URI, the command's result)."""
    work = tmp_path_factory.mktemp("tracked")
    uri = f"sqlite:///{work / 'mlflow.db'}"
    proc = decrun("-m", *SWEEP, f"tracker.uri={uri}", "hydra.sweep.dir=sweep", cwd=work)
    return work, work / "sweep", uri, proc


def test_a_sweeps_runs_equal_its_metrics_csv_row_by_row(swept):
    work, sweep, uri, proc = swept
    assert proc.returncode == 1, proc.stderr  # two jobs failed: the sweep says so, and is tracked all the same
    assert "decrun: tracker=mlflow: 6 jobs under run" in proc.stdout, proc.stdout
    assert "warning" not in proc.stderr
    table = pd.read_csv(sweep / "metrics.csv")
    assert list(table["status"]) == ["ok"] * 4 + ["failed"] * 2
    runs = _runs(uri)
    parents = [r for r in runs if "mlflow.parentRunId" not in r.data.tags]
    assert len(runs) == 7 and len(parents) == 1  # one run for the sweep, one nested run per job
    parent = parents[0]
    assert parent.info.run_id == read_state(sweep / "tracking.json")[uri]["run_id"]
    assert parent.info.status == "FAILED" and parent.data.tags["status"] == "failed"
    assert parent.data.params["app.dt"] == "2e-2,4e-2,4e-1" and parent.data.metrics["jobs_ok"] == 4.0
    jobs = {r.data.tags["decrun.job"]: r for r in runs if r is not parent}
    manifest = json.loads((sweep / "manifest.json").read_text())
    hashes = {job["job"]: job["config_hash"] for job in manifest["jobs"]}
    first = list(table.columns).index("error") + 1
    metric_columns = list(table.columns)[first:list(table.columns).index("result")]
    for row in table.to_dict("records"):
        run = jobs[str(row["job"])]
        assert run.data.tags["mlflow.parentRunId"] == parent.info.run_id
        assert run.info.run_id == read_state(sweep / str(row["job"]) / "tracking.json")[uri]["run_id"]
        assert run.data.tags["status"] == STATUS[row["status"]] == {"FINISHED": "ok", "FAILED": "failed"}[run.info.status]
        assert run.data.tags["decrun.config_hash"] == hashes[str(row["job"])]
        # the swept options, as params: the resolved values of metrics.csv's override columns
        assert float(run.data.params["app.dt"]) == row["app.dt"] and run.data.params["operator"] == row["operator"]
        assert run.data.params["mesh.subdiv"] == "1" and run.data.params["app"] == "heat"
        for column in metric_columns:
            value = row[column]
            if isinstance(value, float) and math.isnan(value):
                assert column not in run.data.metrics, column  # a metric the job does not have is absent
            elif isinstance(value, (bool, np.bool_, int, float, np.integer, np.floating)):
                assert run.data.metrics[column] == float(value), column  # exact: floats round-trip
            else:
                assert run.data.tags[f"metric.{column}"] == value, column
        if row["status"] == "failed":
            assert run.data.tags["decrun.error"] == row["error"] and "exceeds the stability limit" in row["error"]
            continue
        with h5py.File(sweep / str(row["job"]) / "result.h5", "r") as f:
            steps, mass, commit = f["series/step"][()], f["series/mass"][()], f.attrs["git_commit"]
        history = _client(uri).get_metric_history(run.info.run_id, "series/mass")
        assert [m.step for m in history] == list(steps) and [m.value for m in history] == list(mass)
        assert run.data.tags["mlflow.source.git.commit"] == str(commit)
        assert "u" in run.data.tags["decrun.series_not_logged"]  # the field per step stays in result.h5, named
        figures = {p.name for p in (sweep / str(row["job"])).glob("*.png")}
        assert figures and figures <= {a.path for a in _client(uri).list_artifacts(run.info.run_id)}


def test_a_resumed_sweep_updates_its_runs_and_adds_none(swept):
    work, sweep, uri, first = swept
    before = {r.info.run_id: r for r in _runs(uri)}
    proc = decrun("-m", *SWEEP, f"tracker.uri={uri}", "hydra.sweep.dir=sweep", "hydra.sweeper.resume=true", cwd=work)
    assert proc.returncode == 1, proc.stderr  # the failed jobs ran again (and failed again)
    after = {r.info.run_id: r for r in _runs(uri)}
    assert set(after) == set(before) and len(after) == 7
    for run_id, run in after.items():  # an ok job was not touched: one value per metric, as before
        if run.data.tags.get("status") == "ok" and "mlflow.parentRunId" in run.data.tags:
            assert len(_client(uri).get_metric_history(run_id, "mass")) == 1
    assert "3 sent" in proc.stdout or "2 sent" in proc.stdout, proc.stdout  # the two rerun jobs (+ the sweep)


def test_an_unreachable_tracker_is_one_warning_and_the_named_command_logs_the_sweep_later(tmp_path):
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = decrun("-m", "app=heat", "mesh.subdiv=1", "app.t_end=0.002", "app.dt=1e-3,2e-3", "figures=false",
                  "tracker=mlflow", f"tracker.uri=http://127.0.0.1:{port}", "tracker.timeout_seconds=3",
                  "hydra.sweep.dir=sweep", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr  # the sweep itself went well
    lines = [line for line in proc.stderr.splitlines() if "tracker=mlflow" in line]
    assert len(lines) == 1 and lines[0].startswith("decrun: warning: tracker=mlflow could not log to http://127.0.0.1")
    assert "the files in sweep are complete" in lines[0]
    assert list(pd.read_csv(tmp_path / "sweep" / "metrics.csv")["status"]) == ["ok", "ok"]
    assert not (tmp_path / "sweep" / "tracking.json").exists()
    command = shlex.split(lines[0].split("to log them: ", 1)[1])
    assert command[:4] == ["decrun-track", "sweep", "tracker=mlflow", f"tracker.uri=http://127.0.0.1:{port}"]
    uri = f"sqlite:///{tmp_path / 'later.db'}"
    # the same command, to a store that is there now
    logged = track_command(*command[1:3], f"tracker.uri={uri}", *command[4:], cwd=tmp_path)
    assert logged.returncode == 0, logged.stderr
    assert "decrun-track: tracker=mlflow: 2 jobs under run" in logged.stdout
    runs = _runs(uri)
    assert sorted(r.data.tags.get("decrun.job", "") for r in runs) == ["", "0", "1"]
    again = track_command(*command[1:3], f"tracker.uri={uri}", cwd=tmp_path)  # nothing changed: nothing sent
    assert "(0 sent)" in again.stdout and len(_runs(uri)) == 3


def test_a_single_run_is_one_run_without_a_parent(tmp_path):
    uri = f"sqlite:///{tmp_path / 'one.db'}"
    proc = decrun("app=heat", "mesh.subdiv=1", "app.t_end=0.002", "app.dt=1e-3", "figures=false", "tracker=mlflow",
                  f"tracker.uri={uri}", "tracker.experiment=single", "tracker.result_h5=true", "hydra.run.dir=run",
                  cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    (run,) = _runs(uri, "single")
    assert "mlflow.parentRunId" not in run.data.tags and run.info.status == "FINISHED"
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert run.data.metrics["dirichlet_energy"] == metrics["dirichlet_energy"]
    assert run.data.metrics["steps_done"] == 2.0
    assert "result.h5" in {a.path for a in _client(uri).list_artifacts(run.info.run_id)}  # tracker.result_h5=true


def test_mlflow_missing_is_refused_before_any_work_naming_the_fix(tmp_path, monkeypatch):
    import importlib.util

    from decrun.errors import ConfigError
    from decrun.runner.tracking.mlflow_tracker import MlflowTracker

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "mlflow" else real(name, *a))
    with pytest.raises(ConfigError, match=r"^tracker=mlflow: needs the package 'mlflow'.*pip install 'decrun\[mlflow\]', "
                                          r"or run without it: tracker=none$"):
        MlflowTracker().check()
    proc = decrun("app=heat", "mesh.subdiv=1", "app.t_end=0.002", "app.dt=1e-3", "figures=false", "tracker=none",
                  "hydra.run.dir=run", cwd=tmp_path)  # the override the message names
    assert proc.returncode == 0 and not (tmp_path / "run" / "tracking.json").exists()


def test_bad_tracker_options_name_their_key(tmp_path):
    proc = decrun("app=heat", "tracker=mlflow", "tracker.timeout_seconds=0", cwd=tmp_path)
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines()[-1] == ("error: tracker.timeout_seconds: must be > 0, got 0.0; "
                                                    "e.g. tracker.timeout_seconds=10")
    ok = decrun("app=heat", "mesh.subdiv=1", "app.t_end=0.002", "app.dt=1e-3", "figures=false", "tracker=mlflow",
                f"tracker.uri=sqlite:///{tmp_path / 'x.db'}", "tracker.timeout_seconds=10", cwd=tmp_path)
    assert ok.returncode == 0, ok.stderr


def test_batches_keep_mlflows_limits_and_lose_nothing():
    from decrun.runner.tracking.mlflow_tracker import _batches

    params, tags, metrics = list(range(250)), list(range(30)), list(range(2500))
    batches = _batches(params, tags, metrics)
    for batch in batches:
        assert len(batch["params"]) <= 100 and len(batch["tags"]) <= 100
        assert len(batch["params"]) + len(batch["tags"]) + len(batch["metrics"]) <= 1000
    assert [p for b in batches for p in b["params"]] == params
    assert [t for b in batches for t in b["tags"]] == tags
    assert [m for b in batches for m in b["metrics"]] == metrics
    assert _batches([], [], []) == []


def test_flatten_gives_every_leaf_its_dotted_key():
    assert flatten({"app": {"dt": 0.001, "fields": {"u": {"form": 0}}}, "mesh": {"hole_balls": [[0, 0, 1, 0.5]]},
                    "optimize": {"metric": None}, "export": {}}) == {
        "app.dt": "0.001", "app.fields.u.form": "0", "mesh.hole_balls": "[[0, 0, 1, 0.5]]",
        "optimize.metric": "None", "export": "{}"}


def test_config_sections_a_sweeps_jobs_share_are_flattened_once_and_equal_a_full_parse():
    import yaml

    from decrun.runner.tracking import _params

    a = "app:\n  dt: 0.001\n  fields: {u: {form: 0}}\nmesh:\n  subdiv: 1\n  hole_balls:\n  - [0, 0, 1, 0.5]\nhydra:\n  x: 1\n"
    b = a.replace("dt: 0.001", "dt: 0.002")
    c = "app: &base\n  dt: 0.001\nmesh: *base\n"  # an alias: its meaning lies outside its own text
    d = c.replace("dt: 0.001", "dt: 0.003")
    shared: dict = {}
    for text in (a, b, c, d):
        full = flatten({k: v for k, v in yaml.safe_load(text).items() if k != "hydra"})
        assert _params(Path("job"), {"config_yaml": text}, shared) == full
    assert sorted(key for key, _ in shared) == ["app", "app", "mesh"]  # a's mesh served b; c, d never cached
    assert _params(Path("job"), {"config_yaml": d}, shared)["mesh.dt"] == "0.003"


def test_the_tracker_is_not_part_of_the_config_hash():
    from decrun.runner.job.config import compose_config
    from decrun.runner.sweep.manifest import config_hash

    base = ["app=heat", "mesh.subdiv=1"]
    assert config_hash(compose_config(base)) == config_hash(compose_config([*base, "tracker=mlflow",
                                                                             "tracker.uri=sqlite:///x.db"]))
    assert config_hash(compose_config(base)) != config_hash(compose_config([*base, "app.dt=2e-3"]))


def test_the_docs_commands_run(tmp_path):
    """Every command of docs/tracking.md's ``bash`` blocks, in order, in one directory (the
    server command of the UI section is run by tests/runner/results/test_tracker_ui.py)."""
    doc = (Path(__file__).resolve().parents[3] / "docs" / "tracking.md").read_text()
    blocks = [b.split("```", 1)[0] for b in doc.split("```bash\n")[1:]]
    commands = [line for block in blocks for line in block.splitlines() if line.strip() and not line.startswith("#")]
    assert any(c.startswith("decrun -m") for c in commands) and any(c.startswith("decrun-track") for c in commands)
    for command in commands:
        words = shlex.split(command)
        if words[0] == "mlflow":
            assert words[1] == "server"  # started (and stopped) by the UI test
            continue
        if words[0] == "decrun":
            proc = decrun(*words[1:], cwd=tmp_path)
        elif words[0] == "decrun-track":
            proc = track_command(*words[1:], cwd=tmp_path)
        else:
            raise AssertionError(f"docs/tracking.md: a command this test does not know: {command}")
        assert proc.returncode == 0, (command, proc.stderr)
    runs = _runs(f"sqlite:///{tmp_path / 'mlflow.db'}")
    assert runs and all(r.data.tags["status"] == "ok" for r in runs)


def test_jobs_of_another_launcher_are_logged_from_the_sweeps_end(tmp_path):
    """hydra/launcher=joblib: the jobs run in worker processes; their runs are made by the
    command's own process from the job directories, as for every launcher."""
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher", reason="needs hydra-joblib-launcher (the parallel extra)")
    uri = f"sqlite:///{tmp_path / 'joblib.db'}"
    proc = decrun("-m", "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", "app=heat", "mesh.subdiv=1",
                  "app.t_end=0.002", "app.dt=1e-3,2e-3", "figures=false", "tracker=mlflow", f"tracker.uri={uri}",
                  "hydra.sweep.dir=sweep", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    runs = {r.data.tags.get("decrun.job"): r for r in _runs(uri)}
    assert set(runs) == {None, "0", "1"}
    for job in ("0", "1"):
        metrics = json.loads((tmp_path / "sweep" / job / "metrics.json").read_text())
        assert runs[job].data.metrics["dirichlet_energy"] == metrics["dirichlet_energy"]
        assert runs[job].data.tags["mlflow.parentRunId"] == runs[None].info.run_id


#: 2 tiny jobs for the launcher tests: every job's runs are made at the sweep's end by the command's own process
LAUNCHED = ["app=heat", "mesh.subdiv=1", "app.t_end=0.002", "app.dt=1e-3,2e-3", "figures=false", "tracker=mlflow"]


@pytest.mark.ray
@pytest.mark.slow
def test_jobs_run_by_the_ray_launcher_are_logged_from_the_sweeps_end(tmp_path):
    """hydra/launcher=ray on a local Ray: the jobs run in Ray workers, which never reach the
    store; the runs read back equal the sweep's files."""
    pytest.importorskip("hydra_plugins.hydra_ray_launcher", reason="needs hydra-ray-launcher (pip install 'decrun[ray]')")
    from tracked_sweeps import check_tracked_sweep

    uri = f"sqlite:///{tmp_path / 'ray.db'}"
    proc = decrun("-m", "hydra/launcher=ray", "+hydra.launcher.ray.init.num_cpus=2",
                  "+hydra.launcher.ray.init.include_dashboard=false",
                  "+hydra.launcher.ray.init.object_store_memory=78643200", *LAUNCHED, f"tracker.uri={uri}",
                  "hydra.sweep.dir=sweep", cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "warning" not in proc.stderr, proc.stderr[-3000:]
    check_tracked_sweep(tmp_path / "sweep", uri, proc.stdout)


def test_a_runs_files_go_up_in_one_log_artifacts_of_links_to_exactly_them(tmp_path, monkeypatch):
    import os

    from mlflow.store.artifact.local_artifact_repo import LocalArtifactRepository

    from decrun.runner.tracking.mlflow_tracker import _staged

    (tmp_path / "job" / ".hydra").mkdir(parents=True)
    files = {"u.png": b"\x89PNG one", ".hydra/config.yaml": b"app: {dt: 0.001}\n", "other.png": b"left out"}
    for name, data in files.items():
        (tmp_path / "job" / name).write_bytes(data)
    later = tmp_path / "later" / "u.png"  # a second file of a name: the later one is sent, as per file
    later.parent.mkdir()
    later.write_bytes(b"\x89PNG two")
    paths = [tmp_path / "job" / "u.png", tmp_path / "job" / ".hydra" / "config.yaml", later]
    for fallback in (False, True):
        if fallback:  # another filesystem: os.link refuses, a symbolic link stands in
            monkeypatch.setattr(os, "link", lambda *a, **k: (_ for _ in ()).throw(OSError(18, "cross-device")))
        with _staged(paths) as staged:
            assert sorted(os.listdir(staged)) == ["config.yaml", "u.png"]
            assert os.path.islink(os.path.join(staged, "u.png")) == fallback
            if not fallback:  # a hard link: the file itself, nothing copied
                assert os.stat(os.path.join(staged, "u.png")).st_ino == later.stat().st_ino
            repository = LocalArtifactRepository(str(tmp_path / f"artifacts{int(fallback)}"))
            repository.log_artifacts(staged)
        assert not os.path.exists(staged)
        sent = {f.path: (tmp_path / f"artifacts{int(fallback)}" / f.path).read_bytes()
                for f in repository.list_artifacts()}
        assert sent == {"config.yaml": b"app: {dt: 0.001}\n", "u.png": b"\x89PNG two"}
    assert later.read_bytes() == b"\x89PNG two" and later.stat().st_nlink == 1  # the originals as they were
    monkeypatch.undo()
    with pytest.raises(FileNotFoundError), _staged([tmp_path / "job" / "gone.png"]):
        pass  # a file gone since its record was read is an error, not a dangling link sent on


def test_a_result_checked_twice_in_a_process_is_read_once_and_any_change_is_read_again(tmp_path, monkeypatch):
    import os
    import time

    from decrun.errors import CorruptFileError
    from decrun.runner.results import checked

    path = tmp_path / "result.h5"
    path.write_bytes(bytes(range(256)) * 64)
    record = checked.file_record(path)
    reads = []
    real = checked.file_record
    monkeypatch.setattr(checked, "file_record", lambda p: reads.append(p) or real(p))
    checked.check_record(path, record)
    checked.check_record(path, record)
    assert len(reads) == 2  # just written: not remembered (a change could fall in the same clock tick)
    monkeypatch.setattr(checked, "SETTLED_NS", 0)
    checked.check_record(path, record)
    checked.check_record(path, record)
    checked.check_record(path, record)
    assert len(reads) == 3  # the table's check, then the tracker's: one read
    old = path.stat()
    time.sleep(0.02)
    with open(path, "r+b") as f:  # the same size, the old modification time put back: the change time moves
        f.write(b"altered")
    os.utime(path, ns=(old.st_atime_ns, old.st_mtime_ns))
    assert path.stat().st_size == old.st_size and path.stat().st_mtime_ns == old.st_mtime_ns
    with pytest.raises(CorruptFileError, match="sha256 differs"):
        checked.check_record(path, record)
    assert len(reads) == 4


def test_a_kill_between_making_a_run_and_keeping_its_id_makes_no_second_run(tmp_path):
    """Issue 50, item 13: a SIGKILL after MLflow made a job's run (and the sweep's) but before
    ``tracking.json`` kept its id leaves the run RUNNING and no id on disk. That state, made here
    exactly (the id files removed, the runs set back to RUNNING), then a resume: the same runs are
    found again by their ``decrun.run_key`` tag and logged into — no second run, none left RUNNING."""
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    sweep = ["-m", "app=heat", "mesh.subdiv=1", "app.steps=2", "figures=false", "app.dt=1e-3,2e-3", "tracker=mlflow",
             f"tracker.uri={uri}", "hydra.sweep.dir=sweep"]
    first = decrun(*sweep, cwd=tmp_path)
    assert first.returncode == 0, first.stderr[-2000:]
    before = {r.info.run_id: r for r in _runs(uri)}
    assert len(before) == 3
    client = _client(uri)
    for directory in (tmp_path / "sweep", tmp_path / "sweep" / "0"):
        state = directory / "tracking.json"
        client.set_terminated(json.loads(state.read_text())[uri]["run_id"], status="RUNNING")
        state.unlink()
    resumed = decrun(*sweep, "hydra.sweeper.resume=true", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    after = {r.info.run_id: r for r in _runs(uri)}
    assert set(after) == set(before), [r.info.run_name for r in after.values()]
    assert all(r.info.status == "FINISHED" for r in after.values()), [r.info.status for r in after.values()]
    job = json.loads((tmp_path / "sweep" / "0" / "tracking.json").read_text())[uri]["run_id"]
    assert after[job].data.tags["decrun.job"] == "0" and job in before


@pytest.mark.parametrize("first, then", [("none", "mlflow"), ("mlflow", "none")])
def test_a_sweep_resumes_with_the_tracker_switched(tmp_path, first, then):
    """Issue 50, item 14 (docs/tracking.md): the tracker is not part of a job's identity, so a
    ``tracker=none`` sweep resumes with ``tracker=mlflow`` (which logs it: one run per job under
    one for the sweep), and the other way round (nothing more is logged)."""
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    base = ["-m", "app=heat", "mesh.subdiv=1", "app.steps=2", "figures=false", "app.dt=1e-3,2e-3",
            "hydra.sweep.dir=sweep"]

    def tracker(name):
        return ["tracker=mlflow", f"tracker.uri={uri}"] if name == "mlflow" else ["tracker=none"]

    proc = decrun(*base, *tracker(first), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    logged = len(_runs(uri)) if first == "mlflow" else 0
    proc = decrun(*base, *tracker(then), "hydra.sweeper.resume=true", cwd=tmp_path)
    assert proc.returncode == 0 and "differ" not in proc.stderr, proc.stderr[-2000:]
    assert len(_runs(uri)) == (3 if "mlflow" in (first, then) else 0) and logged in (0, 3)
    if then == "mlflow":
        assert "decrun: tracker=mlflow: 2 jobs under run" in proc.stdout, proc.stdout
