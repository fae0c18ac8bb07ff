"""Command-line overhead: ``decrun --help`` wall time and the per-job time of a small sweep.

    python benchmarks/bench_cli.py [--reference CHECKOUT] [--repeat 3]

Runs, for this checkout (and, with ``--reference``, for another checkout of decrun in the same
run, e.g. an older commit made with ``git worktree add``), each measurement ``--repeat`` times
in fresh processes and reports the best wall time and the CPU time of that run:

* ``decrun --help``;
* ``decrun -m app.dt=<8 values> figures=false`` on the default mesh with the basic launcher,
  divided by 8 (the per-job time of a small sweep, where Hydra's composition and the imports
  dominate ~0.1 s of computation per job).
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

REPO = Path(__file__).resolve().parents[1]
DTS = "0.001,0.002,0.003,0.004,0.005,0.006,0.007,0.008"


def timed(args: list[str], checkout: Path, cwd: Path) -> tuple[float, float]:
    """(wall seconds, CPU seconds of the child) of ``python -m decrun <args>``."""
    env = dict(os.environ, PYTHONPATH=str(checkout), MPLBACKEND="Agg")
    env.pop("HYDRA_FULL_ERROR", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "decrun", *args], cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"decrun {' '.join(args)} failed in {checkout}:\n{proc.stderr[-2000:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def measure(checkout: Path, repeat: int) -> dict[str, tuple[float, float]]:
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        cases = {"decrun --help": (["--help"], 1),
                 "8-job app.dt sweep, per job": (["-m", f"app.dt={DTS}", "figures=false"], 8)}
        for name, (args, jobs) in cases.items():
            runs = [timed(args, checkout, Path(tmp)) for _ in range(repeat)]
            wall, cpu = min(runs)
            out[name] = (wall / jobs, cpu / jobs)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reference", type=Path, help="another checkout of decrun to measure in the same run")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    checkouts = {"this checkout": REPO}
    if args.reference:
        checkouts["reference"] = args.reference.resolve()
    results = {label: measure(path, args.repeat) for label, path in checkouts.items()}
    print("| measurement | " + " | ".join(f"{label} wall s (cpu s)" for label in results) + " |")
    print("|---|" + "---:|" * len(results))
    for name in next(iter(results.values())):
        cells = [f"{r[name][0]:.3f} ({r[name][1]:.3f})" for r in results.values()]
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
