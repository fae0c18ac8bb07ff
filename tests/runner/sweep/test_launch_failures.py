"""Launchers that cannot start (issue 34, item 3): no ``srun`` on the machine, ``sbatch``
refused, a Ray address nobody answers at, a joblib job over ``hydra.launcher.timeout``.
Each ends in one line naming the launcher, the cause and the command that fixes it, within
a bounded time; the fix is run as printed (decrun.runner.sweep.launchers)."""

from __future__ import annotations

import importlib.util
import json
import os
import shlex
import socket
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from decrun.runner.sweep.tables import load_sweep

from cli_processes import env

#: two jobs of a fraction of a second
TINY = ["-m", "app.dt=0.001,0.002", "app.steps=2", "mesh.subdiv=1", "app.critical_dt=false", "figures=false",
        "progress=false"]


def has(plugin: str) -> bool:
    return importlib.util.find_spec(f"hydra_plugins.{plugin}") is not None


def run(args, cwd, path: str | None = None, timeout: float = 300) -> tuple[subprocess.CompletedProcess, float]:
    """``decrun args`` (as ``python -m decrun``) with ``PATH`` replaced by ``path``; and its wall seconds."""
    environment = env() if path is None else {**env(), "PATH": path}
    started = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "decrun", *args], cwd=cwd, env=environment, capture_output=True,
                          text=True, timeout=timeout)
    return proc, time.monotonic() - started


def the_error(proc: subprocess.CompletedProcess) -> str:
    """The one ``error:`` line of a refused command (and no traceback)."""
    assert proc.returncode == 1, proc.stdout[-2000:] + proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
    errors = [line for line in proc.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, proc.stderr[-3000:]
    return errors[0]


def fixed_command(line: str, marker: str) -> list[str]:
    """The command a message gives after ``marker``, as arguments of ``decrun``."""
    words = shlex.split(line.split(marker, 1)[1])
    assert words[0] == "decrun", line
    return words[1:]


def fake_slurm(tmp_path: Path) -> str:
    """A PATH whose ``srun`` exists and whose ``sbatch`` refuses every job, as when the
    controller does not answer."""
    bin_dir = tmp_path / "fake-slurm"
    bin_dir.mkdir()
    (bin_dir / "srun").write_text("#!/bin/sh\nexit 1\n")
    (bin_dir / "sbatch").write_text("#!/bin/sh\necho 'sbatch: error: Batch job submission failed: Unable to "
                                    "contact slurm controller (connect failure)' >&2\nexit 1\n")
    for name in ("srun", "sbatch"):
        (bin_dir / name).chmod(0o755)
    return f"{bin_dir}{os.pathsep}{Path(sys.executable).parent}{os.pathsep}/usr/bin{os.pathsep}/bin"


@pytest.mark.skipif(not has("hydra_submitit_launcher"), reason="hydra-submitit-launcher is not installed")
def test_slurm_without_srun_is_one_line_before_anything_is_written_and_its_fix_runs(tmp_path):
    no_slurm = str(Path(sys.executable).parent)  # python, no srun / sbatch
    proc, seconds = run([*TINY, "hydra/launcher=submitit_slurm", "hydra.launcher.partition=gpu",
                         "hydra.sweep.dir=s"], tmp_path, path=no_slurm)
    line = the_error(proc)
    assert line.startswith("error: hydra/launcher=submitit_slurm: `srun` is not on PATH"), line
    assert "nothing ran" in line and seconds < 30, (line, seconds)
    assert not (tmp_path / "s").exists()  # refused before planning: nothing written
    fix = fixed_command(line, "run the sweep on this machine with: ")
    assert "hydra/launcher=submitit_local" in fix and "hydra/launcher=submitit_slurm" not in fix
    assert not any(a.startswith("hydra.launcher.partition") for a in fix)  # a SLURM-only option is dropped
    fixed, _ = run(fix, tmp_path, path=no_slurm)
    assert fixed.returncode == 0, fixed.stderr[-3000:]
    assert list(load_sweep(tmp_path / "s")["status"]) == ["ok", "ok"]


@pytest.mark.skipif(not has("hydra_submitit_launcher"), reason="hydra-submitit-launcher is not installed")
def test_a_refused_submission_leaves_the_manifest_and_the_printed_resume_finishes_the_sweep(tmp_path):
    proc, _ = run([*TINY, "hydra/launcher=submitit_slurm", "hydra.sweep.dir=s"], tmp_path, path=fake_slurm(tmp_path))
    line = the_error(proc)
    assert line.startswith("error: hydra/launcher=submitit_slurm: cannot submit its jobs (sbatch: error: Batch job "
                           "submission failed: Unable to contact slurm controller"), line
    assert "jobs 0, 1 not started" in line and "ended without a result" not in proc.stderr, proc.stderr
    manifest = json.loads((tmp_path / "s" / "manifest.json").read_text())
    assert [j["job"] for j in manifest["jobs"]] == ["0", "1"] and manifest["runs"][-1]["finished"] is None
    fix = fixed_command(line, "resume here with: ")
    assert fix[-2:] == ["hydra.sweep.dir=s", "hydra.sweeper.resume=true"] and "hydra/launcher=submitit_local" in fix
    resumed, _ = run(fix, tmp_path)
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert list(load_sweep(tmp_path / "s")["status"]) == ["ok", "ok"]


def closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.skipif(not has("hydra_ray_launcher"), reason="hydra-ray-launcher is not installed")
@pytest.mark.ray
def test_a_ray_address_that_refuses_is_given_up_at_once(tmp_path):
    address = f"127.0.0.1:{closed_port()}"
    proc, seconds = run([*TINY, "hydra/launcher=ray", f"hydra.launcher.ray.init.address={address}",
                         "hydra.sweep.dir=r"], tmp_path)
    line = the_error(proc)
    assert line.startswith(f"error: hydra/launcher=ray: cannot reach the Ray cluster at "
                           f"hydra.launcher.ray.init.address={address} (connection refused)"), line
    assert "nothing ran" in line and seconds < 30 and not (tmp_path / "r").exists(), (line, seconds)
    assert fixed_command(line, "on a local Ray with: ")[-1] == "hydra.launcher.ray.init.address=local"


@pytest.mark.skipif(not has("hydra_ray_launcher"), reason="hydra-ray-launcher is not installed")
@pytest.mark.ray
def test_a_ray_address_that_never_answers_is_given_up_after_connect_timeout_and_the_fix_runs(tmp_path):
    """A socket that accepts connections and never speaks: Ray retries it for minutes."""
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(64)
        address = f"127.0.0.1:{silent.getsockname()[1]}"
        proc, seconds = run([*TINY, "hydra/launcher=ray", f"hydra.launcher.ray.init.address={address}",
                             "hydra.sweeper.connect_timeout=3", "hydra.sweep.dir=r"], tmp_path, timeout=120)
    line = the_error(proc)
    assert line.startswith(f"error: hydra/launcher=ray: cannot reach the Ray cluster at "
                           f"hydra.launcher.ray.init.address={address} (no Ray cluster answered within 3 s, "
                           f"hydra.sweeper.connect_timeout=3"), line
    assert seconds < 3 + 20, seconds  # the timeout plus the command's start-up
    assert not [l for l in proc.stderr.splitlines() if "gcs_client" in l and not l.startswith("error:")]
    assert not (tmp_path / "r").exists()
    fix = fixed_command(line, "on a local Ray with: ")
    fixed, _ = run([*fix, "+hydra.launcher.ray.init.num_cpus=1", "+hydra.launcher.ray.init.include_dashboard=false"],
                   tmp_path)
    assert fixed.returncode == 0, fixed.stderr[-3000:]
    assert list(load_sweep(tmp_path / "r")["status"]) == ["ok", "ok"]


@pytest.mark.skipif(not has("hydra_joblib_launcher"), reason="hydra-joblib-launcher is not installed")
def test_a_joblib_job_over_its_timeout_is_one_line_with_the_table_and_the_resume_finishes(tmp_path):
    slow = ["-m", "app.dt=0.001,0.002,0.003", "mesh.subdiv=2", "app.scheme=explicit", "app.steps=20000",
            "app.critical_dt=false", "figures=false", "progress=false"]
    proc, _ = run([*slow, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", "hydra.launcher.timeout=2",
                   "hydra.sweep.dir=j"], tmp_path)
    line = the_error(proc)
    assert line.startswith("error: hydra/launcher=joblib: a job ran longer than hydra.launcher.timeout=2 s"), line
    assert "killed" in line or "not started" in line, line  # a loaded machine may start no job within 2 s
    table = load_sweep(tmp_path / "j")
    assert (tmp_path / "j" / "metrics.csv").is_file()  # the table was written
    assert set(table["status"]) <= {"ok", "killed", "missing"} and set(table["status"]) != {"ok"}
    assert all("hydra.launcher.timeout=2" in e for e in table.loc[table["status"] == "killed", "error"])
    fix = fixed_command(line, "resume with no time limit: ")
    assert "hydra.launcher.timeout=null" in fix and fix[-1] == "hydra.sweeper.resume=true"
    resumed, _ = run(fix, tmp_path)
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert list(load_sweep(tmp_path / "j")["status"]) == ["ok", "ok", "ok"]


def test_launch_failures_are_recognised_by_their_launcher_only():
    """A job's own RuntimeError under SLURM, or a ConnectionError under joblib, is not a
    launcher that cannot start."""
    import subprocess as sp

    from hydra_plugins.hydra_joblib_launcher.joblib_launcher import JoblibLauncher as Joblib
    from hydra_plugins.hydra_ray_launcher.ray_launcher import RayLauncher as Ray
    from hydra_plugins.hydra_submitit_launcher.submitit_launcher import SlurmLauncher as Slurm

    from decrun.runner.sweep.launchers import launch_failure, timed_out

    class SlurmLauncher(Slurm):  # the plugin classes, not set up (no cluster here)
        def __init__(self):
            pass

    class JoblibLauncher(Joblib):
        def __init__(self):
            self.joblib = {"timeout": 2}

    class RayLauncher(Ray):
        def __init__(self):
            self.ray_cfg = SimpleNamespace(init={"address": "10.0.0.1:6379"})

    class Named:  # a launcher that only bears a known plugin's name is not that plugin
        pass

    Named.__name__ = "RayLauncher"
    config = {}
    refused = RuntimeError("sbatch: error: invalid partition")
    refused.__cause__ = sp.CalledProcessError(1, ["sbatch", "/x/submission.sh"])
    assert launch_failure(SlurmLauncher(), config, refused)[0].endswith("(sbatch: error: invalid partition)")
    assert launch_failure(SlurmLauncher(), config, RuntimeError("the job's own failure")) is None
    assert launch_failure(JoblibLauncher(), config, ConnectionError("a job's socket")) is None
    assert launch_failure(RayLauncher(), config, ConnectionError("Failed to connect")) is not None
    assert launch_failure(Named(), config, ConnectionError("Failed to connect")) is None
    import multiprocessing

    assert timed_out(JoblibLauncher(), multiprocessing.TimeoutError())
    assert not timed_out(SlurmLauncher(), multiprocessing.TimeoutError())


def test_a_connect_timeout_that_is_no_time_is_refused_and_its_fix_runs(tmp_path):
    proc, _ = run([*TINY, "hydra.sweeper.connect_timeout=0", "hydra.sweep.dir=c"], tmp_path)
    line = the_error(proc)
    assert line.startswith("error: hydra.sweeper.connect_timeout=0.0: must be a number of seconds above 0"), line
    fix = line.rsplit("use ", 1)[1]
    assert fix == "hydra.sweeper.connect_timeout=20", line
    fixed, _ = run([*TINY, fix, "hydra.sweep.dir=c"], tmp_path)
    assert fixed.returncode == 0, fixed.stderr[-3000:]
