"""Reading a run's result back: complete (``result.h5``) or not (its journal).

:func:`read_result` gives a :class:`RecordedResult` whatever state a run was left in (the
crash semantics are in :mod:`decrun.runner.results.recorder`); :func:`read_mesh` the mesh
stored with it.
"""

from __future__ import annotations

import errno as _errno
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from decrun.apps.base import Result
from decrun.runner.results.journal import BLOCK_BYTES, Journal, journal_path, read_journal
from decrun.runner.results.provenance import plain

__all__ = ["RecordedResult", "read_result", "read_mesh"]


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
    the whole valid records). ``figures`` is empty (they are PNG files). Raises
    ``FileNotFoundError`` when neither exists."""
    path = Path(path)
    if path.exists():
        return _read_h5(path)
    partial = journal_path(path)
    if partial.exists():
        return _read_journal(read_journal(partial))
    raise FileNotFoundError(_errno.ENOENT, f"no result: neither {path} nor {partial} exists", str(path))


def _read_h5(path: Path) -> RecordedResult:
    import h5py

    with h5py.File(path, "r") as f:
        fields = {name: f["fields"][name][()] for name in f["fields"]}
        field_on = {name: plain(f["fields"][name].attrs["on"]) for name in f["fields"] if "on" in f["fields"][name].attrs}
        series = {name: f["series"][name][()] for name in f["series"]}
        mesh = {name: f["mesh"][name][()] for name in f["mesh"]} if "mesh" in f else {}
        provenance = {key: plain(f.attrs[key]) for key in f.attrs}
    metrics = json.loads(provenance["metrics_json"])
    steps = provenance.get("steps_recorded", len(series.get("step", ())))
    return RecordedResult(fields=fields, series=series, metrics=metrics, figures={},
                          complete=bool(provenance.get("complete", True)), status=str(provenance.get("status", "ok")),
                          error=str(provenance.get("error", "")), steps_recorded=int(steps), provenance=provenance,
                          mesh=mesh, field_on=field_on, source=path)


def _read_journal(journal: Journal) -> RecordedResult:
    n = journal.n_records
    series = {"step": np.empty(n, np.int64)}
    series.update({c.name: np.empty((n, *c.shape), c.dtype) for c in journal.columns})
    for start, records in journal.blocks(BLOCK_BYTES):
        for name, array in series.items():
            array[start:start + len(records)] = records[name]
    attrs = journal.attrs
    provenance = {"config_yaml": attrs["config_yaml"], "mesh_hash": attrs["mesh_hash"], "created": attrs["created"],
                  **{k: v for k, v in attrs["provenance"].items() if v is not None}, **attrs["extra"]}
    mesh = {name.split("/", 1)[1]: array for name, array in journal.blobs.items()}
    return RecordedResult(series=series, complete=False, status="unfinished", steps_recorded=n, provenance=provenance,
                          mesh=mesh, source=journal.path)


def read_mesh(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, simplices)`` stored in a ``result.h5``."""
    import h5py

    with h5py.File(path, "r") as f:
        return f["mesh"]["vertices"][()], f["mesh"]["simplices"][()]
