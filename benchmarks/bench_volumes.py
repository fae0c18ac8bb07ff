"""Benchmark: tetrahedral meshes from ``mesh=tetrahedralize`` up to ~1M tetrahedra.

For each target size, in a fresh subprocess (peak memory is that case's alone):

* ``tetrahedralize``: TetGen fills the unit icosphere (subdiv 3, 1280 triangles) with
  ``quality`` (radius–edge ≤ 1.5) and ``max_volume`` = ball volume / target;
* ``complex``: ``SimplicialComplex(V, T)`` with its validation;
* ``operators``: ``d(0..2)`` and the circumcentric ``⋆0..⋆3``;
* ``spectrum`` (up to ``--spectrum-max`` tetrahedra): the 10 lowest eigenpairs of Δ0.

The reference, in the same run, is the Kuhn cube with about as many tetrahedra (complex +
operators): the ratio tetrahedralized / Kuhn says what an unstructured mesh costs over a
structured one of the same size, independent of the machine's load.

    python benchmarks/bench_volumes.py            # 10k, 100k, 1M tetrahedra
    python benchmarks/bench_volumes.py --quick    # 10k, 50k
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

import numpy as np
from harness import peak_rss_bytes, reset_peak_rss  # noqa: E402

CASES = {"quick": [10_000, 50_000], "full": [10_000, 100_000, 1_000_000]}


def _operators(vertices, tets):
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC

    start = time.perf_counter()
    K = SimplicialComplex(vertices, tets)
    complex_seconds = time.perf_counter() - start
    start = time.perf_counter()
    dec = DEC(K)
    for k in range(3):
        dec.d(k)
    for k in range(4):
        dec.star(k)
    return K, dec, complex_seconds, time.perf_counter() - start


def run_case(target: int, spectrum_max: int) -> dict:
    """Runs inside the subprocess: one target size."""
    import pymeshlab

    from decrun.core.primitives import kuhn_cube
    from decrun.runner.mesh.sources.volumes import tetrahedralize_surface

    ms = pymeshlab.MeshSet()
    ms.create_sphere(radius=1.0, subdiv=3)
    surface = ms.current_mesh()
    reset_peak_rss()
    start = time.perf_counter()
    vertices, tets, counts = tetrahedralize_surface(surface.vertex_matrix(), surface.face_matrix(),
                                                    max_volume=4.0 / 3.0 * np.pi / target)
    tet_seconds = time.perf_counter() - start
    K, dec, complex_seconds, operator_seconds = _operators(vertices, tets)
    out = {"target": target, "tetrahedra": int(len(tets)), "vertices": int(len(vertices)),
           "edges": int(K.num_simplices(1)), "tetrahedralize_s": tet_seconds, "complex_s": complex_seconds,
           "operators_s": operator_seconds, "peak_rss_mb": peak_rss_bytes() / 2**20}
    if len(tets) <= spectrum_max:
        from decrun.methods.spectrum import laplacian_eigenpairs

        start = time.perf_counter()
        laplacian_eigenpairs(dec, 0, 10)
        out["spectrum_s"] = time.perf_counter() - start
    del K, dec
    cells = max(2, round((len(tets) / 6) ** (1 / 3)))
    kv, kt = kuhn_cube(cells)
    _, _, kuhn_complex, kuhn_operators = _operators(kv, kt)
    out.update(kuhn_tetrahedra=int(len(kt)), kuhn_complex_s=kuhn_complex, kuhn_operators_s=kuhn_operators)
    out["ratio_vs_kuhn_per_tet"] = ((complex_seconds + operator_seconds) / len(tets)) / (
        (kuhn_complex + kuhn_operators) / len(kt))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--spectrum-max", type=int, default=200_000)
    parser.add_argument("--case", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case is not None:
        print(json.dumps(run_case(args.case, args.spectrum_max)))
        return
    rows = []
    for target in CASES["quick" if args.quick else "full"]:
        done = subprocess.run([sys.executable, __file__, "--case", str(target), "--spectrum-max",
                               str(args.spectrum_max)], capture_output=True, text=True)
        if done.returncode != 0:
            print(done.stderr, file=sys.stderr)
            continue
        rows.append(json.loads(done.stdout.strip().splitlines()[-1]))
    print("| tets | vertices | tetrahedralize s | complex s | operators s | Δ0 10 eigenpairs s | peak MB | "
          "(complex+ops)/tet vs Kuhn |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        spectrum = f"{r['spectrum_s']:.2f}" if "spectrum_s" in r else "–"
        print(f"| {r['tetrahedra']:,} | {r['vertices']:,} | {r['tetrahedralize_s']:.2f} | {r['complex_s']:.2f} | "
              f"{r['operators_s']:.2f} | {spectrum} | {r['peak_rss_mb']:.0f} | {r['ratio_vs_kuhn_per_tet']:.2f} |")


if __name__ == "__main__":
    main()
