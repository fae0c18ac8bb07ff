"""benchmarks/mutation_check.py stays runnable: every planted bug still matches the code
exactly once (a refactoring that moves the text makes this fail, instead of the check
silently planting nothing), its test selections exist, and the README's commands run."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "mutation_check.py"


def load():
    spec = importlib.util.spec_from_file_location("mutation_check", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(spec.name, module)  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_every_mutation_matches_the_code_once_and_names_existing_tests():
    module = load()
    assert len(module.MUTATIONS) >= 16
    for mutation in module.MUTATIONS:
        text = (ROOT / mutation.path).read_text()
        for old, new in mutation.replacements:
            assert text.count(old) == 1, (mutation.name, old)
            assert old != new
        for selection in mutation.selections:
            assert (ROOT / selection[0]).is_file(), (mutation.name, selection)


def test_list_runs():
    proc = subprocess.run([sys.executable, str(SCRIPT), "--list"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "sign of the border flux" in proc.stdout


@pytest.mark.slow
def test_the_flux_mutation_is_killed():
    """The README's example: `mutation_check.py -k flux` plants the border-flux sign bug and
    reports it killed (exit 0: no survivor)."""
    proc = subprocess.run([sys.executable, str(SCRIPT), "-k", "flux"], capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 of 1 mutations killed; no survivor" in proc.stdout
