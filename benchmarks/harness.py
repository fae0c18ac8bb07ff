"""What every operator benchmark shares: peak-memory accounting, the test meshes, and running
each case in its own process (so one case's memory and caches do not leak into the next).

Imported by the ``bench_*.py`` scripts of this folder (run as scripts, the folder is on
``sys.path``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np

__all__ = ["warm_up_kernels", "status_bytes", "reset_peak_rss", "peak_rss_bytes", "icosphere_or_kuhn_cube", "spawn", "have_libigl",
           "best_of", "parse_or_run_case"]


def warm_up_kernels() -> float:
    """Run decrun's compiled kernels (the extension, :mod:`decrun.core.extension`) once on a tiny
    mesh, so a case measures the work and not the first call's loading; returns the seconds taken
    (the first-call cost a fresh process pays once)."""
    import time

    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC
    from decrun.core.intrinsic_delaunay import intrinsic_delaunay
    from decrun.core.primitives import grid_triangles, kuhn_cube

    saved = os.environ.get("DECRUN_NUMBA")
    os.environ["DECRUN_NUMBA"] = "1"  # the compiled kernels
    try:
        start = time.perf_counter()
        vertices, faces = grid_triangles(4, 4, jitter=0.2)
        dec = DEC(SimplicialComplex(vertices, faces), star="circumcentric")
        [dec.d(0), dec.d(1)] + [dec.star(k) for k in range(3)]
        intrinsic_delaunay(vertices * [1.0, 5.0], faces)
        DEC(SimplicialComplex(*kuhn_cube(2)), star="circumcentric").star(0)
        return time.perf_counter() - start
    finally:
        if saved is None:
            del os.environ["DECRUN_NUMBA"]
        else:
            os.environ["DECRUN_NUMBA"] = saved


def status_bytes(field: str) -> int:
    """A memory line of /proc/self/status (VmRSS, VmHWM) in bytes."""
    with open("/proc/self/status") as handle:
        for line in handle:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    raise RuntimeError(f"/proc/self/status has no {field}")


def reset_peak_rss() -> bool:
    """Reset the resident high-water mark (VmHWM: write 5 to /proc/self/clear_refs) so the
    peak measures only what follows — not, e.g., the mesh generator's transient memory."""
    try:
        with open("/proc/self/clear_refs", "w") as handle:
            handle.write("5")
        return True
    except OSError:
        return False


def peak_rss_bytes() -> int:
    """The resident high-water mark since the last :func:`reset_peak_rss`, in bytes."""
    return status_bytes("VmHWM")


def icosphere_or_kuhn_cube(kind: str, size: int):
    """(vertices, simplices): pymeshlab's icosphere subdivided ``size`` times (20·4^size
    triangles) or the Kuhn cube of ``size``³ cells (6·size³ tetrahedra)."""
    if kind == "icosphere":
        import pymeshlab

        ms = pymeshlab.MeshSet()
        ms.create_sphere(radius=1.0, subdiv=size)
        mesh = ms.current_mesh()
        return mesh.vertex_matrix().astype(np.float64), mesh.face_matrix().astype(np.int64)
    from decrun.core.primitives import kuhn_cube

    return kuhn_cube(size)


def spawn(script: str, library: str, kind: str, size: int, repeat: int) -> dict:
    """Run ``script --case library kind size --repeat repeat`` in a fresh process and return
    the JSON dict it prints last."""
    out = subprocess.run(
        [sys.executable, script, "--case", library, kind, str(size), "--repeat", str(repeat)],
        capture_output=True, text=True, check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def have_libigl() -> bool:
    """Whether the libigl reference is installed (``pip install -e .[bench]``); says so if not."""
    try:
        import igl  # noqa: F401
    except ImportError:
        print("libigl is not installed (pip install -e .[bench]): reference columns skipped", file=sys.stderr)
        return False
    return True


def best_of(work, repeat: int) -> tuple[float, float, object]:
    """Call ``work()`` ``repeat`` times; returns (best seconds, peak MB above the resident
    memory before the first call, the last result). The peak counts only the work measured
    (the high-water mark is reset first; a warning when the kernel does not allow it)."""
    import gc
    import time

    gc.collect()
    baseline = status_bytes("VmRSS")
    if not reset_peak_rss():
        print("warning: cannot reset the peak RSS; peaks include loading the mesh", file=sys.stderr)
    times, result = [], None
    for _ in range(repeat):
        del result
        gc.collect()
        start = time.perf_counter()
        result = work()
        times.append(time.perf_counter() - start)
    return min(times), (peak_rss_bytes() - baseline) / 2**20, result


def parse_or_run_case(description: str, run_case, argv=None):
    """The command line every benchmark shares: ``--quick``, ``--repeat`` and the hidden
    ``--case LIBRARY KIND SIZE`` its own subprocesses use (:func:`spawn`). With ``--case``
    runs ``run_case(library, kind, size, repeat)``, prints its JSON and returns None;
    otherwise returns the parsed arguments."""
    import argparse

    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="small meshes only")
    parser.add_argument("--repeat", type=int, default=3, help="timed repetitions per case (best is reported)")
    parser.add_argument("--case", nargs=3, metavar=("LIBRARY", "KIND", "SIZE"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.case:
        library, kind, size = args.case
        print(json.dumps(run_case(library, kind, int(size), args.repeat)))
        return None
    return args
