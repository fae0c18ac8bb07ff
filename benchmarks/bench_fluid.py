"""Benchmark: time steps per second of the vorticity fluid (thesis ch. 7), one core.

Cases: unit icospheres of 1.3k, 5k, 20k and 82k faces (a smooth random vorticity,
ν = 1e-3) and the ~12k-face channel of Fig. 7.15–7.17 (inflow 10 units/s, one circular
obstacle, ν = 0.02). The cost of a step grows with the number of triangles a backtracked
point crosses, so each case states its CFL number (max displacement per step / mean edge
length): the spheres run at CFL ≈ 1, the channel at the thesis' dt = 0.005 (CFL ≈ 2 in
the coarse part, ≈ 5 at the obstacle) and at dt = 0.0025, each with the default per-point
substeps (max_cfl = 1) and with one substep (max_cfl = None, the cheapest; it blew up at
ν = 0.005 on 5.3k faces). Wall and CPU time are both reported: on a shared machine the
CPU time of the process is the steadier number.

    OMP_NUM_THREADS=1 python benchmarks/bench_fluid.py            # all cases
    OMP_NUM_THREADS=1 python benchmarks/bench_fluid.py --quick    # the two smallest spheres
    OMP_NUM_THREADS=1 python benchmarks/bench_fluid.py --kernels numpy   # the numpy twins

The numba kernels against the numpy path in one run: benchmarks/bench_fluid_kernels.py.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from decrun.complex import SimplicialComplex  # noqa: E402
from decrun.core.channel_mesh import channel_mesh  # noqa: E402
from decrun.core.solvers.direct import DirectSolver  # noqa: E402
from decrun.dec import DEC  # noqa: E402
from decrun.methods.fluid import VorticityFluid  # noqa: E402
from decrun.methods.fluid.initial import random_vorticity  # noqa: E402


def icosphere(subdiv: int):
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.create_sphere(radius=1.0, subdiv=subdiv)
    v = ms.current_mesh().vertex_matrix()
    return v / np.linalg.norm(v, axis=1, keepdims=True), ms.current_mesh().face_matrix().astype(np.int64)


def mean_edge(dec: DEC) -> float:
    e = dec.K.simplices(1)
    x = dec.K.vertices
    return float(np.linalg.norm(x[e[:, 1]] - x[e[:, 0]], axis=1).mean())


def run(name: str, dec: DEC, seconds: float, **options) -> dict:
    start = time.perf_counter()
    sim = VorticityFluid(dec, DirectSolver, **options)
    setup = time.perf_counter() - start
    speed = np.linalg.norm(sim.triangle_velocities(), axis=1).max()
    cfl = speed * sim.dt / mean_edge(dec)
    sim.step()  # warm-up
    steps, rounds = 0, 0
    start, cpu_start = time.perf_counter(), time.process_time()
    while time.perf_counter() - start < seconds or steps < 3:
        d = sim.step()
        steps += 1
        rounds += d.get("backtrack_rounds", 0)
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    return {"case": name, "faces": dec.K.num_simplices(2), "dt": sim.dt, "cfl": cfl, "setup_s": setup,
            "substeps": d.get("backtrack_substeps", 1),
            "steps_per_s": steps / elapsed, "ms_per_step": 1e3 * elapsed / steps, "walk_rounds": rounds / steps,
            "cpu_steps_per_s": steps / cpu, "cpu_ms_per_step": 1e3 * cpu / steps,
            "stable": d["stable"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="only the 1.3k and 5k spheres")
    parser.add_argument("--seconds", type=float, default=3.0, help="time per case")
    parser.add_argument("--kernels", choices=["numba", "numpy"], default="numba", help="VorticityFluid(kernels=...)")
    args = parser.parse_args()
    rows = []
    for subdiv in ([3, 4] if args.quick else [3, 4, 5, 6]):
        v, f = icosphere(subdiv)
        dec = DEC(SimplicialComplex(v, f))
        w0 = random_vorticity(dec, seed=0, amplitude=4.0)
        probe = VorticityFluid(dec, DirectSolver, dt=1.0, viscosity=0.0, initial_vorticity=w0)
        dt = mean_edge(dec) / np.linalg.norm(probe.triangle_velocities(), axis=1).max()  # CFL 1
        rows.append(run(f"icosphere s{subdiv}", dec, args.seconds, dt=dt, viscosity=1e-3, initial_vorticity=w0,
                        kernels=args.kernels))
        print(rows[-1], flush=True)
    if not args.quick:
        mesh = channel_mesh(target_faces=12000)
        dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
        for dt, max_cfl in ((0.005, 1.0), (0.005, None), (0.0025, 1.0), (0.0025, None)):
            rows.append(run(f"channel dt={dt} max_cfl={max_cfl}", dec, args.seconds, dt=dt, viscosity=0.02,
                            inflow_velocity=(10.0, 0.0), obstacle_loops=mesh.obstacle_loops, max_cfl=max_cfl,
                            kernels=args.kernels))
            print(rows[-1], flush=True)
    print()
    print("| case | faces | dt | CFL | setup s | steps/s (wall) | ms/step (wall) | steps/s (CPU) | ms/step (CPU) "
          "| walk rounds/step | max substeps | stable |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['faces']} | {r['dt']:.4g} | {r['cfl']:.2f} | {r['setup_s']:.2f} | "
              f"{r['steps_per_s']:.1f} | {r['ms_per_step']:.1f} | {r['cpu_steps_per_s']:.1f} | "
              f"{r['cpu_ms_per_step']:.1f} | {r['walk_rounds']:.1f} | {r['substeps']} | {r['stable']} |")


if __name__ == "__main__":
    main()
