"""The convergence tables of docs/models.md: the shipped models against exact answers.

Through the public API (``compose_config`` + ``run_experiment``, the shipped configs,
``operator=mixed_area``, ``solver=auto``): heat on the unit sphere for l = 1, 2, 3 (Crank–Nicolson,
dt = 1e-4 to t = 0.1; relative L2 error against e^{−l(l+1)t} Y_l), Poisson with border values on
the square (``mesh=grid``, nx = 9 … 65) and on a disk (``mesh=planar``, a 96-gon, max_area
quartered), the heat method on the sphere (mean relative error against the great-circle
distance), and the wave's l = 2 frequency (a cosine fitted to the recorded projection over 10
periods, subdiv 3–5) against √6, with the relative drift of Störmer–Verlet's modified energy.
Orders are log(e_i/e_{i+1}) / log(h_i/h_{i+1}), h the mean edge length (1/(nx−1) on the grid).
The errors do not depend on the machine or its load.

``benchmarks/bench_models.py --part convergence`` prints them; ``scripts/doc_numbers.py`` takes
the page's numbers from :func:`numbers`.
"""

from __future__ import annotations

import math

import numpy as np

#: l → the initial value Y_l of the heat runs
HARMONICS = {1: "z", 2: "x*y", 3: "x*y*z"}
SQUARE_NX = (9, 17, 33, 65)
DISK_MAX_AREA = (0.01, 0.0025, 0.000625, 0.00015625)


def run(overrides: list[str]):
    """``(done, h)``: the finished run of ``decrun <overrides> figures=false`` and its mean edge length."""
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    done = run_experiment(compose_config(["figures=false", "progress=false", *overrides]))
    return done, float(done.complex.mean_edge_length)


def orders(errors: list[float], hs: list[float]) -> list[float | None]:
    """log(e_i/e_{i+1}) / log(h_i/h_{i+1}) between consecutive rows (None for the first)."""
    return [None] + [math.log(errors[i] / errors[i + 1]) / math.log(hs[i] / hs[i + 1]) for i in range(len(errors) - 1)]


def _with_orders(rows: list[dict], error: str, h: str = "h") -> list[dict]:
    for row, order in zip(rows, orders([r[error] for r in rows], [r[h] for r in rows]), strict=True):
        row["order"] = order
    return rows


def heat(l: int, subdivs) -> list[dict]:
    """Rows ``{subdiv, vertices, h, error}`` of heat on the unit sphere from u0 = Y_l, with orders."""
    initial, decay = HARMONICS[l], l * (l + 1)
    exact = f"exp(-{decay}*k*t)*{initial}"
    rows = []
    for s in subdivs:
        done, h = run(["+experiment=heat_sphere", f"mesh.subdiv={s}", "app.dt=0.0001", "app.record_every=1000",
                       f"app.fields.u.initial='{initial}'",
                       f"app.metrics={{l2_error_rel: 'norm(u - {exact})/norm({exact})'}}"])
        rows.append({"subdiv": s, "vertices": int(done.result.metrics["n_vertices"]), "h": h,
                     "error": float(done.result.metrics["l2_error_rel"])})
    return _with_orders(rows, "error")


def poisson_square() -> list[dict]:
    """Rows ``{nx, vertices, h, error, max_error}`` of Poisson on the unit square; orders in 1/(nx−1)."""
    rows = []
    for nx in SQUARE_NX:
        done, h = run(["app=poisson", f"mesh.nx={nx}", f"mesh.ny={nx}"])
        metrics = done.result.metrics
        rows.append({"nx": nx, "vertices": int(metrics["n_vertices"]), "h": h, "grid_h": 1.0 / (nx - 1),
                     "error": float(metrics["l2_error_rel"]), "max_error": float(metrics["max_abs_error"])})
    return _with_orders(rows, "error", "grid_h")


def poisson_disk() -> list[dict]:
    """Rows ``{max_area, vertices, h, error, max_error}`` of Poisson on the unit disk (a 96-gon)."""
    angles = np.linspace(0.0, 2 * np.pi, 96, endpoint=False)
    outer = "[" + ",".join(f"[{math.cos(a):.12f},{math.sin(a):.12f}]" for a in angles) + "]"
    rows = []
    for area in DISK_MAX_AREA:
        done, h = run(["app=poisson", "mesh=planar", f"mesh.outer={outer}", "mesh.holes=[]", f"mesh.max_area={area}"])
        metrics = done.result.metrics
        rows.append({"max_area": area, "vertices": int(metrics["n_vertices"]), "h": h,
                     "error": float(metrics["l2_error_rel"]), "max_error": float(metrics["max_abs_error"])})
    return _with_orders(rows, "error")


def geodesics(subdivs) -> list[dict]:
    """Rows ``{subdiv, faces, h, error, max_error}`` of the heat method on the unit sphere."""
    rows = []
    for s in subdivs:
        done, h = run(["+experiment=heat_geodesics_sphere", f"mesh.subdiv={s}"])
        metrics = done.result.metrics
        rows.append({"subdiv": s, "faces": int(metrics["n_faces"]), "h": h,
                     "error": float(metrics["mean_relative_error"]), "max_error": float(metrics["max_abs_error"])})
    return _with_orders(rows, "error")


def wave(subdivs) -> list[dict]:
    """Rows ``{subdiv, vertices, h, omega, error, drift}``: the l = 2 mode's frequency ω fitted to
    the recorded projection over 10 periods, |ω − √6|/√6, and the largest relative change of the
    modified energy."""
    from scipy.optimize import minimize_scalar

    rows = []
    for s in subdivs:
        done, h = run(["app=wave", f"mesh.subdiv={s}", "app.record_every=5"])
        series = done.result.series
        time_, projection = np.asarray(series["time"]), np.asarray(series["projection"])
        energy = np.asarray(series["energy_modified"])

        def misfit(omega, time_=time_, projection=projection):
            basis = np.stack([np.cos(omega * time_), np.sin(omega * time_)], axis=1)
            coefficients = np.linalg.lstsq(basis, projection, rcond=None)[0]
            return float(np.sum((basis @ coefficients - projection) ** 2))

        omega = minimize_scalar(misfit, bounds=(0.95 * math.sqrt(6), 1.05 * math.sqrt(6)), method="bounded",
                                options={"xatol": 1e-12}).x
        rows.append({"subdiv": s, "vertices": int(done.result.metrics["n_vertices"]), "h": h, "omega": float(omega),
                     "error": abs(omega - math.sqrt(6)) / math.sqrt(6),
                     "drift": float(np.abs(energy - energy[0]).max() / abs(energy[0]))})
    return _with_orders(rows, "error")


def tables(subdivs=(3, 4, 5, 6)) -> dict[str, list[dict]]:
    """Every table: ``heat_l1``, ``heat_l2``, ``heat_l3``, ``poisson_square``, ``poisson_disk``,
    ``geodesics`` (subdivs as given) and ``wave`` (the first three subdivs: every recorded step
    holds u and v, 10 periods at subdiv 6 would be 0.3 GB)."""
    out = {f"heat_l{l}": heat(l, subdivs) for l in HARMONICS}
    out["poisson_square"], out["poisson_disk"] = poisson_square(), poisson_disk()
    out["geodesics"], out["wave"] = geodesics(subdivs), wave(subdivs[:3])
    return out


def numbers(subdivs=(3, 4, 5, 6)) -> dict:
    """:func:`tables` flat: ``<table>_<row>_<column>`` (row 0 the coarsest), orders from row 1 on."""
    return {f"{name}_{i}_{column}": value for name, rows in tables(subdivs).items()
            for i, row in enumerate(rows) for column, value in row.items() if value is not None}
