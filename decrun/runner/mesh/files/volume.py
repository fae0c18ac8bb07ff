"""Volume (and other) mesh formats through meshio: VTK, VTU, Gmsh, Medit, TetGen, XDMF, ...

meshio (Schlömer et al., https://github.com/nschloe/meshio) reads the file into points and
typed cell blocks; this module only turns those into a :class:`RawMesh` and refuses what
it cannot represent: cell types other than ``triangle``, ``quad``, ``polygon`` and
``tetra`` are an error that names the type and count (nothing is dropped), and points of
dimension 2 are padded with z = 0 (recorded as ``counts['planar_points']``). Index and
coordinate checks follow in :func:`decrun.runner.mesh.files.checks.validate`; binary formats
carry no line numbers, so errors name the cell's position in the file's cell list.
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from decrun.errors import MeshError
from decrun.runner.mesh.files.checks import RawMesh, polygon_offsets

_SURFACE = ("triangle", "quad", "polygon")


def meshio_extensions() -> list[str]:
    """File endings meshio reads, except those decrun reads itself (and vector drawings)."""
    import meshio

    own = {".obj", ".off", ".ply", ".stl", ".svg", ".wkt"}
    return sorted(set(meshio.extension_to_filetypes) - own)


def read_volume(path: Path, where: str) -> RawMesh:
    """Read ``path`` with meshio into a :class:`RawMesh` (faces or tetrahedra)."""
    import meshio

    printed = io.StringIO()
    try:
        # meshio.read prints each reader's ReadError and then calls sys.exit(1)
        with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(printed):
            mesh = meshio.read(str(path))
    except (Exception, SystemExit) as exc:  # its readers raise anything on garbage
        reason = " ".join(printed.getvalue().split()) or str(exc).strip() or type(exc).__name__
        raise MeshError(f"{where}: meshio cannot read it: {reason[:300]}") from None
    points = np.asarray(mesh.points, dtype=np.float64)
    counts: dict[str, int] = {}
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise MeshError(f"{where}: points have shape {points.shape}; expected (n, 2) or (n, 3)")
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
        counts["planar_points"] = len(points)
    other = [(block.type, len(block.data)) for block in mesh.cells if block.type not in (*_SURFACE, "tetra")]
    if other:
        listed = ", ".join(f"{n} {kind}" for kind, n in other)
        raise MeshError(
            f"{where}: the file holds cells decrun cannot use ({listed}); a mesh must consist of "
            f"triangles/polygons or of tetrahedra only"
        )
    faces = [np.asarray(b.data, dtype=np.int64) for b in mesh.cells if b.type in _SURFACE]
    tets = [np.asarray(b.data, dtype=np.int64) for b in mesh.cells if b.type == "tetra"]
    for block in mesh.cells:
        counts[block.type] = counts.get(block.type, 0) + len(block.data)
    sizes = np.concatenate([np.full(len(f), f.shape[1], dtype=np.int64) for f in faces]) if faces else np.zeros(0, np.int64)
    counts.update(vertices=len(points), faces=int(len(sizes)), tetrahedra=int(sum(len(t) for t in tets)))
    return RawMesh(
        vertices=points, format=f"meshio-{path.suffix.lstrip('.').lower()}",
        face_corners=np.concatenate([f.ravel() for f in faces]) if faces else np.zeros(0, np.int64),
        face_offsets=polygon_offsets(sizes),
        tetrahedra=np.concatenate(tets) if tets else np.zeros((0, 4), np.int64),
        counts=counts,
    )
