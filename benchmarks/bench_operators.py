"""Benchmark: building the DEC operator set, against libigl as the reference.

For each mesh, in a fresh subprocess (so peak memory is that case's alone):

* decrun: ``SimplicialComplex(V, F)`` (with its validation) + ``d(0)``, ``d(1)``, ``⋆0..⋆2``
  (circumcentric) — or, on tetrahedra, ``⋆0..⋆3``;
* libigl (reference, triangles only): ``cotmatrix`` + ``massmatrix(VORONOI)``.

Reports wall time (best of ``--repeat``) and peak resident memory above the process's
memory after loading the mesh, and the ratios decrun / libigl. Requires the ``bench``
extra (``pip install -e .[bench]``); without libigl the reference columns are skipped
with a message.

    python benchmarks/bench_operators.py            # full: up to 1.3M triangles, 1M tets
    python benchmarks/bench_operators.py --quick    # small meshes, seconds
    python benchmarks/bench_operators.py --jit      # numba's first-call cost: cold vs warm cache
"""

from __future__ import annotations

import sys

from harness import best_of, have_libigl, icosphere_or_kuhn_cube, parse_or_run_case, spawn, warm_up_kernels  # noqa: E402

TRIANGLE_CASES = {"quick": [4, 5], "full": [5, 6, 7, 8]}  # icosphere subdivisions: 20·4^s triangles
TET_CASES = {"quick": [8, 12], "full": [15, 25, 40, 55]}  # Kuhn cubes: 6·n³ tetrahedra


def run_case(library: str, kind: str, size: int, repeat: int) -> dict:
    """Runs inside the subprocess: one library on one mesh."""
    vertices, simplices = icosphere_or_kuhn_cube(kind, size)
    if library == "decrun":
        from decrun.core.complex import SimplicialComplex
        from decrun.core.dec import DEC

        warm_up_kernels()  # numba's import and the kernel cache: once per process, reported by --jit

        def work():
            K = SimplicialComplex(vertices, simplices)
            dec = DEC(K)
            ops = [dec.d(0), dec.d(1)] + [dec.star(k) for k in range(K.dim + 1)]
            return ops
    else:
        import igl

        def work():
            return igl.cotmatrix(vertices, simplices), igl.massmatrix(vertices, simplices, igl.MASSMATRIX_TYPE_VORONOI)

    seconds, peak_mb, _ = best_of(work, repeat)
    return {"seconds": seconds, "peak_mb": peak_mb, "simplices": len(simplices)}


def jit_times() -> None:
    """First-call cost of the kernels in fresh processes: an empty cache (compile) and then the
    cache it wrote (load), besides numba's import alone."""
    import os
    import subprocess
    import sys
    import tempfile

    code = ("import time, sys; sys.path.insert(0, %r); t = time.perf_counter(); import numba; "
            "imported = time.perf_counter() - t; from harness import warm_up_kernels; "
            "print(imported, warm_up_kernels())" % os.path.dirname(os.path.abspath(__file__)))
    print("| numba cache | numba import s | kernels' first call s (incl. compile or load) |")
    print("|---|---:|---:|")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, DECRUN_NUMBA="1")
        for label in ("cold (empty)", "warm", "warm"):
            out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
            imported, first = (float(v) for v in out.stdout.split())
            print(f"| {label} | {imported:.2f} | {first:.2f} |", flush=True)


def main(argv=None) -> int:
    if argv is None and "--jit" in sys.argv:
        jit_times()
        return 0
    args = parse_or_run_case(__doc__, run_case, argv)
    if args is None:
        return 0

    have_igl = have_libigl()

    level = "quick" if args.quick else "full"
    print("| mesh | simplices | decrun s | decrun peak MB | libigl s | libigl peak MB | time ratio | memory ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for size in TRIANGLE_CASES[level]:
        ours = spawn(__file__, "decrun", "icosphere", size, args.repeat)
        row = f"| icosphere subdiv {size} | {ours['simplices']:,} | {ours['seconds']:.3f} | {ours['peak_mb']:.0f} |"
        if have_igl:
            ref = spawn(__file__, "igl", "icosphere", size, args.repeat)
            row += (f" {ref['seconds']:.3f} | {ref['peak_mb']:.0f} | {ours['seconds'] / ref['seconds']:.2f} |"
                    f" {ours['peak_mb'] / max(ref['peak_mb'], 1e-9):.2f} |")
        else:
            row += " – | – | – | – |"
        print(row, flush=True)
    for size in TET_CASES[level]:
        ours = spawn(__file__, "decrun", "kuhn", size, 1 if size > 30 else args.repeat)
        print(f"| Kuhn cube n={size} (tets, ⋆0–⋆3) | {ours['simplices']:,} | {ours['seconds']:.3f} |"
              f" {ours['peak_mb']:.0f} | – | – | – | – |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
