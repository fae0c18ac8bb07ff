"""Benchmark: what ``tracker=mlflow`` adds to a sweep, per job, against ``tracker=none`` in the
same run (target: ≤ 30 ms a job).

1. **end to end**: the same N-job sweep (``app=heat``, icosphere subdiv 1, 4 steps, ``app.seed`` swept,
   figures on: they are uploaded) run by the real ``decrun -m`` twice — ``tracker=none`` and
   ``tracker=mlflow`` into a fresh sqlite store — wall and CPU seconds of each child process;
   per job = (mlflow − none) / N. This includes MLflow's one-time costs (its import, making a
   new store's tables), which a sweep pays once, not per job.
2. **per job** (in this process, on the ``tracker=none`` sweep's directory): the one-time cost
   (:meth:`MlflowTracker.client`: import, store, experiment), then
   :func:`decrun.runner.tracking.track_sweep` logging the N jobs and the sweep's run into a
   fresh store — wall and CPU per run — and again on the unchanged sweep (a resume: nothing is
   sent). Beside it the sweep's mean job time (``total_seconds``) and the load average: on a
   machine whose cores are busy the wall times say little, the CPU times more.

    python benchmarks/bench_tracker.py              # 8 jobs
    python benchmarks/bench_tracker.py --jobs 16
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def sweep(work: Path, jobs: int, tracker: list[str], name: str) -> tuple[float, float]:
    """Run an N-job sweep into ``work/name``; (wall, CPU) seconds of the child process."""
    seeds = ",".join(str(k) for k in range(jobs))  # N distinct jobs (one swept key: no product)
    args = ["-m", "app=heat", "mesh.subdiv=1", "app.t_end=0.004", "app.dt=1e-3", f"app.seed={seeds}",
            "progress=false", f"hydra.sweep.dir={name}", *tracker]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "decrun", *args], cwd=work, capture_output=True, text=True,
                          env={**os.environ, "MPLBACKEND": "Agg"})
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    import pandas as pd

    if "warning" in proc.stderr or len(pd.read_csv(work / name / "metrics.csv")) != jobs:
        raise SystemExit(f"sweep {name} failed:\n{proc.stderr[-3000:]}")
    return wall, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


def timed(function) -> tuple[object, float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    value = function()
    return value, time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--jobs", type=int, default=8)
    args = parser.parse_args()
    n = args.jobs
    here = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="bench_tracker_") as tmp:
        work = Path(tmp)
        os.chdir(work)  # a new experiment's artifacts go to ./mlruns of the process that makes it
        try:
            measure(work, n)
        finally:
            os.chdir(here)


def measure(work: Path, n: int) -> None:
    """The two measurements of the module docstring, in ``work``."""
    from decrun.runner.tracking import track_sweep
    from decrun.runner.tracking.mlflow_tracker import MlflowTracker
    import pandas as pd

    none_wall, none_cpu = sweep(work, n, [], "none")
    uri = f"sqlite:///{work / 'e2e.db'}"
    ml_wall, ml_cpu = sweep(work, n, ["tracker=mlflow", f"tracker.uri={uri}"], "mlflow")
    mean_job = float(pd.read_csv(work / "none" / "metrics.csv")["total_seconds"].mean())
    print(f"load average {os.getloadavg()[0]:.1f}; {n} jobs, mean job total_seconds {mean_job * 1e3:.0f} ms")
    print(f"end to end: tracker=none {none_wall:.2f} s wall / {none_cpu:.2f} s CPU, tracker=mlflow "
          f"{ml_wall:.2f} s wall / {ml_cpu:.2f} s CPU → per job {(ml_wall - none_wall) / n * 1e3:+.0f} ms wall, "
          f"{(ml_cpu - none_cpu) / n * 1e3:+.0f} ms CPU (one-time costs included)")

    tracker = MlflowTracker(uri=f"sqlite:///{work / 'direct.db'}")
    _, fixed_wall, fixed_cpu = timed(tracker.client)
    tracked, wall, cpu = timed(lambda: track_sweep(tracker, work / "none"))
    runs = tracked.sent
    assert runs == n + 1, tracked
    again, resume_wall, resume_cpu = timed(lambda: track_sweep(tracker, work / "none"))
    assert again.sent == 0, again
    print(f"one-time: {fixed_wall * 1e3:.0f} ms wall / {fixed_cpu * 1e3:.0f} ms CPU (import mlflow, new store, "
          f"experiment)")
    print(f"per job: {wall / runs * 1e3:.1f} ms wall / {cpu / runs * 1e3:.1f} ms CPU "
          f"({wall / runs / mean_job * 100:.1f} % of a mean job's time; target ≤ 30 ms)")
    print(f"resume, nothing changed: {resume_wall / runs * 1e3:.1f} ms wall / {resume_cpu / runs * 1e3:.1f} ms "
          f"CPU per job (nothing sent)")


if __name__ == "__main__":
    main()
