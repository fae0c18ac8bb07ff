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
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from decrun.core.digest import Digest
from decrun.errors import CorruptFileError
from decrun.runner.io.atomic import write_text_atomic
from decrun.runner.results.checked import CONTENT, check_dataset, file_record, open_h5, parse_json

__all__ = ["FORMAT", "package_versions", "git_commit", "plain", "metrics_to_json", "write_metrics_json", "read_provenance",
           "decrun_attrs", "is_wall_time", "NOT_CONTENT", "NOT_CONTENT_METRICS", "content_sha256", "result_record",
           "SAME_AS", "mark_duplicates"]

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


def decrun_attrs(f, path: Path, keys: tuple[str, ...] | None = None) -> dict[str, Any]:
    """The root attributes of an open ``result.h5`` as plain values, or
    :class:`~decrun.errors.CorruptFileError` naming ``path`` when it is not a file decrun
    wrote (no ``format`` attribute ``decrun-result-1``, no ``metrics_json``). ``keys``: only
    those attributes (where present) besides the two checked ones, for a reader that needs a
    few of the file's two dozen."""
    stored = f.attrs  # h5py builds a new manager at each ``f.attrs``: once here
    names = list(stored) if keys is None else [k for k in dict.fromkeys(("format", "metrics_json", *keys))
                                               if k in stored]
    attrs = {key: plain(stored[key]) for key in names}
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


# ----------------------------------------------------------------------------------
# what two runs of one config share: the content hash
# ----------------------------------------------------------------------------------

#: root attributes of result.h5 that say when, how long, with what and from which config
#: text a result was made — not what it holds: :func:`content_sha256` leaves them out
NOT_CONTENT = ("created", "finished", "timings_json", "config_yaml", "git_commit", "decrun_version",
               "numpy_version", "scipy_version", "pymeshlab_version", "h5py_version", "python_version")

#: metrics that say how a run was made, not what it computed (a sweep job's config hash; the
#: step a resumed run continued from: resumed bit for bit, it holds what an uninterrupted run holds)
NOT_CONTENT_METRICS = ("config_hash", "resumed_from_step")

_WALL_TIME = re.compile(r"(^|_)(seconds|per_second)(_|$)")
#: rows hashed at a time (~16 MB of float64 triples): memory stays flat on a large result
_BLOCK_BYTES = 16 << 20


def is_wall_time(name: str) -> bool:
    """Whether a metric (or ``timing_*`` attribute) is a wall-clock measurement — its name
    has the word ``seconds`` or ``per_second`` (``solve_seconds``, ``step_seconds_max``,
    ``steps_per_second``, as metric names say their unit) — which differs between two runs
    of one config and is left out of :func:`content_sha256`."""
    return bool(_WALL_TIME.search(name))


def _not_content_metric(name: str) -> bool:
    return is_wall_time(name) or name in NOT_CONTENT_METRICS


def _canonical(value: Any) -> bytes:
    """An attribute value as bytes that are equal exactly when the values are (type included)."""
    if isinstance(value, np.ndarray):
        array = np.ascontiguousarray(value)
        return f"array {array.dtype.str} {array.shape} ".encode() + array.tobytes()
    value = plain(value)
    if isinstance(value, bytes):
        return b"bytes " + value
    return f"{type(value).__name__} {value!r}".encode()


def _hash_attrs(digest, where: str, attrs) -> None:
    """Hash the attributes ``attrs`` (a mapping) of the object named ``where``: at the root
    without :data:`NOT_CONTENT` and ``timing_*``, and the metrics (``/metrics``, the root's
    ``metrics_json``) without the wall times and :data:`NOT_CONTENT_METRICS`."""
    for key in sorted(attrs):
        if where == "/" and (key in NOT_CONTENT or key.startswith("timing_")):
            continue
        if where == "/metrics" and _not_content_metric(key):
            continue
        value = attrs[key]
        if where == "/" and key == "metrics_json":
            metrics = parse_json(value, f"attribute {key}")
            value = json.dumps({k: v for k, v in metrics.items() if not _not_content_metric(k)}, sort_keys=True)
        digest.bytes(f"attr {where} {key}=".encode() + _canonical(value) + b"\n")


def _hash_group(digest, group, path: Path, checked: bool) -> None:
    """Hash the members of ``group`` in name order: groups recursively, datasets as name,
    dtype, shape and their values read in row blocks (memory stays flat), then their
    attributes. ``checked``: refuse links and datasets :func:`check_dataset` refuses first."""
    import h5py

    for name in sorted(group):
        if checked and not isinstance(group.get(name, getlink=True), h5py.HardLink):
            raise CorruptFileError(f"{path}: {group.name.rstrip('/')}/{name} is a link; refused (decrun writes "
                                   "only datasets inside the file)")
        member = group[name]
        where = member.name
        if isinstance(member, h5py.Group):
            digest.text(f"group {where}\n")
            _hash_attrs(digest, where, member.attrs)
            _hash_group(digest, member, path, checked)
            continue
        if checked:
            check_dataset(member, path)
        shape, dtype = member.shape, member.dtype
        digest.text(f"dataset {where} {dtype.str} {shape}\n")
        if not shape or 0 in shape:
            digest.array(member[()], header=False)
        else:
            row = max(1, int(np.prod(shape[1:], dtype=np.int64)) * dtype.itemsize)
            step = max(1, _BLOCK_BYTES // row)
            for start in range(0, shape[0], step):
                digest.array(member[start:start + step], header=False)
        _hash_attrs(digest, where, member.attrs)


def content_sha256(path: str | os.PathLike, *, checked: bool = True) -> str:
    """sha256 of what ``result.h5`` holds — every dataset (name, dtype, shape, values) and
    every attribute — but not of when, how long, with which versions or from which config
    text it was made (:data:`NOT_CONTENT`, the ``timing_*`` attributes, the wall-time
    metrics :func:`is_wall_time`, :data:`NOT_CONTENT_METRICS`). Two runs of one config that
    compute the same numbers have the same content hash; their files' sha256 differ (the
    file stores its times). Reads the file as the checked readers do
    (:class:`~decrun.errors.CorruptFileError` naming it); ``checked=False`` skips the
    per-dataset checks, for a file this process has just written (the runner: ~half the cost
    on a small result)."""
    path = Path(path)
    digest = Digest(b"decrun content 1\n")
    with open_h5(path) as f:
        _hash_attrs(digest, "/", decrun_attrs(f, path))
        _hash_group(digest, f, path, checked)
    return digest.hexdigest()


def result_record(path: str | os.PathLike) -> dict[str, Any]:
    """The ``result_h5`` entry of ``metrics.json``: the file's size and sha256
    (:func:`~decrun.runner.results.checked.file_record`: readers never take a truncated or
    altered file for it) and its ``content_sha256`` (:func:`content_sha256`: equal for two
    runs that computed the same result) — of a file this process has just written."""
    return {**file_record(path), CONTENT: content_sha256(path, checked=False)}


#: the column naming the earlier job whose result a job repeats exactly
SAME_AS = "same_as"


def mark_duplicates(rows: list[dict]) -> int:
    """Set ``rows[i]["same_as"]`` to the job of the first earlier ``ok`` row with the same
    ``content_sha256`` (the same numbers in every dataset and metric, wall times aside);
    returns how many rows repeat another."""
    first: dict[str, Any] = {}
    count = 0
    for row in rows:
        content = row.get("content_sha256")
        if row.get("status") != "ok" or not isinstance(content, str) or not content:
            continue
        if content in first:
            row[SAME_AS] = first[content]
            count += 1
        else:
            first[content] = row["job"]
    return count
