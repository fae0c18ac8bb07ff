"""Reading a run's result back: complete (``result.h5``) or not (its journal).

:func:`read_result` gives a :class:`RecordedResult` whatever state a run was left in (the
crash semantics are in :mod:`decrun.runner.results.recorder`); :func:`read_mesh` the mesh
stored with it.
"""

from __future__ import annotations

import errno as _errno
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from decrun.apps.base import Result
from decrun.errors import CorruptFileError
from decrun.runner.io.files import RunFiles
from decrun.runner.results.checked import check_group, check_record, open_h5, parse_json, read_dataset
from decrun.runner.results.journal import BLOCK_BYTES, Journal, journal_path, read_journal
from decrun.runner.results.provenance import decrun_attrs, plain

#: what :func:`~decrun.runner.results.journal.journal_path` appends to a result's name
JOURNAL_SUFFIX = RunFiles.JOURNAL[len(RunFiles.RESULT):]

__all__ = ["RecordedResult", "read_result", "read_mesh", "check_result", "verify_result", "chained_status",
           "CHAINED_STATUS"]

#: the metric (and mesh.meta key) naming the status of an incomplete result a run chained from
#: (``mesh=result``, ``app.input=result``); absent when the source was complete
CHAINED_STATUS = "chained_result_status"


@dataclass
class RecordedResult(Result):
    """A :class:`~decrun.apps.base.Result` read back from ``result.h5`` or its journal.

    Extra attributes: ``complete`` (True only for a finished run), ``status`` ("ok" |
    "failed" | "interrupted" | "killed" | "unfinished" (journal only: the writer was
    killed, or is still running)), ``error``, ``steps_recorded``, ``provenance`` (root
    attributes), ``mesh`` (vertices / simplices / edges arrays), ``field_on`` (field
    name → mesh dataset for declared forms), ``source`` (the file read).
    """

    complete: bool = False
    status: str = ""
    error: str = ""
    steps_recorded: int = 0
    provenance: dict[str, Any] = field(default_factory=dict)
    mesh: dict[str, np.ndarray] = field(default_factory=dict)
    field_on: dict[str, str] = field(default_factory=dict)
    source: Path | None = None


def read_result(path: str | os.PathLike) -> RecordedResult:
    """The :class:`RecordedResult` stored for a run, whatever state it was left in: ``result.h5`` (complete, or
    marked incomplete by ``abort``/``recover_result``; also files of ``write_result``,
    which are complete) or, when absent, its journal ``result.h5.partial`` (incomplete,
    the whole valid records); ``path`` may also be that journal (a sweep table's ``result``
    of a killed job) or the run directory. ``figures`` is empty (they are PNG files). Raises
    ``FileNotFoundError`` when neither exists, and :class:`~decrun.errors.CorruptFileError`
    naming the file when it is not one decrun wrote, is damaged, or holds a dataset
    :func:`~decrun.runner.results.checked.check_dataset` refuses (external storage, a
    virtual dataset, a shape its stored bytes cannot hold) -- before reading any data."""
    path = Path(path)
    if path.is_dir():  # a run or job directory
        path = path / RunFiles.RESULT
    if path.name.endswith(JOURNAL_SUFFIX):  # the journal itself, as a sweep table names a killed job's result
        result = path.with_name(path.name[:-len(JOURNAL_SUFFIX)])
        if path.is_file():
            return _read_journal(read_journal(path))
        if result.is_file():  # the job finished since: its journal became result.h5
            return _read_h5(result)
        raise FileNotFoundError(_errno.ENOENT, f"no result: neither {path} nor {result} exists", str(path))
    if path.exists():
        return _read_h5(path)
    partial = journal_path(path)
    if partial.exists():
        return _read_journal(read_journal(partial))
    raise FileNotFoundError(_errno.ENOENT, f"no result: neither {path} nor {partial} exists", str(path))


def _read_h5(path: Path) -> RecordedResult:
    with open_h5(path) as f:
        provenance = decrun_attrs(f, path)
        check_group(f, path)  # links, external storage, declared sizes: before any data is read
        groups = {}
        for name in ("fields", "series", "mesh"):
            group = f.get(name)
            if group is not None and not hasattr(group, "keys"):
                raise CorruptFileError(f"{path}: /{name} is not a group")
            groups[name] = group if group is not None else {}
        fields, series, mesh = (_arrays(groups[name], path) for name in ("fields", "series", "mesh"))
        field_on = {name: plain(groups["fields"][name].attrs["on"]) for name in fields
                    if "on" in groups["fields"][name].attrs}
    metrics = parse_json(provenance["metrics_json"], f"{path}: attribute metrics_json")
    if not isinstance(metrics, dict):
        raise CorruptFileError(f"{path}: attribute metrics_json is not a JSON object")
    try:
        steps = int(provenance.get("steps_recorded", len(series.get("step", ()))))
        complete, status = bool(provenance.get("complete", True)), str(provenance.get("status", "ok"))
    except (TypeError, ValueError) as exc:
        raise CorruptFileError(f"{path}: malformed status attributes ({exc})") from None
    return RecordedResult(fields=fields, series=series, metrics=metrics, figures={}, complete=complete, status=status,
                          error=str(provenance.get("error", "")), steps_recorded=steps, provenance=provenance,
                          mesh=mesh, field_on=field_on, source=path)


def _arrays(group, path: Path) -> dict[str, np.ndarray]:
    """Every member of ``group`` (already checked) read whole; a member that is not a
    dataset is a CorruptFileError."""
    out = {}
    for name in group:
        if not hasattr(group[name], "shape"):
            raise CorruptFileError(f"{path}: {group[name].name} is a group, not a dataset")
        out[name] = group[name][()]
    return out


def check_result(path: str | os.PathLike) -> None:
    """Check that ``path`` is a whole, complete result.h5 decrun wrote, reading metadata
    only: an HDF5 file with decrun's attributes, ``status`` ok, and no member
    :func:`~decrun.runner.results.checked.check_group` refuses. Raises ``FileNotFoundError``
    or :class:`CorruptFileError` naming the file."""
    path = Path(path)
    with open_h5(path) as f:
        attrs = decrun_attrs(f, path)
        check_group(f, path)
    if attrs.get("status", "ok") != "ok" or not attrs.get("complete", True):
        raise CorruptFileError(f"{path}: marked {attrs.get('status')!r}, not complete")


def verify_result(path: str | os.PathLike, record: Any = None) -> None:
    """Check a job's result.h5 before calling the job ok: against ``record`` (the
    ``result_h5`` entry of its metrics.json: size and sha256, :func:`~decrun.runner.
    results.checked.file_record`) when there is one, else with :func:`check_result`.
    Raises :class:`CorruptFileError` naming the file (also when it is missing)."""
    path = Path(path)
    if record is not None:
        check_record(path, record)
        return
    try:
        check_result(path)
    except FileNotFoundError:
        raise CorruptFileError(f"{path}: missing beside an ok metrics.json") from None


def _read_journal(journal: Journal) -> RecordedResult:
    n = journal.n_records
    series = {"step": np.empty(n, np.int64)}
    series.update({c.name: np.empty((n, *c.shape), c.dtype) for c in journal.columns})
    for start, records in journal.blocks(BLOCK_BYTES):
        for name, array in series.items():
            array[start:start + len(records)] = records[name]
    attrs = journal.attrs
    try:
        provenance = {"config_yaml": attrs["config_yaml"], "mesh_hash": attrs["mesh_hash"], "created": attrs["created"],
                      **{k: v for k, v in attrs["provenance"].items() if v is not None}, **attrs["extra"]}
    except (KeyError, TypeError, AttributeError) as exc:
        raise CorruptFileError(f"{journal.path}: malformed journal attributes ({exc!r})") from None
    mesh = {name.split("/", 1)[1]: array for name, array in journal.blobs.items()}
    return RecordedResult(series=series, complete=False, status="unfinished", steps_recorded=n, provenance=provenance,
                          mesh=mesh, source=journal.path)


def read_mesh(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, simplices)`` stored in a ``result.h5``: (n0, d) float64 and
    (n_top, k+1) int64. :class:`CorruptFileError` naming the file when it has none or
    they are not plain datasets inside the file."""
    path = Path(path)
    with open_h5(path) as f:
        arrays = []
        for name in ("mesh/vertices", "mesh/simplices"):
            if "mesh" not in f or name.split("/")[1] not in f["mesh"] or not hasattr(f[name], "shape"):
                raise CorruptFileError(f"{path}: no dataset /{name}")
            check_group(f["mesh"], path)
            arrays.append(read_dataset(f[name], path))
    return arrays[0], arrays[1]


def chained_status(stored: RecordedResult, where: str, log=None) -> str:
    """``""`` for a complete result, else its status ("failed", "interrupted", "killed",
    "unfinished"), said in one warning naming ``where`` (``mesh.path=...``)."""
    if stored.complete:
        return ""
    status = str(stored.status) or "incomplete"
    (log or logging.getLogger("decrun").warning)(
        f"{where}: the result is not complete (status {status}, {stored.steps_recorded} steps recorded); chained "
        f"anyway, metric {CHAINED_STATUS}={status}")
    return status
