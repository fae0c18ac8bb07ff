"""checkpoint.h5 and the journal it continues, without a run: the state round-trips
exactly, a damaged or incomplete file is a CorruptFileError naming it, and
ResultRecorder.resume keeps the first k records and appends after them, refusing a journal
that is not the checkpoint's."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from decrun.apps.base import Result
from decrun.errors import CorruptFileError
from decrun.runner.results import read_result
from decrun.runner.results.checkpoint import RunCheckpoint, read_checkpoint, write_checkpoint
from decrun.runner.results.recorder import ResultRecorder

STATE = {"v": np.arange(12.0).reshape(4, 3), "n": 7, "t": 0.1 + 0.2, "ok": True, "none": None,
         "nested": {"window": np.zeros((0, 2)), "growth": -np.inf, "ints": np.arange(3)}}


def same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and np.array_equal(a, b)
    return type(a) is type(b) and (a == b or a is b)


def test_the_state_round_trips_exactly(tmp_path):
    write_checkpoint(tmp_path / "c.h5", 5, STATE, {"config_hash": "abc"})
    step, state, attrs = read_checkpoint(tmp_path / "c.h5")
    assert step == 5 and attrs["config_hash"] == "abc" and same(STATE, state)


@pytest.mark.parametrize("damage", ["flip", "incomplete", "not_hdf5"])
def test_a_damaged_checkpoint_is_a_corrupt_file_error_naming_it(tmp_path, damage):
    path = tmp_path / "c.h5"
    write_checkpoint(path, 5, STATE, {"config_hash": "abc"})
    if damage == "flip":
        with h5py.File(path, "r+") as f:
            f["v"][0, 0] = 99.0
    elif damage == "incomplete":
        with h5py.File(path, "r+") as f:
            f.attrs["complete"] = False
    else:
        path.write_bytes(b"not an hdf5 file")
    with pytest.raises(CorruptFileError, match=str(path)):
        read_checkpoint(path)


def recorder(path, vertices):
    return ResultRecorder(path, vertices=vertices, simplices=np.array([[0, 1, 2]]), config_yaml="a: 1")


def test_the_recorder_continues_the_journal_after_the_checkpoints_records(tmp_path):
    vertices = np.eye(3)
    path = tmp_path / "result.h5"
    logged = []
    first = recorder(path, vertices)
    checkpoint = RunCheckpoint(tmp_path / "checkpoint.h5", "hash", recorder=first, log=logged.append)
    for step in range(4):
        first.record(step, x=float(step), w=np.full(3, step))
    checkpoint.save(3, {"k": 3})
    first.record(4, x=-1.0, w=np.full(3, -1))  # after the checkpoint: dropped on resume
    first.abort("interrupted", "SIGTERM")  # keeps the journal: a checkpoint refers to it
    assert first.journal_path.exists() and path.exists()

    second = recorder(path, vertices)
    resumed = RunCheckpoint(tmp_path / "checkpoint.h5", "hash", recorder=second, log=logged.append).load()
    assert resumed == (3, {"k": 3}) and not path.exists()  # the stale incomplete result is gone
    for step in (4, 5):
        second.record(step, x=float(step), w=np.full(3, step))
    second.finish(Result())
    series = read_result(path).series
    assert list(series["step"]) == [0, 1, 2, 3, 4, 5] and list(series["x"]) == [0, 1, 2, 3, 4, 5]
    assert not second.journal_path.exists()


def test_a_checkpoint_whose_journal_is_another_is_not_used(tmp_path):
    vertices = np.eye(3)
    first = recorder(tmp_path / "result.h5", vertices)
    checkpoint = RunCheckpoint(tmp_path / "checkpoint.h5", "hash", recorder=first)
    first.record(0, x=0.0)
    checkpoint.save(1, {"k": 1})
    logged = []
    other = recorder(tmp_path / "result.h5", vertices + 1.0)  # another mesh
    assert RunCheckpoint(tmp_path / "checkpoint.h5", "hash", recorder=other, log=logged.append).load() is None
    assert "no whole journal to continue" in logged[0] and "mesh/vertices differs" in logged[0]
    foreign = RunCheckpoint(tmp_path / "checkpoint.h5", "other", recorder=recorder(tmp_path / "r.h5", vertices),
                            log=logged.append)
    assert foreign.load() is None and "written by another config" in logged[1]
