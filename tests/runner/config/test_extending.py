"""Extending decrun without touching its code: a Hodge-star variant and an application from a
module outside the package plus one YAML file each, found through ``hydra.searchpath`` and
run by the real ``decrun`` command (the README's "Extending decrun" recipe)."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[3]

PLUGIN = '''
from dataclasses import dataclass

import numpy as np

from decrun.apps.base import App, Figure, Result
from decrun.core.stars import HodgeStar


@dataclass
class UniformStar(HodgeStar):
    """⋆_k = weight on every simplex (a toy variant)."""

    name = "uniform"
    weight: float = 2.0

    def diagonal(self, dec, k):
        return np.full(dec.K.num_simplices(k), self.weight)


@dataclass
class EulerApp(App):
    """Reports χ and Σ⋆0; records one series."""

    name = "euler"
    scale: float = 1.0

    def run(self, ctx):
        K = ctx.complex
        for step in range(3):
            ctx.record(step, chi=float(K.euler_characteristic) * step)
        stiffness = ctx.dec.laplacian_symmetric(0)
        return Result(metrics={"euler_characteristic_scaled": K.euler_characteristic * self.scale,
                               "star0_sum": float(ctx.dec.star_diagonal(0).sum()),
                               "stiffness_row_sum_max": float(abs(stiffness.sum(axis=1)).max())},
                      figures={"mesh": Figure("decrun.runner.plots.common.surface_figure",
                                              dict(vertices=K.vertices, faces=K.oriented_simplices()))})
'''


def test_a_toy_star_and_a_toy_app_run_through_the_cli(tmp_path, decrun_cli):
    (tmp_path / "toy_plugins.py").write_text(PLUGIN)
    conf = tmp_path / "toy_conf"
    (conf / "operator").mkdir(parents=True)
    (conf / "app").mkdir()
    (conf / "operator" / "uniform.yaml").write_text("_target_: toy_plugins.UniformStar\nweight: 2.0\n")
    (conf / "app" / "euler.yaml").write_text("_target_: toy_plugins.EulerApp\nscale: 1.0\n")
    proc = decrun_cli(f"hydra.searchpath=[file://{conf}]", "operator=uniform", "app=euler", "operator.weight=3.0",
                      "app.scale=2.0", "mesh.subdiv=1", env={"PYTHONPATH": str(tmp_path)})
    assert proc.returncode == 0, proc.stderr
    run = next((tmp_path / "outputs" / "runs").iterdir())
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["euler_characteristic_scaled"] == 4.0  # χ(sphere) = 2, scale 2
    assert metrics["star0_sum"] == 3.0 * 42  # ⋆0 = weight on each of the 42 vertices
    assert metrics["stiffness_row_sum_max"] < 1e-12  # d0ᵀ ⋆1 d0 annihilates constants
    assert (run / "mesh.png").is_file()
    from decrun.runner.results import read_result

    series = read_result(run / "result.h5").series
    assert list(series["chi"]) == [0.0, 2.0, 4.0] and list(series["step"]) == [0, 1, 2]
    # a misspelt option of the toy plugin is rejected with the toy's own option list
    bad = decrun_cli(f"hydra.searchpath=[file://{conf}]", "app=euler", "+app.scael=2", env={"PYTHONPATH": str(tmp_path)})
    assert bad.returncode == 1 and "app.scael: unknown option of app=euler; it has ['scale']" in bad.stderr



def test_a_misspelt_plugin_option_without_plus_is_one_line_and_its_fix_runs(tmp_path, decrun_cli):
    """``operator.wieght=3`` on a star from ``hydra.searchpath`` (no ``+``): decrun's one line
    with the star's options and the closest one, not Hydra's advice to append ``+operator.wieght``;
    the suggested key runs (⋆0 = 3 on each of the 42 vertices)."""
    (tmp_path / "toy_plugins.py").write_text(PLUGIN)
    conf = tmp_path / "toy_conf"
    (conf / "operator").mkdir(parents=True)
    (conf / "operator" / "uniform.yaml").write_text("_target_: toy_plugins.UniformStar\nweight: 2.0\n")
    (conf / "app").mkdir()
    (conf / "app" / "euler.yaml").write_text("_target_: toy_plugins.EulerApp\nscale: 1.0\n")
    common = (f"hydra.searchpath=[file://{conf}]", "operator=uniform", "app=euler", "mesh.subdiv=1", "figures=false")
    path = {"PYTHONPATH": os.pathsep.join(filter(None, [str(tmp_path), os.environ.get("PYTHONPATH")]))}
    bad = decrun_cli(*common, "operator.wieght=3", env=path)
    assert bad.returncode == 1
    assert bad.stderr.strip().splitlines() == [
        "error: operator.wieght: unknown option of operator=uniform; it has ['weight']; did you mean operator.weight?"]
    assert not (tmp_path / "outputs" / "runs").is_dir() or not any((tmp_path / "outputs" / "runs").iterdir())
    fixed = decrun_cli(*common, "operator.weight=3", env=path)
    assert fixed.returncode == 0, fixed.stderr
    run = next((tmp_path / "outputs" / "runs").iterdir())
    assert json.loads((run / "metrics.json").read_text())["star0_sum"] == 3.0 * 42

def test_plugin_yaml_without_target_or_with_a_wrong_class_is_a_clear_error(tmp_path, decrun_cli):
    conf = tmp_path / "bad_conf" / "operator"
    conf.mkdir(parents=True)
    (conf / "nothing.yaml").write_text("weight: 1.0\n")
    (conf / "wrong.yaml").write_text("_target_: decrun.core.solvers.cg.CGSolver\n")
    for option, words in (("nothing", "operator: the config node names no `_target_`"),
                          ("wrong", "operator._target_='decrun.core.solvers.cg.CGSolver' is not a HodgeStar")):
        proc = decrun_cli(f"hydra.searchpath=[file://{tmp_path / 'bad_conf'}]", f"operator={option}")
        assert proc.returncode == 1 and words in proc.stderr, proc.stderr
        assert "Traceback" not in proc.stderr


STEPPING_PLUGIN = '''
from dataclasses import dataclass

import numpy as np

from decrun.apps.base import App, Figure, Result
from decrun.errors import ConfigError
from decrun.methods.mean_curvature_flow import gershgorin_safe_dt
from decrun.methods.stepping import run_steps


class HeatStepper:
    """Explicit Euler on u' = -L u, L = ⋆0⁻¹ d0ᵀ ⋆1 d0 (the method: a Stepper)."""

    record_divergent_step = True
    state_variable = ()

    def __init__(self, dec, u, dt):
        self.S, self.M, self.dt, self.u = dec.laplacian_symmetric(0), dec.star_diagonal(0), dt, u.copy()

    def energy(self):
        return float(self.u @ (self.S @ self.u))

    def values(self):
        return {"energy": self.energy(), "mass": float(self.M @ self.u)}

    def step(self, n):
        self.u = self.u - self.dt * (self.S @ self.u) / self.M
        return "" if np.all(np.isfinite(self.u)) else "non-finite u"

    def state_dict(self):
        return {"u": self.u}

    def load_state(self, state):
        self.u = np.array(state["u"], dtype=np.float64)


def heat_metrics(first, last, report):
    """The method's metrics from the first and last recorded values."""
    return {"steps_done": report.steps_done, "stable": report.diverged_at_step is None,
            "energy_ratio": last["energy"] / first["energy"], "mass_drift": abs(last["mass"] - first["mass"])}


@dataclass
class ToyHeat(App):
    """Diffuses the height z: options, a method (HeatStepper on run_steps), its metrics, a figure by kind."""

    name = "toy_heat"
    dt: float = 1e-3
    steps: int = 8

    def check(self, K, dec):
        safe = gershgorin_safe_dt(dec.laplacian_symmetric(0), dec.star_diagonal(0))
        if self.dt > safe:
            raise ConfigError(f"app.dt={self.dt:g} exceeds the explicit step bound {safe:.3g} of this mesh; "
                              f"use `app.dt={float(f'{0.9 * safe:.2g}'):g}`")

    def run(self, ctx):
        stepper = HeatStepper(ctx.dec, np.asarray(ctx.complex.vertices)[:, 2], self.dt)
        first = stepper.values()
        report = run_steps(stepper, self.steps, progress=ctx.progress, record=ctx.record,
                           checkpoint=ctx.checkpoint, desc="toy heat")
        return Result(fields={"u": stepper.u}, metrics=heat_metrics(first, stepper.values(), report),
                      figures={"u": Figure.of_kind("surface", values=stepper.u, title="u")})
'''


def test_a_toy_time_stepping_app_runs_on_the_stepping_driver_through_the_cli(tmp_path, decrun_cli):
    """A plugin app of the apps' shape — options, a stepper on decrun.methods.stepping.run_steps,
    a metrics function, a figure by kind — run by the real command: explicit Euler on the heat
    equation keeps Σ ⋆0 u (1ᵀ S = 0) and lowers the Dirichlet energy uᵀ S u at every step; a dt
    beyond the explicit bound is refused before any step with the override that works."""
    from decrun.runner.results import read_result

    (tmp_path / "toy_stepping.py").write_text(STEPPING_PLUGIN)
    conf = tmp_path / "toy_conf" / "app"
    conf.mkdir(parents=True)
    (conf / "toy_heat.yaml").write_text("_target_: toy_stepping.ToyHeat\ndt: 1.0e-3\nsteps: 8\n")
    common = (f"hydra.searchpath=[file://{conf.parent}]", "app=toy_heat", "mesh.subdiv=1")
    env = {"PYTHONPATH": str(tmp_path)}
    bad = decrun_cli(*common, "app.dt=1.0", "hydra.run.dir=bad", env=env)
    assert bad.returncode == 1 and "Traceback" not in bad.stderr, bad.stderr
    fix = bad.stderr.split("use `")[1].split("`")[0]
    assert fix.startswith("app.dt=") and not (tmp_path / "bad" / "result.h5").exists()
    proc = decrun_cli(*common, fix, "hydra.run.dir=good", env=env)
    assert proc.returncode == 0, proc.stderr
    metrics = json.loads((tmp_path / "good" / "metrics.json").read_text())
    assert metrics["steps_done"] == 8 and metrics["stable"] is True
    assert metrics["mass_drift"] < 1e-12 and 0 < metrics["energy_ratio"] < 1
    series = read_result(tmp_path / "good" / "result.h5").series
    assert list(series["step"]) == list(range(9))
    assert np.all(np.diff(series["energy"]) < 0)
    assert (tmp_path / "good" / "u.png").is_file()


TRACKER = '''
import json
from dataclasses import dataclass

from decrun.runner.tracking import Tracker


@dataclass
class JsonLinesTracker(Tracker):
    """A toy second tracker: every run it is given as one JSON line of a file."""

    name = "jsonl"
    path: str = "runs.jsonl"

    def store(self):
        return f"jsonl:{self.path}"

    def log_run(self, record, run_id):
        with open(self.path) as f:
            run_id = run_id or f"r{sum(1 for _ in f)}"
        with open(self.path, "a") as f:
            f.write(json.dumps({"id": run_id, "name": record.name, "parent": record.parent, "status": record.status,
                                "params": record.params, "metrics": record.metrics, "tags": record.tags,
                                "series": {k: [s.tolist(), v.tolist()] for k, (s, v) in record.series.items()},
                                "artifacts": sorted(p.name for p in record.artifacts)}) + "\\n")
        return run_id
'''


def test_a_toy_tracker_is_one_module_and_one_yaml(tmp_path, decrun_cli):
    """A second tracker (``tracker=jsonl``) from a module outside decrun and one YAML file: a
    sweep's jobs reach it nested under the sweep's run, with metrics.json's numbers and the
    series; a resumed sweep whose jobs did not change sends it nothing."""
    (tmp_path / "toy_tracker.py").write_text(TRACKER)
    (tmp_path / "runs.jsonl").write_text("")
    conf = tmp_path / "toy_conf" / "tracker"
    conf.mkdir(parents=True)
    (conf / "jsonl.yaml").write_text("_target_: toy_tracker.JsonLinesTracker\npath: runs.jsonl\n")
    sweep = ["-m", f"hydra.searchpath=[file://{conf.parent}]", "tracker=jsonl", "app=heat", "mesh.subdiv=1",
             "app.t_end=0.002", "app.dt=1e-3,2e-3", "figures=false", "hydra.sweep.dir=sweep"]
    path = {"PYTHONPATH": os.pathsep.join(p for p in (str(tmp_path), os.environ.get("PYTHONPATH")) if p)}
    proc = decrun_cli(*sweep, env=path)
    assert proc.returncode == 0, proc.stderr
    assert "decrun: tracker=jsonl: 2 jobs under run r0 (3 sent) in jsonl:runs.jsonl" in proc.stdout
    lines = [json.loads(line) for line in (tmp_path / "runs.jsonl").read_text().splitlines()]
    sweep_run, *jobs = lines
    assert sweep_run["name"] == "sweep" and sweep_run["parent"] is None and sweep_run["params"] == {
        "tracker": "jsonl", "app": "heat", "mesh.subdiv": "1", "app.t_end": "0.002", "app.dt": "1e-3,2e-3",
        "figures": "false"}  # the sweep's overrides as typed (Hydra's own left out)
    assert [job["name"] for job in jobs] == ["job 0", "job 1"] and {job["parent"] for job in jobs} == {"r0"}
    for job in jobs:
        metrics = json.loads((tmp_path / "sweep" / job["name"][4:] / "metrics.json").read_text())
        numbers = {k: float(v) for k, v in metrics.items() if isinstance(v, (int, float))}
        assert job["metrics"] == numbers and job["status"] == "ok" and job["tags"]["status"] == "ok"
        steps, mass = job["series"]["series/mass"]
        with h5py.File(tmp_path / "sweep" / job["name"][4:] / "result.h5", "r") as f:
            assert steps == f["series/step"][()].tolist() and mass == f["series/mass"][()].tolist()
        assert steps[-1] == metrics["steps_done"]
        assert job["params"]["app.dt"] == str(metrics["dt"]) and job["params"]["tracker"] == "jsonl"
        assert job["tags"]["decrun.config_hash"] == metrics["config_hash"]
    resumed = decrun_cli(*sweep, "hydra.sweeper.resume=true", env=path)
    assert resumed.returncode == 0, resumed.stderr
    assert "(0 sent)" in resumed.stdout and len((tmp_path / "runs.jsonl").read_text().splitlines()) == 3


def page_recipe(text: str) -> tuple[dict[str, str], list[str]]:
    """The files (path → text: every python or yaml block whose first line is ``# <path>``) and
    the command lines (every bash block's non-comment lines) of docs/extending.md's plugin recipe."""
    files, lines = {}, []
    for language, body in re.findall(r"^```(\w+)\n(.*?)^```", text, flags=re.S | re.M):
        if language in ("python", "yaml"):
            first = body.splitlines()[0]
            assert first.startswith("# "), f"docs/extending.md: a {language} block starts with '# <path>': {first!r}"
            files[first[2:].strip()] = body
        elif language == "bash":
            lines += [line for line in body.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    return files, lines


def test_the_extending_pages_plugin_runs_as_written(tmp_path):
    """docs/extending.md: its module and YAML file written where their first lines say, and its
    command line run by bash as written (``PYTHONPATH=.``, ``$PWD``, the quotes) in that
    directory, with ``decrun`` this checkout's command: the run is ok and used the page's star."""
    files, lines = page_recipe((ROOT / "docs" / "extending.md").read_text(encoding="utf-8"))
    assert sorted(files) == ["my_conf/operator/uniform.yaml", "my_plugins.py"] and len(lines) == 1, (files, lines)
    for name, body in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(body)
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    wrapper = bin_dir / "decrun"  # `decrun` = python -m decrun of this checkout, after the line's own PYTHONPATH
    wrapper.write_text(f'#!/bin/sh\nPYTHONPATH="${{PYTHONPATH:+$PYTHONPATH:}}{ROOT}" exec {shlex.quote(sys.executable)} '
                       '-m decrun "$@"\n')
    wrapper.chmod(0o755)
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTHONPATH")}
    env.update(PATH=f"{bin_dir}{os.pathsep}{env.get('PATH', '')}", MPLBACKEND="Agg")
    done = subprocess.run(["bash", "-c", lines[0]], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    (run,) = (tmp_path / "outputs" / "runs").iterdir()
    assert json.loads((run / "metrics.json").read_text())["status"] == "ok"
    with h5py.File(run / "result.h5", "r") as f:
        config = f.attrs["config_yaml"]
    assert "_target_: my_plugins.Uniform" in config and "weight: 1.0" in config, config
