"""Where the time of a small ``decrun`` run goes: wall and CPU time per stage of the default run.

    python benchmarks/bench_small_run.py [--reference CHECKOUT] [--repeat 5] [--best wall|cpu] [-- OVERRIDES...]

Runs ``decrun figures=false`` and ``decrun`` (the default experiment: smoothing on the
642-vertex icosphere; ``-- OVERRIDES`` replaces these two by one command with those
overrides) ``--repeat`` times each (after one unmeasured run that writes the bytecode
caches and the mesh cache, as a user's first run does), in fresh processes, for this checkout and — with
``--reference``, e.g. an older commit made with ``git worktree add`` — for another checkout
in the same run, alternating between them, and prints for the fastest run of each (by
wall time, or with ``--best cpu`` by CPU time: on a loaded machine the wall time of a run is
mostly the others' load) the wall and CPU seconds of each stage and the share of the app's compute; the
machine's load average is printed before and after.

The stages are measured inside the process by a thin wrapper around the command (this
file, run with ``--child``) that times, without changing what runs:

* ``startup``: the interpreter, until the wrapper's first line;
* ``imports``: every top-level ``import`` (wherever it happens: Hydra, the numerical stack,
  h5py, pymeshlab when the mesh source loads it), outside the figures;
* ``plugin scan``: Hydra's scan of the ``hydra_plugins`` packages with the imports it makes
  (each plugin module: decrun's sweeper and every installed launcher/sweeper plugin), timed
  around Hydra's public ``Plugins.instance()`` (its first call scans);
* ``composition``: from the start of decrun's Hydra app until Hydra calls decrun's first callback
  (``on_run_start`` / ``on_multirun_start``): Hydra's command line, search path and its two
  compositions (once to read ``hydra.mode``, once for the run) — timed at these public seams,
  not inside Hydra;
* ``build``: :func:`decrun.runner.job.run.prepare` (plugins checked, mesh, complex, operators);
* ``app``: :func:`decrun.runner.job.run.execute` (the app's compute, its records streamed);
* ``write``: :func:`decrun.runner.job.run.write` without the figures (result.h5, metrics.json);
* ``figure imports``: the imports only the figures need (matplotlib, decrun's plots);
* ``figures``: drawing and saving the figures;
* ``other``: the rest of the command (Hydra's job set-up: run directory, ``.hydra/``,
  logging, callbacks; the lock; the closing lines);
* ``exit``: the interpreter's shutdown, after the exit handlers.

Each stage's time excludes the stages nested in it (an import inside ``build`` counts as
``imports``), so the stages add up to the command's wall and CPU time as the parent sees them
(the CPU time including any child process's, e.g. git's for the provenance).
"""

from __future__ import annotations

import argparse
import atexit
import builtins
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
STAGES = ["startup", "imports", "plugin scan", "composition", "build", "app", "write", "figure imports", "figures",
          "other", "exit"]
#: imports done for the figures only: counted in ``figure imports``
FIGURE_MODULES = ("matplotlib", "decrun.runner.plots", "PIL", "mpl_toolkits")


class Stages:
    """Exclusive wall/CPU time per stage: a stack of open stages, each one's time minus its
    nested stages' added to its total when it closes."""

    def __init__(self) -> None:
        self.totals = {name: [0.0, 0.0] for name in STAGES}
        self.stack: list[list] = []

    def enter(self, name: str) -> None:
        self.stack.append([name, time.perf_counter(), time.process_time(), 0.0, 0.0])

    def leave(self) -> None:
        name, wall0, cpu0, nested_wall, nested_cpu = self.stack.pop()
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        self.totals[name][0] += wall - nested_wall
        self.totals[name][1] += cpu - nested_cpu
        if self.stack:
            self.stack[-1][3] += wall
            self.stack[-1][4] += cpu

    def switch(self, name: str, to: str) -> None:
        """Close the open stage ``name`` (when it is the innermost) and open ``to`` in its place."""
        if self.current() == name:
            self.leave()
            self.enter(to)

    def current(self) -> str | None:
        return self.stack[-1][0] if self.stack else None

    def wrap(self, name: str, function):
        def timed(*args, **kwargs):
            self.enter(name)
            try:
                return function(*args, **kwargs)
            finally:
                self.leave()
        timed.__wrapped__ = function  # type: ignore[attr-defined]
        return timed


def child(argv: list[str], report: Path, spawned: float) -> None:
    """Run ``decrun <argv>`` in this process with the stage clocks; write them to ``report``."""
    first_wall, first_cpu = time.time(), time.process_time()
    stages = Stages()
    stages.totals["startup"] = [first_wall - spawned, first_cpu]
    patched: set[str] = set()
    # (module, attribute path, stage): wrapped as soon as the module is imported; a callback
    # ends the composition (a stage that opens in one function and closes in another)
    targets = [("hydra.core.plugins", "Plugins.instance", "plugin scan"),
               ("decrun.runner.command.task", "_hydra_main", "composition"),
               ("decrun.runner.command.callbacks", "OutputGuard.on_run_start", "end of composition"),
               ("decrun.runner.command.callbacks", "SweepTable.on_multirun_start", "end of composition"),
               ("decrun.runner.job.run", "prepare", "build"),
               ("decrun.runner.job.run", "execute", "app"),
               ("decrun.runner.job.run", "write", "write"),
               ("decrun.runner.plots.common", "draw_figures", "figures")]

    def ended(callback):
        def timed(*args, **kwargs):
            stages.switch("composition", "other")
            return callback(*args, **kwargs)
        return timed

    def patch() -> None:
        for module, path, stage in targets:
            if (module, path) in patched or module not in sys.modules:
                continue
            owner = sys.modules[module]
            *outer, attr = path.split(".")
            for part in outer:
                owner = getattr(owner, part)
            original = owner.__dict__[attr]
            if stage == "end of composition":
                setattr(owner, attr, ended(original))
            elif isinstance(original, staticmethod):
                setattr(owner, attr, staticmethod(stages.wrap(stage, original.__func__)))
            else:
                setattr(owner, attr, stages.wrap(stage, original))
            patched.add((module, path))

    original_import = builtins.__import__

    def timed_import(name, globals=None, locals=None, fromlist=(), level=0):
        top = stages.current()
        if top in ("imports", "figure imports", "plugin scan") or (level == 0 and name in sys.modules and not fromlist):
            return original_import(name, globals, locals, fromlist, level)
        figure = top == "figures" or (top == "write" and name.startswith(FIGURE_MODULES))
        stages.enter("figure imports" if figure else "imports")
        try:
            return original_import(name, globals, locals, fromlist, level)
        finally:
            stages.leave()
            patch()

    def write_report() -> None:  # the last exit handler: what follows is the interpreter's shutdown
        while stages.stack:
            stages.leave()
        builtins.__import__ = original_import
        children = resource.getrusage(resource.RUSAGE_CHILDREN)  # e.g. git for the provenance: "other"
        stages.totals["other"][1] += children.ru_utime + children.ru_stime
        end_wall, end_cpu = time.time(), time.process_time() + children.ru_utime + children.ru_stime
        report.write_text(json.dumps({"stages": stages.totals, "end_wall": end_wall, "end_cpu": end_cpu}))

    atexit.register(write_report)
    builtins.__import__ = timed_import
    stages.enter("other")
    sys.argv = ["decrun", *argv]
    import runpy

    patch()
    runpy.run_module("decrun", run_name="__main__", alter_sys=True)  # as python -m decrun


def measure(checkout: Path, args: list[str], cwd: Path, pycache: Path) -> dict[str, list[float]]:
    """One fresh process of ``decrun <args>`` from ``checkout``: {stage: [wall s, cpu s]}, ``total``.
    Its bytecode is cached under ``pycache`` (``PYTHONPYCACHEPREFIX``: as an installed package
    has it, whatever ``PYTHONDONTWRITEBYTECODE`` says and without writing into the checkout), its
    meshes in a mesh cache beside it (``DECRUN_MESH_CACHE``: as a user's second run has them)."""
    env = dict(os.environ, PYTHONPATH=str(checkout), MPLBACKEND="Agg", PYTHONPYCACHEPREFIX=str(pycache),
               DECRUN_MESH_CACHE=str(pycache.parent / f"meshes-{pycache.name}"))
    for name in ("HYDRA_FULL_ERROR", "PYTHONDONTWRITEBYTECODE"):
        env.pop(name, None)
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as handle:
        report = Path(handle.name)
    try:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        spawned = time.time()
        proc = subprocess.run([sys.executable, __file__, "--child", str(report), str(spawned), "--", *args],
                              cwd=cwd, env=env, capture_output=True, text=True)
        end = time.time()
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if proc.returncode != 0:
            raise RuntimeError(f"decrun {' '.join(args)} failed in {checkout}:\n{proc.stderr[-2000:]}")
        data = json.loads(report.read_text())
    finally:
        report.unlink(missing_ok=True)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    stages = data["stages"]
    stages["exit"] = [end - data["end_wall"], cpu - data["end_cpu"]]
    stages["total"] = [end - spawned, cpu]
    return stages


def table(results: dict[str, dict[str, list[float]]]) -> str:
    """The markdown table: one row per stage, wall s (CPU s) per measured command."""
    labels = list(results)
    lines = ["| stage | " + " | ".join(f"{label}: wall s (CPU s)" for label in labels) + " |",
             "|---|" + "---:|" * len(labels)]
    for stage in [*STAGES, "total"]:
        cells = [f"{results[label][stage][0]:.3f} ({results[label][stage][1]:.3f})".replace("nan", "—")
                 for label in labels]
        lines.append(f"| {stage} | " + " | ".join(cells) + " |")
    for name, parts in (("app / total", ("app",)), ("(build + app) / total", ("build", "app"))):
        cells = []
        for label in labels:
            r = results[label]
            share = [sum(r[p][i] for p in parts) / r["total"][i] for i in (0, 1)]
            cells.append(f"{share[0]:.1%} ({share[1]:.1%})")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def commit(checkout: Path) -> str:
    """The checkout's commit (short), ``+dirty`` when its tracked files differ from it."""
    head = subprocess.run(["git", "-C", str(checkout), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    dirty = subprocess.run(["git", "-C", str(checkout), "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True)
    return (head.stdout.strip() or "?") + ("+dirty" if dirty.stdout.strip() else "")


def machine() -> str:
    """The CPU model and core count."""
    try:
        model = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        model = "?"
    return f"{model}, {os.cpu_count()} cores"


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(sys.argv[5:], Path(sys.argv[2]), float(sys.argv[3]))
        return
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reference", type=Path, help="another checkout of decrun to measure in the same run")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--best", choices=("wall", "cpu"), default="wall",
                        help="the run shown of each command: the one of least wall time (default) or CPU time")
    parser.add_argument("overrides", nargs="*", help="after --: one command's overrides instead of the two defaults")
    args = parser.parse_args()
    commands = [args.overrides] if args.overrides else [["figures=false"], []]
    checkouts = {"this": REPO}
    if args.reference:
        checkouts["reference"] = args.reference.resolve()
    print(f"machine: {machine()}; {sys.executable}; best of {args.repeat} (by {args.best} time)")
    print("commits: " + ", ".join(f"{label} {commit(path)} ({path})" for label, path in checkouts.items()))
    print(f"load average before: {load()}")
    runs: dict[str, list[dict]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for command in commands:  # a first run of each writes the bytecode caches: not measured
            for label, checkout in checkouts.items():
                measure(checkout, command, Path(tmp), Path(tmp) / f"pycache-{label}")
        for _ in range(args.repeat):
            for command in commands:
                for label, checkout in checkouts.items():
                    name = f"{label}: decrun {' '.join(command)}".rstrip()
                    runs.setdefault(name, []).append(measure(checkout, command, Path(tmp),
                                                             Path(tmp) / f"pycache-{label}"))
    print(f"load average after: {load()}")
    column = 0 if args.best == "wall" else 1
    best = {name: min(samples, key=lambda r: r["total"][column]) for name, samples in runs.items()}
    print(table(best))


if __name__ == "__main__":
    main()
