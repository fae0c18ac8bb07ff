"""checkpoint.h5 and the journal it continues, without a run: the state round-trips
exactly, a damaged or incomplete file is a CorruptFileError naming it, and
ResultRecorder.resume keeps the first k records and appends after them, refusing a journal
that is not the checkpoint's."""

from __future__ import annotations

import subprocess
import sys

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


# ---------------------------------------------------------------------------------------
# issue 34 item 1: a checkpoint is hostile until checked, and its state is checked against
# the run (the stepper's fresh state, the run's steps) before anything is changed
# ---------------------------------------------------------------------------------------

class Walk:
    """A stepper of a (4, 3) state that grows by 1 a step, with a history of the steps."""

    record_divergent_step = False
    state_variable = ("history",)

    def __init__(self):
        self.x, self.n, self.history = np.zeros((4, 3)), 0, np.zeros(1)

    def values(self):
        return {"total": float(self.x.sum())}

    def step(self, n):
        self.x, self.n, self.history = self.x + 1.0, n, np.append(self.history, float(n))
        return ""

    def state_dict(self):
        return {"x": self.x, "n": self.n, "history": self.history, "diag": {"t": 0.5}}

    def load_state(self, state):
        self.x, self.n, self.history = np.array(state["x"]), int(state["n"]), np.array(state["history"])


def walk_state(step=3, **changes):
    stepper = {"x": np.full((4, 3), float(step)), "n": step, "history": np.arange(step + 1.0), "diag": {"t": 0.5}}
    driver = {"seconds": 0.25, "step_seconds_max": 0.1}
    for key, value in changes.items():
        group, name = key.split("__")
        target = stepper if group == "stepper" else driver
        if value is None:
            del target[name]
        else:
            target[name] = value
    return {"stepper": stepper, "driver": driver}


def resume_walk(path, logged):
    from decrun.methods.stepping import run_steps

    stepper = Walk()
    report = run_steps(stepper, 10, checkpoint=RunCheckpoint(path, "hash", log=logged.append))
    return stepper, report


def test_a_checkpoint_of_this_run_is_continued(tmp_path):
    path, logged = tmp_path / "checkpoint.h5", []
    write_checkpoint(path, 3, walk_state(), {"config_hash": "hash"})
    stepper, report = resume_walk(path, logged)
    assert report.resumed_from_step == 3 and np.array_equal(stepper.x, np.full((4, 3), 10.0))
    assert list(stepper.history) == list(range(11)) and logged == [f"checkpoint: continuing from step 3 ({path})"]


@pytest.mark.parametrize("step, changes, reason", [
    (-1, {}, "step -1 is outside [0, 10] (this run has 10 steps)"),
    (11, {}, "step 11 is outside [0, 10] (this run has 10 steps)"),
    (3, {"stepper__x": np.zeros((5, 3))}, "stepper.x has shape (5, 3), this run's has (4, 3)"),
    (3, {"stepper__x": np.zeros((4, 3), dtype=np.float32)}, "stepper.x has dtype float32, this run's has float64"),
    (3, {"stepper__x": np.array([[np.nan, 0, 0]] * 4)}, "stepper.x holds 4 non-finite values"),
    (3, {"stepper__n": None}, "stepper.n is missing"),
    (3, {"stepper__n": 3.5}, "stepper.n is a float, not an int"),
    (3, {"stepper__y": np.zeros(3)}, "stepper.y is not part of this run's state"),
    (3, {"stepper__diag": 1}, "stepper.diag is an int, not a group"),
    (3, {"stepper__history": np.zeros((4, 2))}, "stepper.history has shape (4, 2), this run's has (1,)"),
    (3, {"driver__seconds": -1.0}, "driver.seconds is -1.0, not a time in seconds"),
], ids=["negative step", "beyond the steps", "shape", "dtype", "NaN", "missing key", "float for int", "extra key",
        "leaf for group", "history of another shape", "negative seconds"])
def test_a_checkpoint_that_is_not_a_state_of_this_run_is_not_used(tmp_path, step, changes, reason):
    """The checksum is valid (write_checkpoint recomputes it, as anyone can): the state is
    still checked against the run, and the run starts from step 0 with one log line."""
    path, logged = tmp_path / "checkpoint.h5", []
    write_checkpoint(path, step, walk_state(**changes), {"config_hash": "hash"})
    stepper, report = resume_walk(path, logged)
    assert report.resumed_from_step is None and np.array_equal(stepper.x, np.full((4, 3), 10.0))
    assert logged == [f"checkpoint: {path}: {reason}; not a state of this run, not trusted: the run starts from step 0"]


def forge(path, build, **attrs):
    """A checkpoint file made by hand: ``build(file)`` adds its members, then valid root
    attributes (the checksum of what it holds recomputed) updated with ``attrs``."""
    from decrun.runner.results.checkpoint import FORMAT, _digest

    with h5py.File(path, "w") as f:
        build(f)
        leaves = []
        f.visititems(lambda name, node: leaves.append((name, str(node.attrs.get("kind")), node[()]))
                     if isinstance(node, h5py.Dataset) and not node.external and node.size < 1000 else None)
        f.attrs.update({"format": FORMAT, "step": 3, "sha256": _digest(sorted(leaves, key=lambda leaf: leaf[0])),
                        "config_hash": "hash", "records": 0, "journal_created": "", "complete": True, **attrs})


def external_storage(f, outside):
    outside.write_bytes(np.arange(12.0).tobytes())
    f.create_dataset("stepper/x", shape=(4, 3), dtype="f8", external=[(str(outside), 0, 96)]).attrs["kind"] = "array"


def huge(f, outside):  # declares 2.4 TB, stores nothing
    f.create_dataset("stepper/x", shape=(10 ** 11, 3), dtype="f8", chunks=(1024, 3)).attrs["kind"] = "array"


def scalar_kind_of_an_array(f, outside):
    f.create_dataset("stepper/n", data=np.arange(3)).attrs["kind"] = "int"


def unknown_kind(f, outside):
    f.create_dataset("stepper/n", data=np.int64(3)).attrs["kind"] = "pickle"


def text(f, outside):
    f.create_dataset("stepper/n", data=np.bytes_(b"3")).attrs["kind"] = "int"


def soft_link(f, outside):
    f.create_dataset("stepper/n", data=np.int64(3)).attrs["kind"] = "int"
    f["stepper/m"] = h5py.SoftLink("/stepper/n")


@pytest.mark.parametrize("build, attrs, says", [
    (external_storage, {}, "dataset /stepper/x keeps its data in another file"),
    (huge, {}, "dataset /stepper/x claims shape (100000000000, 3) (2.4e+03 GB)"),
    (scalar_kind_of_an_array, {}, "dataset /stepper/n (int64, shape (3,), kind 'int') is not a leaf decrun writes"),
    (unknown_kind, {}, "kind 'pickle') is not a leaf decrun writes"),
    (text, {}, "dataset /stepper/n (|S1, shape (), kind 'int') is not a leaf decrun writes"),
    (soft_link, {}, "/stepper/m is a soft link; refused"),
    (scalar_kind_of_an_array, {"step": "3"}, "its step attribute is '3', not an integer"),
    (scalar_kind_of_an_array, {"step": 3.0}, "its step attribute is '3.0', not an integer"),
], ids=["external storage", "2 TB shape", "scalar kind of an array", "unknown kind", "text", "soft link",
        "step text", "step float"])
def test_a_hostile_checkpoint_is_refused_naming_it_before_its_data_is_read(tmp_path, build, attrs, says):
    path, logged = tmp_path / "checkpoint.h5", []
    forge(path, lambda f: build(f, tmp_path.parent / "outside.bin"), **attrs)
    with pytest.raises(CorruptFileError) as info:
        read_checkpoint(path)
    assert str(info.value).startswith(f"{path}: ") and says in str(info.value), str(info.value)
    stepper, report = resume_walk(path, logged)
    assert report.resumed_from_step is None and np.array_equal(stepper.x, np.full((4, 3), 10.0))
    assert len(logged) == 1 and logged[0].startswith(f"checkpoint: {path}: ") and says in logged[0]
    assert logged[0].endswith("not trusted: the run starts from step 0")


def test_records_that_are_not_a_count_are_not_used_and_the_journal_is_untouched(tmp_path):
    vertices = np.eye(3)
    first = recorder(tmp_path / "result.h5", vertices)
    first.record(0, x=0.0)
    RunCheckpoint(tmp_path / "checkpoint.h5", "hash", recorder=first).save(1, {"k": 1})
    first.abort("interrupted", "SIGTERM")
    step, state, attrs = read_checkpoint(tmp_path / "checkpoint.h5")
    write_checkpoint(tmp_path / "checkpoint.h5", step, state, {**attrs, "records": -1})
    journal = first.journal_path.read_bytes()
    logged = []
    second = recorder(tmp_path / "result.h5", vertices)
    assert RunCheckpoint(tmp_path / "checkpoint.h5", "hash", recorder=second, log=logged.append).load() is None
    assert logged == [f"checkpoint: {tmp_path / 'checkpoint.h5'}: its records attribute is '-1', not a count of "
                      "records; not trusted: the run starts from step 0"]
    assert first.journal_path.read_bytes() == journal and (tmp_path / "result.h5").exists()


def test_leftovers_of_a_killed_checkpoint_write_are_removed(tmp_path):
    from decrun.runner.results.checkpoint import remove_checkpoint

    path = tmp_path / "checkpoint.h5"
    leftover = tmp_path / ".checkpoint.h5.tmp-99999"  # a write SIGKILL interrupted
    leftover.write_bytes(b"\x89HDF half")
    assert RunCheckpoint(path, "hash").load() is None and not leftover.exists()
    write_checkpoint(path, 1, {"k": 1}, {"config_hash": "hash"})
    leftover.write_bytes(b"\x89HDF half")
    remove_checkpoint(path)
    assert sorted(p.name for p in tmp_path.iterdir()) == []




_FULL_DISK_DURING_CHECKPOINT = """
import os, sys, numpy as np
import decrun.runner.results.checkpoint as checkpoint_module
directory, rows = sys.argv[1], int(sys.argv[2])
path = os.path.join(directory, "checkpoint.h5")
checkpoint_module.write_checkpoint(path, 1, {"k": 1}, {"config_hash": "hash"})
if rows:  # the early free-space check passes (another process fills the disk meanwhile)
    checkpoint_module.check_free_space = lambda directory, needed: None
state = {"fluid": {name: np.random.default_rng(i).random((rows or 50_000, 3)) for i, name in enumerate("abcd")},
         "t": 0.5, "n": 7}
try:
    checkpoint_module.write_checkpoint(path, 2, state, {"config_hash": "hash"})
except OSError as error:
    print(error.errno, error.filename, error.strerror)
print(sorted(os.listdir(directory)), checkpoint_module.read_checkpoint(path)[0])
"""


@pytest.mark.parametrize("rows", [0, 11_000, 12_000, 20_000, 40_000],
                         ids=["free-space check", "full at 1.06 MB", "full at 1.15 MB", "full at 2 MB", "full at 4 MB"])
def test_a_full_disk_while_writing_a_checkpoint_is_one_error_naming_it(tiny_disk, rows):
    """HDF5 never meets the write error (with its own ENOSPC path the process may die of
    SIGSEGV at exit, hence a real process): an OSError naming checkpoint.h5, no temporary
    file, the previous checkpoint kept and the interpreter exits normally."""
    run = subprocess.run([sys.executable, "-c", _FULL_DISK_DURING_CHECKPOINT, str(tiny_disk), str(rows)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and run.stderr == "", run.stderr[-2000:]
    lines = run.stdout.splitlines()
    assert lines[0].startswith(f"28 {tiny_disk / 'checkpoint.h5'} No space left on device"), lines
    assert lines[1:] == ["['checkpoint.h5'] 1"]


def test_a_checkpoint_step_before_the_records_it_keeps_is_not_used_and_the_journal_is_untouched(tmp_path):
    """Steps 0..3 recorded, the checkpoint says step 1 with those 4 records: continuing
    would record step 2 after step 3 (record() refused it with a traceback)."""
    vertices = np.eye(3)
    first = recorder(tmp_path / "result.h5", vertices)
    checkpoint = RunCheckpoint(tmp_path / "checkpoint.h5", "hash", recorder=first)
    for step in range(4):
        first.record(step, x=float(step))
    checkpoint.save(3, {"k": 3})
    first.abort("interrupted", "SIGTERM")
    _, state, attrs = read_checkpoint(tmp_path / "checkpoint.h5")
    write_checkpoint(tmp_path / "checkpoint.h5", 1, state, attrs)
    journal, logged = first.journal_path.read_bytes(), []
    second = recorder(tmp_path / "result.h5", vertices)
    assert RunCheckpoint(tmp_path / "checkpoint.h5", "hash", recorder=second, log=logged.append).load() is None
    assert len(logged) == 1 and "record 4 is of step 3, after the checkpoint's step 1" in logged[0], logged
    assert logged[0].endswith("not used: the run starts from step 0")
    assert first.journal_path.read_bytes() == journal and (tmp_path / "result.h5").exists()
