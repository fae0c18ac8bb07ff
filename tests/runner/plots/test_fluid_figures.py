"""The fluid's figures through the real CLI: drawn after the result is complete (an interrupt
while drawing keeps result.h5 and metrics.json and leaves no truncated GIF), a rerun leaves no
figure of the earlier run beside its result, and the animation is the recorded frames."""

from __future__ import annotations

import json
import signal
import time

import numpy as np

from decrun.runner.results import read_result

from cli_processes import decrun, start


def test_a_sigterm_while_drawing_keeps_the_complete_result_and_no_truncated_gif(tmp_path):
    proc = start("app=fluid", "app.steps=60", "app.record_every=1", "hydra.run.dir=run", cwd=tmp_path)
    metrics = tmp_path / "run" / "metrics.json"
    deadline = time.monotonic() + 240
    while not metrics.is_file() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    assert metrics.is_file(), proc.communicate()
    proc.send_signal(signal.SIGTERM)  # the result is written: the figures are being drawn
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert "interrupted (SIGTERM) while drawing the figures; the run is complete" in err, err
    record = json.loads(metrics.read_text())
    assert record["status"] == "ok" and record["figures_interrupted"] == "interrupted (SIGTERM)", record
    assert set(record["figures_not_drawn"]) <= {"vorticity", "vorticity_animation"}, record
    assert not [name for name in record["figures_not_drawn"] if list((tmp_path / "run").glob(f"{name}.*"))]
    result = read_result(tmp_path / "run" / "result.h5")
    assert result.complete and result.status == "ok" and result.steps_recorded == 61
    left = sorted(p.name for p in (tmp_path / "run").iterdir())
    assert not [name for name in left if ".tmp-" in name], left  # no temporary, no truncated file
    gif = tmp_path / "run" / "vorticity_animation.gif"
    if gif.exists():  # drawn before the signal: whole
        from PIL import Image

        assert Image.open(gif).n_frames == 60


def test_a_sigterm_while_a_sweep_job_draws_keeps_the_job_ok_and_resume_does_not_rerun_it(tmp_path):
    """The job's result.h5 and metrics.json are final before its figures: interrupted while
    drawing, the job is recorded ok (its figures interrupted), the sweep's message counts it
    finished, and the resume it prints runs only the job that had not started."""
    from decrun.runner.sweep.tables import load_sweep

    sweep = ["-m", "app=fluid", "app.steps=60,20", "app.record_every=1", "progress=false"]
    proc = start(*sweep, "hydra.sweep.dir=s", cwd=tmp_path)
    job = tmp_path / "s" / "0"
    deadline = time.monotonic() + 240
    while not (job / "metrics.json").is_file() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    assert (job / "metrics.json").is_file(), proc.communicate()
    proc.send_signal(signal.SIGTERM)  # job 0's result is written: its figures are being drawn
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert "interrupted (SIGTERM) while drawing the figures; the run is complete" in err, err
    [line] = [line for line in err.splitlines() if line.startswith("decrun: interrupted (SIGTERM) during the sweep")]
    assert "job 0 finished" in line and "job 1 not started" in line and "interrupted;" not in line, line
    record = json.loads((job / "metrics.json").read_text())
    assert record["status"] == "ok" and record["figures_interrupted"] == "interrupted (SIGTERM)", record
    assert read_result(job / "result.h5").steps_recorded == 61
    written = (job / "result.h5").stat().st_mtime_ns

    resume = line.split("resume with: ", 1)[1].split()
    assert resume[0] == "decrun" and resume[-1] == "hydra.sweeper.resume=true", line
    done = decrun(*resume[1:], cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    assert (job / "result.h5").stat().st_mtime_ns == written  # not rerun
    table = load_sweep(tmp_path / "s")
    assert list(table["status"]) == ["ok", "ok"] and list(table["steps_done"]) == [60, 20]


def test_a_rerun_leaves_no_figure_of_the_earlier_run_and_the_gif_holds_the_frames(tmp_path):
    from PIL import Image

    first = decrun("app=fluid", "app.steps=30", "app.record_every=1", "hydra.run.dir=run", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    gif = tmp_path / "run" / "vorticity_animation.gif"
    frames = Image.open(gif)
    assert frames.n_frames == 31 and frames.info["duration"] == 100  # every recorded frame, 10 per second
    series = read_result(tmp_path / "run" / "result.h5").series["vorticity"]
    assert np.abs(series[0] - series[-1]).max() > 0  # the frames differ: the GIF is not one picture
    frames.seek(0)
    start_frame = np.asarray(frames.convert("RGB"), dtype=float)
    frames.seek(30)
    assert np.abs(np.asarray(frames.convert("RGB"), dtype=float) - start_frame).mean() > 1
    again = decrun("app=fluid", "app.steps=30", "app.animation=false", "hydra.run.dir=run", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert not gif.exists() and (tmp_path / "run" / "vorticity.png").is_file()
    assert "removed the earlier run's figures vorticity_animation.gif" in again.stderr
    last = decrun("app=fluid", "app.steps=30", "figures=false", "hydra.run.dir=run", cwd=tmp_path)
    assert last.returncode == 0 and not list((tmp_path / "run").glob("*.png"))
