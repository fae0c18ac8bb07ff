"""``hydra/launcher=ray`` beyond one node: a sweep connected to a ``ray.cluster_utils.Cluster``
of two one-CPU worker nodes (``hydra.launcher.ray.init.address=<cluster>``) spreads its jobs
over both, and when one node is removed while it runs a job, Ray reruns that job on the
other and the table is complete — the basic launcher's.

Each job records the Ray node it starts on (``tests/ray_node_callback.py``, a Hydra
callback run in the job: ``ray.get_runtime_context().get_node_id()``)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from decrun.runner.sweep.tables import load_sweep

pytestmark = [pytest.mark.skipif(importlib.util.find_spec("hydra_plugins.hydra_ray_launcher") is None,
                                 reason="hydra-ray-launcher is not installed (pip install 'decrun[ray]')"),
              pytest.mark.ray]

TESTS = Path(__file__).resolve().parents[2]
#: 4 jobs of ~2 s: explicit smoothing on 162 vertices, no eigen-solve
SWEEP = ["-m", "app.dt=0.001,0.002,0.003,0.004", "app.steps=3000", "mesh.subdiv=2", "app.scheme=explicit",
         "app.critical_dt=false", "figures=false"]
TIMES = ("setup_seconds", "solve_seconds", "total_seconds", "step_seconds_max")
SMALL_STORE = {"object_store_memory": 78_643_200}  # 75 MiB a node: ray clusters are memory-heavy


def env() -> dict:
    """The jobs' environment (and the Ray nodes', started from this process): the node
    callback importable from tests/."""
    paths = [str(TESTS), *filter(None, [os.environ.get("PYTHONPATH")])]
    return {**{k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")},
            "PYTHONPATH": os.pathsep.join(paths)}


def comparable(table: pd.DataFrame) -> pd.DataFrame:
    return table.drop(columns=[c for c in TIMES if c in table.columns]).reset_index(drop=True)


def nodes_of(sweep_dir: Path) -> dict[str, list[str]]:
    """job → the Ray nodes it started on, in order (one per attempt)."""
    return {p.parent.name: p.read_text().split() for p in sorted(sweep_dir.glob("*/ray_node.txt"))}


@pytest.fixture
def cluster(monkeypatch):
    """A head node without CPUs (it schedules no job) and two worker nodes of one CPU."""
    from ray.cluster_utils import Cluster

    monkeypatch.setenv("PYTHONPATH", env()["PYTHONPATH"])  # the nodes' workers run the jobs
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False, **SMALL_STORE})
    try:
        workers = [cluster.add_node(num_cpus=1, **SMALL_STORE) for _ in range(2)]
        cluster.wait_for_nodes()
        yield cluster, workers
    finally:
        cluster.shutdown()


def test_a_sweep_spreads_over_the_nodes_and_a_lost_nodes_job_reruns_on_another(cluster, tmp_path):
    cluster, (first, second) = cluster
    # its own Ray temp dir (tests/conftest.py's ray_private): no ray.init() of another test finds it
    assert cluster.head_node.get_session_dir_path().startswith(os.environ["RAY_TMPDIR"] + os.sep)
    basic = subprocess.run([sys.executable, "-m", "decrun", *SWEEP, "hydra.sweep.dir=basic"], cwd=tmp_path, env=env(),
                           capture_output=True, text=True, timeout=300)
    assert basic.returncode == 0, basic.stderr[-3000:]

    command = [sys.executable, "-m", "decrun", *SWEEP, "hydra/launcher=ray",
               f"hydra.launcher.ray.init.address={cluster.address}",
               "+hydra.callbacks.node._target_=ray_node_callback.RecordRayNode", "hydra.sweep.dir=ray"]  # relative: the jobs must write where the submitter resolved it
    proc = subprocess.Popen(command, cwd=tmp_path, env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        sweep = tmp_path / "ray"
        deadline, lost = time.time() + 120, None
        while time.time() < deadline and lost is None and proc.poll() is None:  # a job running on the second node
            lost = next((job for job, nodes in nodes_of(sweep).items()
                         if nodes[0] == second.node_id and not (sweep / job / "metrics.json").exists()), None)
            time.sleep(0.02)
        if lost is None:
            proc.kill()
            pytest.fail(f"no job ran on the second node: {nodes_of(sweep)}; {proc.communicate()[1][-3000:]}")
        cluster.remove_node(second, allow_graceful=False)
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert proc.returncode == 0, stderr[-3000:]

    nodes = nodes_of(sweep)
    assert sorted(nodes) == ["0", "1", "2", "3"]
    assert {attempts[0] for attempts in nodes.values()} == {first.node_id, second.node_id}  # spread over both
    assert nodes[lost] == [second.node_id, first.node_id]  # the lost node's job ran again on the other
    assert all(len(attempts) == 1 for job, attempts in nodes.items() if job != lost)  # the others ran once
    pd.testing.assert_frame_equal(comparable(load_sweep(sweep)), comparable(load_sweep(tmp_path / "basic")))
