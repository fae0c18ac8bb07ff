"""Benchmark: Whitney (Galerkin) mass matrices M_0..M_n, against libigl as the reference.

For each mesh, in a fresh subprocess (so peak memory is that case's alone):

* decrun: ``whitney_mass_matrix(K, k)`` for k = 0..n on a ``SimplicialComplex`` built
  before the clock starts (its build time is reported in its own column: every operator
  variant shares it);
* libigl (reference, triangles only): ``cotmatrix`` + ``massmatrix(FULL)`` — the P1
  stiffness and mass, i.e. d0ᵀ M1 d0 and M0 — from (V, F).

Reports wall time (best of ``--repeat``) and the peak resident memory above the memory
the process holds before the timed work (mesh, and for decrun the complex), with the
high-water mark reset first; and the ratios decrun / libigl. Requires libigl
(``pip install -e .[bench]``); without it the reference columns are skipped.

    python benchmarks/bench_whitney.py            # up to 1.3M triangles and ~1M tets
    python benchmarks/bench_whitney.py --quick    # small meshes, seconds
"""

from __future__ import annotations

import time

from harness import best_of, have_libigl, icosphere_or_kuhn_cube, parse_or_run_case, spawn  # noqa: E402

TRIANGLE_CASES = {"quick": [4, 5], "full": [6, 7, 8]}  # icosphere subdivisions: 20·4^s triangles
TET_CASES = {"quick": [8, 12], "full": [25, 40, 55]}  # Kuhn cubes: 6·n³ tetrahedra


def run_case(library: str, kind: str, size: int, repeat: int) -> dict:
    """Runs inside the subprocess: one library on one mesh."""
    vertices, simplices = icosphere_or_kuhn_cube(kind, size)
    build_seconds = None
    if library == "decrun":
        from decrun.core.complex import SimplicialComplex
        from decrun.core.whitney import whitney_mass_matrix

        start = time.perf_counter()
        K = SimplicialComplex(vertices, simplices)
        build_seconds = time.perf_counter() - start

        def work():
            return [whitney_mass_matrix(K, k) for k in range(K.dim + 1)]
    else:
        import igl

        def work():
            return igl.cotmatrix(vertices, simplices), igl.massmatrix(vertices, simplices, igl.MASSMATRIX_TYPE_FULL)

    seconds, peak_mb, _ = best_of(work, repeat)
    return {"seconds": seconds, "peak_mb": peak_mb, "simplices": len(simplices), "complex_seconds": build_seconds}


def main(argv=None) -> int:
    args = parse_or_run_case(__doc__, run_case, argv)
    if args is None:
        return 0
    have_igl = have_libigl()

    level = "quick" if args.quick else "full"
    print("| mesh | simplices | complex s | Whitney M_0..M_n s | peak MB | libigl cot+mass s | libigl peak MB "
          "| time ratio | memory ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for size in TRIANGLE_CASES[level]:
        ours = spawn(__file__, "decrun", "icosphere", size, args.repeat)
        row = (f"| icosphere subdiv {size} | {ours['simplices']:,} | {ours['complex_seconds']:.2f} |"
               f" {ours['seconds']:.3f} | {ours['peak_mb']:.0f} |")
        if have_igl:
            ref = spawn(__file__, "igl", "icosphere", size, args.repeat)
            row += (f" {ref['seconds']:.3f} | {ref['peak_mb']:.0f} | {ours['seconds'] / ref['seconds']:.2f} |"
                    f" {ours['peak_mb'] / max(ref['peak_mb'], 1e-9):.2f} |")
        else:
            row += " – | – | – | – |"
        print(row, flush=True)
    for size in TET_CASES[level]:
        ours = spawn(__file__, "decrun", "kuhn", size, 1 if size > 30 else args.repeat)
        print(f"| Kuhn cube n={size} (tets, M_0..M_3) | {ours['simplices']:,} | {ours['complex_seconds']:.2f} |"
              f" {ours['seconds']:.3f} | {ours['peak_mb']:.0f} | – | – | – | – |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
