"""What a result records about how it was made, and its metrics as plain JSON.

The format name, decrun's and the numerical stack's versions and the git commit that
:class:`decrun.runner.results.recorder.ResultRecorder` writes as root attributes of
``result.h5`` (:func:`read_provenance` reads them back), and ``metrics.json``
(:func:`write_metrics_json`). The recorder and the reader both build on this module and
on :mod:`decrun.runner.results.journal`, never on each other.
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from decrun.errors import CorruptFileError
from decrun.runner.atomic import write_text_atomic
from decrun.runner.results.checked import open_h5, parse_json

__all__ = ["FORMAT", "package_versions", "git_commit", "plain", "metrics_to_json", "write_metrics_json", "read_provenance",
           "decrun_attrs"]

FORMAT = "decrun-result-1"


# ----------------------------------------------------------------------------------
# provenance
# ----------------------------------------------------------------------------------


def _version(module: str) -> str:
    try:
        from importlib.metadata import version

        return version(module)
    except Exception:
        return "unknown"


def package_versions() -> dict[str, str]:
    """Versions of decrun and the numerical stack, for the ``*_version`` attributes (read
    once per process: package metadata costs ~10 ms a lookup, on every sweep job)."""
    return dict(_package_versions())


@functools.lru_cache(maxsize=1)
def _package_versions() -> dict[str, str]:
    import decrun

    return {
        "decrun_version": decrun.__version__,
        "numpy_version": np.__version__,
        "scipy_version": _version("scipy"),
        "pymeshlab_version": _version("pymeshlab"),
        "h5py_version": _version("h5py"),
        "python_version": sys.version.split()[0],
    }


@functools.lru_cache(maxsize=1)
def git_commit() -> str | None:
    """``HEAD`` commit (with ``-dirty`` if the tree has changes) of the checkout holding
    the decrun package, or None when it is not in a git checkout (e.g. a wheel). Asked once
    per process (two git processes, ~20-50 ms, on every sweep job otherwise): the code a
    process runs is the one it imported at its start, so that is the commit to record."""
    here = Path(__file__).resolve().parent
    try:
        commit = subprocess.run(["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True,
                                text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(here), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
    except Exception:
        return None
    return commit + ("-dirty" if dirty else "") if commit else None


# ----------------------------------------------------------------------------------
# metrics as plain JSON
# ----------------------------------------------------------------------------------


def plain(value: Any) -> Any:
    """A metric value as a plain Python scalar (numpy scalars → int/float/bool/str)."""
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return float(value)
    if isinstance(value, np.ndarray) and value.ndim == 0:
        return plain(value.item())
    return value


def metrics_to_json(metrics: dict[str, Any]) -> str:
    """JSON text of the metrics (NaN/inf are written as the JSON extensions NaN/Infinity)."""
    return json.dumps({k: plain(v) for k, v in metrics.items()}, indent=2, sort_keys=False)


def write_metrics_json(path: str | os.PathLike, metrics: dict[str, Any]) -> Path:
    """Write ``metrics.json`` atomically (temporary name, then rename)."""
    return write_text_atomic(path, metrics_to_json(metrics) + "\n")


def decrun_attrs(f, path: Path) -> dict[str, Any]:
    """The root attributes of an open ``result.h5`` as plain values, or
    :class:`~decrun.errors.CorruptFileError` naming ``path`` when it is not a file decrun
    wrote (no ``format`` attribute ``decrun-result-1``, no ``metrics_json``)."""
    attrs = {key: plain(f.attrs[key]) for key in f.attrs}
    missing = "format" if attrs.get("format") != FORMAT else None if isinstance(attrs.get("metrics_json"), str) \
        else "metrics_json"
    if missing:
        raise CorruptFileError(f"{path}: not a decrun result.h5 (no {missing} attribute of {FORMAT})")
    return attrs


def read_provenance(path: str | os.PathLike) -> dict[str, Any]:
    """The root attributes of a ``result.h5`` (config_yaml, versions, mesh_hash, timings...).
    :class:`~decrun.errors.CorruptFileError` naming the file when it is not a result
    decrun wrote or its ``timings_json`` is not a JSON object."""
    path = Path(path)
    with open_h5(path) as f:
        out = decrun_attrs(f, path)
    timings = parse_json(out.pop("timings_json", "{}"), f"{path}: attribute timings_json")
    if not isinstance(timings, dict):
        raise CorruptFileError(f"{path}: attribute timings_json is not a JSON object")
    out["timings"] = timings
    return out
