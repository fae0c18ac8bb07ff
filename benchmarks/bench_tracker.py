"""Benchmark: what ``tracker=mlflow`` adds to a sweep, per job, against ``tracker=none`` (target:
≤ 30 ms a job).

**Overhead a job** is the CPU time (``time.process_time``: this process, all its threads) that
:func:`decrun.runner.tracking.track_sweep` spends per run it sends into a sqlite store, once the
one-time costs are paid. Those are printed apart: importing mlflow, opening the store and
making the experiment (:meth:`MlflowTracker.client`), and the first sweep's warm-up in the process
(MLflow's lazy imports, SQLAlchemy compiling its statements) — measured as the CPU of logging
the sweep into a fresh store minus that of logging it again into a second fresh store. A sweep
pays them once. Wall times are printed beside the CPU times and the load average: on a machine
whose cores are shared, wall time mostly measures the others' work (and sqlite's fsyncs).

1. **end to end**: the same N-job sweep (``app=heat``, icosphere subdiv 1, 4 steps, ``app.seed`` swept,
   figures on: they are uploaded) run by the real ``decrun -m`` twice — ``tracker=none`` and
   ``tracker=mlflow`` into a fresh sqlite store — CPU seconds of each child process; per job =
   (mlflow − none) / N, one-time costs included.
2. **per job** (in this process, on the ``tracker=none`` sweep's directory): the one-time costs,
   then the overhead a job (above) ``--repeats`` times, each repeat logging the whole sweep into a
   fresh sqlite store with the job directories' ``tracking.json`` removed first (a sweep logged
   for the first time), split into each MLflow call (``create_run``, ``log_batch``,
   ``set_terminated``, the artifact upload) and decrun's part (reading the job's records,
   ``tracking.json``: the rest). Every repeat is printed, then the median (the headline) and the
   min, and the rest's ratio to MLflow's three calls (the same work in every version of decrun:
   a ratio that the machine's load changes less than the milliseconds); then the unchanged sweep
   again (a resume: nothing is sent).

    python benchmarks/bench_tracker.py                          # 8 jobs, 5 repeats
    python benchmarks/bench_tracker.py --jobs 16 --repeats 5
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
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


class Calls:
    """CPU seconds and count of each MLflow call made while installed (:meth:`install`); a
    call made inside another (the client's ``log_artifact`` uploading a file) counts in the outer."""

    def __init__(self):
        self.cpu: dict[str, float] = {}
        self.count: dict[str, int] = {}
        self.depth = 0

    def wrap(self, owner, name: str, label: str) -> None:
        """Replace ``owner.name`` by the same call, timed under ``label``."""
        function = getattr(owner, name)

        def timed_call(*args, **kwargs):
            if self.depth:
                return function(*args, **kwargs)
            start = time.process_time()
            self.depth += 1
            try:
                return function(*args, **kwargs)
            finally:
                self.depth -= 1
                self.cpu[label] = self.cpu.get(label, 0.0) + time.process_time() - start
                self.count[label] = self.count.get(label, 0) + 1

        setattr(owner, name, timed_call)

    def install(self, client) -> None:
        """Time the calls ``client`` makes for a run, and the file copies of local artifact repositories."""
        from mlflow.store.artifact.local_artifact_repo import LocalArtifactRepository

        for name in ("create_run", "log_batch", "set_terminated", "update_run", "get_run", "log_artifact",
                     "log_artifacts"):
            self.wrap(client, name, name)
        for name in ("log_artifact", "log_artifacts"):
            self.wrap(LocalArtifactRepository, name, f"{name} (local)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--jobs", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=5, help="in-process measurements of the overhead a job")
    args = parser.parse_args()
    n = args.jobs
    here = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="bench_tracker_") as tmp:
        work = Path(tmp)
        os.chdir(work)  # a new experiment's artifacts go to ./mlruns of the process that makes it
        try:
            measure(work, n, max(1, args.repeats))
        finally:
            os.chdir(here)


def measure(work: Path, n: int, repeats: int) -> None:
    """The two measurements of the module docstring, in ``work``."""
    import pandas as pd

    from decrun.runner.tracking import track_sweep
    from decrun.runner.tracking.mlflow_tracker import MlflowTracker

    print(f"load average before: {' '.join(f'{x:.1f}' for x in os.getloadavg())} ({os.cpu_count()} CPUs)")
    none_wall, none_cpu = sweep(work, n, [], "none")
    uri = f"sqlite:///{work / 'e2e.db'}"
    ml_wall, ml_cpu = sweep(work, n, ["tracker=mlflow", f"tracker.uri={uri}"], "mlflow")
    mean_job = float(pd.read_csv(work / "none" / "metrics.csv")["total_seconds"].mean())
    print(f"{n} jobs, mean job total_seconds {mean_job * 1e3:.0f} ms")
    print(f"end to end: tracker=none {none_cpu:.2f} s CPU, tracker=mlflow {ml_cpu:.2f} s CPU → "
          f"{(ml_cpu - none_cpu) / n * 1e3:+.0f} ms CPU a job, one-time costs included "
          f"(wall {none_wall:.1f} s / {ml_wall:.1f} s)")

    swept = work / "none"
    cold = MlflowTracker(uri=f"sqlite:///{work / 'cold.db'}")
    _, fixed_wall, fixed_cpu = timed(cold.client)
    first, _, first_cpu = timed(lambda: track_sweep(cold, swept))
    per_job, parts = [], []
    for k in range(repeats):
        forget(swept)
        warm = MlflowTracker(uri=f"sqlite:///{work / f'warm{k}.db'}")
        warm.client()
        calls = Calls()
        calls.install(warm.client())
        warm.close = lambda: None  # keep the instrumented client for the resume below
        tracked, wall, cpu = timed(lambda: track_sweep(warm, swept))  # noqa: B023 — called at once
        runs = tracked.sent
        assert runs == first.sent == n + 1, tracked
        if k == 0:
            print(f"one-time: {fixed_cpu * 1e3:.0f} ms CPU (import mlflow, new store, experiment; "
                  f"{fixed_wall:.1f} s wall) + {(first_cpu - cpu) * 1e3:.0f} ms CPU (the first sweep's warm-up)")
        split = {label: seconds / runs for label, seconds in calls.cpu.items()}
        split["decrun (the rest)"] = (cpu - sum(calls.cpu.values())) / runs
        per_job.append(cpu / runs)
        parts.append(split)
        print(f"repeat {k + 1}: {cpu / runs * 1e3:.1f} ms CPU a job ({wall / runs * 1e3:.0f} ms wall) over {runs} "
              f"runs (the {n} jobs and the sweep's): "
              + ", ".join(f"{label} {seconds * 1e3:.1f}" for label, seconds in split.items())
              + f"; load {os.getloadavg()[0]:.1f}")
    median = statistics.median(per_job)
    print(f"overhead a job: median {median * 1e3:.1f} ms CPU, min {min(per_job) * 1e3:.1f} ms over {repeats} "
          "repeats; target ≤ 30 ms CPU")
    labels = list(dict.fromkeys(label for split in parts for label in split))
    for label in labels:
        values = [split.get(label, 0.0) for split in parts]
        count = calls.count.get(label)
        print(f"  {label:26s} median {statistics.median(values) * 1e3:5.1f} ms CPU a job"
              + (f" ({count / runs:.0f} a job)" if count else ""))
    mlflow_calls = ("create_run", "log_batch", "set_terminated")
    ratios = [(sum(split.values()) - sum(split.get(c, 0.0) for c in mlflow_calls))
              / max(sum(split.get(c, 0.0) for c in mlflow_calls), 1e-12) for split in parts]
    print(f"  the rest (files, decrun) over MLflow's three calls: median {statistics.median(ratios):.2f} "
          "(the calls are MLflow's own work: a reference within each repeat that the load scales alike)")
    again, resume_wall, resume_cpu = timed(lambda: track_sweep(warm, swept))
    assert again.sent == 0, again
    print(f"resume, nothing changed: {resume_cpu / runs * 1e3:.1f} ms CPU a job (nothing sent)")
    print(f"load average after: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")


def forget(sweep_dir: Path) -> None:
    """Remove the ``tracking.json`` of ``sweep_dir`` and its jobs: the next logging is a first one."""
    from decrun.runner.io.files import RunFiles, SweepFiles

    for path in [SweepFiles(sweep_dir).dir / SweepFiles.TRACKING,
                 *(RunFiles(p).tracking for p in sweep_dir.iterdir() if p.is_dir())]:
        path.unlink(missing_ok=True)


if __name__ == "__main__":
    main()
