"""The layers of DESIGN.md, enforced: the import-linter contracts of pyproject.toml
(core ← methods ← apps ← runner; no app imports another; only the runner imports hydra,
omegaconf, pymeshlab, h5py and matplotlib) hold, and a planted violation is caught."""

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
    assert "3 kept, 0 broken" in proc.stdout


@pytest.mark.parametrize("module, planted, contract", [
    ("core/geometry.py", "    from decrun.runner import cli  # noqa\n", "layers"),
    ("apps/hodge.py", "    from decrun.apps import smoothing  # noqa\n", "no app imports another app"),
    ("methods/singularities.py", "    import matplotlib  # noqa\n", "only the runner imports"),
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
