"""Benchmark: the fluid's numba kernels against their numpy twins, steps per second in one run.

Cases (issues 17, 26): the default scheme (least-squares walk, swept_bounded; ``--scheme wshd07``:
the thesis' interpolation) on the unit icosphere of 20,480 faces (a smooth random vorticity, ν = 1e-3, CFL ≈ 1)
and the ~12k-face channel of Fig. 7.15–7.17 (inflow 10 units/s, one obstacle, ν = 0.02, dt =
0.005) with the default per-point substeps (max_cfl = 1) and with one substep. Three simulations
of a case are built on the same mesh and stepped in turn, 20 steps at a time — the numpy twins, the numba kernels on
one thread and on all of numba's threads (``NUMBA_NUM_THREADS``, default the machine's cores) —
so machine load hits them alike; the numbers are wall steps/s, to be read on a quiet machine (the
load average is printed: on a loaded one the threads wait for cores). Every row also splits the
numba step (all threads) into the compiled backtracking (walk, interpolation, end velocities, and
on the swept scheme its interval sums), the sparse solves and the rest.

    python benchmarks/bench_fluid_kernels.py                  # the three cases
    python benchmarks/bench_fluid_kernels.py --case sphere    # one case
    python benchmarks/bench_fluid_kernels.py --jit            # first-call JIT times

``--jit`` builds a small fluid in fresh processes with an empty numba cache directory (cold: every
kernel compiles and is written to the cache) and again with that directory (warm: loaded), and
prints the extra time of building it with numba kernels (numba's import and the kernels' compile
or load, done at construction), its first step and numba's cache hit / miss counters.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from decrun.complex import SimplicialComplex  # noqa: E402
from decrun.core.channel_mesh import channel_mesh  # noqa: E402
from decrun.core.solvers.auto import AutoSolver  # noqa: E402
from decrun.core.solvers.direct import DirectSolver  # noqa: E402
from decrun.dec import DEC  # noqa: E402
from decrun.methods.fluid.initial import random_vorticity  # noqa: E402
from decrun.methods.fluid.simulation import VorticityFluid  # noqa: E402

TARGET = {"sphere": 100.0, "channel": 150.0}  # steps/s, issue 17


def sphere_case():
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.create_sphere(radius=1.0, subdiv=5)
    v = ms.current_mesh().vertex_matrix()
    dec = DEC(SimplicialComplex(v / np.linalg.norm(v, axis=1, keepdims=True),
                                ms.current_mesh().face_matrix().astype(np.int64)))
    w0 = random_vorticity(dec, seed=0, amplitude=4.0)
    probe = VorticityFluid(dec, DirectSolver, dt=1.0, viscosity=0.0, initial_vorticity=w0, kernels="numpy")
    edges = dec.K.simplices(1)
    h = np.linalg.norm(dec.K.vertices[edges[:, 1]] - dec.K.vertices[edges[:, 0]], axis=1).mean()
    dt = h / np.linalg.norm(probe.triangle_velocities(), axis=1).max()  # CFL 1
    return dec, dict(dt=dt, viscosity=1e-3, initial_vorticity=w0)


def channel_case(max_cfl):
    mesh = channel_mesh(target_faces=12000)
    dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
    return dec, dict(dt=0.005, viscosity=0.02, inflow_velocity=(10.0, 0.0), obstacle_loops=mesh.obstacle_loops,
                     max_cfl=max_cfl)


class Split:
    """Wall seconds spent in the compiled backtracking (the plain walk, or the swept intervals with
    their sums) and in the solves of one simulation."""

    def __init__(self, sim):
        self.kernel = self.solve = 0.0
        for owner, name in ((sim.walker, "backtrack_compiled"), (sim, "_backtrack_sweeping_compiled")):
            if hasattr(owner, name):  # (an older checkout, PYTHONPATH=...: its swept loop is not timed)
                setattr(owner, name, self._timed(getattr(owner, name), "kernel"))
        for solver in (sim._diffusion, sim._poisson):
            if solver is not None:
                solver.solve = self._timed(solver.solve, "solve")

    def _timed(self, function, account):
        def timed(*args, **kwargs):
            start = time.perf_counter()
            result = function(*args, **kwargs)
            setattr(self, account, getattr(self, account) + time.perf_counter() - start)
            return result

        return timed


SOLVERS = {"auto": AutoSolver, "direct": DirectSolver}  # solver=auto (CHOLMOD for SPD, the default) | SuperLU


#: ``--scheme``: the default (least-squares walk, swept_bounded) or the thesis' (WSHD07 walk)
SCHEMES = {"default": {}, "wshd07": dict(velocity="wshd07", circulation="corrected_trapezoid")}


def compare(name: str, dec, options: dict, seconds: float, solver: str = "auto", scheme: str = "default",
            block: int = 20) -> dict:
    """Steps/s (wall) of the numpy twins, the numba kernels on one thread and on all of numba's
    threads (the machine's cores), each a VorticityFluid of its own, stepped in turn, ``block``
    steps at a time (one step each in turn measured the kernels with cold caches and, on
    OpenMP, with threads that slept through the other simulations' steps: 20 % slower than a run)."""
    import numba

    from decrun.core import jit

    # numba's threading layer as decrun picks it, before numba starts its threads (an older checkout
    # run through PYTHONPATH=... may have no parallel kernels and no jit.threads)
    every = jit.threads() if hasattr(jit, "threads") else numba.get_num_threads()
    runs = {"numpy": ("numpy", None), "numba1": ("numba", 1), "numba": ("numba", every)}
    sims = {k: VorticityFluid(dec, SOLVERS[solver], kernels=kernels, **SCHEMES[scheme], **options)
            for k, (kernels, _) in runs.items()}
    for sim in sims.values():
        sim.step()  # warm-up (loads or compiles the kernels)
    split = Split(sims["numba"])
    cpu = {k: 0.0 for k in sims}
    wall = {k: 0.0 for k in sims}
    steps = 0
    start = time.perf_counter()
    try:
        while time.perf_counter() - start < 3 * seconds or steps < 3:
            for k, sim in sims.items():  # a block of steps each, as a run steps (caches, threads awake)
                if runs[k][1] is not None:
                    numba.set_num_threads(runs[k][1])
                c, w = time.process_time(), time.perf_counter()
                for _ in range(block):
                    d = sim.step()
                cpu[k] += time.process_time() - c
                wall[k] += time.perf_counter() - w
            steps += block
    finally:
        numba.set_num_threads(every)
    same = all(np.array_equal(sims[k].vorticity, sims["numpy"].vorticity) for k in sims)
    kind = name.split()[0]
    return {"case": name, "solver": solver, "faces": dec.K.num_simplices(2), "steps": steps, "threads": every,
            "substeps": d.get("backtrack_substeps", 1),
            **{f"{k}_steps_per_s": steps / wall[k] for k in sims},
            "numba_cpu_steps_per_s": steps / cpu["numba"], "ratio": wall["numpy"] / wall["numba"],
            "ratio1": wall["numpy"] / wall["numba1"], "target": TARGET[kind],
            "kernel_ms": 1e3 * split.kernel / steps, "solve_ms": 1e3 * split.solve / steps,
            "numba_ms": 1e3 * wall["numba"] / steps, "bitwise_equal": same, "stable": d["stable"]}


JIT_PROBE = """
import json, time
import numpy as np
from decrun.complex import SimplicialComplex
from decrun.core.channel_mesh import channel_mesh
from decrun.core.solvers.direct import DirectSolver
from decrun.dec import DEC
from decrun.methods.fluid.simulation import VorticityFluid
mesh = channel_mesh(target_faces=600)
dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
options = dict(dt=0.005, viscosity=0.02, inflow_velocity=(10.0, 0.0), obstacle_loops=mesh.obstacle_loops,
               velocity="wshd07", circulation="corrected_trapezoid")
t0 = time.perf_counter(); VorticityFluid(dec, DirectSolver, kernels="numpy", **options)
t1 = time.perf_counter(); sim = VorticityFluid(dec, DirectSolver, kernels="numba", **options)  # loads the kernels
t2 = time.perf_counter(); sim.step(); t3 = time.perf_counter()
from decrun.methods.fluid import compiled
def dispatcher(name):  # a parallel kernel stays decrun's lazy kernel; its numba dispatcher holds the stats
    kernel = getattr(compiled, name)
    return kernel.dispatcher() if hasattr(kernel, "dispatcher") else kernel
stats = {name: [int(sum(getattr(dispatcher(name).stats, kind).values())) for kind in ("cache_hits", "cache_misses")]
         for name in ("backtrack_points", "circulation_sums")}
print(json.dumps({"load_s": (t2 - t1) - (t1 - t0), "first_step_s": t3 - t2, "cache_hits_misses": stats}))
"""


def jit_times() -> None:
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("cold (empty cache)", "warm (cache written by the cold run)", "warm, another process"):
            out = subprocess.run([sys.executable, "-c", JIT_PROBE], env=env, capture_output=True, text=True, check=True)
            r = json.loads(out.stdout.strip().splitlines()[-1])
            print(f"| {label} | {r['load_s']:.2f} | {r['first_step_s'] * 1e3:.1f} ms | "
                  f"{r['cache_hits_misses']} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=4.0, help="time per kernel and case")
    parser.add_argument("--jit", action="store_true", help="first-call JIT times, cold and warm cache")
    parser.add_argument("--solver", choices=sorted(SOLVERS), default="auto", help="the two SPD systems' solver")
    parser.add_argument("--scheme", choices=sorted(SCHEMES), default="default",
                        help="default: least squares + swept_bounded; wshd07: + corrected_trapezoid")
    parser.add_argument("--case", choices=["sphere", "channel", "channel1"], action="append",
                        help="only these cases (default: all three)")
    args = parser.parse_args()
    if args.jit:
        print("| numba cache | import + compile or load s | first step | cache hits, misses (backtrack_points, "
              "circulation_sums) |")
        print("|---|---:|---:|---|")
        jit_times()
        return
    cases = args.case or ["sphere", "channel", "channel1"]
    rows = []
    for case in cases:
        if case == "sphere":
            rows.append(compare("sphere", *sphere_case(), args.seconds, args.solver, args.scheme))
        else:
            max_cfl = 1.0 if case == "channel" else None
            rows.append(compare("channel " + ("CFL <= 1 substeps" if max_cfl else "one substep"),
                                *channel_case(max_cfl), args.seconds, args.solver, args.scheme))
        print(json.dumps(rows[-1]), flush=True)
    print()
    print(f"solver={args.solver} scheme={args.scheme} numba threads {rows[-1]['threads']} "
          f"load average {os.getloadavg()[0]:.1f}")
    print("| case | faces | numpy steps/s | numba 1 thread | numba all threads | ratio (all / numpy) | target "
          "| numba ms/step: backtracking + solves + rest | bitwise equal |")
    print("|---|---:|---:|---:|---:|---:|---:|---|---|")
    for r in rows:
        rest = r["numba_ms"] - r["kernel_ms"] - r["solve_ms"]
        print(f"| {r['case']} | {r['faces']} | {r['numpy_steps_per_s']:.1f} | {r['numba1_steps_per_s']:.1f} | "
              f"{r['numba_steps_per_s']:.1f} | {r['ratio']:.2f}× | ≥ {r['target']:.0f} | "
              f"{r['kernel_ms']:.1f} + {r['solve_ms']:.1f} + {rest:.1f} | {r['bitwise_equal']} |")


if __name__ == "__main__":
    main()
