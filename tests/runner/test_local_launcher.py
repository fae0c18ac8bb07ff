"""decrun's loop of the basic launcher (decrun.runner.sweep.local) against Hydra's own: the
same sweep run both ways — Hydra's ``BasicLauncher.launch`` / ``run_job`` in one process,
decrun's in another — writes the same ``.hydra/`` files, logs, metrics and table, and
returns the same ``JobReturn`` for every job (its config, its Hydra config, overrides,
working directory, status, return value, task name)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from cli_processes import comparable, env
from omegaconf import OmegaConf

from decrun.runner.sweep import local

#: run in a child process: the sweep ``sys.argv[2:]`` with Hydra's launcher loop (argv[1] ==
#: "hydra") or decrun's ("local"); every JobReturn summarized into <sweep dir>/returns.json
CHILD = r"""
import json, os, sys
from omegaconf import OmegaConf
import decrun.runner.sweep.local as local
import decrun.runner.sweep.sweeper as sweeper

mode, args = sys.argv[1], sys.argv[2:]
if mode == "hydra":
    local.is_basic_launcher = lambda launcher: False  # the sweeper then calls BasicLauncher.launch itself
launch, local_run_job, local_jobs = sweeper.ManifestSweeper._launch, local.run_job, []

def counted(**kwargs):  # the jobs decrun's loop ran through its own run_job
    local_jobs.append(kwargs["config"].hydra.job.num)
    return local_run_job(**kwargs)

local.run_job = counted

def summarized(self, overrides, first):
    returns = launch(self, overrides, first)
    out = [{"status": r.status.name, "return_value": repr(r.return_value), "task_name": r.task_name,
            "working_dir": r.working_dir, "overrides": r.overrides, "cfg": OmegaConf.to_yaml(r.cfg),
            "hydra_cfg": OmegaConf.to_yaml(r.hydra_cfg), "output_dir": r.hydra_cfg.hydra.runtime.output_dir}
           for r in returns]
    sweep_dir = str(self.config.hydra.sweep.dir)
    with open(os.path.join(sweep_dir, "returns.json"), "w") as f:
        json.dump({"returns": out, "cwd": os.getcwd(), "local_jobs": local_jobs}, f)
    return returns

sweeper.ManifestSweeper._launch = summarized
import decrun.runner.cli as cli
sys.argv = ["decrun", "-m", *args]
cli.main()
"""

#: metrics that measure time, and log lines' time stamps: the only differences allowed
TIMING = re.compile(r"seconds")
STAMP = re.compile(r"^\[\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3}\]", re.M)
LOGGED_TIME = re.compile(r"\b(\w*seconds\w*)=[-+.\deE]+")


def _sweep(mode: str, sweep_dir: Path, cwd: Path, *overrides: str) -> dict:
    proc = subprocess.run([sys.executable, "-c", CHILD, mode, *overrides, "figures=false", "progress=false",
                           f"hydra.sweep.dir={sweep_dir}"], cwd=cwd, env=env(), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads((sweep_dir / "returns.json").read_text())


def _files(sweep_dir: Path) -> dict[str, str]:
    """Every file of the sweep that is not binary or a record of time, as text to compare."""
    files = {}
    for path in sorted(sweep_dir.rglob("*")):
        name = str(path.relative_to(sweep_dir))
        if not path.is_file() or path.suffix in (".h5", ".lock") or path.name in ("returns.json", "manifest.json"):
            continue
        text = path.read_text()
        if path.name == "metrics.json":
            text = json.dumps({k: v for k, v in json.loads(text).items() if not TIMING.search(k)
                               and k != "result_h5"}, sort_keys=True)
        elif path.suffix in (".csv", ".md"):  # the tables: compared without their wall times (test)
            continue
        files[name] = LOGGED_TIME.sub(r"\1=[t]", STAMP.sub("[T]", text))
    return files


@pytest.mark.parametrize("extra", [[], ["hydra.job.chdir=true"]], ids=["default", "chdir"])
def test_decruns_launcher_loop_returns_and_writes_what_hydras_does(tmp_path, extra):
    sweep_dir = tmp_path / "s"
    results = {}
    for mode in ("hydra", "local"):
        results[mode] = (_sweep(mode, sweep_dir, tmp_path, "app.dt=0.001,0.002", "app.steps=3", *extra),
                         _files(sweep_dir))
        sweep_dir.rename(tmp_path / mode)
    (hydra_returns, hydra_files), (local_returns, local_files) = results["hydra"], results["local"]
    tables = [comparable(pd.read_csv(tmp_path / mode / "metrics.csv")) for mode in ("hydra", "local")]
    pd.testing.assert_frame_equal(*tables)
    assert list(tables[1]["status"]) == ["ok", "ok"]
    assert hydra_returns.pop("local_jobs") == [] and local_returns.pop("local_jobs") == [0, 1]
    assert hydra_returns == local_returns  # both ran in tmp_path/s (renamed after each run)
    assert hydra_files == local_files
    assert set(local_files) >= {"0/.hydra/config.yaml", "0/.hydra/hydra.yaml", "0/.hydra/overrides.yaml",
                                "1/.hydra/hydra.yaml", "0/decrun.log", "1/metrics.json"}
    for job, returned in enumerate(local_returns["returns"]):
        assert returned["status"] == "COMPLETED" and returned["return_value"] == "0"
        assert returned["output_dir"] == str(sweep_dir / str(job))
        assert returned["working_dir"] == (returned["output_dir"] if extra else str(tmp_path))
    assert local_returns["cwd"] == str(tmp_path)  # chdir=true: back where the sweep started


def test_a_job_directory_that_interpolates_goes_through_hydras_run_job(monkeypatch):
    """Only literal directory keys are read without a HydraConfig; anything else, and a
    config that leaves hydra.job.chdir to the version base, is Hydra's run_job's."""
    literal = OmegaConf.create({"hydra": {"sweep": {"dir": "/tmp/s", "subdir": "3"}, "job": {"chdir": False}}})
    assert local.literal_output_dir(literal, "hydra.sweep.dir", "hydra.sweep.subdir") == "/tmp/s/3"
    pattern = OmegaConf.create({"hydra": {"sweep": {"dir": "/tmp/s", "subdir": "${hydra.job.num}"},
                                          "job": {"num": 3, "chdir": False}}})
    assert local.literal_output_dir(pattern, "hydra.sweep.dir", "hydra.sweep.subdir") is None
    calls = []
    monkeypatch.setattr(local, "hydra_run_job", lambda **kwargs: calls.append(kwargs) or "hydra's")
    assert local.run_job(hydra_context=None, task_function=None, config=pattern, job_dir_key="hydra.sweep.dir",
                         job_subdir_key="hydra.sweep.subdir") == "hydra's"
    unset = OmegaConf.create({"hydra": {"sweep": {"dir": "/tmp/s", "subdir": "3"}, "job": {"chdir": None}}})
    assert local.run_job(hydra_context=None, task_function=None, config=unset, job_dir_key="hydra.sweep.dir",
                         job_subdir_key="hydra.sweep.subdir") == "hydra's"
    assert len(calls) == 2


def test_only_hydras_basic_launcher_itself_is_run_by_decrun():
    from hydra._internal.core_plugins.basic_launcher import BasicLauncher

    class Mine(BasicLauncher):
        pass

    assert local.is_basic_launcher(BasicLauncher())
    assert not local.is_basic_launcher(Mine()) and not local.is_basic_launcher(object())
