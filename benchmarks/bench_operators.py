"""Benchmark: building the DEC operator set, against libigl and the scipy floor, in one run.

The work: ``SimplicialComplex(V, F)`` (with its validation) + ``d(0)``, ``d(1)``, ``⋆0..⋆2``
(circumcentric). The anchor: libigl's ``cotmatrix`` + ``massmatrix(VORONOI)``. The floor:
scipy building the same five operators as CSR from COO triplets holding the same nonzeros
(what any sparse assembly of them pays at least).

Each mesh runs in fresh subprocesses:

* **fresh** (two processes of their own, nothing else run in them before): importing decrun's
  complex and operators (reported alone), then the first build in the process under ``auto``
  (what a one-off ``decrun`` run pays), in CPU time; and, in the other, libigl's first call;
* **whole process** (``--whole``): a fresh Python process that loads the mesh (``.npz``), imports
  decrun and builds once, against one that imports libigl and calls it once: each process's
  CPU time from start to exit (interpreter, numpy, scipy and all), interleaved, best and median;
* **warm** (the same process): ``--repeat`` interleaved rounds of libigl, the floor, decrun's
  numpy twins (``numpy``) and decrun's compiled extension (``auto``, when the install built it),
  each timed in CPU time
  (``time.process_time``: the shared machine's load distorts wall time), best of the rounds;
  and the worst of the extension's own rounds (a build touches its memory anew each time).

Ratios are decrun / libigl (and decrun / floor) from the same process; the fresh ratio is decrun's
first build over libigl's first call, each the best of ``--repeat`` fresh processes (and decrun's worst
process over libigl's best). The machine's load
average is printed before and after.

``--keep-freed-memory`` runs every process with glibc's ``mallopt`` keeping the memory a build
frees for the next one (``M_MMAP_THRESHOLD`` and ``M_TRIM_THRESHOLD`` at 1 GiB): no warm round,
of the floor or of decrun, pays the first touch of memory the previous round gave back to the
system, so their ratio is the work's (decrun does not set this itself: it is the process's
policy, not a library's).

    python benchmarks/bench_operators.py            # 82k, 328k, 1.31M triangles
    python benchmarks/bench_operators.py --quick    # 20k, 82k triangles, seconds
    python benchmarks/bench_operators.py --whole    # whole processes: decrun's against libigl's, 82k and 328k
    python benchmarks/bench_operators.py --keep-freed-memory   # warm rounds without first touches
"""

from __future__ import annotations

import os
import sys
import time

from harness import have_libigl, icosphere_or_kuhn_cube, parse_or_run_case, spawn  # noqa: E402

TRIANGLE_CASES = {"quick": [5, 6], "full": [6, 7, 8]}  # icosphere subdivisions: 20·4^s triangles


KEEP_FREED_MEMORY = "BENCH_OPERATORS_KEEP_FREED_MEMORY"  # set by --keep-freed-memory for the case processes


def _keep_freed_memory() -> bool:
    """glibc's ``mallopt``: allocations up to 1 GiB from the heap, and freed heap memory kept up to
    1 GiB (instead of given back, to be touched anew by the next round). False where it is no glibc."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3  # glibc's malloc.h
    return bool(mallopt(m_mmap_threshold, 1 << 30)) and bool(mallopt(m_trim_threshold, 1 << 30))


def _cpu(work) -> float:
    start = time.process_time()
    work()
    return time.process_time() - start


def _decrun_operators(vertices, faces):
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC

    K = SimplicialComplex(vertices, faces)
    dec = DEC(K)
    return [dec.d(0), dec.d(1)] + [dec.star(k) for k in range(3)]


def _floor_work(operators):
    """The floor: the same nonzeros (COO triplets, computed beforehand) to CSR with scipy."""
    import scipy.sparse as sp

    triplets = []
    for op in operators:
        coo = op.tocoo()
        triplets.append((coo.data.copy(), coo.row.copy(), coo.col.copy(), op.shape))

    def work():
        return [sp.coo_matrix((data, (row, col)), shape=shape).tocsr() for data, row, col, shape in triplets]

    return work


def _reference(vertices, faces):
    import igl

    return igl.cotmatrix(vertices, faces), igl.massmatrix(vertices, faces, igl.MASSMATRIX_TYPE_VORONOI)


def run_case(library: str, kind: str, size: int, repeat: int) -> dict:
    """Runs inside the subprocess: ``fresh`` (decrun's import and first build, nothing else),
    ``igl-fresh`` (libigl's first call, nothing else) or ``all`` (the other columns)."""
    kept = os.environ.get(KEEP_FREED_MEMORY) == "1" and _keep_freed_memory()
    vertices, faces = icosphere_or_kuhn_cube(kind, size)
    if library == "igl-fresh":
        import igl  # noqa: F401  (its import is not its call)

        return {"igl_fresh_s": _cpu(lambda: _reference(vertices, faces))}
    if library == "fresh":
        def imports():
            import decrun.core.complex  # noqa: F401
            import decrun.core.dec  # noqa: F401

        result = {"import_s": _cpu(imports)}  # decrun's modules with numpy and scipy's
        result["fresh_auto_s"] = _cpu(lambda: _decrun_operators(vertices, faces))
        result["fresh_imported_numba"] = "numba" in sys.modules
        return result
    import numpy as np

    from decrun.core import extension, jit

    load_before = os.getloadavg()[0]
    result = {"simplices": int(len(faces)), "extension": extension.built() is not None, "kept": kept}

    def ours():
        return _decrun_operators(vertices, faces)

    def reference():
        return _reference(vertices, faces)

    reference()  # libigl's own first call (page faults of its code) stays out of its best
    with jit.use("auto"):
        operators = ours()
    with jit.use("numpy"):
        twins = ours()
    for a, b in zip(operators, twins, strict=True):  # the two paths agree (the tests hold them to it)
        assert a.shape == b.shape and abs(a - b).max() <= 1e-12 * max(abs(b).max(), 1.0)
    floor = _floor_work(operators)
    best = {"igl": np.inf, "floor": np.inf, "numpy": np.inf, "extension": np.inf}
    worst = {"extension": 0.0}
    for _ in range(repeat):
        best["igl"] = min(best["igl"], _cpu(reference))
        best["floor"] = min(best["floor"], _cpu(floor))
        with jit.use("numpy"):
            best["numpy"] = min(best["numpy"], _cpu(ours))
        if result["extension"]:
            with jit.use("auto"):
                spent = _cpu(ours)
                best["extension"], worst["extension"] = min(best["extension"], spent), max(worst["extension"], spent)
    result.update({f"{k}_s": float(v) for k, v in best.items()})
    result.update({f"{k}_worst_s": float(v) for k, v in worst.items()})
    result["load"] = [load_before, os.getloadavg()[0]]
    return result


WHOLE_SETUP = "import numpy as np; m = np.load(%r); V, F = m['V'], m['F']"
WHOLE = {
    "decrun": "; import decrun; from decrun.core.complex import SimplicialComplex; from decrun.core.dec import DEC; "
              "dec = DEC(SimplicialComplex(V, F)); [dec.d(0), dec.d(1)] + [dec.star(k) for k in range(3)]",
    "libigl": "; import igl; igl.cotmatrix(V, F); igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI)",
    "mesh load only": "",
}


def whole_processes(repeat: int) -> None:
    """Whole fresh processes, in CPU time (user + system, from start to exit): load an icosphere
    (.npz, so that no mesh library is imported), then decrun's import and one build, or libigl's
    import and one call; interleaved, ``repeat`` times each; best and median."""
    import resource
    import statistics
    import subprocess
    import tempfile

    import numpy as np

    print(f"load average {os.getloadavg()[0]:.1f}")
    print("| triangles | decrun best / median s | libigl best / median s | mesh load only s | decrun / libigl, best | "
          "decrun / libigl, median |")
    print("|---:|---:|---:|---:|---:|---:|")
    for size in (6, 7):
        vertices, faces = icosphere_or_kuhn_cube("icosphere", size)
        with tempfile.TemporaryDirectory() as directory:
            path = os.path.join(directory, "mesh.npz")
            np.savez(path, V=vertices, F=faces)
            spent: dict[str, list[float]] = {name: [] for name in WHOLE}
            for _ in range(repeat):
                for name, code in WHOLE.items():
                    before = resource.getrusage(resource.RUSAGE_CHILDREN)
                    subprocess.run([sys.executable, "-c", WHOLE_SETUP % path + code], check=True, cwd=directory)
                    after = resource.getrusage(resource.RUSAGE_CHILDREN)
                    spent[name].append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
        best = {name: min(times) for name, times in spent.items()}
        median = {name: statistics.median(times) for name, times in spent.items()}
        print(f"| {len(faces):,} | {best['decrun']:.3f} / {median['decrun']:.3f} | {best['libigl']:.3f} / "
              f"{median['libigl']:.3f} | {best['mesh load only']:.3f} | {best['decrun'] / best['libigl']:.2f} | "
              f"{median['decrun'] / median['libigl']:.2f} |", flush=True)
    print(f"load average {os.getloadavg()[0]:.1f}")


def main(argv=None) -> int:
    if argv is None and "--whole" in sys.argv:
        sys.argv.remove("--whole")
        repeat = int(sys.argv[sys.argv.index("--repeat") + 1]) if "--repeat" in sys.argv else 7
        if not have_libigl():
            return 1
        whole_processes(repeat)
        return 0
    if argv is None and "--keep-freed-memory" in sys.argv:
        sys.argv.remove("--keep-freed-memory")
        os.environ[KEEP_FREED_MEMORY] = "1"  # the case processes inherit it
    args = parse_or_run_case(__doc__, run_case, argv)
    if args is None:
        return 0
    if not have_libigl():
        print("bench_operators.py measures against libigl: pip install -e .[bench]", file=sys.stderr)
        return 1
    import numpy as np

    level = "quick" if args.quick else "full"
    print(f"CPU ms, best of {args.repeat} interleaved rounds; ratios to libigl (and to the floor) from the same process;"
          f" fresh: first calls, each in a process of its own, best of {args.repeat} processes"
          + ("; freed memory kept (mallopt)" if os.environ.get(KEEP_FREED_MEMORY) == "1" else ""))
    print("| triangles | load | libigl | floor | numpy twins | extension | numpy / libigl |"
          " extension / libigl | extension / floor | fresh: import | fresh: first build, auto |"
          " fresh: libigl's first call | fresh ratio |"
          " extension, worst round | fresh: worst process's first build |"
          " fresh: worst / libigl's best |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for size in TRIANGLE_CASES[level]:
        fresh, igl_fresh = {"fresh_auto_s": np.inf}, {"igl_fresh_s": np.inf}
        fresh_worst = 0.0
        for _ in range(args.repeat):  # the best of --repeat fresh processes each, interleaved
            ours = spawn(__file__, "fresh", "icosphere", size, args.repeat)
            fresh = ours if ours["fresh_auto_s"] < fresh["fresh_auto_s"] else fresh
            fresh_worst = max(fresh_worst, ours["fresh_auto_s"])
            theirs = spawn(__file__, "igl-fresh", "icosphere", size, args.repeat)
            igl_fresh = theirs if theirs["igl_fresh_s"] < igl_fresh["igl_fresh_s"] else igl_fresh
        r = spawn(__file__, "all", "icosphere", size, args.repeat)
        if os.environ.get(KEEP_FREED_MEMORY) == "1" and not r["kept"]:
            print("--keep-freed-memory: this C library has no glibc mallopt; the rounds ran without it", file=sys.stderr)
        igl_s, ext_s = r["igl_s"], r["extension_s"]
        extension = (f" {1e3 * ext_s:.1f} |", f" {ext_s / igl_s:.2f} |", f" {ext_s / r['floor_s']:.2f} |") \
            if r["extension"] else (" (not built) |", " - |", " - |")
        worst_round = f" {1e3 * r['extension_worst_s']:.1f} |" if r["extension"] else " - |"
        print(f"| {r['simplices']:,} | {r['load'][0]:.0f}–{r['load'][1]:.0f} | {1e3 * igl_s:.1f} | {1e3 * r['floor_s']:.1f} |"
              f" {1e3 * r['numpy_s']:.1f} |{extension[0]} {r['numpy_s'] / igl_s:.2f} |"
              f"{extension[1]}{extension[2]}"
              f" {1e3 * fresh['import_s']:.0f} | {1e3 * fresh['fresh_auto_s']:.1f} | {1e3 * igl_fresh['igl_fresh_s']:.1f} |"
              f" {fresh['fresh_auto_s'] / igl_fresh['igl_fresh_s']:.2f} |{worst_round}"
              f" {1e3 * fresh_worst:.1f} | {fresh_worst / igl_fresh['igl_fresh_s']:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
