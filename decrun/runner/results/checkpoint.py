"""A time-stepping run's checkpoint: ``<run dir>/checkpoint.h5`` (:data:`CHECKPOINT`).

:class:`RunCheckpoint` is the runner's :class:`decrun.methods.stepping.Checkpoint`. While a
run steps (:func:`decrun.methods.stepping.run_steps`) it writes, every ``checkpoint.steps``
steps and/or every ``checkpoint.seconds`` seconds, the stepper's whole state (nested dicts of
numpy arrays and scalars) as HDF5 groups and datasets, atomically
(:func:`decrun.runner.atomic.atomic_path`: the old checkpoint or the whole new one), with
root attributes::

    format "decrun-checkpoint-1", step (int), config_hash (16 hex, the run's
    decrun.runner.sweep.manifest.config_hash), records (records in the run's journal
    result.h5.partial when it was written), journal_created (that journal's header time),
    sha256 (over every leaf's path, kind, dtype, shape and bytes), complete (true)

A rerun of the same config into the same directory (the same command with the same
``hydra.run.dir``, a resumed sweep, a requeued SLURM job) loads it: the recorder continues
the journal after ``records`` records (:meth:`~decrun.runner.results.recorder.ResultRecorder.resume`)
and the stepper its state, so the run ends as the uninterrupted run would, bitwise. A
checkpoint of another config is not used; a corrupt one (not HDF5, truncated, checksum
wrong, not complete) or one whose journal is gone or damaged is reported in the log and not
trusted: the run starts from step 0. A finished run removes its checkpoint.
"""

from __future__ import annotations

import hashlib
import time
from pathlib import Path
from typing import Any, Callable, Optional

import numpy as np

from decrun.errors import CorruptFileError
from decrun.runner.atomic import atomic_path
from decrun.runner.files import RunFiles

__all__ = ["CHECKPOINT", "RunCheckpoint", "write_checkpoint", "read_checkpoint"]

#: the checkpoint's file name in the run directory
CHECKPOINT = RunFiles.CHECKPOINT
FORMAT = "decrun-checkpoint-1"


def _leaves(state: dict, prefix: str = ""):
    """``(path, kind, array)`` for every leaf of ``state`` in sorted order."""
    for name in sorted(state):
        if not isinstance(name, str) or not name or "/" in name:
            raise TypeError(f"checkpoint: state key {name!r} must be a non-empty str without '/'")
        value, path = state[name], f"{prefix}{name}"
        if isinstance(value, dict):
            yield from _leaves(value, path + "/")
        elif value is None:
            yield path, "none", np.zeros(0, dtype=np.uint8)
        elif isinstance(value, (bool, np.bool_)):
            yield path, "bool", np.asarray(value, dtype=np.bool_)
        elif isinstance(value, (int, np.integer)):
            yield path, "int", np.asarray(value, dtype=np.int64)
        elif isinstance(value, (float, np.floating)):
            yield path, "float", np.asarray(value, dtype=np.float64)
        elif isinstance(value, np.ndarray) and value.dtype.kind in "biufc":
            yield path, "array", np.array(value, order="C")
        else:
            raise TypeError(f"checkpoint: state {path!r} is a {type(value).__name__}; a stepper's state holds "
                            "numeric numpy arrays, numbers, bools, None and dicts of them")


def _digest(leaves) -> str:
    h = hashlib.sha256()
    for path, kind, array in leaves:
        h.update(f"{path}\0{kind}\0{array.dtype.str}\0{array.shape}\0".encode())
        h.update(array.tobytes())
    return h.hexdigest()


def write_checkpoint(path: str | Path, step: int, state: dict, attrs: dict[str, Any]) -> Path:
    """Write ``state`` after ``step`` to ``path`` atomically (module docstring); ``attrs``
    are extra root attributes (str / numbers)."""
    import h5py

    leaves = list(_leaves(state))
    with atomic_path(path) as tmp:
        with h5py.File(tmp, "w") as f:
            for leaf, kind, array in leaves:
                f.create_dataset(leaf, data=array).attrs["kind"] = kind
            f.attrs.update({"format": FORMAT, "step": int(step), "sha256": _digest(leaves), **attrs})
            f.attrs["complete"] = True
    return Path(path)


def read_checkpoint(path: str | Path) -> tuple[int, dict, dict]:
    """``(step, state, root attributes)`` of a checkpoint; CorruptFileError naming the file
    when it is not one, is incomplete or its checksum does not match."""
    import h5py

    path = Path(path)
    leaves, state = [], {}
    try:
        with h5py.File(path, "r") as f:
            attrs = {key: (value.item() if hasattr(value, "item") else value) for key, value in f.attrs.items()}
            if attrs.get("format") != FORMAT:
                raise CorruptFileError(f"{path}: not a decrun checkpoint (format {attrs.get('format')!r})")
            if attrs.get("complete") is not True:
                raise CorruptFileError(f"{path}: the checkpoint is not marked complete")

            def visit(name, node):
                if isinstance(node, h5py.Dataset):
                    leaves.append((name, str(node.attrs["kind"]), np.array(node[()])))

            f.visititems(visit)
    except CorruptFileError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as exc:  # truncated, not HDF5, damaged
        raise CorruptFileError(f"{path}: cannot read it as a decrun checkpoint ({str(exc).splitlines()[0]})") from None
    leaves.sort(key=lambda leaf: leaf[0])
    if _digest(leaves) != attrs.get("sha256"):
        raise CorruptFileError(f"{path}: checksum mismatch (the file was altered or damaged)")
    for leaf, kind, array in leaves:
        *groups, name = leaf.split("/")
        node = state
        for group in groups:
            node = node.setdefault(group, {})
        node[name] = (None if kind == "none" else array if kind == "array" else
                      bool(array) if kind == "bool" else int(array) if kind == "int" else float(array))
    return int(attrs["step"]), state, attrs


class RunCheckpoint:
    """``checkpoint.h5`` of one run (module docstring).

    path : the file; config_hash : the run's config hash; recorder : the run's
    ResultRecorder (or None: no records to continue); steps : write every this many steps
    (None: not by steps); seconds : write when this many seconds passed since the start or
    the last checkpoint (None: not by time); log : where load() says what it did.
    """

    def __init__(self, path: str | Path, config_hash: str, *, recorder=None, steps: Optional[int] = None,
                 seconds: Optional[float] = None, log: Callable[[str], None] = print):
        self.path, self.config_hash, self.recorder = Path(path), config_hash, recorder
        self.steps, self.seconds, self.log = steps, seconds, log
        self._last = time.monotonic()

    def load(self) -> Optional[tuple[int, dict]]:
        if not self.path.exists():
            return None
        try:
            step, state, attrs = read_checkpoint(self.path)
        except CorruptFileError as exc:
            self.log(f"checkpoint: {exc}; not trusted: the run starts from step 0")
            return None
        if attrs.get("config_hash") != self.config_hash:
            self.log(f"checkpoint: {self.path} was written by another config (hash {attrs.get('config_hash')}, "
                     f"this run's {self.config_hash}); not used: the run starts from step 0")
            return None
        if self.recorder is not None:
            try:
                self.recorder.resume(int(attrs["records"]), str(attrs["journal_created"]))
            except (CorruptFileError, OSError, ValueError, KeyError) as exc:
                self.log(f"checkpoint: {self.path} at step {step} has no whole journal to continue ({exc}); "
                         "not used: the run starts from step 0")
                return None
        self.log(f"checkpoint: continuing from step {step} ({self.path})")
        self._last = time.monotonic()
        return step, state

    def due(self, step: int) -> bool:
        if self.steps and step % self.steps == 0:
            return True
        return self.seconds is not None and time.monotonic() - self._last >= self.seconds

    def save(self, step: int, state: dict) -> None:
        attrs = {"config_hash": self.config_hash, "records": 0, "journal_created": ""}
        if self.recorder is not None:
            attrs.update(records=int(self.recorder.steps_recorded), journal_created=self.recorder.journal_created)
            self.recorder.keep_journal = True
        write_checkpoint(self.path, step, state, attrs)
        self._last = time.monotonic()

    def remove(self) -> None:
        self.path.unlink(missing_ok=True)
