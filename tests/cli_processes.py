"""The real ``decrun`` command as a child process, for the sweep and output-directory tests
(``tests/`` is on ``sys.path``: ``from cli_processes import decrun, start, comparable``).

The child gets this process's environment without ``HYDRA_FULL_ERROR`` (so it prints its
one-line errors, not tracebacks) and ``PYTEST_CURRENT_TEST``."""

from __future__ import annotations

import os
import subprocess
import sys

import pandas as pd

#: metric columns that differ between two runs of the same jobs (wall times)
TIMES = ("setup_seconds", "solve_seconds", "total_seconds", "step_seconds_max")


def env() -> dict:
    """The child's environment (module docstring)."""
    return {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}


def decrun(*args: str, cwd, timeout: float = 300) -> subprocess.CompletedProcess:
    """Run ``python -m decrun *args`` in ``cwd`` to its end; stdout and stderr captured as text."""
    return subprocess.run([sys.executable, "-m", "decrun", *args], cwd=cwd, env=env(), capture_output=True,
                          text=True, timeout=timeout)


def start(*args: str, cwd) -> subprocess.Popen:
    """Start ``python -m decrun *args`` in ``cwd`` without waiting (stdout/stderr piped)."""
    return subprocess.Popen([sys.executable, "-m", "decrun", *args], cwd=cwd, env=env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def comparable(table: pd.DataFrame) -> pd.DataFrame:
    """A sweep table without its wall-time columns (:data:`TIMES`), rows renumbered."""
    return table.drop(columns=[c for c in TIMES if c in table.columns]).reset_index(drop=True)


def result_contents(h5) -> dict:
    """Every dataset under fields/ and series/ of a result.h5, and its status attributes
    (``complete``, ``status``): what two runs that should be bit-equal are compared by."""
    import h5py

    out = {}
    with h5py.File(h5, "r") as f:
        for group in ("fields", "series"):
            for name, dataset in f[group].items():
                out[f"{group}/{name}"] = dataset[()]
        out["complete"], out["status"] = bool(f.attrs["complete"]), str(f.attrs["status"])
    return out

