"""Steady flows with known answers for the vorticity fluid (issue 18): shared by
tests/methods/test_fluid.py and benchmarks/bench_fluid_drift.py.

Each case is an exact steady solution of the Euler equations (ν = 0): rigid rotation
w = 2z and the degree-2 state w = 6xz on the unit sphere; the cellular flow
ψ = sin πx sin πy, w = 2π² ψ in the unit square (slip walls), on a regular and a jittered
lattice. The drift of one step, ‖w₁ − w₀‖_⋆0 / ‖w₀‖_⋆0 / dt (1/s), must shrink with h.
"""

from __future__ import annotations

import numpy as np

from decrun.complex import SimplicialComplex
from decrun.core.solvers.direct import DirectSolver
from decrun.dec import DEC
from decrun.methods.fluid.simulation import VorticityFluid

from meshes_for_tests import icosphere, square_lattice

CASES = ("rigid_rotation", "degree_2", "cellular_regular", "cellular_jittered")
#: (velocity, circulation) pairs: the thesis, decrun's first default, WSHD07 with the swept
#: circulation, the unlimited swept default of issue 18, and the default (swept + limiter, issue 25)
SCHEMES = {"thesis": ("wshd07", "trapezoid"), "corrected": ("wshd07", "corrected_trapezoid"),
           "wshd07_swept": ("wshd07", "swept"), "swept": ("least_squares", "swept"),
           "default": ("least_squares", "swept_bounded")}


def steady_case(case: str, level: int):
    """(dec, w0, mask): the mesh (sphere subdivision ``level`` or lattice of ``level`` cells per
    side), the exact vorticity and the vertices the drift is measured on (the square's walls
    create vorticity: only x, y ∈ (0.2, 0.8) count there)."""
    if case in ("rigid_rotation", "degree_2"):
        v, f = icosphere(level)
        x, _, z = v.T
        w0 = 2.0 * z if case == "rigid_rotation" else 6.0 * x * z
        return DEC(SimplicialComplex(v, f)), w0, np.ones(len(v), dtype=bool)
    v, f = square_lattice(level, jitter=0.15 if case == "cellular_jittered" else 0.0)
    x, y = v.T
    w0 = 2.0 * np.pi**2 * np.sin(np.pi * x) * np.sin(np.pi * y)
    return DEC(SimplicialComplex(v, f)), w0, (x > 0.2) & (x < 0.8) & (y > 0.2) & (y < 0.8)


def drift_per_s(dec, w0, mask, scheme: str = "default", dt: float = 1e-3) -> float:
    """‖w₁ − w₀‖_⋆0 / ‖w₀‖_⋆0 / dt over ``mask`` after one step at ν = 0 (1/s)."""
    velocity, circulation = SCHEMES[scheme]
    sim = VorticityFluid(dec, DirectSolver, dt=dt, viscosity=0.0, initial_vorticity=w0, velocity=velocity,
                         circulation=circulation)
    w = sim.vorticity.copy()
    sim.step()
    star = sim.star0[mask]
    return float(np.sqrt(star @ (sim.vorticity - w)[mask] ** 2 / (star @ w[mask] ** 2)) / dt)
