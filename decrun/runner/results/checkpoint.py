"""A time-stepping run's checkpoint: ``<run dir>/checkpoint.h5`` (:data:`CHECKPOINT`).

:class:`RunCheckpoint` is the runner's :class:`decrun.methods.stepping.Checkpoint`. While a
run steps (:func:`decrun.methods.stepping.run_steps`) it writes, every ``checkpoint.steps``
steps and/or every ``checkpoint.seconds`` seconds, the stepper's whole state (nested dicts of
numpy arrays and scalars) as HDF5 groups and datasets, atomically
(:func:`decrun.runner.io.atomic.atomic_path`: the old checkpoint or the whole new one), with
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
wrong, not complete, or a member the checked readers refuse: links and external storage
out of the file, virtual datasets, shapes the stored bytes cannot hold), one whose state is
not this run's (``check`` of :meth:`RunCheckpoint.load`: the stepper's
:func:`decrun.methods.stepping.state_mismatch` and the step range -- the sha256 proves only
that the file is whole, anyone can recompute it) or one whose journal is gone or damaged is
reported in one log line naming the file and not trusted: the run starts from step 0. A
finished run removes its checkpoint and the temporary files of a write a killed process
left (:func:`remove_checkpoint`); a disk too full to write it is an ``OSError`` naming it.
"""

from __future__ import annotations

import errno as _errno
import os
import time
from pathlib import Path
from typing import Any, Callable, Optional

import numpy as np

from decrun.core.digest import Digest
from decrun.errors import CorruptFileError
from decrun.runner.io.atomic import QuietFile, atomic_path, check_free_space
from decrun.runner.io.files import RunFiles
from decrun.runner.results.checked import check_group, open_h5, read_dataset

__all__ = ["CHECKPOINT", "RunCheckpoint", "write_checkpoint", "read_checkpoint", "remove_checkpoint"]

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
    h = Digest()
    for path, kind, array in leaves:
        h.text(f"{path}\0{kind}\0{array.dtype.str}\0{array.shape}\0").array(array, header=False)
    return h.hexdigest()


def _bytes_needed(leaves, attrs: dict[str, Any]) -> int:
    """An upper bound of the checkpoint's size (bytes): its data plus generous metadata."""
    data = sum(array.nbytes for _, _, array in leaves)
    return int(1.02 * data) + 4096 * (len(leaves) + 16) + 2 * len(repr(attrs)) + (64 << 10)


def write_checkpoint(path: str | Path, step: int, state: dict, attrs: dict[str, Any]) -> Path:
    """Write ``state`` after ``step`` to ``path`` atomically (module docstring); ``attrs``
    are extra root attributes (str / numbers; its format, step, sha256 and complete are
    this function's).

    A disk too full for it (checked before HDF5 starts, or met while HDF5 writes: kept from
    HDF5 by :class:`~decrun.runner.io.atomic.QuietFile`) is an ``OSError`` naming ``path``
    (``filename``), raised after HDF5 closed the file; the temporary file is removed and
    the previous checkpoint is kept."""
    import h5py

    path = Path(path)
    leaves = list(_leaves(state))
    try:
        check_free_space(path.parent, _bytes_needed(leaves, attrs))
        with atomic_path(path) as tmp:
            target = QuietFile(tmp)
            try:
                with h5py.File(target, "w") as f:
                    for leaf, kind, array in leaves:
                        f.create_dataset(leaf, data=array).attrs["kind"] = kind
                    f.attrs.update({**attrs, "format": FORMAT, "step": int(step), "sha256": _digest(leaves)})
                    f.attrs["complete"] = True
            finally:
                target.close()
            if target.error is not None:
                raise target.error
    except OSError as exc:
        if exc.filename == str(path):
            raise
        code = exc.errno if isinstance(exc.errno, int) else _errno.EIO
        raise OSError(code, exc.strerror or os.strerror(code), str(path)) from exc
    return path


def remove_checkpoint(path: str | Path) -> None:
    """Remove the checkpoint ``path`` and the temporary files of a write a killed process
    left beside it (``.checkpoint.h5.tmp-<pid>``); only while no process writes it (the
    run directory's lock)."""
    path = Path(path)
    for leftover in path.parent.glob(f".{path.name}.tmp-*"):
        leftover.unlink(missing_ok=True)
    path.unlink(missing_ok=True)


#: the kinds of leaf a checkpoint stores (:func:`_leaves`) and the dtype kinds each may have
_KINDS = {"none": "u", "bool": "b", "int": "i", "float": "f", "array": "biufc"}


def read_checkpoint(path: str | Path) -> tuple[int, dict, dict]:
    """``(step, state, root attributes)`` of a checkpoint; CorruptFileError naming the file
    when it is not one, is incomplete, its checksum does not match, its ``step`` is not an
    integer, or a member is one the checked readers refuse
    (:func:`~decrun.runner.results.checked.check_group`: links and external storage out of
    the file, virtual datasets, shapes the stored bytes cannot hold -- checked before any
    data is read) or not a leaf :func:`write_checkpoint` writes. The checksum proves no
    more than that the file is whole (anyone can recompute it): :class:`RunCheckpoint`
    checks the state against the run before using it."""
    path = Path(path)
    try:
        return _read_checkpoint(path)
    except CorruptFileError:
        raise
    except (ValueError, TypeError) as exc:  # h5py on an attribute or dtype it cannot convert
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:200]
        raise CorruptFileError(f"{path}: cannot read it as a decrun checkpoint ({first})") from None


def _read_checkpoint(path: Path) -> tuple[int, dict, dict]:
    leaves, state = [], {}
    with open_h5(path) as f:
        attrs = {key: (value.item() if hasattr(value, "item") and np.ndim(value) == 0 else value)
                 for key, value in f.attrs.items()}
        if attrs.get("format") != FORMAT:
            raise CorruptFileError(f"{path}: not a decrun checkpoint (format {str(attrs.get('format'))[:40]!r})")
        if attrs.get("complete") is not True:
            raise CorruptFileError(f"{path}: the checkpoint is not marked complete")
        step = attrs.get("step")
        if not isinstance(step, int) or isinstance(step, bool):
            raise CorruptFileError(f"{path}: its step attribute is {str(step)[:40]!r}, not an integer")
        check_group(f, path)  # links, external storage, declared sizes: before any data is read

        def visit(name, node):
            if hasattr(node, "shape"):
                kind = node.attrs.get("kind")
                kind = kind.decode() if isinstance(kind, bytes) else str(kind)
                if kind not in _KINDS or node.dtype.kind not in _KINDS[kind] or \
                        (kind not in ("array", "none") and node.shape != ()):
                    raise CorruptFileError(f"{path}: dataset /{name} ({node.dtype}, shape {node.shape}, kind "
                                           f"{kind[:20]!r}) is not a leaf decrun writes")
                leaves.append((name, kind, np.array(read_dataset(node, path))))

        f.visititems(visit)
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
    return step, state, attrs


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

    def load(self, check: Optional[Callable[[int, dict], str]] = None) -> Optional[tuple[int, dict]]:
        """``(step, state)`` of this run's checkpoint, the journal set back to its records;
        None (one log line naming the file and why: the run starts from step 0) when there
        is none, it is corrupt (:func:`read_checkpoint`), another config's, ``check(step,
        state)`` (the stepper's: :func:`decrun.methods.stepping.state_mismatch`) finds it is
        not a state of this run, or its journal is gone. Removes the temporary files of a
        write a killed process left."""
        for leftover in self.path.parent.glob(f".{self.path.name}.tmp-*"):
            leftover.unlink(missing_ok=True)
        if not self.path.exists():
            return None
        try:
            step, state, attrs = read_checkpoint(self.path)
        except CorruptFileError as exc:
            self.log(f"checkpoint: {exc}; not trusted: the run starts from step 0")
            return None
        if attrs.get("config_hash") != self.config_hash:
            self.log(f"checkpoint: {self.path} was written by another config (hash "
                     f"{str(attrs.get('config_hash'))[:40]}, this run's {self.config_hash}); not used: the run starts "
                     "from step 0")
            return None
        reason = check(step, state) if check is not None else ""
        if reason:
            self.log(f"checkpoint: {self.path}: {reason}; not a state of this run, not trusted: the run starts "
                     "from step 0")
            return None
        if self.recorder is not None:
            records = attrs.get("records")
            if not isinstance(records, int) or isinstance(records, bool) or records < 0:
                self.log(f"checkpoint: {self.path}: its records attribute is {str(records)[:40]!r}, not a count of "
                         "records; not trusted: the run starts from step 0")
                return None
            try:
                self.recorder.resume(records, str(attrs["journal_created"]), step)
            except (CorruptFileError, OSError, ValueError, KeyError, TypeError) as exc:
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
        remove_checkpoint(self.path)
