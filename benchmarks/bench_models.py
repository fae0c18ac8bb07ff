"""Benchmark: declarative models (``app=<model>``, :mod:`decrun.methods.model`) — speed against
the same step written by hand, the cost of compiling a model, and convergence to exact answers.

1. **Step speed** (goal ≤ 1.2×). Every shipped time-dependent model — heat (implicit Euler and
   Crank–Nicolson), wave (Störmer–Verlet), mcf (implicit Euler, 3 fields), gray_scott (imex),
   brusselator (rk4), klausmeier (rk4, with lie), cahn_hilliard (imex, Δ² and explicit(·)) and
   halfar (semi_implicit: a new factorization every step) — runs its own config on a larger mesh
   (:func:`speed_cases`) as the compiled model's step (the
   :class:`~decrun.methods.model.stepper.ModelStepper` step that ``run_steps`` calls) and as the
   same scheme written by hand with numpy/scipy (``model_twins.py``), interleaved in rounds in one
   process, both factorizing the same matrices with the same library: SuperLU (``solver=direct``
   vs ``scipy.sparse.linalg.splu``) and CHOLMOD (``solver=auto``, the default, vs ``cholespy``
   called directly). The final states must agree to round-off (asserted; the last column).
   Reported: steps/s both ways (best round) and model/hand of wall and of CPU time per step.
2. **Compile cost** (goal ≤ 0.2 s): loading a model (its YAML read, the app's options built) and
   compiling it (:func:`~decrun.methods.model.compile_model`: parse, type, fold the linear blocks,
   sample initial values) plus the integrator's set-up — without the factorization, which
   either way is paid at the first step — against the DEC operator build the step needs (complex,
   ⋆0, ⋆1, d0, the stiffness d0ᵀ⋆1d0).
3. **Convergence** over ≥ 3 refinements, through the public API (``compose_config`` +
   ``run_experiment``, the shipped configs): heat on the unit sphere for l = 1, 2, 3
   (Crank–Nicolson, dt = 1e-4 to t = 0.1; relative L2 error against e^{−l(l+1)t} Y_l), Poisson
   with border values on the square (``mesh=grid``, nx = 9 … 65) and on a disk (``mesh=planar``,
   a 96-gon, max_area quartered), the heat method on the sphere (mean relative error against
   the great-circle distance), and the wave's l = 2 frequency (a cosine fitted to the recorded
   projection over 10 periods, subdiv 3–5) against √6, with the relative drift of Störmer–Verlet's
   modified energy. Orders are log(e_i/e_{i+1}) / log(h_i/h_{i+1}), h the mean edge length.
4. **Halfar** (``--part halfar``): the CISM v2.1 Halfar dome at 4, 2 and 1 km (``+experiment=cism_halfar``):\n   the errors, and the run's wall and CPU time against the same steps written by hand.

    python benchmarks/bench_models.py               # all three parts (~8 min on 2 shared cores)
    python benchmarks/bench_models.py --quick       # ~10,000 vertices for parts 1 and 2
    python benchmarks/bench_models.py --part speed  # speed | compile | convergence | halfar
    python benchmarks/bench_models.py --quick --part speed --model halfar   # one model's rows

One core for BLAS (the steps are sparse solves and vector arithmetic); the load average is printed
with each table, since other processes share the machine.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import icosphere_or_kuhn_cube  # noqa: E402

GRAY_SCOTT = {"Du": 2e-5, "Dv": 1e-5, "F": 0.04, "k": 0.06}
GRAY_SCOTT_EQUATIONS = ["dt(u) = Du*laplacian(u) - u*v**2 + F*(1-u)", "dt(v) = Dv*laplacian(v) + u*v**2 - (F+k)*v"]
BUMP = "exp(-10*((x-1)**2 + y**2 + z**2))"


def load() -> str:
    return f"load average {os.getloadavg()[0]:.2f}"


# ---------------------------------------------------------------------------------------------- part 1
def speed_cases(quick: bool) -> list[tuple[str, str, list[str]]]:
    """(label, model, overrides) of part 1: each shipped model's own config on a larger mesh —
    the sphere at subdiv 5 (quick) or 7 for heat, wave and mcf; the n × n grid (n = 101 or 405,
    and h = 1 for Klausmeier, whose bands need it) for the reaction–diffusion models; the CISM
    Halfar domain at 1 km (quick) or 0.25 km. Explicit steps (rk4, Störmer–Verlet) at a dt
    inside their stability limit on that mesh."""
    subdiv, n = (5, 101) if quick else (7, 405)
    h = 1.0 / (n - 1)
    sphere = ["mesh=icosphere_clean", f"mesh.subdiv={subdiv}"]
    grid = [f"mesh.nx={n}", f"mesh.ny={n}"]
    halfar = ["mesh=cism_halfar/1km"] if quick else ["mesh=cism_halfar/1km", "mesh.nx=241", "mesh.ny=401"]
    return [
        ("heat, implicit_euler", "heat", [*sphere, "app.integrator=implicit_euler"]),
        ("heat, crank_nicolson", "heat", sphere),
        ("wave, symplectic", "wave", [*sphere, "app.dt=0.001"]),
        ("mcf (3 fields), implicit_euler", "mcf", sphere),
        ("gray_scott (2 fields), imex", "gray_scott", grid),
        ("brusselator (2 fields), rk4", "brusselator", [*grid, f"app.dt={0.2 * h * h / 0.01:.3g}", "app.t_end=null",
                                                       "app.steps=100"]),  # t_end / dt need not be whole
        ("klausmeier (2 fields, lie), rk4", "klausmeier", [*grid, f"mesh.width={n - 1}", f"mesh.height={n - 1}",
                                                          "app.dt=0.05"]),
        ("cahn_hilliard (Δ², explicit(·)), imex", "cahn_hilliard", grid),
        ("halfar (refactorized every step), semi_implicit", "halfar", halfar),
    ]


def rounds(first, second, steps: int, count: int) -> tuple[float, float, float, float]:
    """Best wall and CPU seconds per step of ``first`` and ``second`` over ``count`` interleaved
    rounds of ``steps`` steps each (one warm-up step each first: the factorization):
    (first wall, second wall, first CPU, second CPU)."""
    first()
    second()
    best = [math.inf] * 4
    for _ in range(count):
        for i, step in enumerate((first, second)):
            start, cpu = time.perf_counter(), time.process_time()
            for _ in range(steps):
                step()
            best[i] = min(best[i], (time.perf_counter() - start) / steps)
            best[i + 2] = min(best[i + 2], (time.process_time() - cpu) / steps)
    return best[0], best[1], best[2], best[3]


def speed(quick: bool, steps: int, count: int, only: list[str] | None = None) -> None:
    from model_twins import model_and_twin

    print(f"\n### Step speed: each shipped model's compiled step against the same scheme by hand ({steps} steps × "
          f"{count} interleaved rounds, best round; model / hand of wall and of CPU time per step)\n")
    print("| case | vertices | solver | hand steps/s | model steps/s | model / hand (wall) | model / hand (CPU) |"
          " max \\|model − hand\\| / max \\|hand\\| |")
    print("|---|---:|---|---:|---:|---:|---:|---:|")
    for label, name, overrides in speed_cases(quick):
        if only and name not in only:
            continue
        for library, solver in (("direct", "SuperLU (solver=direct)"), ("auto", "CHOLMOD (solver=auto)")):
            model, stepper, hand, state = model_and_twin(name, overrides, library)
            explicit = stepper.integrator.__class__.__name__ in ("Explicit", "Symplectic")
            solver = "– (explicit: no solve)" if explicit else solver
            hand_s, model_s, hand_cpu, model_cpu = rounds(hand, model, steps, count)
            difference = max(float(np.abs(stepper.state[u] - state[u]).max() / np.abs(state[u]).max()) for u in state)
            # round-off of two solve paths, amplified by the conditioning: 1.1e-10 measured for the Halfar dome at
            # 96,641 vertices under CHOLMOD (a wrong term differs by far more than 1e-9)
            assert difference <= 1e-9, f"{label}: the model and its twin differ by {difference:.1e} (relative)"
            print(f"| {label} | {len(stepper.model.ops.K.vertices):,} | {solver} | {1 / hand_s:.1f} | {1 / model_s:.1f} |"
                  f" {model_s / hand_s:.2f}× | {model_cpu / hand_cpu:.2f}× | {difference:.1e} |", flush=True)
            if explicit:
                break  # no factorization: the solver does not matter
    print(f"\n{load()}")


# ---------------------------------------------------------------------------------------------- part 2
def compile_cost(subdiv: int, repeat: int) -> None:
    from omegaconf import OmegaConf

    from decrun.apps.model import Model
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC
    from decrun.core.solvers import solver_factory
    from decrun.methods.model.integrators import make_integrator
    from decrun.runner.job.config import config_dir

    vertices, faces = icosphere_or_kuhn_cube("icosphere", subdiv)
    vertices = vertices / np.linalg.norm(vertices, axis=1, keepdims=True)
    gray_scott = {"model": "gray_scott", "fields": {"u": {"form": 0, "initial": f"1 - 0.5*{BUMP}"},
                                                    "v": {"form": 0, "initial": f"0.25*{BUMP}"}},
                  "constants": dict(GRAY_SCOTT), "equations": GRAY_SCOTT_EQUATIONS, "integrator": "imex", "dt": 1.0,
                  "steps": 10}
    cases = {"heat (crank_nicolson)": config_dir() / "app" / "heat.yaml", "gray_scott (imex)": gray_scott,
             "heat_geodesics (3 solves)": config_dir() / "app" / "heat_geodesics.yaml",
             "wave (symplectic)": config_dir() / "app" / "wave.yaml"}
    print(f"\n### Loading and compiling a model against the operator build ({len(vertices):,} vertices; best of "
          f"{repeat})\n")
    print("| model | operator build s | load s | compile + integrator set-up s | load + compile s | "
          "/ operator build | goal |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for name, source in cases.items():
        best = [math.inf, math.inf, math.inf]
        for _ in range(repeat):
            start = time.perf_counter()
            dec = DEC(SimplicialComplex(vertices, faces), star="mixed_area")
            dec.star(0), dec.star(1), dec.d(0), dec.laplacian_symmetric(0), dec.laplacian(0)
            built = time.perf_counter()
            if isinstance(source, dict):
                options = dict(source)
            else:
                options = OmegaConf.to_container(OmegaConf.load(source))
                options.pop("defaults", None)
                options.pop("_target_", None)
            app = Model(**options)
            loaded = time.perf_counter()
            new_solver = solver_factory("auto")
            model = app.compiled(dec, new_solver)
            if not model.is_static:
                make_integrator(model, str(app.integrator), app.dt, new_solver)
            done = time.perf_counter()
            best = [min(best[0], built - start), min(best[1], loaded - built), min(best[2], done - loaded)]
        total = best[1] + best[2]
        print(f"| {name} | {best[0]:.3f} | {best[1]:.4f} | {best[2]:.3f} | {total:.3f} | {total / best[0]:.2f} |"
              f" {'≤ 0.2 s: yes' if total <= 0.2 else '≤ 0.2 s: NO'} |", flush=True)
    print(f"\n{load()}")


# ---------------------------------------------------------------------------------------------- part 3
def run(overrides: list[str]):
    from model_convergence import run as run_

    return run_(overrides)


def _order(value) -> str:
    return "–" if value is None else f"{value:.2f}"


def table(title: str, header: str, rows: list[str]) -> None:
    print(f"\n### {title}\n")
    print(header)
    print("|" + "---|" * (header.count("|") - header.count("\\|") - 1))
    for row in rows:
        print(row)
    sys.stdout.flush()


def convergence(subdivs: list[int]) -> None:
    """The tables of ``model_convergence.tables`` (docs/models.md's convergence section), printed."""
    from model_convergence import HARMONICS, tables

    got = tables(tuple(subdivs))
    for l, initial in HARMONICS.items():
        table(f"Heat on the unit sphere, l = {l} (u0 = {initial}, exact e^(−{l * (l + 1)}t) u0; crank_nicolson, "
              "dt = 1e-4, t = 0.1)", "| subdiv | vertices | h | relative L2 error | order |",
              [f"| {r['subdiv']} | {r['vertices']:,} | {r['h']:.4f} | {r['error']:.3e} | {_order(r['order'])} |"
               for r in got[f"heat_l{l}"]])
    table("Poisson on the unit square (mesh=grid; u = sin(πx)cos(πy) + x², border values)",
          "| nx = ny | vertices | h (mean edge) | relative L2 error | max abs error | order |",
          [f"| {r['nx']} | {r['vertices']:,} | {r['h']:.4f} | {r['error']:.3e} | {r['max_error']:.2e} | "
           f"{_order(r['order'])} |" for r in got["poisson_square"]])
    table("Poisson on the unit disk (mesh=planar, a 96-gon, min angle 25°; same u, border values)",
          "| max_area | vertices | h | relative L2 error | max abs error | order |",
          [f"| {r['max_area']:g} | {r['vertices']:,} | {r['h']:.4f} | {r['error']:.3e} | {r['max_error']:.2e} | "
           f"{_order(r['order'])} |" for r in got["poisson_disk"]])
    table("The heat method on the unit sphere (exact: arccos(p·s); t = h², operator=mixed_area)",
          "| subdiv | faces | h | mean relative error | max abs error | order |",
          [f"| {r['subdiv']} | {r['faces']:,} | {r['h']:.4f} | {r['error']:.3e} | {r['max_error']:.2e} | "
           f"{_order(r['order'])} |" for r in got["geodesics"]])
    table("The wave's l = 2 mode on the unit sphere (symplectic, dt = 0.005, 10 periods): frequency against √6",
          "| subdiv | vertices | h | ω fitted | \\|ω − √6\\| / √6 | order | modified-energy drift (relative) |",
          [f"| {r['subdiv']} | {r['vertices']:,} | {r['h']:.4f} | {r['omega']:.6f} | {r['error']:.3e} | "
           f"{_order(r['order'])} | {r['drift']:.1e} |" for r in got["wave"]])
    print(f"\n{load()}")


def hand_halfar(done, library: str) -> tuple[np.ndarray, float, float]:
    """The Halfar run's scheme by hand on the run's own complex (the reference for its time): 200
    lagged steps (⋆0 + dt d0ᵀ diag(⋆1 D(Hⁿ)) d0) H⁺ = ⋆0 Hⁿ, dt = 1 a, with D per edge the mean
    over its triangles of Γ H̄^{n+2} |∇H|^{n−1} (H̄ the triangle's vertex mean, ∇H its P1 gradient).
    Returns (H at 200 a, wall s, CPU s)."""
    import scipy.sparse as sp
    from model_twins import HandSolver

    from decrun.core.dec import DEC
    from decrun.methods.model import discrete

    K = done.complex
    dec = DEC(K)
    d0, s0, s1 = dec.d(0).tocsr(), dec.star_diagonal(0), dec.star_diagonal(1)
    gamma = 2 * 1e-16 * (910.0 * 9.8101) ** 3 / 5
    triangles = K.simplices(2)
    P = K.vertices[triangles][:, :, :2]
    inverse = np.linalg.inv(np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=1))  # rows: ∂λ1, ∂λ2
    rows, cols = np.repeat(np.arange(len(triangles)), 3), triangles.ravel()
    shape = (len(triangles), K.num_simplices(0))
    gradient = [sp.csr_matrix((np.column_stack([-inverse[:, a].sum(axis=1), inverse[:, a, 0], inverse[:, a, 1]]).ravel(),
                               (rows, cols)), shape=shape) for a in (0, 1)]
    mean = sp.csr_matrix((np.full(rows.size, 1 / 3), (rows, cols)), shape=shape)
    to_edges = discrete.cell_to_edge_matrix(K)
    r = np.hypot(K.vertices[:, 0], K.vertices[:, 1])
    H = 707.1067811865476 * np.maximum(0.0, 1 - (r / 21213.203435596424) ** (4 / 3)) ** (3 / 7)
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(200):
        squared = (gradient[0] @ H) ** 2 + (gradient[1] @ H) ** 2
        D = gamma * (to_edges @ ((mean @ H) ** 5 * squared))
        H = HandSolver(sp.diags(s0) + d0.T @ sp.diags(s1 * D) @ d0, library).solve(s0 * H)
    return H, time.perf_counter() - wall, time.process_time() - cpu


def halfar() -> None:
    """The CISM v2.1 Halfar dome (``+experiment=cism_halfar``, ``app=halfar``: semi_implicit, dt = 1 a,
    0 → 200 a) on the benchmark's grid at 4, 2 and 1 km, the dome on the centre vertex: RMS and max
    error against Halfar's solution over the ice (CISM reports 6.43 m and 9.06 m RMS at 2 km), and
    the time of the default run (``solver=auto``: CHOLMOD) — wall and CPU seconds of the whole run
    (mesh, operators, 200 steps, result), the model's stepping, and the same 200 steps written by
    hand (:func:`hand_halfar`, cholespy's CHOLMOD) in the same process: their ratio is what load
    does not distort."""
    rows = []
    for spacing in ("4km", "2km", "1km"):
        wall, cpu = time.perf_counter(), time.process_time()
        done, h = run(["+experiment=cism_halfar", f"mesh=cism_halfar/{spacing}"])
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        m = done.result.metrics
        volume = np.asarray(done.result.series["volume_m3"])
        H, hand_wall, hand_cpu = hand_halfar(done, "cholmod")
        agree = float(np.abs(H - np.asarray(done.result.fields["H"])).max())
        rows.append(f"| {spacing} | {m['n_vertices']:,} | {m['rms_error_m']:.2f} | {m['max_error_m']:.1f} |"
                    f" {m['min_thickness_m']:.1e} | {abs(volume[-1] - volume[0]) / volume[0]:.1e} |"
                    f" {wall:.2f} / {cpu:.2f} | {m['solve_seconds']:.2f} | {hand_wall:.2f} / {hand_cpu:.2f} |"
                    f" {m['solve_seconds'] / hand_wall:.2f} | {agree:.0e} |")
    table("The Halfar dome, CISM v2.1 (+experiment=cism_halfar: semi_implicit, dt = 1 a, 200 a; CISM: 6.43 / 9.06 m "
          "RMS at 2 km)", "| grid | vertices | RMS error over the ice (m) | max error (m) | min H (m) |"
          " volume drift (relative) | run wall / CPU s | model steps s | hand steps wall / CPU s | model / hand |"
          " max \\|H − H_hand\\| (m) |", rows)
    print(f"\n{load()}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="subdiv 5 (10,242 vertices) for the speed and compile parts")
    parser.add_argument("--part", choices=["speed", "compile", "convergence", "halfar"], action="append",
                        help="only these parts (default: all)")
    parser.add_argument("--steps", type=int, default=40, help="steps per round (speed)")
    parser.add_argument("--model", action="append", help="only these models in the speed part (default: all)")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (speed; the best is reported)")
    args = parser.parse_args(argv)
    parts = args.part or ["speed", "compile", "convergence", "halfar"]
    subdiv = 5 if args.quick else 7
    print(f"bench_models: {' '.join(sys.argv)}  ({load()}, {os.cpu_count()} cores)")
    if "speed" in parts:
        speed(args.quick, args.steps, args.rounds, args.model)
    if "compile" in parts:
        compile_cost(subdiv, 3)
    if "convergence" in parts:
        convergence([3, 4, 5] if args.quick else [3, 4, 5, 6])
    if "halfar" in parts:
        halfar()
    print(f"\nrerun: OMP_NUM_THREADS=1 python benchmarks/bench_models.py {' '.join(argv if argv is not None else sys.argv[1:])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
