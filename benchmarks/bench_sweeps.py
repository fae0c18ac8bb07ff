"""Benchmark: per-job overhead of ``decrun -m`` sweeps against a plain Python loop.

Two measurements, each a fresh process timed from the outside (imports included, as a
user waits for them):

1. **overhead**: an 8-job ``app.dt`` sweep on the default mesh (icosphere subdiv 3, 642
   vertices; implicit smoothing, 10 steps, ``figures=false``) on Hydra's basic launcher,
   against one ``python`` process that composes the config once and calls
   :func:`decrun.runner.run.run_experiment` (with the per-process mesh/operator cache a
   sweep job uses) + :func:`~decrun.runner.run.write_run` for the same 8 time steps (the
   same work, the same files). Target: sweep ≤ 2 × loop.
2. **parallel**: 8 jobs of ~1 s each (``mesh.subdiv=4``, explicit steps) on the basic
   launcher against ``hydra/launcher=joblib hydra.launcher.n_jobs=2``. Target: joblib
   ≥ 1.6 × faster (needs 2 free cores: the ratio is meaningless on a loaded machine, so
   the load average is printed beside it).

    python benchmarks/bench_sweeps.py                # both, best of --repeat (default 2)
    python benchmarks/bench_sweeps.py --only overhead --repeat 3
    PYTHONPATH=/path/to/old/checkout python benchmarks/bench_sweeps.py   # "before" numbers
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DTS = [0.001, 0.002, 0.003, 0.004, 0.005, 0.006, 0.007, 0.008]
SMALL = ["figures=false", "progress=false"]
#: ~1 s of work per job on the project machine (2 cores): 2562 vertices, 300 explicit steps
HEAVY = ["mesh.subdiv=4", "app.scheme=explicit", "app.steps=300", "app.dt=1e-5", "app.critical_dt=false",
         "figures=false", "progress=false"]
HEAVY_SEEDS = list(range(8))

LOOP = """
import inspect, sys, time
from pathlib import Path
from decrun.runner.config import compose_config
from decrun.runner.run import run_experiment, write_run
out = Path(sys.argv[1]); overrides = sys.argv[2].split()
cfg = compose_config(overrides)
cache = {{"cache": True}} if "cache" in inspect.signature(run_experiment).parameters else {{}}  # older decrun: none
for i, dt in enumerate({dts}):
    cfg.app.dt = dt
    job = out / str(i); job.mkdir(parents=True)
    result, mesh, timings = run_experiment(cfg, out=job, **cache)
    write_run(job, cfg, result, mesh, timings)
"""


def _env() -> dict:
    return {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}


def timed(args: list[str], cwd: Path) -> float:
    """Wall seconds of one process; raises when it fails."""
    t = time.perf_counter()
    proc = subprocess.run(args, cwd=cwd, env=_env(), capture_output=True, text=True)
    seconds = time.perf_counter() - t
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed:\n{proc.stderr[-2000:]}")
    return seconds


def best(make_args, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            times.append(timed(make_args(Path(tmp)), Path(tmp)))
    return min(times)


def decrun(*args: str) -> list[str]:
    return [sys.executable, "-m", "decrun", *args]


def overhead(repeat: int) -> dict:
    dts = ",".join(map(str, DTS))
    loop = best(lambda tmp: [sys.executable, "-c", LOOP.format(dts=DTS), str(tmp / "loop"), " ".join(SMALL)], repeat)
    sweep = best(lambda tmp: decrun("-m", f"app.dt={dts}", *SMALL, f"hydra.sweep.dir={tmp / 'sweep'}"), repeat)
    return {"loop_s": loop, "sweep_basic_s": sweep, "ratio": sweep / loop}


def parallel(repeat: int) -> dict:
    seeds = ",".join(map(str, HEAVY_SEEDS))
    basic = best(lambda tmp: decrun("-m", f"mesh.seed={seeds}", *HEAVY, f"hydra.sweep.dir={tmp / 's'}"), repeat)
    joblib = best(lambda tmp: decrun("-m", "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", f"mesh.seed={seeds}",
                                     *HEAVY, f"hydra.sweep.dir={tmp / 's'}"), repeat)
    return {"basic_s": basic, "joblib2_s": joblib, "speedup": basic / joblib, "loadavg": os.getloadavg()[0]}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--only", choices=["overhead", "parallel"])
    args = parser.parse_args(argv)
    if args.only in (None, "overhead"):
        r = overhead(args.repeat)
        print(f"overhead: 8-job app.dt sweep, basic launcher {r['sweep_basic_s']:.2f} s; plain loop "
              f"{r['loop_s']:.2f} s; ratio {r['ratio']:.2f} (target ≤ 2)", flush=True)
    if args.only in (None, "parallel"):
        r = parallel(args.repeat)
        print(f"parallel: 8 jobs of ~1 s, basic {r['basic_s']:.2f} s; joblib n_jobs=2 {r['joblib2_s']:.2f} s; "
              f"speed-up {r['speedup']:.2f} (target ≥ 1.6; load average {r['loadavg']:.1f})", flush=True)


if __name__ == "__main__":
    main()
