"""Results of one run: :class:`Result` (what an application returns) and its HDF5 file.

Applications never touch the disk; the runner writes a ``Result`` to ``result.h5`` and
``metrics.json``.

Layout of ``result.h5`` (written by :func:`write_result`, read by :func:`read_result`)::

    /mesh/vertices   (n0, d) float64      the mesh the run used (after noise etc.)
    /mesh/simplices  (n2, 3) int64
    /mesh/edges      (n1, 2) int64        the edge list that orders the 1-forms
    /fields/<name>   arrays of Result.fields; 1-forms carry the attribute
                     ``edges = "mesh/edges"`` (their row order)
    /series/<name>   1-D arrays of Result.series
    /metrics         group whose attributes are the metrics (browsable);
                     the exact values (with their Python types) are in the root
                     attribute ``metrics_json``
    root attributes: format, created (UTC ISO time), config_yaml (resolved config),
                     decrun_version, numpy_version, scipy_version, pymeshlab_version,
                     h5py_version, python_version, mesh_hash, git_commit (when the
                     package lives in a git checkout), timings_json, figures (names)

The file is written under a temporary name in the same directory and renamed when
complete, so a killed run never leaves a ``result.h5`` that looks complete.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from decrun.apps.base import FieldOnEdges, Result

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
    tmp.write_text(metrics_to_json(metrics) + "\n")
    os.replace(tmp, path)
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
    """Write ``result`` (and the mesh, config and provenance) to ``path`` atomically.

    Returns the final path. On any error the temporary file is removed and nothing is
    left at ``path``.
    """
    import h5py

    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["format"] = FORMAT
            f.attrs["created"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
            f.attrs["config_yaml"] = config_yaml
            for key, value in package_versions().items():
                f.attrs[key] = value
            f.attrs["mesh_hash"] = mesh_hash
            commit = git_commit()
            if commit:
                f.attrs["git_commit"] = commit
            f.attrs["timings_json"] = json.dumps(timings or {})
            for key, value in (timings or {}).items():
                f.attrs[f"timing_{key}"] = float(value)
            f.attrs["metrics_json"] = metrics_to_json(result.metrics)
            f.attrs["figures"] = json.dumps(sorted(result.figures))
            for key, value in (attrs or {}).items():
                f.attrs[key] = value
            mesh = f.create_group("mesh")
            if vertices is not None:
                mesh.create_dataset("vertices", data=np.asarray(vertices, dtype=np.float64))
            if simplices is not None:
                mesh.create_dataset("simplices", data=np.asarray(simplices, dtype=np.int64))
            if edges is not None:
                mesh.create_dataset("edges", data=np.asarray(edges, dtype=np.int64))
            for group_name, arrays in (("fields", result.fields), ("series", result.series)):
                group = f.create_group(group_name)
                for name, array in arrays.items():
                    one_form = isinstance(array, FieldOnEdges)
                    array = np.asarray(array.values if one_form else array)
                    if array.dtype == object:
                        raise TypeError(f"Result.{group_name}[{name!r}] is not a numeric array")
                    dataset = group.create_dataset(name, data=array, compression="gzip" if array.size > 4096 else None)
                    if one_form:
                        if edges is None or len(edges) != len(array):
                            raise ValueError(f"Result.fields[{name!r}] is a 1-form with {len(array)} values, "
                                             f"but the mesh has {0 if edges is None else len(edges)} edges")
                        dataset.attrs["edges"] = "mesh/edges"
            metrics = f.create_group("metrics")
            for name, value in result.metrics.items():
                value = plain(value)
                metrics.attrs[name] = "null" if value is None else value
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def read_result(path: str | os.PathLike) -> Result:
    """Read the :class:`Result` written by :func:`write_result` (fields, series, metrics
    equal to what was written; ``figures`` is empty: they live beside it as PNG files)."""
    import h5py

    with h5py.File(path, "r") as f:
        fields = {name: f["fields"][name][()] for name in f["fields"]}
        series = {name: f["series"][name][()] for name in f["series"]}
        metrics = json.loads(f.attrs["metrics_json"])
    return Result(fields=fields, series=series, metrics=metrics, figures={})


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


def isclose_metrics(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """True when two metric dicts have the same keys and equal values (NaN equals NaN)."""
    if a.keys() != b.keys():
        return False
    for key in a:
        x, y = a[key], b[key]
        if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
            continue
        if x != y:
            return False
    return True
