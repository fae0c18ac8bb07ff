"""The operator registry (issue 47): one entry per operator — typing rule, discrete definition,
evaluation, derivative — read by every pass; value-by-value functions accepted alike by every
integrator with the same answer; and operators added by an installed package's entry points
(group ``decrun.operators``) without editing decrun, run through the real ``decrun`` command."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tomllib

from decrun.core.dec import DEC
from decrun.core.solvers import solver_factory
from decrun.methods.model import FieldSpec, ModelSpec, compile_model
from decrun.methods.model.integrators import make_integrator
from decrun.methods.model.operators import OPERATORS, POINTWISE, Operator, PluginError, pointwise, register
from decrun.methods.model.stepper import ModelStepper
from decrun.methods.stepping import run_steps
from decrun.runner.job.plugins import option

from cli_processes import env


def _grid_dec(n: int = 6) -> DEC:
    from decrun.core.complex import SimplicialComplex

    mesh = option("mesh", "grid", nx=n, ny=n).load()
    return DEC(SimplicialComplex(mesh.vertices, mesh.simplices, orient="fix"))


@pytest.mark.parametrize("name", sorted(POINTWISE))
def test_every_elementwise_function_has_a_derivative_rule_equal_to_finite_differences(name):
    """f'(x) of the registry's rule against the central difference (f(x+ε) − f(x−ε)) / 2ε at
    points inside every function's domain (away from sign's and abs's kink at 0)."""
    operator = OPERATORS[name]
    assert operator.pointwise and operator.derivative is not None
    x = np.linspace(0.11, 0.83, 9)
    eps = 1e-6
    f = operator.evaluate
    numeric = (f(None, [], x + eps) - f(None, [], x - eps)) / (2 * eps)
    exact = operator.derivative(None, [], [x], 0)
    assert np.allclose(exact, numeric, rtol=1e-7, atol=1e-8)


def _run(function: str, scheme: str) -> np.ndarray:
    """u at t = 0.2 of dt(u) = 0.01 Δu − 0.1 f(u) on a small grid, integrator ``scheme``."""
    spec = ModelSpec(fields={"u": FieldSpec(0, "0.3 + 0.2*x*y")}, equations=[f"dt(u) = 0.01*laplacian(u) - "
                                                                             f"0.1*{function}(u)"], dt=0.01)
    model = compile_model(spec, _grid_dec(), solver_factory("auto"))
    integrator = make_integrator(model, scheme, 0.01, solver_factory("auto"), rtol=1e-10, atol=1e-12)
    stepper = ModelStepper(model, integrator, 0.01)
    run_steps(stepper, 20)
    return np.asarray(stepper.environment()["u"])


@pytest.mark.parametrize("function", sorted(POINTWISE))
def test_every_elementwise_function_runs_under_every_integrator_with_the_same_answer(function):
    """``dt(u) = 0.01*laplacian(u) - 0.1*f(u)`` for every value-by-value f: rk4 (the reference,
    O(dt⁴)) and the adaptive bdf / radau / rk45 at tight tolerances agree to 1e-7; the
    first-order imex, semi_implicit, explicit and implicit Euler agree to O(dt) (2e-2 of the
    change), Crank–Nicolson to O(dt²) (1e-4). bdf/radau read the Jacobian pattern from the
    registry's ``pointwise`` flag, implicit Euler and Crank–Nicolson take Newton with the
    derivative rules — ``cosh`` was refused by all four."""
    reference = _run(function, "rk4")
    start = 0.3 + 0.2 * _grid_dec().K.vertices[:, 0] * _grid_dec().K.vertices[:, 1]
    change = np.abs(reference - start).max()
    assert change > 1e-4 or function == "sign"
    for scheme in ("bdf", "radau", "rk45"):
        assert np.abs(_run(function, scheme) - reference).max() <= 1e-7 + 1e-6 * change, scheme
    assert np.abs(_run(function, "crank_nicolson") - reference).max() <= 1e-4 * change + 1e-12  # Newton, O(dt²)
    for scheme in ("imex", "semi_implicit", "explicit_euler", "implicit_euler"):
        assert np.abs(_run(function, scheme) - reference).max() <= 2e-2 * change + 1e-12, scheme


def test_a_plugin_may_not_replace_a_built_in_operator():
    with pytest.raises(PluginError, match="'laplacian' is decrun's own"):
        register(pointwise("laplacian", np.exp, np.exp, "x"), "test")
    with pytest.raises(PluginError, match="neither evaluate nor linear"):
        register(Operator("nothing", (1,), "", "", lambda args, n: args[0], None), "test")


DOCS = Path(__file__).resolve().parents[2] / "docs" / "models.md"


def _docs_blocks() -> dict[str, str]:
    """language → body of the fenced blocks of docs/models.md's "Your own operators"."""
    text = DOCS.read_text(encoding="utf-8")
    start = text.index("## Your own operators\n")
    end = text.index("\n## ", start + 3)
    return {m.group(1): m.group(2) for m in re.finditer(r"^```(\w*)\n(.*?)^```", text[start:end], re.S | re.M)}


@pytest.fixture
def plugin_path(tmp_path):
    """The package of docs/models.md's "Your own operators", installed as a temporary
    distribution: its module (the page's Python block) and a ``*.dist-info`` whose
    ``entry_points.txt`` holds the page's ``pyproject.toml`` entry points."""
    blocks = _docs_blocks()
    project = tomllib.loads(blocks["toml"])["project"]
    site = tmp_path / "site"
    info = site / f"{project['name'].replace('-', '_')}-{project['version']}.dist-info"
    info.mkdir(parents=True)
    (site / blocks["python"].splitlines()[0][2:].strip()).write_text(blocks["python"])
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {project['name']}\nVersion: {project['version']}\n")
    lines = [f"[{group}]" + "".join(f"\n{name} = {value}" for name, value in entries.items())
             for group, entries in project["entry-points"].items()]
    (info / "entry_points.txt").write_text("\n\n".join(lines) + "\n")
    return site


def _decrun(site, cwd, *args):
    child = env()
    child["PYTHONPATH"] = os.pathsep.join([str(site), child.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-m", "decrun", *args], cwd=cwd, env=child, capture_output=True, text=True,
                          timeout=300)


def test_an_installed_package_adds_an_operator_that_a_model_uses_through_the_cli(plugin_path, tmp_path):
    """The page's command runs with the page's package installed; ``softplus`` in ``dt(u) =
    k*laplacian(u) - softplus(u)`` through the real ``decrun`` (rk4, and bdf: the derivative rule
    gives bdf its pattern) equals the same model with ``log(1 + exp(u))`` written out (rk4: to
    round-off; bdf at rtol 1e-10: to 1e-6); without the package the operator is unknown."""
    (command,) = [line for line in _docs_blocks()["bash"].splitlines() if line.startswith("decrun ")]
    page = _decrun(plugin_path, tmp_path, *shlex.split(command)[1:], "figures=false", "progress=false",
                   "hydra.run.dir=page")
    assert page.returncode == 0, page.stderr
    common = ["app=heat", "mesh.subdiv=1", "app.t_end=null", "app.steps=5", "figures=false", "progress=false"]
    results = {}
    for label, term, scheme in (("plugin", "softplus(u)", "rk4"), ("written", "log(1 + exp(u))", "rk4"),
                                ("plugin_bdf", "softplus(u)", "bdf")):
        done = _decrun(plugin_path, tmp_path, *common, f"app.integrator={scheme}", "app.rtol=1e-10",
                       f"app.equations=['dt(u) = k*laplacian(u) - {term}']",
                       "+app.metrics.u_sum='integral(u)'", f"hydra.run.dir={label}")
        assert done.returncode == 0, done.stderr
        results[label] = json.loads((tmp_path / label / "metrics.json").read_text())["u_sum"]
    assert results["plugin"] == pytest.approx(results["written"], rel=1e-13)
    assert results["plugin_bdf"] == pytest.approx(results["written"], rel=1e-6)
    without = subprocess.run([sys.executable, "-m", "decrun", *common, "app.equations=['dt(u) = softplus(u)']"],
                             cwd=tmp_path, env=env(), capture_output=True, text=True, timeout=300)
    assert without.returncode != 0 and "unknown operator 'softplus'" in without.stderr


def test_a_broken_plugin_is_one_line_naming_its_entry_point(plugin_path, tmp_path):
    (next(plugin_path.glob("*.dist-info")) / "entry_points.txt").write_text(
        "[decrun.operators]\nsoftplus = my_operators:MISSING\n")
    done = _decrun(plugin_path, tmp_path, "app=heat", "mesh.subdiv=1", "app.steps=1", "app.t_end=null",
                   "figures=false", "progress=false")
    lines = [line for line in done.stderr.strip().splitlines() if line.strip()]
    assert done.returncode != 0 and len(lines) == 1, done.stderr
    assert "softplus = my_operators:MISSING" in lines[0] and "decrun.operators" in lines[0]
