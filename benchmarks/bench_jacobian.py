"""Newton's Jacobian assembly against one residual evaluation (issue 47's goal: ≤ 2×).

On a grid of ≥ 50k vertices (``mesh=grid``, nx = ny = 225: 50,625 vertices), for Allen–Cahn
``dt(u) = 1e-4*laplacian(u) + u - u**3`` and Gray–Scott (``conf/app/gray_scott.yaml``'s equations
and constants), the compiled model's ``Problem`` (``model.problem``: M y' = f(y, t) over the free
values) is timed in the same run:

- ``residual``: one f(y, t) — the evaluator of every term;
- ``jacobian``: one ∂f/∂y — the derivative pass's closures (each operator's rule) assembled into
  one sparse matrix, L + M ∂R/∂y.

Each is the best of ``--repeat`` timings (time.perf_counter) after one warm-up call; the ratio
jacobian/residual is printed with the load average, as the machine is shared.

    python benchmarks/bench_jacobian.py [--nx 225] [--repeat 7]
"""

from __future__ import annotations

import argparse
import os
import time

MODELS = {
    "allen_cahn": {"fields": {"u": "0.1*sin(7*x)*cos(5*y)"}, "constants": {},
                   "equations": ["dt(u) = 1e-4*laplacian(u) + u - u**3"]},
    "gray_scott": {"fields": {"v": "0.25 + 0.1*sin(9*x)*cos(7*y)", "u": "0.5 + 0.1*cos(5*x)*sin(3*y)"},
                   "constants": {"Du": 8.0e-4, "Dv": 4.0e-4, "F": 0.035, "k": 0.065},
                   "equations": ["dt(v) = Dv*laplacian(v) + u*v**2 - (F + k)*v",
                                 "dt(u) = Du*laplacian(u) - u*v**2 + F*(1 - u)"]},
}


def problem_of(name: str, nx: int):
    """The compiled model ``name`` on an nx × nx grid of the unit square, and its ``Problem``."""
    from decrun import DEC, SimplicialComplex
    from decrun.core.solvers import solver_factory
    from decrun.methods.model import FieldSpec, ModelSpec, compile_model
    from decrun.runner.mesh.sources.primitives import Grid

    mesh = Grid(nx=nx, ny=nx, width=1.0, height=1.0).make()
    dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
    entry = MODELS[name]
    spec = ModelSpec(fields={field: FieldSpec(0, initial) for field, initial in entry["fields"].items()},
                     equations=entry["equations"], constants=entry["constants"], dt=1.0)
    model = compile_model(spec, dec, solver_factory("auto"))
    return model, model.problem, dec.K.num_simplices(0)


def best_of(function, repeat: int) -> float:
    """The shortest of ``repeat`` wall times of ``function()`` (s), after one warm-up call."""
    function()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def measure(name: str, nx: int, repeat: int) -> dict:
    """``{"vertices", "residual_s", "jacobian_s", "ratio"}`` of model ``name``."""
    model, problem, vertices = problem_of(name, nx)
    y = problem.free_values(model.initial_values)
    problem.check_jacobian()
    residual = best_of(lambda: problem.f(y, 0.0), repeat)
    jacobian = best_of(lambda: problem.jacobian(y, 0.0), repeat)
    return {"vertices": vertices, "residual_s": residual, "jacobian_s": jacobian, "ratio": jacobian / residual}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nx", type=int, default=225)
    parser.add_argument("--repeat", type=int, default=7)
    arguments = parser.parse_args()
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    for name in MODELS:
        row = measure(name, arguments.nx, arguments.repeat)
        print(f"{name:12s} vertices={row['vertices']}  residual={1e3 * row['residual_s']:.2f} ms  "
              f"jacobian={1e3 * row['jacobian_s']:.2f} ms  ratio={row['ratio']:.2f}")
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
