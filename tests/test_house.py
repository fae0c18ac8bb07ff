"""The shape of the code, kept so: apps are options + a method + its metrics (short functions,
figures by kind, steppers in ``methods/``, no config error once ``run`` started), and every
option has one home (the fluid's choices in ``methods/fluid/options.py``, mesh post steps
reading the typed source, closed options as :class:`decrun.core.choices.Choice`)."""

from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path

import pytest
import yaml

from decrun.core.choices import Choice

ROOT = Path(__file__).resolve().parents[1]
APPS = sorted((ROOT / "decrun" / "apps").glob("*.py"))
#: the longest function an app module may have (its lines, decorators and docstring included)
MAX_APP_FUNCTION_LINES = 60


def functions(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node


def test_no_app_function_exceeds_60_lines():
    long = {f"{path.name}:{node.name}": node.end_lineno - node.lineno + 1
            for path in APPS for node in functions(path)
            if node.end_lineno - node.lineno + 1 > MAX_APP_FUNCTION_LINES}
    assert long == {}, f"split these app functions (lines): {long}"


def test_apps_name_figures_by_kind_never_a_runner_module():
    from decrun.runner.plots import FIGURE_KINDS

    assert {path.name: path.read_text().count("decrun.runner.plots") for path in APPS} == \
        {path.name: 0 for path in APPS}
    used = set()
    for path in APPS:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "of_kind":
                assert node.args and isinstance(node.args[0], ast.Constant), f"{path.name}: a kind by name"
                used.add(node.args[0].value)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "Figure":
                pytest.fail(f"{path.name}:{node.lineno}: Figure(...) with a drawing path; use Figure.of_kind")
    assert used and used <= set(FIGURE_KINDS), used - set(FIGURE_KINDS)
    for kind, target in FIGURE_KINDS.items():  # every kind draws with a function that exists
        module, _, name = target.rpartition(".")
        assert callable(getattr(importlib.import_module(module), name)), kind


def test_steppers_live_in_methods_and_run_raises_no_config_error():
    """An app wraps a method: no class with ``step``/``state_dict`` (a stepper) in apps/, and
    no ``raise ConfigError`` inside an app's ``run`` (the checks come before any work)."""
    for path in APPS:
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                methods = {item.name for item in node.body if isinstance(item, ast.FunctionDef)}
                assert not {"step", "state_dict"} <= methods, f"{path.name}: {node.name} is a stepper"
            if isinstance(node, ast.FunctionDef) and node.name == "run":
                raised = [ast.unparse(item.exc) for item in ast.walk(node) if isinstance(item, ast.Raise)
                          and item.exc is not None and "ConfigError" in ast.unparse(item.exc)]
                assert not raised, f"{path.name}: run raises {raised}"
    from decrun.methods.fluid.stepper import FluidStepper
    from decrun.methods.mean_curvature_flow import SmoothingStepper

    assert all(hasattr(kind, "state_dict") for kind in (FluidStepper, SmoothingStepper))


def test_the_fluid_method_takes_its_options_from_options_py():
    path = ROOT / "decrun" / "methods" / "fluid" / "simulation.py"
    imported = {node.module for node in ast.walk(ast.parse(path.read_text())) if isinstance(node, ast.ImportFrom)}
    assert "decrun.methods.fluid.options" in imported
    from decrun.methods.fluid.options import FluidOptions

    options = FluidOptions()
    for name in ("velocity", "circulation", "walls", "kernels", "integrator"):
        assert isinstance(getattr(options, name), Choice), name


def test_mesh_post_steps_read_the_typed_source():
    text = (ROOT / "decrun" / "runner" / "mesh" / "post.py").read_text()
    assert text.count("getattr(cfg") == 0


#: ``key: value   # a | b | c`` — an option whose comment lists its closed set of values (a norm's
#: ``||x||`` is no list)
CLOSED = re.compile(r"^([a-z_]+):\s*([^#\s]+)\s*#\s*(.* \| .*)$")


def closed_options():
    for group in ("app", "mesh", "operator", "solver", "boundary"):
        for path in sorted((ROOT / "conf" / group).glob("*.yaml")):
            node = yaml.safe_load(path.read_text()) or {}
            if path.stem.startswith("_") or "_target_" not in node:
                continue
            for line in path.read_text().splitlines():
                match = CLOSED.match(line)
                if match and match.group(1) != "_target_":
                    yield f"{group}/{path.stem}", node["_target_"], match.group(1)


def test_no_closed_option_is_a_bare_string():
    """Every option a shipped config documents as ``a | b | c`` is a Choice once its plugin is
    made (the dataclass field, or its ``__post_init__`` for values that are no Python names)."""
    found = list(closed_options())
    assert len(found) >= 15  # the scan sees the options (scheme, rescale, border, refine, method …)
    strings = []
    for where, target, key in found:
        module, _, name = target.rpartition(".")
        made = getattr(importlib.import_module(module), name)()
        if not isinstance(getattr(made, key), Choice):
            strings.append(f"{where}: {key}={getattr(made, key)!r}")
    assert strings == []
    from decrun.runner.mesh.source import MeshSource

    assert isinstance(MeshSource().up_axis, Choice) and MeshSource(up_axis="-x").up_axis == "-x"
