"""Benchmark: stability of the vorticity fluid at ν = 0 and steady-state drift, per scheme (issue 25).

Unforced runs at ν = 0 of a smooth random vorticity (seed 4, amplitude 5, dt = 0.02):
unit icospheres (1280, 5120, 20480 faces; 81920 with --full) and the unit square with walls at
rest (regular lattice, 2.4k / 9.5k faces); per run: the largest relative rise of energy
(½ uᵀ⋆1u) and of enstrophy (½ Σ⋆0 w²) in one step, how many steps raised each above round-off
(relative 1e-12), the step at which the run diverged (non-finite), the energy and enstrophy
ratios at the end, and the bound's activity (steps within the bound / blended towards the
smoothed field / energy-fixed along ψ / rescaled). Then the Fig. 7.15 channels (inflow 10, ν = 0,
dt = 0.005, 80 steps): blow-up step and the energy ratio. Then the steady-state drift of one
step (tests/fluid_cases.py: rigid rotation and degree 2 on icospheres 320 … 20k faces) with
the observed order in h.

    OMP_NUM_THREADS=1 python benchmarks/bench_fluid_stability.py                  # ~10 min, 200 steps
    OMP_NUM_THREADS=1 python benchmarks/bench_fluid_stability.py --steps 1000     # the issue's length
    OMP_NUM_THREADS=1 python benchmarks/bench_fluid_stability.py --full --steps 1000 --parts sphere
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
from decrun.methods.fluid.initial import random_vorticity  # noqa: E402
from decrun.methods.fluid.simulation import VorticityFluid  # noqa: E402

from fluid_cases import drift_per_s, steady_case  # noqa: E402
from meshes_for_tests import icosphere, square_lattice  # noqa: E402

#: scheme name → (velocity, circulation, walls); walls "auto" is slip at ν = 0 for the swept rules
SCHEMES = {"default": ("least_squares", "swept_bounded", "auto"),
           "no_slip": ("least_squares", "swept_bounded", "no_slip"),
           "clamped": ("least_squares", "swept_clamped", "auto"),
           "swept": ("least_squares", "swept", "auto"),
           "former": ("wshd07", "corrected_trapezoid", "auto"), "thesis": ("wshd07", "trapezoid", "auto")}
TOLERANCE = 1e-12  # a rise above this relative size is counted


def unforced_run(dec, scheme: str, steps: int, dt: float = 0.02, seed: int = 4, amplitude: float = 5.0) -> dict:
    """Run ν = 0 from a random vorticity; per-step rises of energy and enstrophy (relative)."""
    velocity, circulation, walls = SCHEMES[scheme]
    w0 = random_vorticity(dec, seed=seed, amplitude=amplitude)
    sim = VorticityFluid(dec, DirectSolver, dt=dt, viscosity=0.0, initial_vorticity=w0, velocity=velocity,
                         circulation=circulation, walls=walls)
    e = [sim.kinetic_energy()]
    z = [sim.diagnostics()["enstrophy"]]
    actions = []
    start = time.process_time()
    diverged = None
    for _ in range(steps):
        d = sim.step()
        if "diverged_at_step" in d or not d["stable"]:
            diverged = d.get("diverged_at_step", d["step"])
            break
        e.append(d["kinetic_energy"])
        z.append(d["enstrophy"])
        actions.append(d.get("bound_action", 0))
    seconds = time.process_time() - start
    e, z = np.array(e), np.array(z)
    rise_e, rise_z = np.diff(e) / e[:-1], np.diff(z) / z[:-1]
    return {"faces": dec.K.num_simplices(2), "steps": len(e) - 1, "diverged": diverged,
            "max_rise_e": rise_e.max(), "n_rise_e": int((rise_e > TOLERANCE).sum()),
            "max_rise_z": rise_z.max(), "n_rise_z": int((rise_z > TOLERANCE).sum()),
            "energy_ratio": e[-1] / e[0], "enstrophy_ratio": z[-1] / z[0], "actions": [sum(a == 0 for a in actions)] + [sum(bool(a & flag) for a in actions) for flag in (1, 2, 4)],
            "cpu_per_step": seconds / max(len(e) - 1, 1)}


def channel_run(target: int, scheme: str, steps: int, dt: float = 0.005) -> dict:
    """The Fig. 7.15 channel at ν = 0 (inflow 10): blow-up step, energy and enstrophy ratios."""
    velocity, circulation, walls = SCHEMES[scheme]
    mesh = channel_mesh(target_faces=target)
    dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
    sim = VorticityFluid(dec, DirectSolver, dt=dt, viscosity=0.0, inflow_velocity=(10.0, 0.0),
                         obstacle_loops=mesh.obstacle_loops, velocity=velocity, circulation=circulation,
                         walls=walls)
    e0 = sim.kinetic_energy()
    d = sim.diagnostics()
    for _ in range(steps):
        d = sim.step()
        if "diverged_at_step" in d or not d["stable"]:
            break
    return {"faces": dec.K.num_simplices(2), "steps": d["step"], "diverged": d.get("diverged_at_step",
            None if d["stable"] else d["step"]), "energy_ratio": d["kinetic_energy"] / e0,
            "enstrophy": d["enstrophy"], "vorticity_max": max(abs(d["vorticity_min"]), d["vorticity_max"])}


def lattice_dec(cells: int):
    v, f = square_lattice(cells)
    return DEC(SimplicialComplex(v, f))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--channel-steps", type=int, default=80)
    parser.add_argument("--channels", nargs="*", type=int, default=[1400, 2800, 5300, 12000])
    parser.add_argument("--full", action="store_true", help="add the 81920-face sphere")
    parser.add_argument("--schemes", nargs="*", default=["default", "swept"], choices=list(SCHEMES))
    parser.add_argument("--parts", nargs="*", default=["sphere", "square", "channel", "drift"],
                        choices=["sphere", "square", "channel", "drift"])
    parser.add_argument("--levels", nargs="*", type=int, default=None, help="icosphere levels (default 3 4 5)")
    args = parser.parse_args()
    if "sphere" in args.parts or "square" in args.parts:
        print("| mesh | faces | scheme | steps | diverged | max energy rise | steps up | max enstrophy rise | "
              "steps up | energy ratio | enstrophy ratio | bound none/blend/energy fix/rescale | CPU s/step |")
        print("|---|---:|---|---:|---|---:|---:|---:|---:|---:|---:|---|---:|")
        meshes = []
        if "sphere" in args.parts:
            levels = args.levels or ([3, 4, 5, 6] if args.full else [3, 4, 5])
            meshes += [("sphere", lambda lv=lv: DEC(SimplicialComplex(*icosphere(lv)))) for lv in levels]
        if "square" in args.parts:
            meshes += [("square", lambda c=c: lattice_dec(c)) for c in (32, 64)]
        for name, build in meshes:
            dec = build()
            for scheme in args.schemes:
                r = unforced_run(dec, scheme, args.steps)
                print(f"| {name} | {r['faces']} | {scheme} | {r['steps']} | {r['diverged'] or '-'} | "
                      f"{r['max_rise_e']:.2g} | {r['n_rise_e']} | {r['max_rise_z']:.2g} | {r['n_rise_z']} | "
                      f"{r['energy_ratio']:.4g} | {r['enstrophy_ratio']:.4g} | {'/'.join(map(str, r['actions']))} | "
                      f"{r['cpu_per_step']:.3f} |", flush=True)
    if "channel" in args.parts:
        print("\n| channel faces | scheme | steps | diverged | energy ratio | enstrophy | max abs w |")
        print("|---:|---|---:|---|---:|---:|---:|")
        for target in args.channels:
            for scheme in args.schemes:
                r = channel_run(target, scheme, args.channel_steps)
                print(f"| {r['faces']} | {scheme} | {r['steps']} | {r['diverged'] or '-'} | {r['energy_ratio']:.4g} | "
                      f"{r['enstrophy']:.4g} | {r['vorticity_max']:.4g} |", flush=True)
    if "drift" in args.parts:
        print("\n| case | faces | " + " | ".join(args.schemes) + " |")
        print("|---|---:|" + "---:|" * len(args.schemes))
        for case in ("rigid_rotation", "degree_2"):
            previous = None
            for level in (2, 3, 4, 5):
                dec, w0, mask = steady_case(case, level)
                faces = dec.K.num_simplices(2)
                drift = {s: drift_per_s(dec, w0, mask, s) for s in args.schemes}
                cells = [f"{drift[s]:.3g}" + ("" if previous is None else
                         f" ({np.log(previous[1][s] / drift[s]) / np.log(np.sqrt(faces / previous[0])):+.2f})")
                         for s in args.schemes]
                print(f"| {case} | {faces} | " + " | ".join(cells) + " |", flush=True)
                previous = (faces, drift)


if __name__ == "__main__":
    main()
