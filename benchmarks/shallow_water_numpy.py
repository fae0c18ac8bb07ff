"""The TRiSK shallow-water step written by hand in numpy/scipy (the baseline the YAML model is
timed against, and the scheme the slow tests run): the equations of :mod:`decrun.core.trisk`,
classical RK4 or SSPRK3, on the icosphere of radius a.

    PYTHONPATH=. python benchmarks/shallow_water_numpy.py --case tc2 --alpha 0 --subdiv 5
    PYTHONPATH=. python benchmarks/shallow_water_numpy.py --case tc2 --subdiv 5 --largest-dt
    PYTHONPATH=. python benchmarks/shallow_water_numpy.py --case galewsky --subdiv 5
    PYTHONPATH=. python benchmarks/shallow_water_numpy.py --case tc5 --subdiv 5 --reference
    PYTHONPATH=. python benchmarks/shallow_water_numpy.py --case tc2 --subdiv 5 --lloyd 3000

prints the case's l1/l2/l∞(h) against the initial state (TC2's exact solution), with --reference
against the stored spectral reference (TC5 day 15, TC6 day 10), the relative drifts of mass, energy
and potential enstrophy, the dt used and the wall time per step; --lloyd first moves the icosphere's
vertices towards the spherical centroidal Voronoi grid (decrun.core.sphere_lloyd).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.sphere_lloyd import lloyd_sphere, subdivide_sphere
from decrun.core.trisk import TRiSK
from decrun.methods import williamson as W


@dataclass
class ShallowWater:
    """The semi-discrete TRiSK equations on ``trisk`` with topography b (n0,) and Coriolis f (n2,)."""

    trisk: TRiSK
    topography: np.ndarray
    coriolis: np.ndarray
    g: float = W.GRAVITY

    def __post_init__(self):
        T = self.trisk
        self.d0 = T.dec.d(0)
        self.d0T = self.d0.T.tocsr()
        self.areas = T.cell_areas
        self.star1 = T.star1
        self.average = T.edge_average()
        self.kinetic = T.kinetic_matrix()
        self.curl = (T.dec.d(1).multiply(1.0 / T.triangle_areas[:, None])).tocsr()
        self.to_triangles = T.cell_to_triangle()
        self.to_edges = T.triangle_to_edge()
        self.perp = T.perp()

    def tendencies(self, h: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(∂h/∂t, ∂U/∂t): ∂h/∂t = (d0ᵀ G)/A, ∂U/∂t = −d0 (K + g (h + b)) − ½ (q_e W G + W (q_e G))."""
        G = self.star1 * (self.average @ h) * U
        dh = (self.d0T @ G) / self.areas
        q = (self.curl @ U + self.coriolis) / (self.to_triangles @ h)
        qe = self.to_edges @ q
        dU = -(self.d0 @ (self.kinetic @ (U * U) + self.g * (h + self.topography)))
        dU -= 0.5 * (qe * (self.perp @ G) + self.perp @ (qe * G))
        return dh, dU

    def step(self, h: np.ndarray, U: np.ndarray, dt: float, method: str = "rk4") -> tuple[np.ndarray, np.ndarray]:
        """One step of classical RK4 or of SSPRK3 (Shu–Osher)."""
        f = self.tendencies
        if method == "rk4":
            k1h, k1u = f(h, U)
            k2h, k2u = f(h + 0.5 * dt * k1h, U + 0.5 * dt * k1u)
            k3h, k3u = f(h + 0.5 * dt * k2h, U + 0.5 * dt * k2u)
            k4h, k4u = f(h + dt * k3h, U + dt * k3u)
            return (h + dt / 6.0 * (k1h + 2 * k2h + 2 * k3h + k4h), U + dt / 6.0 * (k1u + 2 * k2u + 2 * k3u + k4u))
        k1h, k1u = f(h, U)
        h1, U1 = h + dt * k1h, U + dt * k1u
        k2h, k2u = f(h1, U1)
        h2, U2 = 0.75 * h + 0.25 * (h1 + dt * k2h), 0.75 * U + 0.25 * (U1 + dt * k2u)
        k3h, k3u = f(h2, U2)
        return h / 3.0 + 2.0 / 3.0 * (h2 + dt * k3h), U / 3.0 + 2.0 / 3.0 * (U2 + dt * k3u)


def icosphere_trisk(subdiv: int, radius: float = W.EARTH_RADIUS, lloyd: int = 0, cache: str | None = None) -> TRiSK:
    """TRiSK on pymeshlab's icosphere of ``subdiv`` and ``radius`` (what `mesh=icosphere` builds);
    with ``lloyd`` > 0 on the centroidal grid instead: the icosahedron Lloyd-iterated (at most
    ``lloyd`` steps, until no vertex moves by 1e-12 a) and refined (:func:`subdivide_sphere`), level by
    level up to ``subdiv`` — the same triangles as the icosphere's, the vertices moved. ``cache``: an
    .npz read if it exists, else written with the mesh."""
    import pymeshlab

    if cache and Path(cache).exists():
        with np.load(cache) as stored:
            return TRiSK(DEC(SimplicialComplex(stored["vertices"], stored["faces"], orient="fix")))

    ms = pymeshlab.MeshSet()
    ms.create_sphere(radius=float(radius), subdiv=0 if lloyd else int(subdiv))
    vertices, faces = ms.current_mesh().vertex_matrix(), ms.current_mesh().face_matrix().astype(np.int64)
    vertices = radius * vertices / np.linalg.norm(vertices, axis=1, keepdims=True)
    for _level in range(subdiv if lloyd else 0):
        vertices, faces = subdivide_sphere(*lloyd_sphere(vertices, faces, lloyd, tolerance=1e-12)[:1], faces)
    if lloyd:
        vertices, _ = lloyd_sphere(vertices, faces, lloyd, tolerance=1e-12)
    if cache:
        np.savez(cache, vertices=vertices, faces=faces)
    return TRiSK(DEC(SimplicialComplex(vertices, faces, orient="fix")))


def initial_state(trisk: TRiSK, case: W.Case, radius: float = W.EARTH_RADIUS):
    """(h (n0,), U (n1,), b (n0,), f (n2,)) of ``case`` on ``trisk``'s mesh."""
    points = trisk.K.vertices
    f = case.coriolis(trisk.coriolis_points())
    return case.depth(points), W.circulation(trisk, case.velocity, radius), case.topography(points), f


def run(trisk: TRiSK, case: W.Case, dt: float, duration: float, method: str = "rk4", every: int = 0):
    """Run ``case`` for ``duration`` s (the last step shortened to land on it); returns
    (h, U, report) with report the norms against the initial state, the invariants' drifts,
    steps, wall time per step and whether the depth stayed positive and finite."""
    h, U, b, f = initial_state(trisk, case)
    model = ShallowWater(trisk, b, f)
    start = W.invariants(trisk, h, U, b, f)
    h_initial = h.copy()
    steps = int(np.ceil(duration / dt - 1e-9))
    tick = time.perf_counter()
    stable, diverged_at = True, None
    for n in range(steps):
        step_dt = min(dt, duration - n * dt)
        h, U = model.step(h, U, step_dt, method)
        if not (np.isfinite(h).all() and h.min() > 0):
            stable, diverged_at = False, n + 1
            break
        if every and (n + 1) % every == 0:
            print(json.dumps({"step": n + 1, "days": (n + 1) * dt / W.DAY,
                              **W.error_norms(h, h_initial, trisk.cell_areas)}), flush=True)
    seconds = time.perf_counter() - tick
    end = W.invariants(trisk, h, U, b, f) if stable else {k: float("nan") for k in start}
    report = {"case": case.name, "cells": trisk.K.num_simplices(0), "dt": dt, "steps": steps, "method": method,
              "stable": stable, "seconds_per_step": seconds / max(1, (diverged_at or steps)),
              **{f"{k}_vs_initial": v for k, v in W.error_norms(h, h_initial, trisk.cell_areas).items()},
              **{f"{k}_drift": (end[k] - start[k]) / abs(start[k]) for k in start}}
    if diverged_at is not None:
        report["diverged_at_step"] = diverged_at
    return h, U, report


def largest_stable_dt(trisk: TRiSK, case: W.Case, method: str = "rk4", duration: float = 2 * W.DAY,
                      tolerance: float = 0.02) -> tuple[float, float]:
    """(the formula's dt, the largest dt (bisection to ``tolerance``) with which ``case`` stays finite,
    positive and within 10× its first day's l2 change for ``duration``)."""
    h, U, b, f = initial_state(trisk, case)
    formula = W.stable_time_step(trisk, h.max(), float(np.abs(U / trisk.primal_lengths).max()), method)

    def stable(dt):
        _, _, report = run(trisk, case, dt, duration, method)
        return report["stable"] and report["l2_vs_initial"] < 0.05

    low, high = formula, formula
    while stable(high):
        low, high = high, high * 1.5
    while high - low > tolerance * low:
        middle = 0.5 * (low + high)
        low, high = (middle, high) if stable(middle) else (low, middle)
    return formula, low


def against_reference(case: str, day: float, h: np.ndarray, trisk: TRiSK) -> dict[str, float]:
    """l1/l2/l∞ of h against the spectral reference of ``case`` at ``day`` at the cell centres
    (the reference's loader, benchmarks/shallow_water_reference.py, evaluates its spherical harmonics there)."""
    from shallow_water_reference import reference_depth

    reference = reference_depth(case, day, trisk.K.vertices)
    return {f"{k}_vs_reference": v for k, v in W.error_norms(h, reference, trisk.cell_areas).items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", default="tc2", choices=["tc2", "tc5", "tc6", "galewsky", "galewsky_unperturbed"])
    parser.add_argument("--alpha", type=float, default=0.0)
    parser.add_argument("--subdiv", type=int, default=5)
    parser.add_argument("--days", type=float, default=None)
    parser.add_argument("--dt", type=float, default=None, help="default: the stability formula's dt")
    parser.add_argument("--dt-fraction", type=float, default=0.8, help="of the formula's dt when --dt is not given")
    parser.add_argument("--method", default="rk4", choices=sorted(W.RK_STABILITY_INTERVAL))
    parser.add_argument("--largest-dt", action="store_true")
    parser.add_argument("--every", type=int, default=0)
    parser.add_argument("--lloyd", type=int, default=0, help="Lloyd steps towards the SCVT before the run")
    parser.add_argument("--mesh-cache", default=None, help="an .npz of the mesh: read if it exists, else written")
    parser.add_argument("--save", default=None, help="write the final h, U and the cell centres to this .npz")
    parser.add_argument("--reference", action="store_true",
                        help="tc5/tc6: l1/l2/l∞(h) against the stored spectral reference (benchmarks/shallow_water_reference.py)")
    args = parser.parse_args()
    cases = {"tc2": lambda: W.williamson_tc2(args.alpha), "tc5": W.williamson_tc5, "tc6": W.williamson_tc6,
             "galewsky": W.galewsky, "galewsky_unperturbed": lambda: W.galewsky(perturbed=False)}
    case = cases[args.case]()
    tick = time.perf_counter()
    trisk = icosphere_trisk(args.subdiv, lloyd=args.lloyd, cache=args.mesh_cache)
    trisk.perp()
    setup = time.perf_counter() - tick
    if args.largest_dt:
        formula, largest = largest_stable_dt(trisk, case, args.method)
        print(json.dumps({"subdiv": args.subdiv, "method": args.method, "formula_dt": formula, "largest_stable_dt": largest,
                          "ratio": largest / formula}))
        return
    h, U, b, f = initial_state(trisk, case)
    formula = W.stable_time_step(trisk, h.max(), float(np.abs(U / trisk.primal_lengths).max()), args.method)
    dt = args.dt if args.dt is not None else args.dt_fraction * formula
    duration = case.duration if args.days is None else args.days * W.DAY
    h, U, report = run(trisk, case, dt, duration, args.method, args.every)
    if args.save:
        np.savez(args.save, h=h, U=U, points=trisk.K.vertices, areas=trisk.cell_areas, days=duration / W.DAY)
    if args.reference:
        report.update(against_reference(args.case, duration / W.DAY, h, trisk))
    print(json.dumps({"subdiv": args.subdiv, "alpha": args.alpha, "lloyd": args.lloyd, "setup_seconds": setup, "formula_dt": formula,
                      **report}))


if __name__ == "__main__":
    main()
