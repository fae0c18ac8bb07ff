"""A sweep that stops while its jobs run (``decrun -m`` processes, joblib launcher): one
worker SIGKILLed mid-job, and SIGTERM to the sweep after its first jobs finished. The
finished rows are kept, the lost jobs say so, and resume completes the table of an
uninterrupted sweep (decrun.runner.sweep.stops)."""

from __future__ import annotations

import json
import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from decrun.runner.sweep.tables import load_sweep

from cli_processes import comparable, decrun, env

pytest.importorskip("hydra_plugins.hydra_joblib_launcher", reason="hydra-joblib-launcher is not installed")

# 4 jobs of ~2 s: explicit Euler on 162 vertices, no eigen-solve, well below dt_crit 0.0278
JOBS = ["-m", "app.dt=0.001,0.002,0.003,0.004", "mesh.subdiv=2", "app.scheme=explicit", "app.steps=6000",
        "app.critical_dt=false", "figures=false", "progress=false"]
JOBLIB = ["hydra/launcher=joblib", "hydra.launcher.n_jobs=2"]
def descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (from /proc)."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                ppid = int(Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(entry))
    out, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


def holder_of(root: int, job_dir: Path) -> int | None:
    """The process below ``root`` with a file of ``job_dir`` open (the worker running it:
    its log file is open while the job runs)."""
    prefix = str(job_dir.resolve()) + os.sep
    for pid in descendants(root):
        try:
            fds = os.listdir(f"/proc/{pid}/fd")
        except OSError:
            continue
        for fd in fds:
            try:
                if os.readlink(f"/proc/{pid}/fd/{fd}").startswith(prefix):
                    return pid
            except OSError:
                continue
    return None


def wait_for(condition, what: str, seconds: float = 180) -> None:
    deadline = time.time() + seconds
    while not condition():
        if time.time() > deadline:
            raise AssertionError(f"{what} within {seconds} s")
        time.sleep(0.02)


def error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("error:")]


def test_a_killed_joblib_worker_keeps_the_finished_rows_and_resume_completes_the_table(tmp_path):
    reference = decrun(*JOBS, "hydra.sweep.dir=reference", cwd=tmp_path)
    assert reference.returncode == 0, reference.stderr

    proc = subprocess.Popen([sys.executable, "-m", "decrun", *JOBS, *JOBLIB, "hydra.sweep.dir=killed"], cwd=tmp_path,
                            env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = tmp_path / "killed"
    journal = killed / "1" / "result.h5.partial"
    try:
        wait_for(lambda: journal.is_file() and journal.stat().st_size > 20_000, "job 1 recorded steps")
        worker = holder_of(proc.pid, killed / "1")
        assert worker is not None and worker != proc.pid, "no worker process holds job 1's files"
        os.kill(worker, signal.SIGKILL)
        out, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 1, err
    assert "Traceback" not in err, err
    [line] = error_lines(err)  # one line: who died, what finished, how to resume
    assert "a worker process died (TerminatedWorkerError)" in line and "killed" in line, line
    resume = line.split("resume the rest with: ", 1)[1]
    assert resume.endswith("hydra.sweep.dir=killed hydra.sweeper.resume=true"), resume

    table = load_sweep(killed)
    assert table.loc[1, "status"] == "killed" and "its worker process died" in table.loc[1, "error"]
    assert "recorded steps" in table.loc[1, "error"]  # from its journal
    assert set(table["status"]) <= {"ok", "killed", "missing"}, table[["status", "error"]]
    assert list(table["app.dt"]) == [0.001, 0.002, 0.003, 0.004]
    written = pd.read_csv(killed / "metrics.csv")  # the table was written, finished rows kept
    assert list(written["status"]) == list(table["status"])
    manifest = json.loads((killed / "manifest.json").read_text())
    assert "1" in manifest["runs"][-1]["killed"] and manifest["runs"][-1]["finished"] is None
    ok = [str(i) for i, status in enumerate(table["status"]) if status == "ok"]
    done = {job: (killed / job / "metrics.json").stat().st_mtime_ns for job in ok}

    # the printed command, as typed
    words = shlex.split(resume)
    assert words[0] == "decrun"
    resumed = decrun(*words[1:], cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert {job: (killed / job / "metrics.json").stat().st_mtime_ns for job in ok} == done  # not rerun
    pd.testing.assert_frame_equal(comparable(pd.read_csv(killed / "metrics.csv")),
                                  comparable(pd.read_csv(tmp_path / "reference" / "metrics.csv")))


def test_sigterm_after_the_first_jobs_finished_says_which_finished_and_which_were_interrupted(tmp_path):
    proc = subprocess.Popen([sys.executable, "-m", "decrun", *JOBS, *JOBLIB, "hydra.sweep.dir=s"], cwd=tmp_path,
                            env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    sweep = tmp_path / "s"
    try:
        wait_for(lambda: all((sweep / j / "metrics.json").is_file() for j in ("0", "1"))
                 and (sweep / "2").is_dir(), "jobs 0 and 1 finished")
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 143, err
    assert "Traceback" not in err and "before the run started" not in err, err
    [line] = [line for line in err.splitlines() if line.startswith("decrun: interrupted (SIGTERM) during the sweep")]
    assert "jobs 0, 1 finished" in line and "2" in line.split("finished", 1)[1] and "interrupted" in line, line
    assert line.endswith("hydra.sweep.dir=s hydra.sweeper.resume=true"), line
    table = load_sweep(sweep)
    assert list(table["status"][:2]) == ["ok", "ok"]
    assert table.loc[2, "status"] == "interrupted" and table.loc[2, "error"] == "interrupted (SIGTERM)"
