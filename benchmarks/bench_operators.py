"""Benchmark: building the DEC operator set, against libigl and the scipy floor, in one run.

The work: ``SimplicialComplex(V, F)`` (with its validation) + ``d(0)``, ``d(1)``, ``⋆0..⋆2``
(circumcentric). The anchor: libigl's ``cotmatrix`` + ``massmatrix(VORONOI)``. The floor:
scipy building the same five operators as CSR from COO triplets holding the same nonzeros
(what any sparse assembly of them pays at least).

Each mesh runs in fresh subprocesses:

* **fresh** (two processes of their own, nothing else run in them before): importing decrun's
  complex and operators (reported alone), then the first build in the process under ``auto``
  (what a one-off ``decrun`` run pays), in CPU time; and, in the other, libigl's first call;
* **sweep worker** (a third process): builds under ``auto`` with the compiled extension set
  aside (an install without a C compiler), one after another, until ``auto`` starts numba (the
  count is reported; with the extension, ``auto`` runs its twins and never starts numba here);
* **warm** (the same process): ``--repeat`` interleaved rounds of libigl, the floor, decrun's
  numpy twins (``numpy``), decrun's compiled extension (``auto``, when the install built it)
  and decrun's numba kernels (``numba``, started), each timed in CPU time
  (``time.process_time``: the shared machine's load distorts wall time), best of the rounds;
  and the worst of the extension's own rounds (a build touches its memory anew each time).

Ratios are decrun / libigl (and decrun / floor) from the same process; the fresh ratio is decrun's
first build over libigl's first call, each the best of ``--repeat`` fresh processes (and decrun's worst
process over libigl's best). The machine's load
average is printed before and after. ``--jit`` reports what a fresh process pays to start
numba: importing it, and the first kernel calls (numba's typing registries, then each
cached kernel's machine code), with an empty cache and with the cache it wrote.

``--keep-freed-memory`` runs every process with glibc's ``mallopt`` keeping the memory a build
frees for the next one (``M_MMAP_THRESHOLD`` and ``M_TRIM_THRESHOLD`` at 1 GiB): no warm round,
of the floor or of decrun, pays the first touch of memory the previous round gave back to the
system, so their ratio is the work's (decrun does not set this itself: it is the process's
policy, not a library's).

    python benchmarks/bench_operators.py            # 82k, 328k, 1.31M triangles
    python benchmarks/bench_operators.py --quick    # 20k, 82k triangles, seconds
    python benchmarks/bench_operators.py --jit      # numba's start in a fresh process
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
        from decrun.core import jit

        result["fresh_auto_started_numba"] = jit.started()
        return result
    import numpy as np

    from decrun.core import jit
    from decrun.core.jit import kernels

    load_before = os.getloadavg()[0]
    result = {"simplices": int(len(faces)), "extension": bool(kernels.extension_twins()), "kept": kept}

    def ours():
        return _decrun_operators(vertices, faces)

    def reference():
        return _reference(vertices, faces)

    reference()  # libigl's own first call (page faults of its code) stays out of its best
    twins = kernels._twins
    kernels._twins = {}  # the sweep worker of an install without the extension: numpy until auto starts numba
    builds = 0
    while not jit.started() and builds < 400:
        ours()
        builds += 1
    kernels._twins = twins
    result["builds_until_kernels"] = builds if jit.started() else None
    with jit.use("numba"):
        operators = ours()  # the kernels that are not loaded yet, loaded
    with jit.use("numpy"):
        twins = ours()
    for a, b in zip(operators, twins, strict=True):  # the two paths agree (the tests hold them to it)
        assert a.shape == b.shape and abs(a - b).max() <= 1e-12 * max(abs(b).max(), 1.0)
    floor = _floor_work(operators)
    best = {"igl": np.inf, "floor": np.inf, "numpy": np.inf, "extension": np.inf, "kernels": np.inf}
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
        with jit.use("numba"):
            best["kernels"] = min(best["kernels"], _cpu(ours))
    result.update({f"{k}_s": float(v) for k, v in best.items()})
    result.update({f"{k}_worst_s": float(v) for k, v in worst.items()})
    result["load"] = [load_before, os.getloadavg()[0]]
    return result


def jit_times() -> None:
    """numba's start in fresh processes, in CPU time: its import, then the first build of a
    small complex with every kernel on the operators' path (compile, or load from the cache);
    decrun's own modules are imported before either is timed."""
    import subprocess
    import tempfile

    code = ("import time, sys; import decrun.core.complex, decrun.core.dec; "
            "from decrun.core.primitives import grid_triangles; "
            "sys.path.insert(0, %r); from bench_operators import _decrun_operators; "
            "V, F = grid_triangles(4, 4, jitter=0.2); t = time.process_time(); import numba; "
            "imported = time.process_time() - t; t = time.process_time(); _decrun_operators(V, F); "
            "first = time.process_time() - t; t = time.process_time(); _decrun_operators(V, F); "
            "print(imported, first, time.process_time() - t)" % os.path.dirname(os.path.abspath(__file__)))
    print(f"load average {os.getloadavg()[0]:.1f}")
    print("| numba cache | numba import CPU s | first build CPU s (kernels compiled or loaded) | second build CPU s |")
    print("|---|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, DECRUN_NUMBA="1")
        for label in ("cold (empty)", "warm", "warm", "warm"):
            out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
            imported, first, second = (float(v) for v in out.stdout.split())
            print(f"| {label} | {imported:.3f} | {first:.3f} | {second:.4f} |", flush=True)
    print(f"load average {os.getloadavg()[0]:.1f}")


def main(argv=None) -> int:
    if argv is None and "--jit" in sys.argv:
        jit_times()
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
    print("| triangles | load | libigl | floor | numpy twins | extension | numba kernels | numpy / libigl |"
          " extension / libigl | numba / libigl | extension / floor | fresh: import | fresh: first build, auto |"
          " fresh: libigl's first call | fresh ratio | no extension: builds until auto starts numba |"
          " extension, worst round | fresh: worst process's first build |"
          " fresh: worst / libigl's best |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
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
              f" {1e3 * r['numpy_s']:.1f} |{extension[0]} {1e3 * r['kernels_s']:.1f} | {r['numpy_s'] / igl_s:.2f} |"
              f"{extension[1]} {r['kernels_s'] / igl_s:.2f} |{extension[2]}"
              f" {1e3 * fresh['import_s']:.0f} | {1e3 * fresh['fresh_auto_s']:.1f} | {1e3 * igl_fresh['igl_fresh_s']:.1f} |"
              f" {fresh['fresh_auto_s'] / igl_fresh['igl_fresh_s']:.2f} | {r['builds_until_kernels']} |{worst_round}"
              f" {1e3 * fresh_worst:.1f} | {fresh_worst / igl_fresh['igl_fresh_s']:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
