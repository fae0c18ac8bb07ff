"""Issue 24: nothing decrun writes or deletes leaves its output directory, and one process
at a time per run or sweep directory — real ``decrun`` processes on hostile state on disk
(symlinks out of the sweep, an edited manifest, a log or metrics.json linked elsewhere) and
two processes at once (concurrent resumes, a second run into a run still recording)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from decrun.runner.io.atomic import temporary_name, write_text_atomic
from decrun.runner.io.locks import LOCK_NAME, LockedError, acquire, holds, release
from decrun.runner.io.paths import OutsideError

from cli_processes import decrun, start

QUICK = ["mesh.subdiv=1", "app.steps=2", "app.critical_dt=false", "figures=false"]
SWEEP = ["-m", "app.dt=0.001,0.002", *QUICK]
#: a run of a few seconds (explicit Euler on 162 vertices, well below dt_crit)
SLOW = ["mesh.subdiv=2", "app.scheme=explicit", "app.dt=0.001", "app.critical_dt=false", "figures=false"]


def one_line(result) -> str:
    text = result.stderr.strip()
    assert result.returncode == 1, (result.returncode, result.stderr)
    assert text.splitlines() == [text], text  # one line, no traceback
    assert text.startswith("error: ")
    return text


def snapshot(directory: Path) -> dict:
    """Every entry under ``directory`` (not following links) → its bytes (None for a directory)."""
    return {str(p.relative_to(directory)): None if p.is_dir() else p.read_bytes()
            for p in sorted(directory.rglob("*"))}


def wait_for(predicate, what: str, seconds: float = 120):
    deadline = time.time() + seconds
    while time.time() < deadline:
        if predicate():
            return
        time.sleep(0.01)
    raise AssertionError(f"{what} did not happen within {seconds} s")


@pytest.fixture
def victim(tmp_path) -> Path:
    """A directory outside every output directory, with a file decrun must not touch."""
    path = tmp_path / "victim"
    path.mkdir()
    (path / "metrics.json").write_text('{"status": "failed", "error": "mine"}\n')
    (path / "notes.txt").write_text("precious\n")
    return path


@pytest.fixture
def sweep(tmp_path) -> Path:
    """A finished 2-job sweep ``sw`` whose job 1 is to be rerun (its metrics.json removed)."""
    done = decrun(*SWEEP, "hydra.sweep.dir=sw", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    (tmp_path / "sw" / "1" / "metrics.json").unlink()
    return tmp_path / "sw"


def resume(tmp_path, sweep_dir="sw"):
    return decrun(*SWEEP, f"hydra.sweep.dir={sweep_dir}", "hydra.sweeper.resume=true", cwd=tmp_path)


# ----------------------------------------------------------------------------------
# item 1: writes stay inside the output directory
# ----------------------------------------------------------------------------------


def test_resume_refuses_a_job_directory_symlinked_out_of_the_sweep(tmp_path, sweep, victim):
    import shutil

    shutil.rmtree(sweep / "1")
    (sweep / "1").symlink_to("../victim")
    before, manifest = snapshot(victim), (sweep / "manifest.json").read_bytes()
    message = one_line(resume(tmp_path))
    assert "job 1" in message and "sw/1 resolves to" in message and str(victim) in message
    assert "outside the sweep directory sw" in message and "hydra.sweep.dir=DIR" in message
    assert snapshot(victim) == before  # nothing deleted, no .hydra/, no result.h5, no log
    assert (sweep / "manifest.json").read_bytes() == manifest  # refused before the manifest is touched
    # the fix the message names: a new sweep
    fresh = decrun(*SWEEP, "hydra.sweep.dir=fresh", cwd=tmp_path)
    assert fresh.returncode == 0, fresh.stderr


def test_resume_refuses_a_job_directory_under_a_parent_symlinked_out(tmp_path, victim):
    made = decrun(*SWEEP, "hydra.sweep.dir=sw", "hydra.sweep.subdir=a/${hydra.job.num}", cwd=tmp_path)
    assert made.returncode == 0, made.stderr
    import shutil

    shutil.copytree(tmp_path / "sw" / "a", victim / "a")
    (victim / "a" / "1" / "metrics.json").unlink()
    shutil.rmtree(tmp_path / "sw" / "a")
    (tmp_path / "sw" / "a").symlink_to(victim / "a")
    before = snapshot(victim)
    message = one_line(decrun(*SWEEP, "hydra.sweep.dir=sw", "hydra.sweep.subdir=a/${hydra.job.num}",
                              "hydra.sweeper.resume=true", cwd=tmp_path))
    assert "sw/a/0 resolves to" in message and "outside the sweep directory" in message
    assert snapshot(victim) == before


@pytest.mark.parametrize("where", ["../victim", "ABSOLUTE", ".", "1/../../victim"])
def test_resume_refuses_a_manifest_job_directory_outside_the_sweep(tmp_path, sweep, victim, where):
    path = sweep / "manifest.json"
    manifest = json.loads(path.read_text())
    manifest["jobs"][1]["dir"] = str(victim) if where == "ABSOLUTE" else where
    path.write_text(json.dumps(manifest))
    before, sweep_before = snapshot(victim), snapshot(sweep)
    message = one_line(resume(tmp_path))
    assert "sw/manifest.json: job 1" in message and "not a path inside the sweep directory" in message
    assert "hydra.sweep.dir=DIR" in message
    assert snapshot(victim) == before and snapshot(sweep) == sweep_before


@pytest.mark.parametrize("name", ["decrun.log", ".hydra", ".hydra/config.yaml"])
def test_resume_refuses_a_job_whose_log_or_hydra_files_lead_out(tmp_path, sweep, victim, name):
    import shutil

    target = victim / "sink"
    if name == ".hydra":
        shutil.rmtree(sweep / "1" / ".hydra")
        target.mkdir()
    else:
        (sweep / "1" / name).unlink()
        target.write_text("victim's\n")
    (sweep / "1" / name).symlink_to(target)
    before = snapshot(victim)
    message = one_line(resume(tmp_path))
    assert f"sw/1/{name} resolves to {target}" in message, message
    assert snapshot(victim) == before


@pytest.mark.parametrize("name", ["decrun.log", ".hydra"])
def test_a_run_whose_log_or_hydra_dir_leads_out_is_refused_before_hydra_writes(tmp_path, victim, name):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    target = victim / "notes.txt" if name == "decrun.log" else victim
    (run_dir / name).symlink_to(target)
    before = snapshot(victim)
    message = one_line(decrun(*QUICK, "hydra.run.dir=run", cwd=tmp_path))
    assert f"run/{name} resolves to {target}, outside the run directory run" in message
    assert "hydra.run.dir=DIR" in message
    assert snapshot(victim) == before
    assert sorted(p.name for p in run_dir.iterdir()) == [name]  # nothing written, no lock left
    fixed = decrun(*QUICK, "hydra.run.dir=elsewhere", cwd=tmp_path)  # the override the message names
    assert fixed.returncode == 0, fixed.stderr


def test_a_run_whose_metrics_json_leads_out_is_refused_and_the_target_kept(tmp_path, victim):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "metrics.json").symlink_to(victim / "metrics.json")
    before = snapshot(victim)
    message = one_line(decrun(*QUICK, "hydra.run.dir=run", cwd=tmp_path))
    assert f"run/metrics.json resolves to {victim / 'metrics.json'}" in message
    assert snapshot(victim) == before
    assert (run_dir / "metrics.json").is_symlink()  # neither followed nor replaced


def test_atomic_writes_refuse_links_out_of_their_directory_and_allow_links_inside(tmp_path, victim):
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.json").symlink_to(victim / "notes.txt")
    with pytest.raises(OutsideError, match="a.json resolves to .*victim/notes.txt, outside the directory"):
        write_text_atomic(out / "a.json", "x")
    temporary_name(out / "b.json").symlink_to(victim / "notes.txt")  # a planted temporary name
    with pytest.raises(OutsideError, match=r"\.b\.json\.tmp-\d+ resolves to"):
        write_text_atomic(out / "b.json", "x")
    assert (victim / "notes.txt").read_text() == "precious\n" and not (out / "b.json").exists()
    (out / "inner.txt").write_text("old")
    (out / "c.json").symlink_to("inner.txt")  # stays in the directory: replaced, not followed
    write_text_atomic(out / "c.json", "new")
    assert (out / "c.json").read_text() == "new" and not (out / "c.json").is_symlink()
    assert (out / "inner.txt").read_text() == "old"


# ----------------------------------------------------------------------------------
# item 2: locks
# ----------------------------------------------------------------------------------


def test_two_concurrent_resumes_the_second_is_refused_and_the_first_finishes(tmp_path):
    args = ["-m", "app.steps=2,6000", *SLOW, "hydra.sweep.dir=sw"]
    killed = start(*args, cwd=tmp_path)  # killed while its slow job 1 records: job 1 is to be rerun
    wait_for((tmp_path / "sw" / "1" / "result.h5.partial").is_file, "job 1's first record")
    killed.send_signal(signal.SIGKILL)
    killed.communicate(timeout=30)
    first = start(*args, "hydra.sweeper.resume=true", cwd=tmp_path)
    lock = tmp_path / "sw" / LOCK_NAME
    wait_for(lambda: lock.is_file() and lock.read_text().startswith(str(first.pid)), "the first resume's lock")
    second = decrun(*args, "hydra.sweeper.resume=true", cwd=tmp_path)
    still_running = first.poll() is None
    _, err = first.communicate(timeout=300)
    assert first.returncode == 0, err
    assert still_running, "the first resume ended before the second tried: the test proves nothing"
    message = one_line(second)
    assert f"in use by decrun process {first.pid} (a sweep running there)" in message
    assert "hydra.sweep.dir=DIR" in message
    manifest = json.loads((tmp_path / "sw" / "manifest.json").read_text())
    assert len(manifest["runs"]) == 2 and manifest["runs"][-1]["finished"] is not None
    assert not lock.exists()  # released after the table was written


def test_a_sweep_directory_locked_by_another_process_is_refused_untouched(tmp_path, sweep):
    before = snapshot(sweep)
    assert acquire(sweep, "sweep")  # this test process plays the running sweep
    try:
        message = one_line(resume(tmp_path))
        assert f"sw: sw is in use by decrun process {os.getpid()} (a sweep running there)" in message
        after = snapshot(sweep)
        after.pop(LOCK_NAME)
        assert after == before
    finally:
        release(sweep)
    resumed = resume(tmp_path)
    assert resumed.returncode == 0, resumed.stderr


def test_a_second_run_into_a_run_directory_still_recording_is_refused_and_the_first_completes(tmp_path):
    first = start(*SLOW, "app.steps=8000", "hydra.run.dir=run", cwd=tmp_path)
    journal = tmp_path / "run" / "result.h5.partial"
    wait_for(journal.is_file, "the first run's first record")
    second = decrun(*QUICK, "hydra.run.dir=run", cwd=tmp_path)
    still_running = first.poll() is None
    _, err = first.communicate(timeout=300)
    assert first.returncode == 0, err
    assert still_running, "the first run ended before the second tried: the test proves nothing"
    message = one_line(second)
    assert f"run is in use by decrun process {first.pid} (a run recording there)" in message
    assert "hydra.run.dir=DIR" in message
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["status"] == "ok" and metrics["steps_done"] == 8000
    overrides = (tmp_path / "run" / ".hydra" / "overrides.yaml").read_text()
    assert "app.steps=8000" in overrides  # the second process did not rewrite .hydra/
    assert "app.steps=2" not in (tmp_path / "run" / "decrun.log").read_text()
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == [".hydra", "decrun.log", "metrics.json",
                                                                     "result.h5"]


def test_a_locked_run_directory_names_the_holder_and_another_directory_runs(tmp_path):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    assert acquire(run_dir, "run")
    try:
        message = one_line(decrun(*QUICK, "hydra.run.dir=run", cwd=tmp_path))
        assert f"in use by decrun process {os.getpid()} (a run recording there)" in message
        assert sorted(p.name for p in run_dir.iterdir()) == [LOCK_NAME]
        other = decrun(*QUICK, "hydra.run.dir=other", cwd=tmp_path)  # the override the message names
        assert other.returncode == 0, other.stderr
    finally:
        release(run_dir)
    assert not (run_dir / LOCK_NAME).exists()


def test_a_lock_left_by_a_dead_process_does_not_block(tmp_path):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from decrun.runner.io.locks import acquire; "
                               "acquire(sys.argv[1]); print('locked', flush=True); time.sleep(600)", str(run_dir)],
                              stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "locked"
    with pytest.raises(LockedError, match=f"process {holder.pid} "):
        acquire(run_dir)
    holder.send_signal(signal.SIGKILL)
    holder.wait(timeout=30)
    assert (run_dir / LOCK_NAME).read_text().startswith(str(holder.pid))  # its file is left behind
    done = decrun(*QUICK, "hydra.run.dir=run", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert not (run_dir / LOCK_NAME).exists()


def test_locks_are_reentrant_in_a_process_and_refuse_a_symlinked_lock_file(tmp_path, victim):
    assert acquire(tmp_path, "run") and holds(tmp_path)
    assert not acquire(tmp_path, "run")  # held already: the caller must not release
    release(tmp_path)
    assert not holds(tmp_path) and not (tmp_path / LOCK_NAME).exists()
    linked = tmp_path / "linked"
    linked.mkdir()
    (linked / LOCK_NAME).symlink_to(victim / "notes.txt")
    with pytest.raises(OutsideError, match="is a symlink"):
        acquire(linked)
    assert (victim / "notes.txt").read_text() == "precious\n"


def test_a_refused_attempt_leaves_no_run_directory_behind(tmp_path):
    """A value typo or a missing file is one line and no ``outputs/runs/<stamp>/`` (it held
    only .hydra/, the log and a failed metrics.json), nor the ``outputs/runs`` made for it in
    a fresh folder; a parent that existed before stays, and a directory that existed before
    keeps the failed status (a sweep job's keeps it for its row: not a single run)."""
    for args in (["app=fluid", "app.initial=spin"], ["mesh=file", "mesh.path=nope.obj"], ["app.dt=-1", *QUICK]):
        done = decrun(*args, cwd=tmp_path)
        assert done.returncode == 1 and done.stderr.startswith("error: "), done.stderr
        assert sorted(p.name for p in tmp_path.iterdir()) == [], args  # no outputs/, no outputs/runs/
    (tmp_path / "kept").mkdir()
    assert decrun("app.dt=-1", *QUICK, "hydra.run.dir=kept/a/b", cwd=tmp_path).returncode == 1
    assert list((tmp_path / "kept").iterdir()) == []  # a/b made for the run: gone; kept/ was there before
    (tmp_path / "mine").mkdir()
    assert decrun("app.dt=-1", *QUICK, "hydra.run.dir=mine", cwd=tmp_path).returncode == 1
    assert json.loads((tmp_path / "mine" / "metrics.json").read_text())["status"] == "failed"
    assert decrun(*QUICK, cwd=tmp_path).returncode == 0  # a run that ran stays
    assert len(list((tmp_path / "outputs" / "runs").iterdir())) == 1
