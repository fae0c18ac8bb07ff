"""Sweeps end to end (``decrun -m`` processes): a sweep killed with SIGKILL mid-job, its
table, the refusals, and resume to the table of an uninterrupted sweep; the optimising
sweeper finding the critical time step; submitit and Ray launchers giving the basic
launcher's table. Launcher and sweeper tests skip with a message when their extra is
not installed."""

from __future__ import annotations

import importlib.util
import json
import signal
import subprocess
import sys
import time

import pandas as pd
import pytest
import yaml

from decrun.runner.command.table import table_main
from decrun.runner.sweep.tables import load_sweep

from cli_processes import comparable, decrun, env

# 4 jobs of ~0.5 s: explicit Euler on 162 vertices, no eigen-solve, well below dt_crit 0.0278
SWEEP = ["-m", "app.dt=0.001,0.002,0.003,0.004", "mesh.subdiv=2", "app.scheme=explicit", "app.steps=1500",
         "app.critical_dt=false", "figures=false"]
def test_a_sweep_killed_mid_job_resumes_to_the_table_of_an_uninterrupted_sweep(tmp_path):
    reference = decrun(*SWEEP, "hydra.sweep.dir=reference", cwd=tmp_path)
    assert reference.returncode == 0, reference.stderr

    # SIGKILL while job 1 records its steps (the whole basic-launcher process dies)
    proc = subprocess.Popen([sys.executable, "-m", "decrun", *SWEEP, "hydra.sweep.dir=killed"], cwd=tmp_path, env=env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    journal = tmp_path / "killed" / "1" / "result.h5.partial"
    deadline = time.time() + 120
    while time.time() < deadline and not (journal.is_file() and journal.stat().st_size > 20_000):
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    killed = tmp_path / "killed"
    assert journal.is_file(), "job 1 recorded nothing within 120 s"

    table = load_sweep(killed)
    assert list(table["status"]) == ["ok", "killed", "missing", "missing"]  # never looks complete
    assert list(table["app.dt"]) == [0.001, 0.002, 0.003, 0.004]
    assert table.loc[1, "result"] == "1/result.h5.partial" and table.loc[3, "error"] == "never started"
    manifest = json.loads((killed / "manifest.json").read_text())
    assert manifest["runs"][-1]["finished"] is None
    assert table_main([str(killed)]) == 1

    # the same command again is refused: its jobs would mix with the old ones
    again = decrun(*SWEEP, "hydra.sweep.dir=killed", cwd=tmp_path)
    assert again.returncode == 1
    assert again.stderr.strip().splitlines() == [again.stderr.strip()]  # one line
    assert "is not empty" in again.stderr and "hydra.sweeper.resume=true" in again.stderr
    # resume with other jobs, or with a job whose config hash differs, is refused
    other = decrun(*[a.replace("0.004", "0.005") for a in SWEEP], "hydra.sweep.dir=killed",
                   "hydra.sweeper.resume=true", cwd=tmp_path)
    assert other.returncode == 1 and "job 3: overrides" in other.stderr, other.stderr
    planned = json.loads((killed / "manifest.json").read_text())
    changed = json.loads(json.dumps(planned))
    changed["jobs"][2]["config_hash"] = "0" * 16
    (killed / "manifest.json").write_text(json.dumps(changed))
    hashed = decrun(*SWEEP, "hydra.sweep.dir=killed", "hydra.sweeper.resume=true", cwd=tmp_path)
    assert hashed.returncode == 1 and "job 2: config hash" in hashed.stderr, hashed.stderr
    (killed / "manifest.json").write_text(json.dumps(planned))

    done = (killed / "0" / "metrics.json").stat().st_mtime_ns
    resumed = decrun(*SWEEP, "hydra.sweep.dir=killed", "hydra.sweeper.resume=true", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert "1 of 4 jobs are ok; running 1, 2, 3" in resumed.stderr
    assert (killed / "0" / "metrics.json").stat().st_mtime_ns == done  # the finished job was not rerun
    assert not (killed / "1" / "result.h5.partial").exists()
    assert json.loads((killed / "manifest.json").read_text())["runs"][-1]["finished"]
    pd.testing.assert_frame_equal(comparable(pd.read_csv(killed / "metrics.csv")),
                                  comparable(pd.read_csv(tmp_path / "reference" / "metrics.csv")))


@pytest.mark.skipif(importlib.util.find_spec("hydra_plugins.hydra_optuna_sweeper") is None,
                    reason="hydra-optuna-sweeper is not installed (pip install 'decrun[optuna]')")
def test_optuna_finds_the_critical_time_step_within_5_percent(tmp_path):
    """Regression case of conf/experiment/dt_crit_search.yaml: the search maximises the
    stable app.dt without the eigen-solve; dt_crit = 2/λ_max from the same mesh."""
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    proc = decrun("-m", "hydra/sweeper=dt_crit_search", "+experiment=dt_crit_search", "hydra.sweep.dir=search",
                  cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stderr
    best = yaml.safe_load((tmp_path / "search" / "optimization_results.yaml").read_text())
    found = best["best_params"]["app.dt"]
    assert best["best_value"] == found
    exact = run_experiment(compose_config(["+experiment=dt_crit_search", "app.critical_dt=true", "app.steps=1"])).result
    dt_crit = exact.metrics["dt_critical_explicit"]
    assert abs(found - dt_crit) <= 0.05 * dt_crit, (found, dt_crit)
    table = load_sweep(tmp_path / "search")
    assert len(table) == 24 and set(table["status"]) == {"ok"}
    # every stable run is below ~dt_crit, every unstable one above it
    assert table.loc[~table["stable"], "dt"].min() > 0.95 * dt_crit
    assert table.loc[table["stable"], "dt"].max() < 1.05 * dt_crit


def _launcher_table(tmp_path, launcher: list[str], name: str) -> pd.DataFrame:
    small = ["-m", "app.dt=0.001,0.002", "mesh.subdiv=2", "app.steps=3", "figures=false"]
    proc = decrun(*small, *launcher, f"hydra.sweep.dir={name}", cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return comparable(pd.read_csv(tmp_path / name / "metrics.csv"))


@pytest.mark.skipif(importlib.util.find_spec("hydra_plugins.hydra_submitit_launcher") is None,
                    reason="hydra-submitit-launcher is not installed (pip install 'decrun[slurm]')")
def test_submitit_local_launcher_gives_the_basic_launchers_table(tmp_path):
    basic = _launcher_table(tmp_path, [], "basic")
    submitit = _launcher_table(tmp_path, ["hydra/launcher=submitit_local", "hydra.launcher.timeout_min=10"], "submitit")
    pd.testing.assert_frame_equal(submitit, basic)


@pytest.mark.skipif(importlib.util.find_spec("hydra_plugins.hydra_ray_launcher") is None,
                    reason="hydra-ray-launcher is not installed (pip install 'decrun[ray]')")
@pytest.mark.ray
def test_ray_launcher_on_a_local_cluster_gives_the_basic_launchers_table(tmp_path):
    basic = _launcher_table(tmp_path, [], "basic")
    ray = _launcher_table(tmp_path, ["hydra/launcher=ray", "+hydra.launcher.ray.init.num_cpus=2",
                                     "+hydra.launcher.ray.init.include_dashboard=false"], "ray")
    pd.testing.assert_frame_equal(ray, basic)


@pytest.mark.skipif(importlib.util.find_spec("hydra_plugins.hydra_submitit_launcher") is None,
                    reason="hydra-submitit-launcher is not installed (pip install 'decrun[slurm]')")
def test_the_readme_slurm_launcher_config_composes(tmp_path):
    """README's SLURM example (conf/hydra/launcher/slurm_example.yaml) is a valid
    submitit_slurm launcher config (there is no SLURM cluster here to run it)."""
    proc = decrun("hydra/launcher=slurm_example", "--cfg", "hydra", "--package", "hydra.launcher", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    launcher = yaml.safe_load(proc.stdout)
    launcher = launcher.get("hydra", {}).get("launcher", launcher)
    assert launcher["_target_"] == "hydra_plugins.hydra_submitit_launcher.submitit_launcher.SlurmLauncher"
    assert (launcher["partition"], launcher["timeout_min"], launcher["array_parallelism"]) == ("compute", 60, 64)


SMALL = ["mesh.subdiv=2", "app.steps=2", "figures=false"]


def test_every_planned_job_is_type_checked_before_the_first_starts(tmp_path):
    proc = decrun("-m", "app.dt=0.001,fast", *SMALL, "hydra.sweep.dir=bad", cwd=tmp_path)
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()], proc.stderr  # one line
    assert proc.stderr.startswith("error: job 1 (app.dt=fast") and "app.dt: " in proc.stderr, proc.stderr
    assert not (tmp_path / "bad").exists()  # job 0 did not run


@pytest.mark.parametrize("subdir, dirs", [("${hydra.job.override_dirname}", ["app.dt=0.001", "app.dt=0.002"]),
                                          ("run_${hydra.job.num}", ["run_0", "run_1"])])
def test_any_sweep_subdir_works_with_the_manifest_resume_and_the_table(tmp_path, subdir, dirs):
    args = ["-m", "app.dt=0.001,0.002", *SMALL, "hydra.sweep.dir=s", f"hydra.sweep.subdir={subdir}"]
    first = decrun(*args, "hydra.job.config.override_dirname.exclude_keys=[mesh.subdiv,app.steps,figures]",
                   cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    sweep = tmp_path / "s"
    manifest = json.loads((sweep / "manifest.json").read_text())
    assert [j["dir"] for j in manifest["jobs"]] == dirs
    assert list(load_sweep(sweep)["result"]) == [f"{d}/result.h5" for d in dirs]
    (sweep / dirs[1] / "metrics.json").unlink()
    kept = (sweep / dirs[0] / "metrics.json").stat().st_mtime_ns
    resumed = decrun(*args, "hydra.job.config.override_dirname.exclude_keys=[mesh.subdiv,app.steps,figures]",
                     "hydra.sweeper.resume=true", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert "1 of 2 jobs are ok; running 1" in resumed.stderr
    assert (sweep / dirs[0] / "metrics.json").stat().st_mtime_ns == kept
    assert sorted(p.name for p in sweep.iterdir() if p.is_dir()) == dirs  # the rerun landed in its directory
    assert list(load_sweep(sweep)["status"]) == ["ok", "ok"]


def test_jobs_sharing_a_directory_stop_the_sweep_before_it_starts(tmp_path):
    proc = decrun("-m", "app.dt=0.001,0.002", *SMALL, "hydra.sweep.dir=s", "hydra.sweep.subdir=same", cwd=tmp_path)
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1, proc.stderr
    assert "jobs 0 and 1 both get directory 'same'" in proc.stderr
    assert not (tmp_path / "s").exists()


def test_a_sweep_that_is_not_a_grid_stops_with_one_line_naming_it(tmp_path):
    proc = decrun("-m", "app.dt=interval(0.001,0.002)", *SMALL, "hydra.sweep.dir=s", cwd=tmp_path)
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1, proc.stderr
    assert proc.stderr.startswith("error: app.dt=interval(0.001,0.002): the decrun sweeper runs a grid of values: "
                                  "give them as a list (app.dt=a,b,c)"), proc.stderr
    assert not (tmp_path / "s").exists()


def test_an_override_named_like_a_metric_gets_its_own_column(tmp_path):
    """fig6_9_square sweeps boundary=none,flux and vector_field reports the boundary it used."""
    proc = decrun("-m", "+experiment=fig6_9_square", "mesh.max_area=0.01", "figures=false", "hydra.sweep.dir=s",
                  cwd=tmp_path)
    assert proc.returncode == 0 and "UserWarning" not in proc.stderr, proc.stderr
    table = pd.read_csv(tmp_path / "s" / "metrics.csv")
    assert table.columns.is_unique
    assert list(table["boundary"]) == list(table["metric.boundary"]) == ["none", "none", "flux", "flux"]
    header = next(line for line in proc.stdout.splitlines() if line.startswith("| job |")).split(" | ")
    assert "boundary" in header  # the printed table (the callback ran): swept keys + headline metrics
    markdown = (tmp_path / "s" / "metrics.md").read_text().splitlines()[0].split(" | ")
    assert "boundary" in markdown and "metric.boundary" in markdown  # metrics.md keeps every column
    assert table_main([str(tmp_path / "s"), "--all"]) == 0
