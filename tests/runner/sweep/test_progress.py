"""Progress: sweep job counts as Hydra expands them, jobs done counted from the sweep
directory, the task context on and off (decrun.runner.job.progress)."""

from __future__ import annotations

import io
import json
import time

import pytest

from decrun.apps.base import Context
from decrun.runner.job.progress import Progress, SweepProgress, make_progress, sweep_size


@pytest.mark.parametrize("overrides, params, total", [
    (["app.scheme=explicit,implicit", "app.dt=0.002,0.005,0.05"], {}, 6),
    (["+experiment=fig5_5_flat_hole"], {"app.border": "circle,conformal", "app.weights": "dec,uniform,mean_value"}, 6),
    (["operator=circumcentric,mixed_area,barycentric", "app.steps=3"], {}, 3),
    (["app.steps=range(1,5)"], {}, 4),
    (["app.steps=3"], {}, 1),
])
def test_sweep_size_counts_the_jobs_hydra_runs(overrides, params, total):
    assert sweep_size(overrides, params) == total


def test_sweep_progress_counts_finished_jobs(tmp_path, monkeypatch):
    progress = SweepProgress(tmp_path, total=3, enabled=True, poll=0.01)
    monkeypatch.setattr("sys.stderr", io.StringIO())
    progress.start()
    for job in range(3):
        (tmp_path / str(job) / ".hydra").mkdir(parents=True)
    assert progress.done() == 0
    for job in range(2):
        (tmp_path / str(job) / "metrics.json").write_text(json.dumps({"status": "ok"}))
    deadline = time.time() + 5
    while progress._bar.n < 2 and time.time() < deadline:
        time.sleep(0.01)
    assert progress._bar.n == 2 and progress.done() == 2
    progress.stop()


def test_progress_is_off_under_pytest_and_task_always_runs_the_block():
    assert make_progress(True).enabled is False  # not a terminal / under pytest
    for progress in (Progress(False), Progress(True)):
        ran = []
        with progress.task("waiting"):
            ran.append(1)
        assert ran == [1]
        assert list(progress(range(3), total=3)) == [0, 1, 2]
    ctx = Context.__new__(Context)
    ctx.progress = lambda iterable, **_: iterable  # a factory without task(): a null context
    with ctx.task("x"):
        pass
