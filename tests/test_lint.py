"""The linter finds nothing: ``ruff check`` (the rules of ``[tool.ruff]`` in pyproject.toml:
unused imports, undefined names and ``__all__`` entries, redefinitions, pycodestyle errors)
over the package, the tests, the benchmarks, the scripts and the Hydra plugin; and it does
find a planted unused import. No function of the runner, the apps or the Hydra plugin is above
McCabe complexity 20 (ruff's C901), and that check finds a planted one."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PATHS = ["decrun", "tests", "benchmarks", "scripts", "hydra_plugins"]

pytest.importorskip("ruff")


def ruff(cwd: Path, *paths: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise", *paths],
                          cwd=cwd, capture_output=True, text=True, timeout=300)


def test_ruff_finds_nothing():
    proc = ruff(REPO, *PATHS)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_no_function_of_the_core_is_above_mccabe_20():
    """ruff's C901 at complexity 20 over decrun/core (the lowest layer)."""
    proc = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise",
                           "--select", "C901", "--config", "lint.mccabe.max-complexity=20", "decrun/core"],
                          cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_ruff_finds_a_planted_unused_import_and_a_missing_all_name(tmp_path):
    shutil.copy(REPO / "pyproject.toml", tmp_path / "pyproject.toml")
    (tmp_path / "mod.py").write_text('import os\n\n__all__ = ["missing"]\n')
    proc = ruff(tmp_path, "mod.py")
    assert proc.returncode == 1
    assert "F401" in proc.stdout and "F822" in proc.stdout


#: the packages held to McCabe complexity ≤ 20 (ruff's C901); decrun/core and decrun/methods join
#: once their last functions above it are split
COMPLEXITY_PATHS = ["decrun/runner", "decrun/apps", "hydra_plugins"]


def test_no_function_is_above_mccabe_20():
    proc = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise",
                           "--select", "C901", "--config", "lint.mccabe.max-complexity=20", *COMPLEXITY_PATHS],
                          cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_the_complexity_check_finds_a_planted_branchy_function(tmp_path):
    shutil.copy(REPO / "pyproject.toml", tmp_path / "pyproject.toml")
    branches = "".join(f"    if x == {i}:\n        return {i}\n" for i in range(21))
    (tmp_path / "mod.py").write_text(f"def branchy(x):\n{branches}    return -1\n")
    proc = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise",
                           "--select", "C901", "--config", "lint.mccabe.max-complexity=20", "mod.py"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1 and "C901 `branchy` is too complex (22 > 20)" in proc.stdout, proc.stdout
