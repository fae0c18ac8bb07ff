"""Mesh files that never slip through: read and validate before anything native sees them.

:func:`read_mesh_file` reads OBJ, OFF, PLY (ASCII/binary), STL (ASCII/binary) with
decrun's own vectorized readers and tetrahedral/other formats (VTK, VTU, Gmsh ``.msh``,
Medit ``.mesh``, TetGen, XDMF, ...) through meshio, and validates the raw content before
any native code sees it (:func:`decrun.runner.mesh.files.checks.validate`). Every problem is one
:class:`decrun.errors.MeshError` (or a subclass: ``IndexOutOfRangeError``,
``RepeatedVertexError``, ``NonFiniteCoordinateError``) whose message starts with
``mesh.path='<file>':`` and names the cause and the place, e.g.
``mesh.path='fin.obj': line 14: face 3 references vertex 0 (OBJ indices start at 1)``.
Vertex and face numbers are 0-based positions in the file's lists; OBJ indices are quoted
as written. Polygons with more than 3 corners are split into a fan and counted in
``counts['triangulated_faces']``; nothing is dropped or repaired silently.

decrun reads every file itself because pymeshlab (2025.7) drops OBJ faces with a repeated
vertex, NaN vertices with the faces using them, and PLY faces whose ``flags`` property has
VCG's "deleted" bit without a word; it turns OBJ index 0 into an out-of-range face and
aborts (heap corruption) on an index above the vertex count.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from decrun.errors import MeshError
from decrun.runner.mesh.files.checks import validate
from decrun.runner.mesh.files.obj import read_obj
from decrun.runner.mesh.files.off import read_off
from decrun.runner.mesh.files.ply import read_ply
from decrun.runner.mesh.files.stl import read_stl
from decrun.runner.mesh.files.volume import meshio_extensions, read_volume

__all__ = ["MeshFile", "read_mesh_file", "supported_extensions"]

_TEXT_READERS = {".obj": read_obj, ".off": read_off}
_BYTES_READERS = {".ply": read_ply, ".stl": read_stl}


@dataclass(frozen=True)
class MeshFile:
    """A validated mesh file.

    - ``vertices`` (n, 3) float64 (model units, as in the file; 2-D points padded with z = 0)
    - ``cells`` (m, 3) int64 triangles or (m, 4) int64 tetrahedra, 0-based, in file order
      (a polygon's fan triangles are consecutive)
    - ``cell_face`` (m,) int64: the file face (or tetrahedron) each cell comes from
    - ``face_line`` (f,) int64 1-based line of each file face, or None (binary formats)
    - ``counts``: element kind → number read (``vertices``, ``faces``, ``cells``,
      ``triangulated_faces``, ``normals``, ``texture_coordinates``, other PLY elements ...)
    - ``format``: ``obj``, ``off``, ``ply-ascii``, ``ply-binary_little_endian``,
      ``stl-binary``, ``stl-ascii``, ``meshio-<ext>``
    - ``path``, ``key``: the file and the config key it came from (for messages)
    """

    path: str
    key: str
    format: str
    vertices: np.ndarray
    cells: np.ndarray
    cell_face: np.ndarray
    face_line: np.ndarray | None
    counts: dict[str, int]

    @property
    def where(self) -> str:
        """``key='path'``, the prefix of every message about this file."""
        return f"{self.key}={self.path!r}"

    @property
    def is_volume(self) -> bool:
        """True for tetrahedra (cells (m, 4)), False for triangles (m, 3)."""
        return self.cells.shape[1] == 4


def supported_extensions() -> list[str]:
    """All file endings :func:`read_mesh_file` accepts (lower case, with the dot)."""
    return sorted([*_TEXT_READERS, *_BYTES_READERS, *meshio_extensions()])


def read_mesh_file(path, *, key: str = "mesh.path") -> MeshFile:
    """Read and validate the mesh file ``path`` (str or Path).

    Raises :class:`MeshError` (or a subclass) for a missing path, a directory, an empty or
    unreadable file, an unsupported extension, malformed content, index 0 in OBJ, indices
    out of range (positive or negative-relative), a vertex repeated in a face, NaN/inf or
    |x| > 1e150 coordinates, faces with < 3 corners, vertices without faces, and
    triangles mixed with tetrahedra. The message starts with ``{key}='{path}':``.
    """
    given = str(path)
    where = f"{key}={given!r}"
    path = Path(given).expanduser()
    try:
        found = path.exists()
    except OSError as exc:  # a name too long for the file system (Path.exists raises it)
        raise MeshError(f"{where}: cannot be read ({os.strerror(exc.errno or 0)})") from None
    if not found:
        raise MeshError(f"{where}: file not found")
    if path.is_dir():
        raise MeshError(f"{where}: is a directory, not a file")
    if not path.is_file():
        raise MeshError(f"{where}: not a regular file")
    suffix = _suffix(path)
    if suffix is None and _is_hdf5(path):  # a run's result.h5: its mesh is read by mesh=result
        raise MeshError(f"{where}: an HDF5 file (a decrun run's result.h5?), not a mesh file; a run's mesh and "
                        f"fields are read by `mesh=result` with `mesh.path={given}`")
    if suffix is None:
        raise MeshError(
            f"{where}: unsupported file extension {path.suffix or '(none)'!r}; "
            f"supported: {' '.join(supported_extensions())}"
        )
    try:
        size = path.stat().st_size
        raw = path.read_bytes() if suffix in _TEXT_READERS or suffix in _BYTES_READERS else b""
    except OSError as exc:
        raise MeshError(f"{where}: cannot read the file: {exc.strerror or exc}") from exc
    if size == 0:
        raise MeshError(f"{where}: the file is empty")
    if suffix in _TEXT_READERS:
        rawmesh = _TEXT_READERS[suffix](raw, where)
    elif suffix in _BYTES_READERS:
        rawmesh = _BYTES_READERS[suffix](raw, where)
    else:
        rawmesh = read_volume(path, where)
    vertices, cells, cell_face, counts = validate(rawmesh, where)
    return MeshFile(
        path=given, key=key, format=rawmesh.format, vertices=vertices, cells=cells,
        cell_face=cell_face, face_line=rawmesh.face_line, counts=counts,
    )


def _is_hdf5(path: Path) -> bool:
    """Whether ``path`` starts with the HDF5 signature (a decrun ``result.h5``, whatever its name)."""
    try:
        with open(path, "rb") as f:
            return f.read(8) == b"\x89HDF\r\n\x1a\n"
    except OSError:
        return False


def _suffix(path: Path) -> str | None:
    """The supported extension ``path`` ends with (longest match, case-insensitive); meshio
    (a slow import) is consulted only for endings decrun does not read itself."""
    name = path.name.lower()
    own = [ext for ext in (*_TEXT_READERS, *_BYTES_READERS) if name.endswith(ext)]
    if own:
        return own[0]
    matches = [ext for ext in meshio_extensions() if name.endswith(ext)]
    return max(matches, key=len) if matches else None
