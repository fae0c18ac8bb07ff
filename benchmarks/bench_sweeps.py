"""Benchmark: what a sweep costs beyond its jobs, and what joblib buys, both against the
basic launcher in the same run (issue 17's sweep rows).

Each measurement is a fresh ``decrun -m`` process timed from the outside (imports included,
as a user waits for them), best of ``--repeat``:

1. **overhead**: an 8-job ``app.dt`` sweep of small jobs (the default mesh, icosphere subdiv
   3, 642 vertices; implicit smoothing, 10 steps, ``figures=false``) against the 1-job sweep
   of the same job, basic launcher. Target: 8 jobs ≤ 1.3 × 1 job.
2. **parallel**: 4 jobs of ≥ 4 s each (2562 vertices, 5000 explicit steps, one mesh seed each) on
   the basic launcher against ``hydra/launcher=joblib hydra.launcher.n_jobs=2``. Target:
   joblib ≥ 1.6 × faster. The mean job time (``total_seconds`` of the jobs) and the load
   average are printed beside it: on a machine whose two cores are busy the ratio says
   little.

3. **planning** (``--only planning``): the seconds from a ``decrun -m`` start until its
   manifest is written (every job composed, checked and hashed; no job has run), for a
   1-job and an N-job ``app.steps`` sweep (``--jobs``, default 2000): ms per planned job =
   (t_N − t_1) / (N − 1). Target ≤ 2 ms/job (10 000 jobs planned within 30 s). Measured
   with ``hydra.sweeper.fast=true`` (decrun's default: jobs derived from their group's
   composition) and ``false`` (Hydra composes every job; on 1/10 of the jobs, it is slow),
   and their ratio.

``--profile`` prints where the time of an 8-job sweep goes, in one process (Hydra's per-job
work, decrun's job, planning).

    python benchmarks/bench_sweeps.py                 # both rows, best of --repeat (default 2)
    python benchmarks/bench_sweeps.py --only overhead --repeat 3
    python benchmarks/bench_sweeps.py --only planning --jobs 10000
    python benchmarks/bench_sweeps.py --profile
    PYTHONPATH=/path/to/old/checkout python benchmarks/bench_sweeps.py   # "before" numbers
"""

from __future__ import annotations

import argparse
import collections
import functools
import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DTS = [0.001, 0.002, 0.003, 0.004, 0.005, 0.006, 0.007, 0.008]
SMALL = ["figures=false", "progress=false"]
#: ≥ 4 s of work per job on the project machine (2 cores, quiet): 2562 vertices, 5000 explicit steps (4000 took 3.7 s on a faster day)
#: (1500 steps were 1.9 s: too short for issue 26's "jobs of >= 4 s")
HEAVY = ["mesh.subdiv=4", "app.scheme=explicit", "app.steps=5000", "app.dt=1e-5", "app.critical_dt=false",
         "figures=false", "progress=false"]
HEAVY_SEEDS = [0, 1, 2, 3]


def _env() -> dict:
    return {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}


def decrun(*args: str) -> list[str]:
    return [sys.executable, "-m", "decrun", *args]


def _children_cpu() -> float:
    """CPU seconds (user + system) of this process's finished children."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed_sweep(args: list[str], repeat: int, cpu: list | None = None) -> tuple[float, float]:
    """(best wall seconds, mean job ``total_seconds`` of that run) of ``decrun -m args``;
    ``cpu``, when given, gets the least CPU seconds (user + system) of the runs appended."""
    best = (float("inf"), 0.0)
    least_cpu = float("inf")
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            t, c = time.perf_counter(), _children_cpu()
            proc = subprocess.run(decrun("-m", *args, f"hydra.sweep.dir={tmp}/s"), cwd=tmp, env=_env(),
                                  capture_output=True, text=True)
            seconds = time.perf_counter() - t
            least_cpu = min(least_cpu, _children_cpu() - c)
            if proc.returncode != 0:
                raise RuntimeError(f"decrun -m {' '.join(args)} failed:\n{proc.stderr[-2000:]}")
            jobs = [json.loads(p.read_text())["total_seconds"] for p in Path(tmp, "s").glob("*/metrics.json")]
            best = min(best, (seconds, sum(jobs) / len(jobs)))
    if cpu is not None:
        cpu.append(least_cpu)
    return best


def overhead(repeat: int) -> dict:
    cpu: list[float] = []
    one, _ = timed_sweep([f"app.dt={DTS[0]}", *SMALL], repeat, cpu)
    eight, _ = timed_sweep([f"app.dt={','.join(map(str, DTS))}", *SMALL], repeat, cpu)
    return {"sweep1_s": one, "sweep8_s": eight, "ratio": eight / one, "cpu1_s": cpu[0], "cpu8_s": cpu[1],
            "cpu_ratio": cpu[1] / cpu[0]}


def parallel(repeat: int) -> dict:
    seeds = f"mesh.seed={','.join(map(str, HEAVY_SEEDS))}"
    basic, job = timed_sweep([seeds, *HEAVY], repeat)
    joblib, _ = timed_sweep(["hydra/launcher=joblib", "hydra.launcher.n_jobs=2", seeds, *HEAVY], repeat)
    return {"basic_s": basic, "joblib2_s": joblib, "speedup": basic / joblib, "job_s": job,
            "loadavg": os.getloadavg()[0]}


def time_to_manifest(jobs: int, *extra: str) -> float:
    """Seconds from the start of ``decrun -m app.steps=range(1, jobs + 1)`` until its
    manifest.json exists (the plan is complete; the process is then killed)."""
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        proc = subprocess.Popen(decrun("-m", f"app.steps=range(1,{jobs + 1})", *SMALL, *extra, f"hydra.sweep.dir={tmp}/s"),
                                cwd=tmp, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                start_new_session=True)
        manifest = Path(tmp, "s", "manifest.json")
        while not manifest.exists() and proc.poll() is None:
            time.sleep(0.01)
        seconds = time.perf_counter() - t
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        _, err = proc.communicate()
        if not manifest.exists():
            raise RuntimeError(f"no manifest from a {jobs}-job sweep:\n{err.decode()[-2000:]}")
    return seconds


def planning(jobs: int, repeat: int) -> dict:
    """ms per planned job, derived (decrun's default) and Hydra-composed (every job)."""
    one = min(time_to_manifest(1) for _ in range(repeat))
    derived = min(time_to_manifest(jobs) for _ in range(repeat))
    small = max(jobs // 10, 2)
    hydra = min(time_to_manifest(small, "hydra.sweeper.fast=false") for _ in range(repeat))
    per_derived = 1000 * (derived - one) / (jobs - 1)
    per_hydra = 1000 * (hydra - one) / (small - 1)
    return {"one_s": one, "jobs": jobs, "derived_s": derived, "derived_ms": per_derived, "hydra_jobs": small,
            "hydra_ms": per_hydra, "ratio": per_hydra / per_derived}


def profile() -> None:
    """Seconds and calls of the phases of an 8-job basic-launcher sweep, in this process."""
    import hydra.core.hydra_config as hydra_config
    import hydra.core.utils as hydra_utils

    import decrun.runner.command.task as cli
    import decrun.runner.job.run as run
    import decrun.runner.sweep.fast.planning as planning_module
    import decrun.runner.sweep.sweeper as sweeper

    totals, calls = collections.defaultdict(float), collections.Counter()

    def timed(owner, name, label):
        original = getattr(owner, name)

        @functools.wraps(original)
        def wrapper(*args, **kwargs):
            t = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                totals[label] += time.perf_counter() - t
                calls[label] += 1

        setattr(owner, name, wrapper)

    timed(hydra_utils, "run_job", "hydra run_job (Hydra's per-job work + the job)")
    timed(hydra_utils, "_save_config", "  hydra: .hydra/*.yaml")
    timed(hydra_config.HydraConfig, "set_config", "  hydra: HydraConfig.set_config")
    timed(run, "run", "  decrun job (run)")
    timed(run, "prepare", "    prepare (plugins, mesh, complex, checks)")
    timed(run, "execute", "    execute (the app)")
    timed(run, "write", "    write (result.h5, metrics.json, figures)")
    timed(sweeper.ManifestSweeper, "plan", "sweeper: plan (compose + check every job)")
    timed(planning_module.Composer, "_start", "  compose each group's template (Hydra)")
    with tempfile.TemporaryDirectory() as tmp:
        sys.argv = ["decrun", "-m", f"app.dt={','.join(map(str, DTS))}", *SMALL, f"hydra.sweep.dir={tmp}/s"]
        t = time.perf_counter()
        try:
            cli.main()
        except SystemExit:
            pass
        wall = time.perf_counter() - t
    print(f"profile: 8-job sweep in-process {wall:.2f} s (load average {os.getloadavg()[0]:.1f})")
    for label, seconds in totals.items():
        print(f"  {label:52s} {calls[label]:3d} calls {seconds:7.3f} s")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--only", choices=["overhead", "parallel", "planning"])
    parser.add_argument("--jobs", type=int, default=2000, help="jobs of the planning row")
    parser.add_argument("--profile", action="store_true")
    args = parser.parse_args(argv)
    if args.profile:
        profile()
        return
    if args.only in (None, "overhead"):
        r = overhead(args.repeat)
        print(f"overhead: basic launcher, 8-job app.dt sweep {r['sweep8_s']:.2f} s / 1-job sweep {r['sweep1_s']:.2f} s"
              f" = {r['ratio']:.2f}x (target <= 1.3); CPU {r['cpu8_s']:.2f} s / {r['cpu1_s']:.2f} s = "
              f"{r['cpu_ratio']:.2f}x (load average {os.getloadavg()[0]:.1f})", flush=True)
    if args.only in (None, "parallel"):
        r = parallel(args.repeat)
        print(f"parallel: 4 jobs of {r['job_s']:.1f} s, basic {r['basic_s']:.2f} s / joblib n_jobs=2 "
              f"{r['joblib2_s']:.2f} s = {r['speedup']:.2f}x (target >= 1.6; load average {r['loadavg']:.1f})",
              flush=True)
    if args.only in (None, "planning"):
        r = planning(args.jobs, args.repeat)
        print(f"planning: {r['jobs']} jobs planned in {r['derived_s']:.2f} s (1 job {r['one_s']:.2f} s): "
              f"{r['derived_ms']:.2f} ms/job (target <= 2); Hydra composing every job "
              f"(hydra.sweeper.fast=false, {r['hydra_jobs']} jobs) {r['hydra_ms']:.1f} ms/job = "
              f"{r['ratio']:.0f}x (load average {os.getloadavg()[0]:.1f})", flush=True)


if __name__ == "__main__":
    main()
