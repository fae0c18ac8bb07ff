"""Benchmark: the fluid claims of docs/apps/fluid.md, measured.

1. Wake antisymmetry: the Fig. 7.15 channel (inflow 10, ν = 0.02, dt = 0.005, 30 steps) at
   1455, 2790 and 5399 faces; |Σ_above + Σ_below| / (|Σ_above| + |Σ_below|) of ⋆0 w over the
   wake x ∈ (0.65, 1.5), above y > 0.52 and below y < 0.48 (tests/methods/test_fluid.py).
2. Counter-rotating vortex pair on the unit sphere (5120 faces, Γ = 4, blob radius 0.12,
   dt = 0.02, 20 steps, ν = 0): speed / (Γ/(4π) cot(θ/2)) at θ = 60° and 90° with two
   estimators of the +Γ vortex's latitude: the centroid of the positive vorticity (the test's)
   and the centroid of its core (w above half its current maximum).
3. Energy ½ψᵀSψ and enstrophy ½Σ⋆0w² without forces at ν = 0 (smooth random start, seed 4,
   amplitude 5, dt = 0.02; benchmarks/bench_fluid_stability.py's unforced run): in how many of
   ``--steps`` steps each rose above round-off (relative 1e-12), and the largest rise, for the
   default (swept_bounded) and the unbounded swept rule, on closed icospheres (1280, 5120 faces;
   more with --levels) and the unit square with walls at rest (2405 faces). With inflow (the
   Fig. 7.15 channel, 1455 faces, ν = 0.02, dt = 0.005, 120 steps) nothing bounds the energy:
   the steps that raised it and the energy ratio.

    OMP_NUM_THREADS=1 python benchmarks/bench_fluid_claims.py [--circulation swept]   # ~5 min
    OMP_NUM_THREADS=1 python benchmarks/bench_fluid_claims.py --parts energy --steps 1000 --levels 3 4 5 6
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from decrun.complex import SimplicialComplex  # noqa: E402
from decrun.core.channel_mesh import channel_mesh  # noqa: E402
from decrun.core.solvers.direct import DirectSolver  # noqa: E402
from decrun.dec import DEC  # noqa: E402
from decrun.methods.fluid.initial import sphere_vortex_pair  # noqa: E402
from decrun.methods.fluid.simulation import VorticityFluid  # noqa: E402

from meshes_for_tests import icosphere, square_lattice  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_fluid_stability import TOLERANCE, unforced_run  # noqa: E402


def wake_asymmetry(target: int, circulation: str) -> tuple[int, float]:
    """(faces, relative asymmetry of the wake's upper and lower circulation)."""
    mesh = channel_mesh(target_faces=target)
    dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
    sim = VorticityFluid(dec, DirectSolver, dt=0.005, viscosity=0.02, inflow_velocity=(10.0, 0.0),
                         obstacle_loops=mesh.obstacle_loops, circulation=circulation)
    for _ in range(30):
        sim.step()
    x, y = dec.K.vertices.T
    wake = ~dec.K.border_vertices() & (x > 0.65) & (x < 1.5)
    w = sim.vorticity * sim.star0
    above, below = w[wake & (y > 0.52)].sum(), w[wake & (y < 0.48)].sum()
    return dec.K.num_simplices(2), abs(above + below) / (abs(above) + abs(below))


def pair_speeds(degrees: float, circulation: str) -> tuple[float, float]:
    """Speed of the +Γ vortex / the analytic rate, by the positive centroid and by the core centroid."""
    dec = DEC(SimplicialComplex(*icosphere(4)))
    theta, gamma = np.radians(degrees), 4.0
    w0, _ = sphere_vortex_pair(dec, theta, gamma, radius=0.12)
    sim = VorticityFluid(dec, DirectSolver, dt=0.02, viscosity=0.0, initial_vorticity=w0, circulation=circulation)
    x = dec.K.vertices
    times, centroid, core = [], [], []
    for _ in range(20):
        w = sim.vorticity
        for estimate, weight in ((centroid, np.clip(w, 0, None)), (core, np.where(w > 0.5 * w.max(), w, 0.0))):
            center = (weight * sim.star0) @ x
            estimate.append(np.arcsin(center[2] / np.linalg.norm(center)))
        times.append(sim.time)
        sim.step()
    expected = gamma / (4 * np.pi) / np.tan(theta / 2)
    return tuple(-np.polyfit(times, series, 1)[0] / expected for series in (centroid, core))


def inflow_energy(target: int = 1400, steps: int = 120) -> tuple[int, int, int, float]:
    """(faces, steps, steps that raised the energy, energy ratio) of the default scheme in the
    Fig. 7.15 channel (inflow 10, ν = 0.02, dt = 0.005), where no bound applies."""
    mesh = channel_mesh(target_faces=target)
    dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
    sim = VorticityFluid(dec, DirectSolver, dt=0.005, viscosity=0.02, inflow_velocity=(10.0, 0.0),
                         obstacle_loops=mesh.obstacle_loops)
    energy = [sim.kinetic_energy()]
    for _ in range(steps):
        energy.append(sim.step()["kinetic_energy"])
    energy = np.array(energy)
    return dec.K.num_simplices(2), steps, int((np.diff(energy) > TOLERANCE * energy[:-1]).sum()), energy[-1] / energy[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--circulation", default="swept_bounded", help="the scheme of parts wake and pair")
    parser.add_argument("--parts", nargs="*", default=["wake", "pair", "energy"], choices=["wake", "pair", "energy"])
    parser.add_argument("--steps", type=int, default=200, help="steps of the unforced runs of part energy")
    parser.add_argument("--levels", nargs="*", type=int, default=[3, 4], help="icosphere levels of part energy")
    args = parser.parse_args()
    if "wake" in args.parts:
        print("| channel faces | wake asymmetry |\n|---:|---:|")
        for target in (1400, 2800, 5300):
            faces, asymmetry = wake_asymmetry(target, args.circulation)
            print(f"| {faces} | {100 * asymmetry:.1f} % |", flush=True)
    if "pair" in args.parts:
        print("\n| θ | speed / analytic (positive centroid) | (core centroid) |\n|---:|---:|---:|")
        for degrees in (60, 90):
            a, b = pair_speeds(degrees, args.circulation)
            print(f"| {degrees}° | {a:.3f} | {b:.3f} |", flush=True)
    if "energy" in args.parts:
        print("\n| mesh | faces | circulation | steps | energy up (steps) | largest energy rise | "
              "enstrophy up (steps) | largest enstrophy rise |\n|---|---:|---|---:|---:|---:|---:|---:|")
        meshes = [("sphere", lambda lv=lv: DEC(SimplicialComplex(*icosphere(lv)))) for lv in args.levels]
        meshes.append(("square, walls", lambda: DEC(SimplicialComplex(*square_lattice(32)))))
        for name, build in meshes:
            dec = build()
            for scheme, circulation in (("default", "swept_bounded"), ("swept", "swept")):
                r = unforced_run(dec, scheme, args.steps)
                print(f"| {name} | {r['faces']} | {circulation} | {r['steps']} | {r['n_rise_e']} | {r['max_rise_e']:.2g} | "
                      f"{r['n_rise_z']} | {r['max_rise_z']:.2g} |", flush=True)
        faces, steps, up, ratio = inflow_energy()
        print(f"\nchannel with inflow, {faces} faces, default, {steps} steps: energy up in {up} steps, "
              f"energy ratio {ratio:.4f} (no bound applies)", flush=True)


if __name__ == "__main__":
    main()
