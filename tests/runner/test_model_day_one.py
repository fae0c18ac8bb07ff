"""A newcomer's own model, through the real ``decrun`` command (issue 48, items 7, 8, 10, 11):
the docs' "Your first model" written verbatim takes every documented option of a model
(``conf/app/_model.yaml``) as a plain override, and so does decrun's own advice for a bad
``dt``; a misspelt constant, field or metric is one did-you-mean line, and a constant nothing
reads is refused also in its ``+`` form; a sweep with a ``t_end`` that is not a whole number of
one job's ``dt`` is refused before any job runs; ``app=<my model>`` without
``hydra.searchpath`` names the override that finds it. Each suggested override is then run."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import yaml

from decrun.runner.command.model_keys import documented_options

from cli_processes import decrun

ROOT = Path(__file__).resolve().parents[2]
FAST = ["figures=false", "progress=false"]


def first_model(folder: Path) -> Path:
    """The YAML block of docs/models.md's "Your first model", written verbatim where its first
    line says (``my_conf/app/mymodel.yaml``) under ``folder``; the config directory returned."""
    text = (ROOT / "docs" / "models.md").read_text(encoding="utf-8")
    section = text.split("## Your first model", 1)[1].split("\n## ", 1)[0]
    body = re.search(r"^```yaml\n(.*?)^```", section, re.S | re.M).group(1)
    where = body.splitlines()[0].removeprefix("# ").strip()
    assert where == "my_conf/app/mymodel.yaml" and "_model" not in body  # the template has no `- _model`
    path = folder / where
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(body)
    return folder / "my_conf"


def one_line(proc) -> str:
    """The command's error: exactly one line on stderr, starting ``error:``."""
    assert proc.returncode != 0, proc.stdout
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    return lines[0]


def run_config(run_dir: Path) -> dict:
    return yaml.safe_load((run_dir / ".hydra" / "config.yaml").read_text())["app"]


#: a value for every documented option of a model (conf/app/_model.yaml), as plain overrides
EVERY_OPTION = {
    "model": "app.model=damped",
    "fields": "app.fields.u.initial='2*x*y'",
    "constants": "app.constants.a=0.25",
    "equations": "app.equations=['dt(u) = k*laplacian(u) - a*u','exact_u = exp(-(6*k + a)*t) * x*y','velocity = flux_field(d(u))']",
    "integrator": "app.integrator=implicit_euler",
    "dt": "app.dt=0.002",
    "t_end": "app.t_end=null",
    "steps": "app.steps=5",
    "record_every": "app.record_every=5",
    "metrics": "app.metrics={amplitude: 'inner(u, x*y) / inner(x*y, x*y)'}",
    "seed": "app.seed=3",
    "rtol": "app.rtol=1e-7",
    "atol": "app.atol=1e-10",
    "stability_check": "app.stability_check=false",
    "snapshots": "app.snapshots=2",
    "animation": "app.animation=false",
    "plots": "app.plots.view={color: u, arrows: velocity}",
    "parts": "app.parts={}",
    "require": "app.require=['k >= 0']",
    # false: true prints the compiled model and runs nothing (tests/apps/test_model_explain.py runs it)
    "explain": "app.explain=false",
}


def test_the_first_model_takes_every_documented_option(tmp_path):
    conf = first_model(tmp_path)
    assert set(EVERY_OPTION) == documented_options()  # a new documented option gets a value here
    proc = decrun(f"hydra.searchpath=[file://{conf}]", "app=mymodel", *FAST, *EVERY_OPTION.values(),
                  "hydra.run.dir=every", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    app = run_config(tmp_path / "every")
    assert (app["model"], app["seed"], app["steps"], app["snapshots"], app["stability_check"], app["rtol"]) == \
        ("damped", 3, 5, 2, False, 1e-7)
    assert app["plots"] == {"view": {"color": "u", "arrows": "velocity"}} and app["require"] == ["k >= 0"]
    metrics = json.loads((tmp_path / "every" / "metrics.json").read_text())
    assert metrics["steps_done"] == 5 and metrics["integrator"] == "implicit_euler"
    # implicit Euler on u = 2xy (Δ eigenvalue ≈ −6): 2/(1 + (6k + a)dt)^5 within O(h²) of the mesh
    assert math.isclose(metrics["amplitude"], 2 / (1 + 6.25 * 0.002) ** 5, rel_tol=0.02)


def test_decruns_own_advice_for_a_bad_dt_runs_in_the_first_model(tmp_path):
    conf = first_model(tmp_path)
    line = one_line(decrun(f"hydra.searchpath=[file://{conf}]", "app=mymodel", *FAST, "app.dt=0.003",
                           cwd=tmp_path))
    advice = re.search(r"\(or `([^`]+)`\)", line).group(1)
    assert advice == "app.steps=67 app.t_end=null", line
    proc = decrun(f"hydra.searchpath=[file://{conf}]", "app=mymodel", *FAST, "app.dt=0.003", *advice.split(),
                  "hydra.run.dir=advised", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert json.loads((tmp_path / "advised" / "metrics.json").read_text())["steps_done"] == 67


def test_a_misspelt_constant_field_or_metric_is_one_line_and_its_fix_runs(tmp_path):
    conf = first_model(tmp_path)
    base = [f"hydra.searchpath=[file://{conf}]", "app=mymodel", *FAST, "app.steps=2", "app.t_end=null"]
    constant = "error: app.constants.kk: unknown constant of app=mymodel (no equation, metric or requirement " \
               "reads it); did you mean app.constants.k?"
    assert one_line(decrun(*base, "app.constants.kk=2", cwd=tmp_path)) == constant
    assert one_line(decrun(*base, "+app.constants.kk=2", cwd=tmp_path)) == constant  # Hydra's advice: refused too
    assert one_line(decrun(*base, "app.fields.uu.initial=z", cwd=tmp_path)) == \
        "error: app.fields.uu.initial: unknown field of app=mymodel; did you mean app.fields.u.initial? (its fields: u)"
    assert one_line(decrun(*base, "app.metrics.amplitud=u", cwd=tmp_path)) == \
        "error: app.metrics.amplitud: unknown metric of app=mymodel; did you mean app.metrics.amplitude? " \
        "(its metrics: amplitude, exact, l2_error_rel); a new metric is added with `+app.metrics.amplitud=…`"
    proc = decrun(*base, "app.constants.k=2", "app.fields.u.initial=z", "app.metrics.amplitude='inner(u, z)'",
                  "hydra.run.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    app = run_config(tmp_path / "fixed")
    assert app["constants"] == {"k": 2, "a": 0.5} and app["fields"]["u"]["initial"] == "z"
    # z is orthogonal to xy: the amplitude along z of u = z ≠ 0, the metric is the one asked for
    assert json.loads((tmp_path / "fixed" / "metrics.json").read_text())["amplitude"] > 1


def test_a_sweep_whose_t_end_is_no_whole_number_of_a_jobs_dt_is_refused_before_any_job(tmp_path):
    conf = first_model(tmp_path)
    base = ["-m", f"hydra.searchpath=[file://{conf}]", "app=mymodel", *FAST, "app.t_end=0.02"]
    line = one_line(decrun(*base, "app.dt=0.001,0.003", "hydra.sweep.dir=refused", cwd=tmp_path))
    assert line.startswith("error: job 1 ") and line.endswith("nothing ran"), line
    assert not list(tmp_path.rglob("result.h5")) and not list(tmp_path.rglob("metrics.json"))
    fix = re.search(r"use `(app\.dt=[0-9.e-]+)`", line).group(1)
    proc = decrun(*base, f"app.dt=0.001,{fix.split('=')[1]}", "hydra.sweep.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert json.loads((tmp_path / "fixed" / "1" / "metrics.json").read_text())["steps_done"] == 7


def test_my_model_without_the_searchpath_names_the_override_that_finds_it(tmp_path):
    conf = first_model(tmp_path)
    line = one_line(decrun("app=mymodel", *FAST, cwd=tmp_path))
    fix = f"hydra.searchpath=[file://{conf}]"
    assert f"my_conf/app/mymodel.yaml is there: add `{fix}`" in line, line
    proc = decrun("app=mymodel", fix, *FAST, "app.steps=1", "app.t_end=null", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    elsewhere = tmp_path / "empty"
    elsewhere.mkdir()
    line = one_line(decrun("app=mymodel", *FAST, cwd=elsewhere))
    assert "a file <dir>/app/mymodel.yaml, found with `hydra.searchpath=[file://<dir>]`" in line, line


def test_decruns_own_models_start_from_every_documented_option():
    """The command composes a config to find a model's missing options only for a model on a
    ``hydra.searchpath`` directory: decrun's own (``_target_`` a Model) must all have every one."""
    from decrun.runner.command.model_keys import MODEL_TARGET
    from decrun.runner.job.config import load_option

    apps = {p.stem: load_option("app", p.stem) for p in (ROOT / "conf" / "app").glob("*.yaml")
            if not p.stem.startswith("_")}
    models = {name: app for name, app in apps.items() if app.get("_target_") == MODEL_TARGET}
    assert len(models) >= 10
    for name, app in models.items():
        assert documented_options() <= set(app.keys()), name
