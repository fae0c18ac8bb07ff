"""The run pipeline's spine (issue 27.5): one place for the run directory's file names, one
App.validate that checks each thing once and in order, one Run record through prepare →
execute → write."""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

from decrun.apps.base import App
from decrun.errors import ConfigError, TopologyError
from decrun.runner.io.files import RunFiles, SweepFiles

PACKAGE = Path(__file__).resolve().parents[2] / "decrun"


def _names() -> set[str]:
    return {value for cls in (RunFiles, SweepFiles) for key, value in vars(cls).items()
            if key.isupper() and isinstance(value, str)}


def _docstrings(tree: ast.AST) -> set[int]:
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                found.add(id(first.value))
    return found


def test_no_module_spells_a_run_directory_file_name_but_files_py():
    """A string that is exactly one of the names (``"result.h5"``, ``"metrics.json"``,
    ``"*.png"`` ...) appears in no module of decrun but decrun/runner/io/files.py: code takes the
    name from RunFiles / SweepFiles (messages that merely mention a file are not code paths)."""
    names = _names()
    assert {"result.h5", "metrics.json", "manifest.json", ".decrun.lock", "*.png"} <= names
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path == PACKAGE / "runner" / "io" / "files.py":
            continue
        tree = ast.parse(path.read_text())
        skip = _docstrings(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names \
                    and id(node) not in skip:
                found.append(f"{path.relative_to(PACKAGE)}:{node.lineno}: {node.value!r}")
    assert not found, found


def test_run_files_paths_are_the_names_in_the_directory(tmp_path):
    files = RunFiles(tmp_path)
    assert files.result == tmp_path / "result.h5" and files.metrics == tmp_path / "metrics.json"
    assert files.journal.name == RunFiles.RESULT + ".partial" and files.figure("uv") == tmp_path / "uv.png"
    assert set(RunFiles.JOB_OUTPUTS) == {RunFiles.METRICS, RunFiles.RESULT, RunFiles.JOURNAL, RunFiles.STALE}
    assert SweepFiles(tmp_path).manifest == tmp_path / "manifest.json"


@dataclass
class _Recording(App):
    """An app whose checks say when they run."""

    name = "recording"

    def __post_init__(self):
        self.calls = []

    def check_dimension(self, K):
        self.calls.append("dimension")
        super().check_dimension(K)

    def check_operators(self, dec):
        self.calls.append("operators")

    def check_solver(self, solver, dec=None):
        self.calls.append(("solver", dec is not None))

    def check(self, K, dec):
        self.calls.append("check")


class _K:
    def __init__(self, dim):
        self.dim = dim


def test_app_validate_checks_each_once_in_order_and_builds_the_operators_after_the_dimension():
    app = _Recording()
    built = []
    assert app.validate(_K(2), "solver", lambda: built.append(1) or "dec") == "dec"
    assert app.calls == ["dimension", "operators", ("solver", True), "check"] and built == [1]
    app = _Recording()
    with pytest.raises(TopologyError, match="app=recording runs on a triangle mesh"):
        app.validate(_K(3), "solver", lambda: built.append(2))
    assert app.calls == ["dimension"] and built == [1]  # no operators built for a mesh the app refuses


def test_one_run_record_through_prepare_execute_write(tmp_path):
    """prepare → execute → write: the Run carries mesh, complex, dec, recorder, result and
    timings; write puts exactly the RunFiles names into the directory."""
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import execute, prepare, write

    run = prepare(compose_config(["mesh.subdiv=1", "app.steps=2", "figures=false"]), out=tmp_path)
    assert run.complex.num_simplices(2) == len(run.mesh.simplices) and run.dec.K is run.complex
    assert run.result is None and set(run.timings) == {"mesh_seconds", "complex_seconds"}
    execute(run)
    assert run.recorder is not None and run.result.metrics["status"] == "ok"
    written = write(run)
    assert [p.name for p in written] == [RunFiles.RESULT, RunFiles.METRICS]
    assert {"mesh_seconds", "complex_seconds", "app_seconds", "figures_seconds", "total_seconds"} == set(run.timings)
    assert not hasattr(run.mesh, "complex") and not hasattr(run.mesh, "recorder")


def test_an_error_of_the_app_names_its_key_once():
    """An app error raised by the core (no config key in its message) gets ``app=<name>`` in
    front once, through Run.naming_errors (the check of the solver against an unsymmetric
    app is the config's own, before any mesh: it names the solver)."""
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    with pytest.raises(ConfigError) as info:
        run_experiment(compose_config(["app=parametrization", "mesh=sphere_cap", "solver=cg"]))
    assert str(info.value).startswith("solver=cg: app=parametrization") and str(info.value).count("app=") == 1
