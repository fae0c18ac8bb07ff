"""Benchmark: sparse direct solvers on the SPD systems the applications factorize.

Systems on an icosphere (mixed-area ⋆0, circumcentric ⋆1; S = d0ᵀ ⋆1 d0, M = ⋆0):

* ``smoothing``: M + dt S, the implicit mean curvature flow step (dt = 1e-3);
* ``diffusion``: M + ν dt S, the fluid's viscosity step (ν dt = 1e-5);
* ``poisson``: S + ε M, the shifted singular Poisson problem of the Hodge decomposition
  (:class:`decrun.core.solvers.SingularSolve`, ε = 1e-10 relative).

Solvers: ``direct`` (SuperLU, COLAMD — its configured default), ``auto`` (the default: CHOLMOD
through the fastest binding installed), ``cholmod:sksparse`` (scikit-sparse, CHOLMOD's
supernodal factorization), ``cholmod:cholespy`` (the cholespy wheel, which fixes CHOLMOD's
simplicial factorization), ``pardiso`` (MKL PARDISO via pypardiso, mtype 11 as configured), and
the anchor ``scikit-sparse``: ``sksparse.cholmod.cholesky`` called directly, which decrun's
``auto`` is measured against (the last column, factorization CPU seconds). Each case
runs in its own process; factor and solve (one right-hand side) seconds are the best of
``--repeat`` (wall clock, and the factorization's CPU seconds over all threads: PARDISO and
CHOLMOD may use several cores), and the relative residual checks the answer.

    python benchmarks/bench_solvers.py            # 164k and 655k vertices
    python benchmarks/bench_solvers.py --quick    # 10k and 41k vertices

``--iterative`` instead runs three slow-to-converge cases through the real CLI, each with
``solver=direct`` and ``solver=iterative`` in its own process, and prints the apps' solve
seconds, their iterative/direct ratio (the goal: ≤ 10) and the largest difference of the
result fields (relative to the largest field of the same shape) except those defined only
up to a gauge: the potentials α, β (up to constants, as in
``tests/apps/test_iterative_solver_apps.py``) and the eigenforms (up to sign and a rotation
within an eigenspace; the eigenvalues are compared):

    python benchmarks/bench_solvers.py --iterative
"""

from __future__ import annotations

import time

import numpy as np

from harness import icosphere_or_kuhn_cube, parse_or_run_case, spawn  # noqa: E402

SIZES = {"quick": [5, 6], "full": [7, 8]}  # icosphere subdivisions: 10·4^s + 2 vertices
SYSTEMS = ["smoothing", "diffusion", "poisson"]
SOLVERS = ["direct", "auto", "cholmod:sksparse", "cholmod:cholespy", "pardiso", "scikit-sparse"]


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
    name, _, backend = library.partition(":")
    for _ in range(repeat):
        solver = _Anchor() if library == "scikit-sparse" else \
            make_solver(name, backend=backend) if backend else make_solver(name)
        start, start_cpu = time.perf_counter(), time.process_time()
        solver.factorize(A)
        factor, factor_cpu = min(factor, time.perf_counter() - start), min(factor_cpu, time.process_time() - start_cpu)
        start = time.perf_counter()
        x = solver.solve(b)
        solve = min(solve, time.perf_counter() - start)
    residual = float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))
    return {"factor": factor, "factor_cpu": factor_cpu, "solve": solve, "residual": residual, "n": A.shape[0]}


class _Anchor:
    """scikit-sparse's CHOLMOD called directly (supernodal, its default ordering): the anchor."""

    def factorize(self, A):
        import scipy.sparse as sp
        from sksparse.cholmod import cholesky

        self.factor = cholesky(sp.csc_matrix(A), mode="supernodal")
        return self

    def solve(self, b):
        return self.factor(b)


#: the cases where solver=iterative was 100–200× slower than direct
ITERATIVE_CASES = {
    "hodge torus circumcentric noisy": ["app=hodge", "mesh=torus", "mesh.noise=0.05", "operator=circumcentric"],
    "hodge bunny circumcentric": ["app=hodge", "mesh=bunny", "operator=circumcentric"],
    "spectrum bunny degree 1": ["app=spectrum", "mesh=bunny", "app.degree=1", "operator=whitney"],
}


UP_TO_A_GAUGE = {"alpha", "beta", "eigenforms"}


def cli_fields(overrides: list[str], solver: str, run_dir: str) -> tuple[dict, dict]:
    """Runs ``decrun <overrides> solver=<solver>`` in its own process; (fields, metrics)."""
    import subprocess
    import sys
    from pathlib import Path

    from decrun.runner.results import read_result

    decrun = Path(sys.executable).with_name("decrun")
    subprocess.run([str(decrun), *overrides, f"solver={solver}", "figures=false", f"hydra.run.dir={run_dir}"],
                   check=True, capture_output=True, text=True)
    result = read_result(Path(run_dir) / "result.h5")
    fields = {k: np.asarray(v, dtype=float) for k, v in result.fields.items()
              if np.asarray(v).dtype.kind in "fc" and np.asarray(v).size and k not in UP_TO_A_GAUGE}
    return fields, result.metrics


def iterative_against_direct() -> int:
    """The table of ``--iterative``."""
    import tempfile

    print("| case | direct solve s | iterative solve s | iterative / direct | max field difference |")
    print("|---|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, overrides in ITERATIVE_CASES.items():
            runs = {solver: cli_fields(overrides, solver, f"{tmp}/{solver}-{len(name)}") for solver in ("direct", "iterative")}
            (direct, direct_metrics), (iterative, metrics) = runs["direct"], runs["iterative"]
            difference = max(np.abs(iterative[k] - v).max()
                             / (max(np.abs(w).max() for w in direct.values() if w.shape == v.shape) or 1.0)
                             for k, v in direct.items())
            print(f"| {name} | {direct_metrics['solve_seconds']:.2f} | {metrics['solve_seconds']:.2f} |"
                  f" {metrics['solve_seconds'] / direct_metrics['solve_seconds']:.1f} | {difference:.1e} |", flush=True)
    return 0


def main(argv=None) -> int:
    import sys

    if "--iterative" in (sys.argv[1:] if argv is None else argv):
        return iterative_against_direct()
    args = parse_or_run_case(__doc__, run_case, argv)
    if args is None:
        return 0
    import os

    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print("| system | vertices | solver | factor s | factor CPU s | solve s | relative residual | factor vs direct |"
          " factor CPU vs scikit-sparse |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for size in SIZES["quick" if args.quick else "full"]:
        for kind in SYSTEMS:
            rows = {}
            for library in SOLVERS:
                try:
                    rows[library] = spawn(__file__, library, kind, size, args.repeat)
                except Exception as exc:  # a solver that is not installed or fails: say so
                    print(f"| {kind} | – | {library} | failed: {str(exc).splitlines()[0][:60]} | | | | | |", flush=True)
            reference, anchor = rows.get("direct"), rows.get("scikit-sparse")
            for library, row in rows.items():
                versus = f"{row['factor'] / reference['factor']:.2f}" if reference else "–"
                cpu = f"{row['factor_cpu'] / anchor['factor_cpu']:.2f}" if anchor else "–"
                print(f"| {kind} | {row['n']:,} | {library} | {row['factor']:.3f} | {row['factor_cpu']:.3f} |"
                      f" {row['solve']:.4f} | {row['residual']:.1e} | {versus} | {cpu} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
