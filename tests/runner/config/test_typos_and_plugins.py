"""One decrun line, through the real CLI, for a misspelt option of any plugin group (with or
without ``+``: the group's options and the closest one, whose override then runs) and for a
launcher whose plugin is not installed (the pip line; the plugin hidden from the process);
the sweep progress bar starts."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

SMALL = ["app.steps=1", "figures=false", "hydra.run.dir=run"]


@pytest.mark.parametrize("typo, fix, options", [
    (["app.stpes=3"], "app.steps", "'dt', 'dt_factor', 'dt_unit', 'record_vertices', 'rescale', 'scheme', 'steps'"),
    (["+app.stpes=3"], "app.steps", "'dt', 'dt_factor', 'dt_unit', 'record_vertices', 'rescale', 'scheme', 'steps'"),
    (["mesh=torus", "mesh.major_radus=2"], "mesh.major_radius", "'major_radius', 'major_segments'"),
    (["solver=cg", "solver.tool=1e-8"], "solver.tol", "'tol'"),
    (["-m", "app.stpes=3,4"], "app.steps", "'steps'"),
])
def test_a_misspelt_option_names_the_groups_options_and_the_closest(decrun_cli, typo, fix, options):
    proc = decrun_cli(*typo, *SMALL, "hydra.sweep.dir=sweep")
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()], proc.stderr  # one line
    key = typo[-1].split("=")[0].lstrip("+")
    assert proc.stderr.startswith(f"error: {key}: unknown option of") and options in proc.stderr, proc.stderr
    assert proc.stderr.strip().endswith(f"did you mean {fix}?")
    fixed = [a.replace(key, fix).split(",")[0] for a in typo if a != "-m"]
    rerun = decrun_cli(*[a.lstrip("+") for a in fixed], *SMALL)
    assert rerun.returncode == 0, rerun.stderr


def test_solver_options_without_a_close_one_are_listed(decrun_cli):
    proc = decrun_cli("solver=direct", "solver.tol=1e-3", *SMALL)
    assert proc.returncode == 1
    assert proc.stderr.strip() == "error: solver.tol: unknown option of solver=direct; it has ['permc_spec']"


#: runs decrun with the ray launcher's plugin package hidden, as if decrun[ray] were not installed
WITHOUT_RAY = """
import sys
class Hide:
    def find_spec(self, name, path=None, target=None):
        if name.startswith("hydra_plugins.hydra_ray_launcher"):
            raise ModuleNotFoundError(name)
sys.meta_path.insert(0, Hide())
from decrun.__main__ import console_main
sys.argv = ["decrun", *sys.argv[1:]]
console_main()
"""


def test_a_launcher_that_is_not_installed_gives_the_pip_line(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    proc = subprocess.run([sys.executable, "-W", "ignore", "-c", WITHOUT_RAY, "-m", "hydra/launcher=ray", *SMALL,
                           "hydra.sweep.dir=sweep"], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 1
    assert proc.stderr.strip() == 'error: hydra/launcher=ray: hydra-ray-launcher is not installed; pip install "decrun[ray]"'
    assert not (tmp_path / "sweep").exists()


def test_the_sweep_progress_bar_starts_and_counts_jobs_in_any_subdir(tmp_path, monkeypatch):
    from omegaconf import OmegaConf

    from decrun.runner.command import callbacks
    from decrun.runner.command.callbacks import SweepTable

    monkeypatch.setattr(callbacks, "terminal", lambda enabled=True: enabled)
    config = OmegaConf.create({"progress": True, "hydra": {"sweep": {"dir": str(tmp_path / "s")},
                                                         "sweeper": {"_target_": "hydra_plugins.decrun_sweeper.DecrunSweeper"},
                                                         "overrides": {"task": ["app.dt=0.1,0.2,0.3"]}}})
    SweepTable().on_multirun_start(config)
    bar = SweepTable._progress
    assert bar is not None and bar.total == 3
    (tmp_path / "s" / "app.dt=0.1").mkdir(parents=True)
    (tmp_path / "s" / "app.dt=0.1" / "metrics.json").write_text("{}")
    assert bar.done() == 1
    bar.stop()
    SweepTable._progress = None
