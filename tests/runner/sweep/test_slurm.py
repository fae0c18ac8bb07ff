"""``hydra/launcher=submitit_slurm`` sweeps against a real SLURM (``scripts/slurm_local.sh
start``: one node, accounting off): the table equals the basic launcher's, ``scancel`` of a
job mid-run gives its row ``killed`` and resume finishes it, ``array_parallelism`` is
honoured (one sweep checks both), and the output has one line about accounting instead of submitit's sacct
warnings.

Without SLURM (no ``sinfo``, or no controller answers) the tests skip, saying how to start
one; under ``CI=true`` they fail instead (CI starts SLURM in ``.ci/run``)."""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path

import pandas as pd
import pytest

from decrun.runner.sweep.tables import load_sweep

#: wall-time columns (differ between two runs of the same jobs)
TIMES = ("setup_seconds", "solve_seconds", "total_seconds", "step_seconds_max")
SLURM = ["hydra/launcher=submitit_slurm", "hydra.launcher.timeout_min=5"]
#: cheap jobs: explicit smoothing on 162 vertices, no eigen-solve
CHEAP = ["mesh.subdiv=2", "app.scheme=explicit", "app.critical_dt=false", "figures=false"]


def slurm_problem() -> str | None:
    """Why no SLURM sweep can run here (None: a controller answers and a node is usable)."""
    if importlib.util.find_spec("hydra_plugins.hydra_submitit_launcher") is None:
        return "hydra-submitit-launcher is not installed (pip install 'decrun[slurm]')"
    if shutil.which("sinfo") is None:
        return "no SLURM here (sinfo not found); start a local one with: sudo scripts/slurm_local.sh start"
    try:
        proc = subprocess.run(["sinfo", "--noheader", "--format=%T"], capture_output=True, text=True, timeout=20)
    except subprocess.TimeoutExpired:
        return "sinfo did not answer within 20 s; start a local SLURM with: sudo scripts/slurm_local.sh start"
    if proc.returncode != 0:
        cause = (proc.stderr.strip().splitlines() or ["no output"])[0]
        return f"no SLURM controller answers (sinfo: {cause}); start a local one with: sudo scripts/slurm_local.sh start"
    if not {"idle", "mixed", "allocated"} & set(proc.stdout.split()):
        return f"no usable SLURM node (sinfo: {' '.join(proc.stdout.split()) or 'no nodes'})"
    return None


@pytest.fixture(scope="module")
def slurm():
    """Skip without a SLURM (fail under CI=true, where .ci/run starts one)."""
    problem = slurm_problem()
    if problem is not None:
        if os.environ.get("CI") == "true":
            pytest.fail(f"CI=true but {problem}")
        pytest.skip(problem)


def env() -> dict:
    return {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}


def decrun(*args, cwd, timeout=300):
    return subprocess.run([sys.executable, "-m", "decrun", *args], cwd=cwd, env=env(), capture_output=True,
                          text=True, timeout=timeout)


def comparable(table: pd.DataFrame) -> pd.DataFrame:
    return table.drop(columns=[c for c in TIMES if c in table.columns]).reset_index(drop=True)


def job_spans(sweep_dir: Path) -> list[tuple[float, float]]:
    """(start, end) of each SLURM job of a sweep, in seconds: the first and last timestamp
    of submitit's log of the job (``.submitit/<id>/<id>_0_log.out``, written in the job)."""
    spans = []
    for log in sorted((sweep_dir / ".submitit").glob("*/*_log.out")):
        stamps = [datetime.strptime(m, "%Y-%m-%d %H:%M:%S,%f").timestamp()
                  for m in re.findall(r"\((\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3})\)", log.read_text())]
        spans.append((stamps[0], stamps[-1]))
    return spans


def most_at_once(spans: list[tuple[float, float]]) -> int:
    """The largest number of spans that overlap at one instant."""
    events = sorted([(s, 1) for s, _ in spans] + [(e, -1) for _, e in spans], key=lambda x: (x[0], x[1]))
    running = best = 0
    for _, step in events:
        running += step
        best = max(best, running)
    return best


def test_a_slurm_sweep_gives_the_basic_launchers_table_honours_array_parallelism_and_says_accounting_once(
        slurm, tmp_path):
    """One sweep of three tiny jobs: its table is the basic launcher's; with
    ``array_parallelism=1`` no two of its jobs ran at once (the node has room for two, so
    without the cap they overlap); no sacct warning, at most one line saying accounting is off."""
    cpus = subprocess.run(["sinfo", "--noheader", "--format=%c"], capture_output=True, text=True).stdout.split()
    assert int(cpus[0]) >= 2, f"the SLURM node has {cpus[0]} CPU: array_parallelism=1 would not be a cap"
    sweep = ["-m", "app.dt=0.001,0.002,0.003", "app.steps=20", *CHEAP]
    basic = decrun(*sweep, "hydra.sweep.dir=basic", cwd=tmp_path)
    assert basic.returncode == 0, basic.stderr
    proc = decrun(*sweep, *SLURM, "hydra.launcher.array_parallelism=1", "hydra.sweep.dir=slurm", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    pd.testing.assert_frame_equal(comparable(load_sweep(tmp_path / "slurm")), comparable(load_sweep(tmp_path / "basic")))
    spans = job_spans(tmp_path / "slurm")
    assert len(spans) == 3 and most_at_once(spans) == 1, spans
    output = proc.stdout + proc.stderr
    assert "sacct" not in output.replace("decrun: SLURM accounting is off (sacct:", ""), output
    assert output.count("SLURM accounting is off") <= 1, output
    accounting = subprocess.run(["sacct", "--noheader", "-j", "1"], capture_output=True).returncode == 0
    assert ("SLURM accounting is off" in output) == (not accounting)


def test_a_job_cancelled_mid_run_is_killed_in_the_table_and_resume_finishes_it(slurm, tmp_path):
    # job 1 runs long enough to be cancelled while it records; jobs 0 and 2 are short
    sweep = ["-m", "app.steps=100,40000,150", "app.dt=0.001", *CHEAP, *SLURM, "hydra.sweep.dir=cut"]
    proc = subprocess.Popen([sys.executable, "-m", "decrun", *sweep], cwd=tmp_path, env=env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    journal = tmp_path / "cut" / "1" / "result.h5.partial"
    deadline = time.time() + 120
    while time.time() < deadline and not (journal.is_file() and journal.stat().st_size > 20_000):
        time.sleep(0.05)
    assert journal.is_file(), "job 1 recorded nothing within 120 s"
    job_id = next(p.name for p in (tmp_path / "cut" / ".submitit").iterdir() if p.name.endswith("_1"))
    subprocess.run(["scancel", job_id], check=True)  # SIGTERM, then SIGKILL after KillWait
    try:
        stdout, stderr = proc.communicate(timeout=180)
    finally:
        proc.kill()
    assert proc.returncode == 1, stderr  # a job is not ok
    assert f"a SLURM job ended without a result (Job {job_id} " in stderr and "hydra.sweeper.resume=true" in stderr
    table = load_sweep(tmp_path / "cut")
    assert list(table["status"]) == ["ok", "killed", "ok"], table[["job", "status", "error"]]
    assert table.loc[1, "result"] == "1/result.h5.partial"

    resumed = decrun(*sweep, "hydra.sweeper.resume=true", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert "2 of 3 jobs are ok; running 1" in resumed.stderr
    table = load_sweep(tmp_path / "cut")
    assert list(table["status"]) == ["ok", "ok", "ok"]
    assert table.loc[1, "result"] == "1/result.h5" and not journal.exists()


def test_a_preempted_fluid_job_is_requeued_and_continues_from_its_checkpoint(slurm, tmp_path):
    """``scancel --signal=USR2`` is what submitit asks SLURM to send before the time limit
    (and what preemption sends): the launcher's checkpoint requeues the job and the rerun
    continues from checkpoint.h5, ending bitwise equal to an uninterrupted run. SLURM holds a
    requeued job for ~2 minutes; the test lets it start at once (scontrol)."""
    import json

    import h5py
    import numpy as np

    run = ["app=fluid", "app.steps=3000", "checkpoint.steps=4", "figures=false", "progress=false"]
    reference = decrun("-m", *run, "hydra.sweep.dir=reference", cwd=tmp_path)
    assert reference.returncode == 0, reference.stderr
    sweep = ["-m", *run, *SLURM, "hydra.launcher.max_num_timeout=2", "hydra.sweep.dir=preempted"]
    proc = subprocess.Popen([sys.executable, "-m", "decrun", *sweep], cwd=tmp_path, env=env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    job_dir = tmp_path / "preempted" / "0"
    deadline = time.time() + 180
    while time.time() < deadline and not (job_dir / "checkpoint.h5").is_file():
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    # the job's folder (its SLURM id, "<id>" or "<id>_<task>"), not submitit's hidden .submission_file_*.sh
    job_id = next(p.name for p in sorted((tmp_path / "preempted" / ".submitit").iterdir())
                  if p.is_dir() and p.name.split("_")[0].isdigit())
    # A step takes ~2 ms (1,280 faces): 3,000 steps keep the job running for seconds after
    # its first checkpoint, long past USR2's delivery (SLURM refuses to signal a suspended job,
    # so the job cannot be held still instead).
    assert not (job_dir / "metrics.json").exists(), "the job ended before USR2 was sent: raise app.steps"
    subprocess.run(["scancel", "--signal=USR2", job_id], check=True)
    deadline = time.time() + 60
    while time.time() < deadline:  # requeued: pending until its begin time; start it now
        state = subprocess.run(["squeue", "--noheader", "-j", job_id, "--format=%T %r"], capture_output=True,
                               text=True).stdout
        if "PENDING" in state:
            subprocess.run(["scontrol", "update", f"jobid={job_id}", "StartTime=now"], check=True)
            break
        time.sleep(0.2)
    try:
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert proc.returncode == 0, stderr[-3000:]
    metrics = json.loads((job_dir / "metrics.json").read_text())
    assert metrics["status"] == "ok" and metrics["resumed_from_step"] > 0
    assert "checkpoint: continuing from step" in (job_dir / "decrun.log").read_text()
    with h5py.File(job_dir / "result.h5") as a, h5py.File(tmp_path / "reference" / "0" / "result.h5") as b:
        for group in ("fields", "series"):
            assert sorted(a[group]) == sorted(b[group])
            for name in a[group]:
                assert np.array_equal(a[group][name][()], b[group][name][()]), f"{group}/{name}"


def test_a_tracked_slurm_sweep_is_logged_from_the_sweeps_end(slurm, tmp_path):
    """tracker=mlflow on submitit_slurm: the jobs run as SLURM jobs, which never reach the
    store; the command that submitted them logs them once the table is written, and the runs
    read back equal the sweep's files."""
    pytest.importorskip("mlflow", reason="tracker=mlflow needs the mlflow extra: pip install 'decrun[mlflow]'")
    from tracked_sweeps import check_tracked_sweep

    uri = f"sqlite:///{tmp_path / 'slurm.db'}"
    proc = decrun("-m", "app.dt=0.001,0.002", "app.steps=3", *CHEAP, *SLURM, "tracker=mlflow", f"tracker.uri={uri}",
                  "hydra.sweep.dir=slurm", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "warning: tracker" not in proc.stderr, proc.stderr[-3000:]
    assert len(list((tmp_path / "slurm" / ".submitit").glob("*/*_log.out"))) == 2  # the jobs ran on SLURM
    check_tracked_sweep(tmp_path / "slurm", uri, proc.stdout)
