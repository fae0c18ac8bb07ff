"""The figure process (:mod:`decrun.runner.figure_process`): a single run's figures drawn by a
process forked at the command's start, which imports matplotlib while the run computes.

The processes forked here inherit this test's patches of the drawing function (forked after
the patch), which is how a failing, warning, slow or dying figure is made."""

from __future__ import annotations

import json
import logging
import os
import re
import signal
import threading
import time
import warnings
from pathlib import Path

import pytest

from decrun.apps.base import Figure
from decrun.runner import figure_process
from decrun.runner.figure_process import FigureProcess, FigureProcessLost, receive, send, wanted
from decrun.runner.plots import common

from cli_processes import decrun, start


@pytest.mark.parametrize("args, expected", [
    ([], True),
    (["app=heat", "mesh.subdiv=3"], True),
    (["figures=true"], True),
    (["figures=false"], False),
    (["figures=False"], False),
    (["+figures=false"], False),
    (["-m", "app.dt=1,2"], False),
    (["--multirun", "app.dt=1,2"], False),
    (["hydra.mode=MULTIRUN"], False),
    (["--cfg", "job"], False),
    (["--help"], False),
    (["--info"], False),
])
def test_a_figure_process_is_wanted_only_for_a_single_run_that_may_draw(args, expected, monkeypatch):
    """``on``: for every single run that may draw; ``auto`` (unset): the same with a core to
    spare (the last minute's load average below the cores less half a core); ``off``: never."""
    cores = len(os.sched_getaffinity(0))
    if cores < 2:
        pytest.skip("one core: the command draws in its own process")
    monkeypatch.setenv("DECRUN_FIGURE_PROCESS", "on")
    monkeypatch.setattr(os, "getloadavg", lambda: (cores + 5.0, 0.0, 0.0))
    assert wanted(args) is expected
    monkeypatch.delenv("DECRUN_FIGURE_PROCESS")
    assert wanted(args) is False  # auto on a busy machine
    monkeypatch.setattr(os, "getloadavg", lambda: (cores - 0.51, 9.0, 9.0))
    assert wanted(args) is expected  # auto with a core to spare
    monkeypatch.setattr(os, "getloadavg", lambda: (cores - 0.5, 0.0, 0.0))
    assert wanted(args) is False
    monkeypatch.setenv("DECRUN_FIGURE_PROCESS", "off")
    monkeypatch.setattr(os, "getloadavg", lambda: (0.0, 0.0, 0.0))
    assert wanted(args) is False


def test_a_setting_that_is_none_of_auto_on_off_is_one_line_naming_the_fix(tmp_path, monkeypatch):
    monkeypatch.setenv("DECRUN_FIGURE_PROCESS", "sometimes")
    refused = decrun("app.steps=1", "figures=false", cwd=tmp_path)
    assert refused.returncode == 1 and refused.stderr.strip() == (
        "error: DECRUN_FIGURE_PROCESS='sometimes': must be one of auto, on, off (or 1, 0); use DECRUN_FIGURE_PROCESS=auto")
    assert not (tmp_path / "outputs").exists()
    monkeypatch.setenv("DECRUN_FIGURE_PROCESS", "auto")
    assert decrun("app.steps=1", "figures=false", cwd=tmp_path).returncode == 0


def test_with_the_figure_process_off_the_run_draws_its_figures_itself(tmp_path):
    """``DECRUN_FIGURE_PROCESS=off``: the run's own process imports matplotlib and draws."""
    import subprocess
    import sys

    from cli_processes import env

    done = subprocess.run([sys.executable, "-X", "importtime", "-m", "decrun", "app.steps=2", "hydra.run.dir=own"],
                          cwd=tmp_path, env={**env(), "DECRUN_FIGURE_PROCESS": "off"}, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    imported = re.findall(r"^import time:\s+\d+ \|\s+\d+ \|\s*(\S+)$", done.stderr, re.M)
    assert "matplotlib" in imported and "decrun.runner.plots.common" in imported
    assert sorted(p.name for p in (tmp_path / "own").glob("*.png")) == ["smoothing.png", "smoothing_series.png"]


def test_messages_of_any_size_cross_a_pipe_whole_and_a_closed_pipe_is_eof():
    """A message larger than the pipe's buffer arrives whole (the reader drains while the writer
    writes); the writer closing before a whole message is EOFError, not a short message."""
    import numpy as np

    read, write = os.pipe()
    big = {"array": np.arange(300_000, dtype=np.float64), "text": "é" * 1000}
    got = []
    reader = threading.Thread(target=lambda: got.append(receive(read)))
    reader.start()
    send(write, big)
    reader.join(timeout=30)
    assert np.array_equal(got[0]["array"], big["array"]) and got[0]["text"] == big["text"]
    os.write(write, b"\x10\x00\x00\x00\x00\x00\x00\x00abc")  # announces 16 bytes, sends 3
    os.close(write)
    with pytest.raises(EOFError):
        receive(read)
    os.close(read)


def _figures(*names: str) -> dict:
    return {name: Figure.of_kind("series", series={"energy": [3.0, 2.0, 1.0]}) for name in names}


@pytest.fixture
def forked():
    """A figure process forked from this test (after its patches); stopped afterwards."""
    made = []

    def fork() -> FigureProcess:
        process = FigureProcess.fork()
        assert process is not None
        made.append(process)
        return process

    yield fork
    for process in made:
        process.stop()


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def test_it_draws_in_the_figures_order_each_share_in_a_process_of_its_own(tmp_path, monkeypatch, forked):
    """The written paths come back in the figures' order; with two cores the second figure is
    drawn by a process forked for it (another pid than the first's)."""
    if len(os.sched_getaffinity(0)) < 2:
        pytest.skip("one core: one process draws them all")

    def draw_figures(figures, out_dir, K=None, series=None):
        [name] = figures
        path = out_dir / f"{name}.png"
        path.write_text(str(os.getpid()))
        return [path]

    monkeypatch.setattr(common, "draw_figures", draw_figures)
    process = forked()
    written = process.draw(_figures("first", "second", "third"), tmp_path, None)
    assert [p.name for p in written] == ["first.png", "second.png", "third.png"]
    pids = {p.stem: p.read_text() for p in written}
    assert pids["first"] == pids["third"] != pids["second"] and str(os.getpid()) not in pids.values()
    # it serves the next job too; through draw(), a run directory named relatively gives its paths so
    monkeypatch.setattr(figure_process, "_current", process)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "run").mkdir()
    assert figure_process.draw(_figures("again"), Path("run"), None) == [Path("run") / "again.png"]
    assert (tmp_path / "run" / "again.png").is_file()


def test_a_failing_figure_is_the_same_error_with_its_cause(tmp_path, monkeypatch, forked):
    """The first figure (in the figures' order) that fails is raised in the run as it was raised:
    its type, message, file names and its cause linked again; the traceback from the figure
    process is a note."""

    def draw_figures(figures, out_dir, K=None, series=None):
        [name] = figures
        if name == "good":
            (out_dir / "good.png").write_text("drawn")
            return [out_dir / "good.png"]
        try:
            raise ValueError(f"bad data in {name}")
        except ValueError as cause:
            raise IsADirectoryError(21, "Is a directory", f".{name}.png.tmp", None, f"{name}.png") from cause

    monkeypatch.setattr(common, "draw_figures", draw_figures)
    process = forked()
    with pytest.raises(IsADirectoryError) as raised:
        process.draw(_figures("good", "broken", "worse"), tmp_path, None)
    assert raised.value.filename2 == "broken.png" and raised.value.strerror == "Is a directory"
    assert isinstance(raised.value.__cause__, ValueError) and str(raised.value.__cause__) == "bad data in broken"
    assert any("figure process" in note and "bad data in broken" in note for note in raised.value.__notes__)
    assert (tmp_path / "good.png").read_text() == "drawn"


def test_its_warnings_and_log_records_reach_the_run(tmp_path, monkeypatch, forked, caplog):
    def draw_figures(figures, out_dir, K=None, series=None):
        warnings.warn("a figure's warning", UserWarning, stacklevel=1)
        logging.getLogger("matplotlib.font_manager").warning("font not found: %s", "Nope Sans")
        logging.getLogger("matplotlib").info("an info record stays there")
        (out_dir / "w.png").write_text("drawn")
        return [out_dir / "w.png"]

    monkeypatch.setattr(common, "draw_figures", draw_figures)
    process = forked()
    with caplog.at_level(logging.INFO), pytest.warns(UserWarning, match="a figure's warning"):
        process.draw(_figures("w"), tmp_path, None)
    records = [(r.name, r.levelno, r.getMessage()) for r in caplog.records]
    assert ("matplotlib.font_manager", logging.WARNING, "font not found: Nope Sans") in records
    assert not [r for r in records if "info record" in r[2]]


def test_an_interrupt_of_the_run_stops_it_and_leaves_no_temporary_file(tmp_path, monkeypatch, forked):
    """Ctrl-C (or SIGTERM) in the run while it waits: the figure process and the processes it
    forked are stopped and gone before the interrupt goes on, their temporary files removed."""

    def draw_figures(figures, out_dir, K=None, series=None):
        [name] = figures
        (out_dir / f"started-{name}").write_text(str(os.getpid()))
        temporary = out_dir / f".{name}.png.tmp-{os.getpid()}"
        temporary.write_text("half")
        try:
            time.sleep(60)
        finally:
            temporary.unlink()
        return []

    monkeypatch.setattr(common, "draw_figures", draw_figures)
    process = forked()
    # both figures at once with two cores (one process each), else the first only
    expected = ["started-slow", "started-slower"] if len(os.sched_getaffinity(0)) >= 2 else ["started-slow"]

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    signalled = []

    def interrupt_once_drawing():  # however loaded the machine: once every expected figure is being drawn
        deadline = time.monotonic() + 120
        while not all((tmp_path / name).exists() for name in expected) and time.monotonic() < deadline:
            time.sleep(0.01)
        signalled.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGALRM)

    previous = signal.signal(signal.SIGALRM, interrupt)
    watcher = threading.Thread(target=interrupt_once_drawing, daemon=True)
    try:
        watcher.start()
        with pytest.raises(KeyboardInterrupt):
            process.draw(_figures("slow", "slower"), tmp_path, None)
        returned = time.monotonic()
    finally:
        watcher.join(timeout=130)
        signal.signal(signal.SIGALRM, previous)
    # SIGTERM's clean-up ended it (stop() would SIGKILL after 10 s), and it was reaped before the interrupt went on
    assert returned - signalled[0] < 9
    assert _gone(process.pid) and not process.alive
    # the figures being drawn (in two processes with two cores) are stopped: their temporaries are gone
    assert sorted(p.name for p in tmp_path.iterdir()) == expected
    assert all(_gone(int((tmp_path / name).read_text())) for name in expected)


def test_a_figure_process_that_dies_is_reported_not_waited_for(tmp_path, monkeypatch, forked):
    def draw_figures(figures, out_dir, K=None, series=None):
        os._exit(3)

    monkeypatch.setattr(common, "draw_figures", draw_figures)
    process = forked()
    with pytest.raises(FigureProcessLost, match=r"ended without an answer \(exit code 3\)"):
        process.draw(_figures("dies"), tmp_path, None)
    assert _gone(process.pid)
    # reaped once: stopping or closing again signals no process and closes no descriptor
    assert process.stop() == "exit code 3" and process.close() is None and process.ended == "exit code 3"


def test_a_figures_process_that_dies_is_that_figures_error(tmp_path, monkeypatch, forked):
    """With two cores the second figure is drawn by a process of its own: when it dies the
    answer names it and how it ended; the first figure is drawn."""
    if len(os.sched_getaffinity(0)) < 2:
        pytest.skip("one core: one process draws them all")

    def draw_figures(figures, out_dir, K=None, series=None):
        [name] = figures
        if name == "second":
            os._exit(3)
        (out_dir / f"{name}.png").write_text("drawn")
        return [out_dir / f"{name}.png"]

    monkeypatch.setattr(common, "draw_figures", draw_figures)
    process = forked()
    with pytest.raises(FigureProcessLost, match=r"^drawing second ended \(exit code 3\)$"):
        process.draw(_figures("first", "second"), tmp_path, None)
    assert (tmp_path / "first.png").read_text() == "drawn" and process.alive


def test_a_figure_process_gone_before_the_job_leaves_the_drawing_to_the_run(tmp_path, forked):
    process = forked()
    os.kill(process.pid, signal.SIGKILL)
    os.waitpid(process.pid, 0)
    assert process.draw(_figures("any"), tmp_path, None) is None and not process.alive
    assert list(tmp_path.iterdir()) == []


def test_a_plugins_drawing_function_or_a_large_mesh_is_drawn_by_the_run(tmp_path, monkeypatch, forked):
    """draw() answers None (the run draws) for a drawing function outside decrun's plots (it may
    rely on the run's process) and for a mesh above MAX_TOP_SIMPLICES, without sending a job."""
    from decrun.core.complex import SimplicialComplex
    from decrun.core.primitives import grid_triangles

    process = forked()
    monkeypatch.setattr(figure_process, "_current", process)
    sent = []
    monkeypatch.setattr(FigureProcess, "draw", lambda self, *a: sent.append(a) or [])
    K = SimplicialComplex(*grid_triangles(3))
    assert figure_process.draw({"mine": Figure("my_plugin.plots.draw", {})}, tmp_path, K) is None
    monkeypatch.setattr(figure_process, "MAX_TOP_SIMPLICES", K.num_simplices(2) - 1)
    assert figure_process.draw(_figures("series"), tmp_path, K) is None
    assert sent == []
    monkeypatch.setattr(figure_process, "MAX_TOP_SIMPLICES", K.num_simplices(2))
    assert figure_process.draw(_figures("series"), tmp_path, K) == [] and len(sent) == 1


def test_the_command_draws_the_same_figures_as_a_run_in_one_process(tmp_path, monkeypatch):
    """``decrun`` (its figure process draws) and ``decrun.run`` (the run's own process draws)
    write byte-identical PNGs of the same result."""
    import decrun as api

    monkeypatch.setenv("DECRUN_FIGURE_PROCESS", "on")
    done = decrun("app.steps=3", "hydra.run.dir=forked", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    monkeypatch.chdir(tmp_path)
    api.run(["app.steps=3"], dir=tmp_path / "here")
    for name in ("smoothing.png", "smoothing_series.png"):
        assert (tmp_path / "forked" / name).read_bytes() == (tmp_path / "here" / name).read_bytes(), name
    forked = json.loads((tmp_path / "forked" / "metrics.json").read_text())
    here = json.loads((tmp_path / "here" / "metrics.json").read_text())
    assert forked["result_h5"]["content_sha256"] == here["result_h5"]["content_sha256"]


def _children(pid: int) -> list[int]:
    path = f"/proc/{pid}/task/{pid}/children"
    try:
        return [int(p) for p in open(path).read().split()]
    except OSError:
        return []


@pytest.mark.skipif(not os.path.exists(f"/proc/{os.getpid()}/task/{os.getpid()}/children")
                    or len(os.sched_getaffinity(0)) < 2,
                    reason="needs /proc/<pid>/task/<pid>/children to find the figure process, and two cores")
def test_a_killed_figure_process_loses_the_figures_not_the_result(tmp_path, monkeypatch):
    """The figure process killed while it draws (the fluid's animation takes a while): the run
    keeps result.h5 and metrics.json (with ``figures_error``), says so in one line naming
    ``figures=false``, and exits 1."""
    monkeypatch.setenv("DECRUN_FIGURE_PROCESS", "on")
    proc = start("app=fluid", "app.steps=60", "app.record_every=1", "hydra.run.dir=run", cwd=tmp_path)
    metrics = tmp_path / "run" / "metrics.json"
    deadline = time.monotonic() + 240
    while not metrics.is_file() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.02)
    assert metrics.is_file(), proc.communicate()
    command_line = open(f"/proc/{proc.pid}/cmdline", "rb").read()
    [worker] = [pid for pid in _children(proc.pid) if open(f"/proc/{pid}/cmdline", "rb").read() == command_line]
    # killed once it has the job (it forks a process for the second figure then): killed before
    # it, the run would draw the figures itself (a figure process gone before its job)
    while not _children(worker) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.002)
    assert _children(worker), proc.communicate()
    os.kill(worker, signal.SIGKILL)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err
    [line] = [line for line in err.splitlines() if line.startswith("error:")]
    assert "figures: the figure process ended without an answer (signal SIGKILL)" in line, line
    assert "figures=false" in line
    record = json.loads(metrics.read_text())
    assert record["status"] == "ok" and record["steps_done"] == 60 and "figures_error" in record


FORK_PROBE = """
import sys, threading
from decrun.runner import figure_process
seen = []
fork = figure_process.FigureProcess.fork
def probe():
    seen.append(("numpy" in sys.modules, "hydra" in sys.modules, threading.active_count()))
    return fork()
figure_process.FigureProcess.fork = staticmethod(probe)
sys.argv = ["decrun", "app.steps=1", "hydra.run.dir=probe"]
from decrun.__main__ import console_main
try:
    console_main()
finally:
    open("seen.txt", "w").write(repr(seen))
"""


def test_the_command_forks_its_figure_process_before_numpy_hydra_or_any_thread(tmp_path):
    """Forked at the command's first instant: nothing that starts threads (numpy's OpenBLAS) or
    holds state (Hydra) is loaded yet, and only the main thread runs."""
    if len(os.sched_getaffinity(0)) < 2:
        pytest.skip("one core: the command starts no figure process")
    import subprocess
    import sys

    from cli_processes import env

    done = subprocess.run([sys.executable, "-c", FORK_PROBE], cwd=tmp_path, env={**env(), "DECRUN_FIGURE_PROCESS": "on"},
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / "seen.txt").read_text() == "[(False, False, 1)]"
    assert (tmp_path / "probe" / "smoothing.png").is_file()
