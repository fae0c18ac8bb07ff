"""The layers of DESIGN.md, enforced: the import-linter contracts of pyproject.toml
(core ← methods ← apps ← runner; no app imports another; only the runner imports hydra,
omegaconf, pymeshlab, h5py and matplotlib; inside the runner api > cli > run > helpers >
sweep | plots > results | mesh, and the layers of runner.mesh and runner.results) hold,
a planted violation is caught, and no module imports itself through others (no cycle,
not even through an import inside a function)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytest.importorskip("importlinter")


def lint_imports(cwd: Path, pythonpath: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(pythonpath))
    return subprocess.run([sys.executable, "-c", "from importlinter.cli import lint_imports_command; "
                           "lint_imports_command()", "--config", str(cwd / "pyproject.toml"), "--no-cache"],
                          cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def test_the_layer_contracts_are_kept():
    proc = lint_imports(REPO, REPO)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "9 kept, 0 broken" in proc.stdout


@pytest.mark.parametrize("module, planted, contract", [
    ("core/geometry.py", "    from decrun.runner.command import task  # noqa\n", "layers"),
    ("apps/hodge.py", "    from decrun.apps import smoothing  # noqa\n", "no app imports another app"),
    ("methods/singularities.py", "    import matplotlib  # noqa\n", "only the runner imports"),
    ("runner/mesh/base.py", "    from decrun.runner.results import read_result  # noqa\n", "runner: api > command | view > job"),
    ("runner/sweep/manifest.py", "    from decrun.runner.job.run import run  # noqa\n", "runner: api > command | view > job"),
    ("runner/job/config.py", "    from decrun.runner.job import run  # noqa\n", "job: run > experiment"),
    ("runner/io/paths.py", "    from decrun.runner.io import atomic  # noqa\n", "io: atomic | locks"),
    ("runner/mesh/files/obj.py", "    from decrun.runner.mesh import post  # noqa\n", "mesh: sources > source"),
    ("runner/mesh/cut.py", "    from decrun.runner.mesh import holes  # noqa\n", "mesh: sources > source"),
    ("runner/results/journal.py", "    from decrun.runner.results import recorder  # noqa\n", "results: recorder"),
])
def test_a_planted_violation_breaks_a_contract(tmp_path, module, planted, contract):
    """Even an import inside a function is seen (a lazy import still couples the layers)."""
    shutil.copytree(REPO / "decrun", tmp_path / "decrun", symlinks=True, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(REPO / "pyproject.toml", tmp_path / "pyproject.toml")
    path = tmp_path / "decrun" / module
    path.write_text(path.read_text() + "\n\ndef _planted():\n" + planted)
    proc = lint_imports(tmp_path, tmp_path)
    assert proc.returncode != 0
    assert contract in proc.stdout and "BROKEN" in proc.stdout


_CYCLES = """
import json, sys
import grimp

graph = grimp.build_graph(sys.argv[1], cache_dir=None, exclude_type_checking_imports=True)
index, low, stack, components = {}, {}, [], []
for start in sorted(graph.modules):  # Tarjan's strongly connected components, iteratively
    if start in index:
        continue
    index[start] = low[start] = len(index)
    stack.append(start)
    work = [(start, iter(sorted(graph.find_modules_directly_imported_by(start))))]
    while work:
        module, children = work[-1]
        child = next(children, None)
        if child is not None:
            if child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                work.append((child, iter(sorted(graph.find_modules_directly_imported_by(child)))))
            elif child in stack:
                low[module] = min(low[module], index[child])
            continue
        work.pop()
        if work:
            low[work[-1][0]] = min(low[work[-1][0]], low[module])
        if low[module] == index[module]:
            component = []
            while True:
                component.append(stack.pop())
                if component[-1] == module:
                    break
            if len(component) > 1:
                components.append(sorted(component))
print(json.dumps(components))
"""


def import_cycles(package: str, root: Path) -> list[list[str]]:
    """The strongly connected components (more than one module) of ``package``'s import
    graph as found in ``root``: imports inside functions included, ``if TYPE_CHECKING:``
    imports left out. In a fresh process, so that ``root``'s copy is the one analysed."""
    import json

    env = dict(os.environ, PYTHONPATH=str(root))
    proc = subprocess.run([sys.executable, "-c", _CYCLES, package], cwd=root, env=env, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_the_runner_has_no_import_cycles():
    assert [c for c in import_cycles("decrun", REPO) if any(m.startswith("decrun.runner") for m in c)] == []


def test_a_planted_cycle_is_found(tmp_path):
    """journal → recorder → journal, hidden in a function, is a cycle."""
    shutil.copytree(REPO / "decrun", tmp_path / "decrun", symlinks=True, ignore=shutil.ignore_patterns("__pycache__"))
    path = tmp_path / "decrun" / "runner" / "results" / "journal.py"
    path.write_text(path.read_text() + "\n\ndef _planted():\n    from decrun.runner.results import recorder  # noqa\n")
    cycles = import_cycles("decrun", tmp_path)
    assert ["decrun.runner.results.journal", "decrun.runner.results.recorder"] in cycles
