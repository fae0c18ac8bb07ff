"""Result files: provenance, ``metrics.json`` and reading/writing ``result.h5``.

Applications never touch the disk; the runner streams a run's recorded series and writes
its :class:`~decrun.apps.base.Result` through :class:`decrun.runner.recorder.ResultRecorder`,
whose docstring gives the layout of ``result.h5`` (mesh, fields — 1-forms with
``form_degree = 1`` and ``on = "mesh/edges"`` — series, metrics, provenance attributes)
and the crash semantics: ``result.h5`` is either absent or whole; a killed run leaves its
recorded steps readable (:func:`read_result`, ``.complete`` False).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from decrun.apps.base import Result

__all__ = ["Result", "write_result", "read_result", "read_provenance", "read_mesh", "write_metrics_json"]

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
    """Versions of decrun and the numerical stack, for the ``*_version`` attributes."""
    import decrun

    return {
        "decrun_version": decrun.__version__,
        "numpy_version": np.__version__,
        "scipy_version": _version("scipy"),
        "pymeshlab_version": _version("pymeshlab"),
        "h5py_version": _version("h5py"),
        "python_version": sys.version.split()[0],
    }


def git_commit() -> str | None:
    """``HEAD`` commit (with ``-dirty`` if the tree has changes) of the checkout holding
    the decrun package, or None when it is not in a git checkout (e.g. a wheel)."""
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
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        tmp.write_text(metrics_to_json(metrics) + "\n")
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


# ----------------------------------------------------------------------------------
# HDF5
# ----------------------------------------------------------------------------------


def write_result(
    path: str | os.PathLike,
    result: Result,
    *,
    vertices: np.ndarray | None = None,
    simplices: np.ndarray | None = None,
    edges: np.ndarray | None = None,
    config_yaml: str = "",
    mesh_hash: str = "",
    timings: dict[str, float] | None = None,
    attrs: dict[str, Any] | None = None,
) -> Path:
    """Write a finished ``result`` (and the mesh, config and provenance) to ``path``
    atomically: a :class:`decrun.runner.recorder.ResultRecorder` with no recorded steps.
    1-forms (:class:`decrun.apps.base.FieldOnEdges`) need ``edges``."""
    from decrun.runner.recorder import ResultRecorder

    recorder = ResultRecorder(path, vertices=vertices, simplices=simplices, edges=edges, config_yaml=config_yaml,
                              mesh_hash=mesh_hash, attrs=attrs)
    return recorder.finish(result, timings)


def read_result(path: str | os.PathLike):
    """The :class:`Result` stored for a run — complete, or incomplete (killed, failed,
    interrupted: ``.complete`` is False and the series hold the steps recorded so far); see
    :func:`decrun.runner.recorder.read_result_any`. ``figures`` is empty (they are PNG files)."""
    from decrun.runner.recorder import read_result_any

    return read_result_any(path)


def read_provenance(path: str | os.PathLike) -> dict[str, Any]:
    """The root attributes of a ``result.h5`` (config_yaml, versions, mesh_hash, timings...)."""
    import h5py

    with h5py.File(path, "r") as f:
        out = {key: plain(f.attrs[key]) for key in f.attrs}
    out["timings"] = json.loads(out.pop("timings_json", "{}"))
    return out


def read_mesh(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, simplices)`` stored in a ``result.h5``."""
    import h5py

    with h5py.File(path, "r") as f:
        return f["mesh"]["vertices"][()], f["mesh"]["simplices"][()]
