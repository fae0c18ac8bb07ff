"""Benchmark: steps per second of the default fluid scheme on the ~12k-face Fig. 7.15 channel,
against the thesis' scheme (``velocity=wshd07 circulation=trapezoid``) as the anchor, in one run.

The channel: inflow 10 units/s, one circular obstacle, ν = 0.02, dt = 0.005. The default scheme
(``circulation=swept_bounded``) backtracks in k equal intervals of dt / k, k set by the largest
CFL number of any circumcenter (``swept_cfl`` edge lengths per interval); every point walks all k
intervals. The benchmark also prints how many intervals each point would need by itself
(ceil(CFL_p / swept_cfl)) — the mean against k is the walk a per-point interval count could save —
the default scheme with ``intervals="per_point"`` (each point walks only the intervals it needs),
and, with ``--swept-cfl``, the default scheme at other ``swept_cfl`` values (fewer intervals for
every point). ``--by-interval`` adds the default scheme walked one kernel call per interval over
all points (compiled.backtrack_points and swept_change_add, as on curved meshes and as every mesh
did before the point-by-point sweep): the same bits, so its ratio to the default is what walking
point by point gains, measured in the same run.

The cases run interleaved (rounds of ``--steps`` steps each, in turn), so the machine's load
affects them alike; the ratio to the anchor is the number to compare: over all rounds and the
median of the rounds' ratios. CPU time of the process and wall time are both printed, with the
load average before and after, and the interval counts k the default scheme walked in the timed
steps (k follows the flow: the start state needs more than the later steps).

    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 python benchmarks/bench_fluid_channel.py
    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 python benchmarks/bench_fluid_channel.py --swept-cfl 2.7 8
    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 python benchmarks/bench_fluid_channel.py --by-interval --rounds 8
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from decrun.complex import SimplicialComplex  # noqa: E402
from decrun.core.channel_mesh import channel_mesh  # noqa: E402
from decrun.core.solvers.direct import DirectSolver  # noqa: E402
from decrun.dec import DEC  # noqa: E402
from decrun.methods.fluid import VorticityFluid  # noqa: E402
from decrun.methods.fluid.interpolation import dot3  # noqa: E402


def interval_counts(sim: VorticityFluid) -> np.ndarray:
    """(m,) the intervals each circumcenter needs by itself: ceil(CFL_p / swept_cfl), at least 1,
    CFL_p = |u(c_p)| dt / (mean edge length of its triangle), u the full velocity at the start."""
    both = sim._point_velocities()
    start = sim._circumcenter_velocity(np.ascontiguousarray(both[..., 1:2]))
    cfl = np.sqrt(dot3(start, start)) * sim.dt / sim.walker.size
    return np.maximum(1, np.ceil(cfl / sim.swept_cfl)).astype(int)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--faces", type=int, default=12000, help="channel_mesh(target_faces=...)")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds")
    parser.add_argument("--steps", type=int, default=10, help="steps per case and round")
    parser.add_argument("--swept-cfl", type=float, nargs="*", default=[], help="also the default at these swept_cfl")
    parser.add_argument("--by-interval", action="store_true",
                        help="also the default walked one kernel call per interval (the same bits)")
    args = parser.parse_args()
    print("load average before:", os.getloadavg(), "cores:", os.cpu_count(), flush=True)
    mesh = channel_mesh(target_faces=args.faces)
    dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
    common = dict(dt=0.005, viscosity=0.02, inflow_velocity=(10.0, 0.0), obstacle_loops=mesh.obstacle_loops)
    cases = {"thesis (wshd07, trapezoid) [anchor]": dict(velocity="wshd07", circulation="trapezoid"),
             "default (swept_bounded)": {},
             "default, intervals=per_point": dict(intervals="per_point")}
    for value in args.swept_cfl:
        cases[f"default, swept_cfl={value:g}"] = dict(swept_cfl=value)
    by_interval = "default, one kernel call per interval"
    if args.by_interval:
        cases[by_interval] = {}
    sims = {name: VorticityFluid(dec, DirectSolver, **common, **options) for name, options in cases.items()}
    if args.by_interval:  # the per-interval kernels: what the default walked on every mesh before
        sims[by_interval]._sweeps_at_once = lambda *tables: False
    for sim in sims.values():
        for _ in range(3):  # warm-up: the flow leaves the start state, the kernels are loaded
            sim.step()
    for name, sim in sims.items():
        if sim.circulation_rule == "trapezoid":
            continue
        need = interval_counts(sim)
        print(f"{name}: {need.size} circumcenters, k = {need.max()} intervals for every point; needed by "
              f"itself: mean {need.mean():.2f}, counts {dict(zip(*(u.tolist() for u in np.unique(need, return_counts=True)), strict=True))}")
    cpu = {name: [] for name in sims}  # per round
    wall = dict.fromkeys(sims, 0.0)
    walked = set()  # the default scheme's interval counts k in the timed steps
    for _ in range(args.rounds):
        for name, sim in sims.items():
            c, w = time.process_time(), time.perf_counter()
            for _ in range(args.steps):
                d = sim.step()
            cpu[name].append(time.process_time() - c)
            wall[name] += time.perf_counter() - w
            assert d["stable"], name
            if name == "default (swept_bounded)":
                walked.add(int(interval_counts(sim).max()))  # (untimed) the k of the next round's first step
    print("load average after:", os.getloadavg())
    anchor = next(iter(sims))
    print(f"\n{dec.K.num_simplices(2)} faces, dt = {common['dt']}, ν = {common['viscosity']}, "
          f"{args.rounds} × {args.steps} steps per case; the default's k at the rounds' ends: {sorted(walked)}\n")
    print("| case | steps/s (CPU) | steps/s (wall) | ratio to anchor (CPU) | median of the rounds' ratios |\n"
          "|---|---:|---:|---:|---:|")
    steps = args.rounds * args.steps
    for name in sims:
        ratios = [a / b for a, b in zip(cpu[anchor], cpu[name], strict=True)]
        print(f"| {name} | {steps / sum(cpu[name]):.1f} | {steps / wall[name]:.1f} | "
              f"{sum(cpu[anchor]) / sum(cpu[name]):.3f} | {np.median(ratios):.3f} |")


if __name__ == "__main__":
    main()
