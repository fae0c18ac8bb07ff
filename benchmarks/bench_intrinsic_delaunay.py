"""Benchmark: the intrinsic Delaunay Laplacian against robust_laplacian (Sharp & Crane 2020).

For each mesh, in a fresh subprocess (so peak memory is that case's alone):

* decrun: ``intrinsic_delaunay_operators(V, F, mollify=1e-5)`` (stiffness + star0);
* robust_laplacian: ``mesh_laplacian(V, F, mollify_factor=1e-5)`` (L + M), its default.

Meshes: pymeshlab's bunny10k (with borders: the tufted cover is flipped), an icosphere
with 1.3M triangles (already Delaunay: no flips) and the same icosphere stretched ×10
along z (about a million flips). Reports wall time (best of ``--repeat``), peak resident
memory above the loaded mesh, decrun's flips and rounds, and the largest entry difference
of the two stiffness matrices relative to the largest entry.

    python benchmarks/bench_intrinsic_delaunay.py            # full
    python benchmarks/bench_intrinsic_delaunay.py --quick    # small meshes, seconds
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from harness import best_of, parse_or_run_case, spawn, warm_up_kernels  # noqa: E402

CASES = {
    "quick": [("bunny10k", 0), ("icosphere", 5), ("stretched icosphere", 5)],
    "full": [("bunny10k", 0), ("icosphere", 8), ("stretched icosphere", 8)],
}
MOLLIFY = 1e-5


def load_mesh(kind: str, size: int):
    import pymeshlab

    ms = pymeshlab.MeshSet()
    if kind == "bunny10k":
        ms.load_new_mesh(str(Path(pymeshlab.__file__).parent / "tests/sample_meshes/bunny10k_textured.obj"))
    else:
        ms.create_sphere(radius=1.0, subdiv=size)
    mesh = ms.current_mesh()
    vertices = mesh.vertex_matrix().astype(np.float64)
    if kind == "stretched icosphere":
        vertices[:, 2] *= 10.0
    return np.ascontiguousarray(vertices), mesh.face_matrix().astype(np.int64)


def run_case(library: str, kind: str, size: int, repeat: int) -> dict:
    """Runs inside the subprocess: one library on one mesh."""
    vertices, faces = load_mesh(kind, size)
    if library == "decrun":
        from decrun.core.intrinsic_delaunay import intrinsic_delaunay_operators

        warm_up_kernels()

        def work():
            return intrinsic_delaunay_operators(vertices, faces, mollify=MOLLIFY)
    else:
        import robust_laplacian

        def work():
            return robust_laplacian.mesh_laplacian(vertices, faces, mollify_factor=MOLLIFY)

    seconds, peak_mb, result = best_of(work, repeat)
    report = {"seconds": seconds, "peak_mb": peak_mb, "faces": len(faces)}
    if library == "decrun":
        report.update(flips=result.flips, rounds=result.rounds)
        stiffness = result.stiffness
    else:
        stiffness = result[0]
    np.save(_matrix_path(library, kind, size), _triplets(stiffness))
    return report


def _matrix_path(library: str, kind: str, size: int) -> str:
    return f"/tmp/bench_intrinsic_delaunay_{library}_{kind.replace(' ', '_')}_{size}.npy"


def _triplets(matrix) -> np.ndarray:
    coo = matrix.tocoo()
    return np.stack([coo.row.astype(np.float64), coo.col.astype(np.float64), coo.data])


def _difference(kind: str, size: int) -> float:
    import scipy.sparse as sp

    mats = []
    for library in ("decrun", "robust"):
        path = _matrix_path(library, kind, size)
        row, col, data = np.load(path)
        Path(path).unlink()
        mats.append(sp.csr_matrix((data, (row.astype(np.int64), col.astype(np.int64)))))
    return float(abs(mats[0] - mats[1]).max() / abs(mats[1]).max())


def main(argv=None) -> int:
    args = parse_or_run_case(__doc__, run_case, argv)
    if args is None:
        return 0
    try:
        import robust_laplacian  # noqa: F401
    except ImportError:
        print("robust_laplacian is not installed (pip install robust-laplacian): nothing to compare", file=sys.stderr)
        return 1

    level = "quick" if args.quick else "full"
    print("| mesh | triangles | flips | rounds | decrun s | decrun peak MB | robust_laplacian s | robust peak MB "
          "| time ratio | memory ratio | max rel. diff of L |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for kind, size in CASES[level]:
        repeat = 1 if size >= 8 else args.repeat
        ours = spawn(__file__, "decrun", kind, size, repeat)
        ref = spawn(__file__, "robust", kind, size, repeat)
        name = kind if kind == "bunny10k" else f"{kind} subdiv {size}"
        print(f"| {name} | {ours['faces']:,} | {ours['flips']:,} | {ours['rounds']} | {ours['seconds']:.3f} |"
              f" {ours['peak_mb']:.0f} | {ref['seconds']:.3f} | {ref['peak_mb']:.0f} |"
              f" {ours['seconds'] / ref['seconds']:.2f} | {ours['peak_mb'] / max(ref['peak_mb'], 1e-9):.2f} |"
              f" {_difference(kind, size):.1e} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
