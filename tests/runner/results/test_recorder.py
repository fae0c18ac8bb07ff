"""decrun.runner.results.recorder: per-step series streamed to disk, never corrupt after a kill.

The central test kills a recording process with SIGKILL at random moments and checks
that what is left is either nothing, the complete result, or a readable incomplete
result whose every series holds exactly the steps written so far.
"""

from __future__ import annotations

import errno
import multiprocessing
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from decrun.apps.base import Result
from decrun.complex import SimplicialComplex
from decrun.dec import DEC
from decrun.errors import DecrunError
from decrun.runner.results import journal as journal_module
from decrun.runner.results import read_provenance, read_result, write_result
from decrun.runner.results.journal import journal_path, read_journal
from decrun.runner.results.recorder import ResultRecorder, ResultWriteError, recover_result

VERTICES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.5, 0.2]])
TRIANGLES = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])


def row(step: int, size: int) -> np.ndarray:
    """The array recorded at ``step`` (distinct per step, so a mix-up is visible)."""
    return np.sin(0.001 * np.arange(size) + step)


def record_steps(recorder: ResultRecorder, steps, size: int) -> None:
    for i in steps:
        recorder.record(i, energy=0.5 * i, vorticity=row(i, size), count=np.int32(i), flag=i % 3 == 0)


def assert_series_are_steps(series: dict, n: int, size: int) -> None:
    """Every series has exactly n records and equals what was recorded for steps 0..n-1."""
    assert {name: len(a) for name, a in series.items()} == dict.fromkeys(("step", "energy", "vorticity", "count", "flag"), n)
    np.testing.assert_array_equal(series["step"], np.arange(n))
    np.testing.assert_array_equal(series["energy"], 0.5 * np.arange(n))
    np.testing.assert_array_equal(series["count"], np.arange(n, dtype=np.int32))
    np.testing.assert_array_equal(series["flag"], np.arange(n) % 3 == 0)
    expected = np.sin(0.001 * np.arange(size)[None, :] + np.arange(n)[:, None])
    np.testing.assert_array_equal(series["vorticity"], expected.reshape(n, size))
    assert series["count"].dtype == np.int32 and series["flag"].dtype == np.bool_


def files_in(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir())


# ----------------------------------------------------------------------------------
# complete runs
# ----------------------------------------------------------------------------------


def test_a_finished_run_round_trips_exactly(tmp_path):
    path = tmp_path / "result.h5"
    fields = {"vertices_final": VERTICES * 2, "labels": np.arange(4, dtype=np.int16)}
    with ResultRecorder(path, vertices=VERTICES, simplices=TRIANGLES, config_yaml="app:\n  dt: 0.1\n",
                        mesh_hash="abc", attrs={"seed": 7}) as recorder:
        record_steps(recorder, range(40), 300)
        assert files_in(tmp_path) == ["result.h5.partial"]
        recorder.finish(Result(fields=fields, series={"residual": np.geomspace(1, 1e-9, 5)},
                               metrics={"stable": True, "energy_drift_rel": 1e-12}), {"app_seconds": 2.5})
    assert files_in(tmp_path) == ["result.h5"]
    back = read_result(path)
    assert back.complete and back.status == "ok" and back.steps_recorded == 40 and back.error == ""
    assert_series_are_steps({k: v for k, v in back.series.items() if k != "residual"}, 40, 300)
    np.testing.assert_array_equal(back.series["residual"], np.geomspace(1, 1e-9, 5))
    for name, array in fields.items():
        np.testing.assert_array_equal(back.fields[name], array)
        assert back.fields[name].dtype == array.dtype
    np.testing.assert_array_equal(back.mesh["vertices"], VERTICES)
    np.testing.assert_array_equal(back.mesh["simplices"], TRIANGLES)
    assert back.metrics == {"stable": True, "energy_drift_rel": 1e-12}
    # the existing reader and provenance reader see the same file
    assert read_result(path).metrics == back.metrics
    provenance = read_provenance(path)
    assert provenance["timings"] == {"app_seconds": 2.5} and provenance["seed"] == 7
    assert provenance["mesh_hash"] == "abc" and provenance["config_yaml"] == "app:\n  dt: 0.1\n"
    with h5py.File(path) as f:  # the streaming layout: chunked, growable along the record axis
        assert f["series/vorticity"].maxshape == (None, 300) and f["series/vorticity"].chunks is not None
        assert f["series/step"].maxshape == (None,)


def test_write_result_has_the_recorder_layout_and_attributes(tmp_path):
    result = Result(fields={"u": np.linspace(0, 1, 5000)}, series={"area": np.array([1.0, 0.9])},
                    metrics={"stable": False, "diverged_at_step": 3}, figures={"plot": None})
    old = write_result(tmp_path / "old.h5", result, vertices=VERTICES, simplices=TRIANGLES, config_yaml="a: 1\n",
                       mesh_hash="m", timings={"app_seconds": 1.0})
    new = ResultRecorder(tmp_path / "new.h5", vertices=VERTICES, simplices=TRIANGLES, config_yaml="a: 1\n",
                         mesh_hash="m").finish(result, {"app_seconds": 1.0})

    def layout(path):
        with h5py.File(path) as f:
            names = []
            f.visit(names.append)
            return set(f.attrs), {n: (f[n].shape, f[n].dtype) if isinstance(f[n], h5py.Dataset) else None for n in names}

    old_attrs, old_objects = layout(old)
    new_attrs, new_objects = layout(new)
    assert new_objects == old_objects
    assert new_attrs == old_attrs  # write_result is a recorder with no recorded steps
    assert {"complete", "status", "steps_recorded", "finished", "config_yaml", "mesh_hash", "metrics_json",
            "timings_json", "figures", "format", "decrun_version", "numpy_version"} <= new_attrs
    a, b = read_result(old), read_result(new)
    assert a.metrics == b.metrics and a.fields.keys() == b.fields.keys()
    np.testing.assert_array_equal(a.fields["u"], b.fields["u"])
    assert read_provenance(new)["figures"] == read_provenance(old)["figures"] == '["plot"]'
    # files written by write_result are complete by construction and read as such
    assert read_result(old).complete and read_result(old).status == "ok"


def test_a_one_form_field_names_its_edge_list(tmp_path):
    """A 1-form df = d0 f stored with forms={"df": 1}: reading mesh/edges back and
    differencing f along each (low → high) edge must reproduce it exactly (Stokes on an edge)."""
    complex_ = SimplicialComplex(VERTICES, TRIANGLES)
    f0 = VERTICES[:, 0] ** 2 + 3 * VERTICES[:, 1]
    df = DEC(complex_).d(0) @ f0
    recorder = ResultRecorder(tmp_path / "result.h5", vertices=VERTICES, simplices=TRIANGLES, edges=complex_.simplices(1))
    with pytest.raises(ValueError, match="'f0'.*mesh/edges has 8 rows"):
        recorder.finish(Result(fields={"f0": f0}), forms={"f0": 1})
    assert files_in(tmp_path) == []
    recorder.finish(Result(fields={"df": df, "f0": f0}), forms={"df": 1, "f0": 0})
    back = read_result(tmp_path / "result.h5")
    assert back.field_on == {"df": "mesh/edges", "f0": "mesh/vertices"}
    with h5py.File(tmp_path / "result.h5") as f:
        edges = f[f["fields/df"].attrs["on"]][()]
        assert f["fields/df"].attrs["form_degree"] == 1
    np.testing.assert_array_equal(edges, complex_.simplices(1))
    np.testing.assert_allclose(back.fields["df"], f0[edges[:, 1]] - f0[edges[:, 0]], rtol=0, atol=1e-15)


# ----------------------------------------------------------------------------------
# crash semantics
# ----------------------------------------------------------------------------------

KILL_STEPS, KILL_SIZE = 1000, 500


def _recording_process(path: str) -> None:
    recorder = ResultRecorder(path, vertices=VERTICES, simplices=TRIANGLES, config_yaml="kill: true\n", mesh_hash="k")
    record_steps(recorder, range(KILL_STEPS), KILL_SIZE)
    recorder.finish(Result(fields={"final": row(KILL_STEPS, KILL_SIZE)}, metrics={"steps": KILL_STEPS}))


def _check_what_a_kill_left(path: Path) -> str:
    """'absent' | 'complete' | 'partial:<k>'; fails unless the state is one of these,
    fully consistent."""
    if not path.exists() and not journal_path(path).exists():
        assert recover_result(path) is None and files_in(path.parent) == []  # temporaries tidied
        return "absent"
    back = read_result(path)
    if back.complete:
        assert path.exists() and back.status == "ok" and back.steps_recorded == KILL_STEPS
        assert_series_are_steps(back.series, KILL_STEPS, KILL_SIZE)
        np.testing.assert_array_equal(back.fields["final"], row(KILL_STEPS, KILL_SIZE))
        assert recover_result(path) is None and files_in(path.parent) == ["result.h5"]
        return "complete"
    assert not path.exists() and back.status == "unfinished"
    k = back.steps_recorded
    assert_series_are_steps(back.series, k, KILL_SIZE)
    np.testing.assert_array_equal(back.mesh["vertices"], VERTICES)
    assert back.provenance["config_yaml"] == "kill: true\n"
    # the leftover journal converts to an HDF5 file marked incomplete, same steps
    assert recover_result(path) == path and files_in(path.parent) == ["result.h5"]
    again = read_result(path)
    assert not again.complete and again.status == "killed" and again.steps_recorded == k
    assert_series_are_steps(again.series, k, KILL_SIZE)
    return f"partial:{k}"


def test_sigkill_at_random_moments_leaves_nothing_or_a_consistent_file(tmp_path):
    fork = multiprocessing.get_context("fork")
    start = time.perf_counter()
    (tmp_path / "whole").mkdir()
    whole = fork.Process(target=_recording_process, args=(str(tmp_path / "whole" / "result.h5"),))
    whole.start()
    whole.join()
    duration = time.perf_counter() - start
    assert whole.exitcode == 0 and _check_what_a_kill_left(tmp_path / "whole" / "result.h5") == "complete"
    rng = random.Random(12345)
    outcomes = []
    for trial in range(20):
        path = tmp_path / f"run{trial}" / "result.h5"
        path.parent.mkdir()
        process = fork.Process(target=_recording_process, args=(str(path),))
        process.start()
        time.sleep(rng.uniform(0.0, 1.1 * duration))
        os.kill(process.pid, signal.SIGKILL)
        process.join()
        outcomes.append(_check_what_a_kill_left(path))
    partial = [o for o in outcomes if o.startswith("partial:") and o != "partial:0"]
    assert len(partial) >= 3, f"too few kills landed mid-run to test anything: {outcomes}"


def test_a_torn_or_damaged_tail_is_dropped(tmp_path):
    path = tmp_path / "result.h5"
    recorder = ResultRecorder(path)
    record_steps(recorder, range(10), 50)
    recorder._journal.close()  # a killed writer: no finish(), no abort()
    partial = journal_path(path)
    with open(partial, "ab") as f:  # half a record, as a kill inside writev leaves it
        f.write(b"\x01" * (read_journal(partial).record_size // 2))
    assert_series_are_steps(read_result(path).series, 10, 50)
    # a damaged byte inside record 6 (e.g. a torn page after a power cut): the checksum
    # stops the valid prefix there
    journal = read_journal(partial)
    with open(partial, "r+b") as f:
        f.seek(journal.data_offset + 6 * journal.record_size + 100)
        byte = f.read(1)
        f.seek(-1, os.SEEK_CUR)
        f.write(bytes([byte[0] ^ 0xFF]))
    assert read_journal(partial).n_records == 6
    assert_series_are_steps(read_result(path).series, 6, 50)


def test_an_exception_keeps_the_steps_and_removes_temporaries(tmp_path):
    path = tmp_path / "result.h5"
    with pytest.raises(ZeroDivisionError):
        with ResultRecorder(path, vertices=VERTICES, simplices=TRIANGLES) as recorder:
            record_steps(recorder, range(7), 20)
            raise ZeroDivisionError("division by zero")
    assert files_in(tmp_path) == ["result.h5"]
    back = read_result(path)
    assert not back.complete and back.status == "failed" and back.steps_recorded == 7
    assert back.error == "ZeroDivisionError: division by zero" and back.metrics["status"] == "failed"
    assert_series_are_steps(back.series, 7, 20)

    with pytest.raises(KeyboardInterrupt):
        with ResultRecorder(path) as recorder:
            record_steps(recorder, range(3), 20)
            raise KeyboardInterrupt
    back = read_result(path)
    assert (back.status, back.steps_recorded, back.complete) == ("interrupted", 3, False)
    assert files_in(tmp_path) == ["result.h5"]


def test_an_error_before_any_step_leaves_no_file(tmp_path):
    with pytest.raises(DecrunError, match="bad input"):
        with ResultRecorder(tmp_path / "result.h5", vertices=VERTICES, simplices=TRIANGLES):
            raise DecrunError("bad input")
    assert files_in(tmp_path) == []


def test_a_failing_finish_leaves_an_incomplete_file_and_no_temporary(tmp_path):
    path = tmp_path / "result.h5"
    with pytest.raises(TypeError, match=r"fields\['bad'\] is not a numeric array"):
        with ResultRecorder(path) as recorder:
            record_steps(recorder, range(5), 20)
            recorder.finish(Result(fields={"ok": np.zeros(3), "bad": np.array([object()], dtype=object)}))
    assert files_in(tmp_path) == ["result.h5"]
    back = read_result(path)
    assert back.status == "failed" and back.error == "TypeError: Result.fields['bad'] is not a numeric array"
    assert_series_are_steps(back.series, 5, 20)


# ----------------------------------------------------------------------------------
# record() rules
# ----------------------------------------------------------------------------------


def test_the_first_record_fixes_keys_shapes_and_dtypes(tmp_path):
    recorder = ResultRecorder(tmp_path / "result.h5")
    recorder.record(0, energy=1.0, w=np.zeros(4), n=np.int32(1))
    bad_calls = [
        (dict(energy=1.0, w=np.zeros(5), n=np.int32(1)), ValueError, r"'w' has shape \(5,\).*fixed \(4,\)"),
        (dict(energy=1.0, w=np.zeros(4), n=1.5), TypeError, r"'n' has dtype float64.*int32"),
        (dict(energy=1.0, w=np.zeros(4)), ValueError, r"missing \['n'\]"),
        (dict(energy=1.0, w=np.zeros(4), n=np.int32(1), extra=2), ValueError, r"unexpected \['extra'\]"),
        (dict(energy="high", w=np.zeros(4), n=np.int32(1)), TypeError, r"'energy' must be a number"),
    ]
    for values, error, message in bad_calls:
        with pytest.raises(error, match=message):
            recorder.record(1, **values)
    with pytest.raises(ValueError, match="step 0 does not follow step 0"):
        recorder.record(0, energy=1.0, w=np.zeros(4), n=np.int32(1))
    recorder.record(1, n=np.int16(2), w=np.ones(4), energy=np.float32(0.5))  # safe casts, any key order
    assert recorder.steps_recorded == 2  # the rejected calls wrote nothing
    back = read_result(tmp_path / "result.h5")
    np.testing.assert_array_equal(back.series["w"], [np.zeros(4), np.ones(4)])
    np.testing.assert_array_equal(back.series["energy"], [1.0, 0.5])
    assert back.series["n"].dtype == np.int32 and list(back.series["n"]) == [1, 2]


# ----------------------------------------------------------------------------------
# memory and disk
# ----------------------------------------------------------------------------------


def _peak_rss_reset() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")  # resets VmHWM (Linux >= 4.0)
        return True
    except OSError:
        return False


def _rss_kib(key: str) -> int:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith(key + ":"))


def test_memory_stays_flat_over_5000_steps_of_10000_floats(tmp_path):
    if not _peak_rss_reset():
        pytest.skip("needs /proc/self/clear_refs (Linux) to measure peak RSS")
    recorder = ResultRecorder(tmp_path / "result.h5")
    pool = np.random.default_rng(0).random((64, 10_000))  # incompressible rows: no gzip at finish

    def w(i):
        return pool[i % 64] + i

    recorder.record(0, w=w(0), e=0.0)
    _peak_rss_reset()
    before = _rss_kib("VmRSS")
    for i in range(1, 5000):  # 400 MB of data in total
        recorder.record(i, w=w(i), e=float(i))
    recording_growth_mib = (_rss_kib("VmHWM") - before) / 1024
    _peak_rss_reset()
    before = _rss_kib("VmRSS")
    recorder.finish(Result())
    finish_growth_mib = (_rss_kib("VmHWM") - before) / 1024
    assert recording_growth_mib < 4, recording_growth_mib
    assert finish_growth_mib < 40, finish_growth_mib  # 8 MiB copy block + its contiguous copy + HDF5 caches
    with h5py.File(tmp_path / "result.h5") as f:
        series = f["series/w"]
        assert series.shape == (5000, 10_000) and series.compression is None
        for i in (0, 1, 4321, 4999):
            np.testing.assert_array_equal(series[i], w(i))
        np.testing.assert_array_equal(f["series/e"][()], np.arange(5000.0))


def test_a_failed_append_is_truncated_away(tmp_path, monkeypatch):
    """A write that fails half-way (disk full) leaves the journal at its last whole record;
    the error is one ResultWriteError naming the file; recording can go on afterwards."""
    path = tmp_path / "result.h5"
    recorder = ResultRecorder(path)
    record_steps(recorder, range(4), 100)
    real_writev = os.writev

    def half_then_full(fd, parts):
        data = b"".join(bytes(p) for p in parts)
        os.write(fd, data[: len(data) // 2])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(journal_module.os, "writev", half_then_full)
    with pytest.raises(ResultWriteError, match=r"cannot write .*result.h5.partial: No space left on device; "
                                               r"step 4 was not recorded; the 4 steps before it are kept") as info:
        record_steps(recorder, [4], 100)
    assert isinstance(info.value, OSError) and info.value.errno == errno.ENOSPC
    assert_series_are_steps(read_result(path).series, 4, 100)
    monkeypatch.setattr(journal_module.os, "writev", real_writev)
    record_steps(recorder, range(4, 9), 100)
    recorder.finish(Result())
    assert_series_are_steps(read_result(path).series, 9, 100)




def test_a_full_disk_is_one_clear_error_and_leaves_nothing_corrupt(tiny_disk):
    # 1: the disk fills while recording (8 kB records on a 1 MiB disk)
    path = tiny_disk / "a" / "result.h5"
    path.parent.mkdir()
    with pytest.raises(ResultWriteError, match="No space left on device") as info:
        with ResultRecorder(path) as recorder:
            record_steps(recorder, range(10_000), 1000)
    assert isinstance(info.value, OSError) and isinstance(info.value, DecrunError)
    # abort() could not write result.h5 either: no temporary file, the journal stays valid
    assert files_in(path.parent) == ["result.h5.partial"]
    back = read_result(path)
    assert not back.complete and 50 < back.steps_recorded < 10_000
    assert_series_are_steps(back.series, back.steps_recorded, 1000)
    journal_path(path).unlink()

    # 2: the steps fit, but result.h5 beside them does not
    path = tiny_disk / "b" / "result.h5"
    path.parent.mkdir()
    recorder = ResultRecorder(path)
    record_steps(recorder, range(75), 1000)
    with pytest.raises(ResultWriteError, match=r"cannot write .*/b/result.h5: No space left on device \(needs up to "
                                               r".* MB free\); the 75 recorded steps are kept in .*result.h5.partial"):
        recorder.finish(Result())
    assert files_in(path.parent) == ["result.h5.partial"]
    assert_series_are_steps(read_result(path).series, 75, 1000)


_FULL_DISK_DURING_HDF5_WRITE = """
import os, sys, numpy as np
import decrun.runner.results.recorder as recorder_module
from decrun.apps.base import Result
from decrun.runner.results import read_result
directory = sys.argv[1]
# the early free-space check passes (as when another process fills the disk meanwhile):
# HDF5's own writes then meet ENOSPC
recorder_module._check_free_space = lambda directory, needed: None
recorder = recorder_module.ResultRecorder(os.path.join(directory, "result.h5"))
for i in range(75):
    recorder.record(i, w=np.random.default_rng(i).random(1000))  # incompressible
try:
    recorder.finish(Result())
except recorder_module.ResultWriteError as error:
    print(error)
print(sorted(os.listdir(directory)))
back = read_result(os.path.join(directory, "result.h5"))
expected = np.array([np.random.default_rng(i).random(1000) for i in range(75)])
print(back.steps_recorded, bool((back.series["w"] == expected).all()))
"""


def test_a_disk_filling_during_the_hdf5_write_ends_cleanly(tiny_disk):
    """HDF5 never sees the write error (it is raised after HDF5 closed the file): one
    clear error, the journal kept, and a normal interpreter exit (with HDF5's own error
    path the process segfaults at exit, hence a real subprocess)."""
    run = subprocess.run([sys.executable, "-c", _FULL_DISK_DURING_HDF5_WRITE, str(tiny_disk)],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr[-2000:]
    lines = run.stdout.splitlines()
    assert lines[0].startswith("cannot write ") and lines[0].endswith(
        "result.h5: No space left on device; the 75 recorded steps are kept in " f"{tiny_disk}/result.h5.partial")
    assert lines[1:] == ["['result.h5.partial']", "75 True"]
