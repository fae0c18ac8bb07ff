"""Benchmark: sparse direct solvers on the SPD systems the applications factorize.

Systems on an icosphere (mixed-area ⋆0, circumcentric ⋆1; S = d0ᵀ ⋆1 d0, M = ⋆0):

* ``smoothing``: M + dt S, the implicit mean curvature flow step (dt = 1e-3);
* ``diffusion``: M + ν dt S, the fluid's viscosity step (ν dt = 1e-5);
* ``poisson``: S + ε M, the shifted singular Poisson problem of the Hodge decomposition
  (:class:`decrun.core.solvers.SingularSolve`, ε = 1e-10 relative).

Solvers: ``direct`` (SuperLU, COLAMD — its configured default), ``cholmod`` (CHOLMOD via the
cholespy wheel), ``pardiso`` (MKL PARDISO via pypardiso, mtype 11 as configured). Each case
runs in its own process; factor and solve (one right-hand side) seconds are the best of
``--repeat`` (wall clock, and the factorization's CPU seconds over all threads: PARDISO and
CHOLMOD may use several cores), and the relative residual checks the answer.

    python benchmarks/bench_solvers.py            # 164k and 655k vertices
    python benchmarks/bench_solvers.py --quick    # 10k and 41k vertices
"""

from __future__ import annotations

import time

import numpy as np

from harness import icosphere_or_kuhn_cube, parse_or_run_case, spawn  # noqa: E402

SIZES = {"quick": [5, 6], "full": [7, 8]}  # icosphere subdivisions: 10·4^s + 2 vertices
SYSTEMS = ["smoothing", "diffusion", "poisson"]
SOLVERS = ["direct", "cholmod", "pardiso"]


def system(kind: str, size: int):
    """The (n, n) CSR matrix of system ``kind`` on the icosphere of ``size`` subdivisions."""
    import scipy.sparse as sp

    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC

    vertices, faces = icosphere_or_kuhn_cube("icosphere", size)
    dec = DEC(SimplicialComplex(vertices, faces), star="mixed_area")
    S, M = dec.laplacian_symmetric(0), dec.star(0)
    if kind == "smoothing":
        return (M + 1e-3 * S).tocsr()
    if kind == "diffusion":
        return (M + 1e-5 * S).tocsr()
    shift = 1e-10 * float(np.abs(S.diagonal()).mean() / M.diagonal().mean())
    return (S + shift * M).tocsr() if kind == "poisson" else sp.csr_matrix(S)


def run_case(library: str, kind: str, size: int, repeat: int) -> dict:
    """Runs inside the subprocess: one solver on one system."""
    from decrun.core.solvers import make_solver

    A = system(kind, size)
    b = A @ np.random.default_rng(0).standard_normal(A.shape[0])
    factor = solve = factor_cpu = np.inf
    for _ in range(repeat):
        solver = make_solver(library)
        start, start_cpu = time.perf_counter(), time.process_time()
        solver.factorize(A)
        factor, factor_cpu = min(factor, time.perf_counter() - start), min(factor_cpu, time.process_time() - start_cpu)
        start = time.perf_counter()
        x = solver.solve(b)
        solve = min(solve, time.perf_counter() - start)
    residual = float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))
    return {"factor": factor, "factor_cpu": factor_cpu, "solve": solve, "residual": residual, "n": A.shape[0]}


def main(argv=None) -> int:
    args = parse_or_run_case(__doc__, run_case, argv)
    if args is None:
        return 0
    print("| system | vertices | solver | factor s | factor CPU s | solve s | relative residual | factor vs direct |")
    print("|---|---:|---|---:|---:|---:|---:|---:|")
    for size in SIZES["quick" if args.quick else "full"]:
        for kind in SYSTEMS:
            reference = None
            for library in SOLVERS:
                try:
                    row = spawn(__file__, library, kind, size, args.repeat)
                except Exception as exc:  # a solver that is not installed or fails: say so
                    print(f"| {kind} | – | {library} | failed: {str(exc).splitlines()[0][:60]} | | | | |", flush=True)
                    continue
                reference = reference or row["factor"]
                print(f"| {kind} | {row['n']:,} | {library} | {row['factor']:.3f} | {row['factor_cpu']:.3f} |"
                      f" {row['solve']:.4f} |"
                      f" {row['residual']:.1e} | {row['factor'] / reference:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
