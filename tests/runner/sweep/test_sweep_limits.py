"""Bounded, honest planning (issue 34, item 5): a grid beyond ``hydra.sweeper.max_jobs`` is
refused at once — counted, not made — naming the override that raises the limit (which the
test runs); planning shows its progress on a terminal; Ctrl-C while planning says so, and a
second Ctrl-C while the first is handled prints no traceback."""

from __future__ import annotations

import os
import pty
import select
import signal
import subprocess
import sys
import textwrap
import time

from decrun.runner.sweep.tables import load_sweep

from cli_processes import env

TINY = ["app.steps=2", "mesh.subdiv=1", "app.critical_dt=false", "figures=false", "progress=false"]


def decrun(args, cwd, timeout: float = 300) -> tuple[subprocess.CompletedProcess, float]:
    started = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "decrun", *args], cwd=cwd, env=env(), capture_output=True, text=True,
                          timeout=timeout)
    return proc, time.monotonic() - started


def the_error(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 1, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
    [line] = [line for line in proc.stderr.splitlines() if line.startswith("error:")]
    return line


def test_a_grid_over_max_jobs_is_refused_and_the_override_it_names_runs_it(tmp_path):
    proc, _ = decrun(["-m", "app.dt=0.001,0.002,0.003", *TINY, "hydra.sweeper.max_jobs=2", "hydra.sweep.dir=s"],
                     tmp_path)
    line = the_error(proc)
    assert line.startswith("error: hydra.sweeper.max_jobs=2: this sweep has 3 jobs (app.dt: 3 values)"), line
    assert "nothing ran" in line and not (tmp_path / "s").exists()
    fix = line.split("plan them all with ", 1)[1].split(",")[0]
    assert fix == "hydra.sweeper.max_jobs=3", line
    ran, _ = decrun(["-m", "app.dt=0.001,0.002,0.003", *TINY, fix, "hydra.sweep.dir=s"], tmp_path)
    assert ran.returncode == 0, ran.stderr[-3000:]
    assert list(load_sweep(tmp_path / "s")["status"]) == ["ok"] * 3


def test_a_large_grid_is_refused_at_once_by_the_default_limit(tmp_path):
    """200 000 jobs: planned, they took minutes before the first started (~1-3 ms each)."""
    proc, seconds = decrun(["-m", "app.dt=range(1,201)", "mesh.noise=range(0,1000)", *TINY, "hydra.sweep.dir=s"],
                           tmp_path, timeout=60)
    line = the_error(proc)
    assert line.startswith("error: hydra.sweeper.max_jobs=10000: this sweep has 200,000 jobs (app.dt: 200 values × "
                           "mesh.noise: 1000 values)"), line
    assert "hydra.sweeper.max_jobs=200000" in line and seconds < 20, (line, seconds)
    assert not (tmp_path / "s").exists()


def on_a_terminal(args, cwd, until: bytes, then=None, timeout: float = 120) -> tuple[int, str]:
    """Run ``decrun args`` with stderr on a pseudo-terminal; once ``until`` has been written,
    call ``then(proc)``; (exit code, everything written to the terminal)."""
    leader, follower = pty.openpty()
    environment = {k: v for k, v in env().items() if k != "PYTEST_CURRENT_TEST"}
    proc = subprocess.Popen([sys.executable, "-m", "decrun", *args], cwd=cwd, env=environment, stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=follower, start_new_session=True)
    os.close(follower)
    out, done, deadline = b"", False, time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([leader], [], [], 0.05)
            if ready:
                try:
                    chunk = os.read(leader, 65536)
                except OSError:  # the child closed the terminal
                    break
                if not chunk:
                    break
                out += chunk
            elif proc.poll() is not None:
                break
            if not done and until in out:
                done = True
                if then is not None:
                    then(proc)
        code = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        os.close(leader)
    assert done, out.decode(errors="replace")[-3000:]
    return code, out.decode(errors="replace")


def twice(proc: subprocess.Popen) -> None:
    """Ctrl-C, and Ctrl-C again while the first is handled."""
    proc.send_signal(signal.SIGINT)
    time.sleep(0.005)
    proc.send_signal(signal.SIGINT)


def test_planning_shows_its_progress_on_a_terminal_and_ctrl_c_while_planning_says_so(tmp_path):
    args = ["-m", "app.dt=range(1,3001)", *[a for a in TINY if a != "progress=false"], "hydra.sweep.dir=s"]
    code, shown = on_a_terminal(args, tmp_path, until=b"jobs checked", then=twice)
    assert "decrun: planning the sweep: " in shown and " of 3,000 jobs checked (" in shown, shown[-2000:]
    assert code == 130, shown[-3000:]
    assert "Traceback" not in shown, shown[-3000:]
    last = shown.replace("\r\n", "\n").split("\r")[-1]  # the planning line was erased before the message
    assert "decrun: interrupted (Ctrl-C) while the sweep was planned (" in last and "nothing was written" in last, last
    assert not (tmp_path / "s" / "manifest.json").exists()


HOOKED = textwrap.dedent("""
    import os, signal, sys, time
    import decrun.runner.command.task as cli

    def interrupted():
        raise KeyboardInterrupt

    where = cli.interrupted_where

    def second_ctrl_c(exc):  # Ctrl-C again while the first one is handled
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.2)
        return where(exc)

    cli._hydra_main, cli.interrupted_where = interrupted, second_ctrl_c
    sys.argv = ["decrun", "-m", "app.dt=0.1,0.2"]
    from decrun.__main__ import console_main
    console_main()
""")


def test_a_second_ctrl_c_while_the_first_is_handled_prints_no_traceback(tmp_path):
    proc = subprocess.run([sys.executable, "-c", HOOKED], cwd=tmp_path, env=env(), capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 130, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert proc.stderr.strip() == "decrun: interrupted (Ctrl-C) before the run started", proc.stderr


def test_the_planning_line_is_drawn_only_after_a_while_and_erased():
    import io

    from decrun.runner.sweep.sweeper import PlanningProgress

    quiet = io.StringIO()
    shown = PlanningProgress(3, enabled=True, after=60, stream=quiet)
    for i in range(3):
        shown.update(i)
    shown.close()
    assert quiet.getvalue() == ""  # a plan quicker than `after` shows nothing
    drawn = io.StringIO()
    shown = PlanningProgress(3, enabled=True, after=0, every=0, stream=drawn)
    for i in range(3):
        shown.update(i)
    shown.close()
    text = drawn.getvalue()
    assert "decrun: planning the sweep: 2 of 3 jobs checked (66 %)" in text and text.endswith("\r\x1b[K")
