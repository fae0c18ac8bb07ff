"""docs/cluster.md's "From laptop to cluster": every command of its block runs as written, and the
four sweeps (basic, joblib, submitit_slurm on the local SLURM, ray on a 2-node cluster)
give the same table (wall times aside).

The commands are read from docs/cluster.md (between the ``laptop-to-cluster`` markers), so an
edited line is tested as it reads. ``sudo`` is dropped (the tests run as root, as CI does);
``scripts/slurm_local.sh start`` is checked with ``status`` and not rerun here, and ``stop``
is not run (``.ci/run`` and the developer own the daemons): the SLURM sweep needs a running
SLURM (skip without one, fail under ``CI=true``: ``test_slurm.slurm_problem``).
``<head>:6379`` becomes the address of a ``ray.cluster_utils.Cluster`` started here."""

from __future__ import annotations

import importlib.util
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from decrun.runner.sweep.tables import load_sweep

ROOT = Path(__file__).resolve().parents[3]
TIMES = ("setup_seconds", "solve_seconds", "total_seconds", "step_seconds_max")
#: keep the page's jobs tiny here (its commands run the default experiment)
TINY = ["mesh.subdiv=2", "app.steps=3", "figures=false"]


def section_commands() -> list[str]:
    """The command lines of docs/cluster.md's laptop-to-cluster block, comments cut."""
    text = (ROOT / "docs" / "cluster.md").read_text()
    block = re.search(r"<!-- laptop-to-cluster -->\n```bash\n(.*?)```\n<!-- /laptop-to-cluster -->", text, re.S)
    assert block, "docs/cluster.md has no laptop-to-cluster block"
    return [line.split("  #", 1)[0].strip() for line in block.group(1).splitlines() if line.strip()]


def env() -> dict:
    return {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}


def comparable(table: pd.DataFrame) -> pd.DataFrame:
    return table.drop(columns=[c for c in TIMES if c in table.columns]).reset_index(drop=True)


def test_the_section_has_the_four_launchers():
    commands = section_commands()
    launchers = [next((w for w in shlex.split(c) if w.startswith("hydra/launcher=")), "basic")
                 for c in commands if c.startswith("decrun ")]
    assert launchers == ["basic", "hydra/launcher=joblib", "hydra/launcher=submitit_slurm", "hydra/launcher=ray"]
    assert "sudo scripts/slurm_local.sh start" in commands and "sudo scripts/slurm_local.sh stop" in commands


@pytest.fixture
def ray_head(monkeypatch):
    """A Ray cluster: a head without CPUs and two 1-CPU nodes; its address."""
    pytest.importorskip("hydra_plugins.hydra_ray_launcher", reason="pip install 'decrun[ray]'")
    from ray.cluster_utils import Cluster

    store = {"object_store_memory": 78_643_200}
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False, **store})
    try:
        for _ in range(2):
            cluster.add_node(num_cpus=1, **store)
        cluster.wait_for_nodes()
        yield cluster.address
    finally:
        cluster.shutdown()


@pytest.mark.ray
@pytest.mark.slow  # ~40 s: four sweeps and a Ray cluster (test_slurm and test_ray_cluster run by default)
def test_every_command_of_the_section_runs_and_the_tables_agree(tmp_path, ray_head):
    from test_slurm import slurm_problem  # tests/runner is on sys.path (pytest rootdir-relative imports)

    for plugin in ("hydra_joblib_launcher", "hydra_submitit_launcher"):
        if importlib.util.find_spec(f"hydra_plugins.{plugin}") is None:
            pytest.skip(f"{plugin} is not installed (pip install -e '.[test,slurm,ray]')")
    tables = {}
    for command in section_commands():
        words = shlex.split(command.replace("<head>:6379", ray_head))
        if words[0] == "sudo":
            words = words[1:]
        if words[0] == "scripts/slurm_local.sh":
            if words[1] == "start":
                problem = slurm_problem()
                if problem is not None:
                    if os.environ.get("CI") == "true":
                        pytest.fail(f"CI=true but {problem}")
                    pytest.skip(problem)
                status = subprocess.run([str(ROOT / words[0]), "status"], capture_output=True, text=True)
                assert status.returncode == 0, status.stderr
            continue
        assert words[0] == "decrun", command
        done = subprocess.run([sys.executable, "-m", "decrun", *words[1:], *TINY], cwd=tmp_path, env=env(),
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, f"{command}: {done.stderr[-3000:]}"
        sweep = next(w.split("=", 1)[1] for w in words if w.startswith("hydra.sweep.dir="))
        tables[sweep] = comparable(load_sweep(tmp_path / sweep))
    assert sorted(tables) == ["sweeps/basic", "sweeps/joblib", "sweeps/ray", "sweeps/slurm"]
    for name, table in tables.items():
        assert list(table["status"]) == ["ok", "ok"], name
        pd.testing.assert_frame_equal(table, tables["sweeps/basic"], obj=name)
