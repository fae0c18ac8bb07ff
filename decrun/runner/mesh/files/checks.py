"""Checks on the raw content of a mesh file, before anything native sees it.

A format reader (:mod:`.obj`, :mod:`.off`, :mod:`.ply`, :mod:`.stl`, :mod:`.volume`)
returns a :class:`RawMesh`: vertices and faces exactly as the file lists them (faces as
polygons of any size, indices already 0-based), or tetrahedra, plus where each came from.
:func:`validate` checks it and fan-triangulates polygons; every failure is one
:class:`decrun.errors.MeshError` (or subclass) naming the file, the cause and the place
(line number for text formats, 0-based vertex/face index in the file's lists).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from decrun.errors import (
    IndexOutOfRangeError,
    MeshError,
    NonFiniteCoordinateError,
    RepeatedVertexError,
)

#: |coordinate| above this is rejected: squared lengths (and products of two of them in
#: areas and cotangents) must stay far below the float64 maximum 1.8e308.
MAX_ABS_COORDINATE = 1e150


@dataclass
class RawMesh:
    """What a reader found in a file.

    - ``vertices`` (n, 3) float64 in file order
    - ``face_corners`` (Σk,) int64 0-based vertex indices of all polygon faces, concatenated;
      ``face_offsets`` (f+1,) int64, face j is ``face_corners[face_offsets[j]:face_offsets[j+1]]``
    - ``tetrahedra`` (t, 4) int64 0-based
    - ``vertex_line``, ``face_line`` (n,), (f,) int64 1-based line numbers, or None (binary)
    - ``counts``: element kind → number read (``vertices``, ``faces``, ``normals``, ...)
    - ``format``: e.g. ``"obj"``, ``"ply-binary_little_endian"``
    """

    vertices: np.ndarray
    format: str
    face_corners: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    face_offsets: np.ndarray = field(default_factory=lambda: np.zeros(1, dtype=np.int64))
    tetrahedra: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), dtype=np.int64))
    vertex_line: np.ndarray | None = None
    face_line: np.ndarray | None = None
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def face_count(self) -> int:
        """Number of polygon faces f."""
        return len(self.face_offsets) - 1

    def where_vertex(self, i: int) -> str:
        """'line 7: vertex 5' (text) or 'vertex 5' (binary)."""
        line = f"line {int(self.vertex_line[i])}: " if self.vertex_line is not None else ""
        return f"{line}vertex {int(i)}"

    def where_face(self, j: int, name: str = "face") -> str:
        """'line 14: face 3' (text) or 'face 3' (binary)."""
        line = f"line {int(self.face_line[j])}: " if self.face_line is not None else ""
        return f"{line}{name} {int(j)}"


def polygon_offsets(sizes: np.ndarray) -> np.ndarray:
    """(f+1,) offsets of polygons with ``sizes`` (f,) corners."""
    return np.concatenate([[0], np.cumsum(sizes, dtype=np.int64)]).astype(np.int64)


def validate(raw: RawMesh, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int]]:
    """Check ``raw`` and build the cell array.

    Checks, in order: at least one vertex; finite coordinates; |x| <= MAX_ABS_COORDINATE;
    at least one face or tetrahedron; not both; every face has >= 3 corners; every index
    in ``[0, n)``; no vertex twice in one face or tetrahedron.

    Returns ``(vertices (n, 3) float64, cells (m, 3|4) int64, cell_face (m,) int64, counts)``:
    polygons with k > 3 corners are split into the fan ``(c0, c_i, c_i+1)``, i = 1..k-2;
    ``cell_face`` is the file face of each cell; ``counts`` adds ``triangulated_faces``
    (faces with more than 3 corners) and ``cells``.
    """
    V = np.asarray(raw.vertices, dtype=np.float64)
    n, f, t = len(V), raw.face_count, len(raw.tetrahedra)
    if n == 0:
        raise MeshError(f"{where}: the file holds no vertices")
    finite = np.isfinite(V).all(axis=1)
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        raise NonFiniteCoordinateError(
            f"{where}: {raw.where_vertex(i)} has a non-finite coordinate {V[i].tolist()} "
            f"({int((~finite).sum())} such vertices)"
        )
    huge = (np.abs(V) > MAX_ABS_COORDINATE).any(axis=1)
    if huge.any():
        i = int(np.flatnonzero(huge)[0])
        raise MeshError(
            f"{where}: {raw.where_vertex(i)} has coordinate {V[i].tolist()} beyond ±{MAX_ABS_COORDINATE:g}: "
            f"squared lengths would overflow ({int(huge.sum())} such vertices)"
        )
    if f == 0 and t == 0:
        raise MeshError(f"{where}: the file holds {n} vertices and no faces")
    if f and t:
        raise MeshError(
            f"{where}: the file mixes {f} faces with {t} tetrahedra; a mesh is either a "
            f"triangle surface or a tetrahedral volume"
        )
    counts = dict(raw.counts)
    if t:
        cells = np.asarray(raw.tetrahedra, dtype=np.int64)
        _check_indices(cells.ravel(), np.arange(t + 1) * 4, n, raw, where, "tetrahedron")
        counts["cells"] = t
        return V, cells, np.arange(t, dtype=np.int64), counts
    corners, offsets = np.asarray(raw.face_corners, dtype=np.int64), np.asarray(raw.face_offsets, dtype=np.int64)
    sizes = np.diff(offsets)
    small = np.flatnonzero(sizes < 3)
    if small.size:
        j = int(small[0])
        raise MeshError(f"{where}: {raw.where_face(j)} has {int(sizes[j])} corners; a face needs at least 3")
    _check_indices(corners, offsets, n, raw, where, "face")
    triangles = sizes - 2
    cell_face = np.repeat(np.arange(f, dtype=np.int64), triangles)
    fan = np.arange(cell_face.size, dtype=np.int64) - np.repeat(np.cumsum(triangles) - triangles, triangles)
    base = offsets[cell_face]
    cells = np.stack([corners[base], corners[base + fan + 1], corners[base + fan + 2]], axis=1)
    counts["triangulated_faces"] = int((sizes > 3).sum())
    counts["cells"] = len(cells)
    return V, cells, cell_face, counts


def _check_indices(corners: np.ndarray, offsets: np.ndarray, n: int, raw: RawMesh, where: str, name: str) -> None:
    """Indices in [0, n) and no repeats inside one cell (cells given as flat + offsets)."""
    sizes = np.diff(offsets)
    plural = "tetrahedra" if name == "tetrahedron" else name + "s"
    owner = np.repeat(np.arange(len(sizes), dtype=np.int64), sizes)
    out = np.flatnonzero((corners < 0) | (corners >= n))
    if out.size:
        j = int(owner[out[0]])
        raise IndexOutOfRangeError(
            f"{where}: {raw.where_face(j, name)} references vertex {int(corners[out[0]])}, outside "
            f"0..{n - 1} (the file has {n} vertices; {len(np.unique(owner[out]))} such {plural})"
        )
    if sizes.size and sizes[0] <= 6 and (sizes == sizes[0]).all():  # all alike: compare corner pairs
        rows = corners.reshape(-1, int(sizes[0]))
        repeated = np.zeros(len(rows), dtype=bool)
        for a in range(rows.shape[1]):  # a fixed small number of corner pairs
            for b in range(a + 1, rows.shape[1]):
                repeated |= rows[:, a] == rows[:, b]
        twice_cells = np.flatnonzero(repeated)
    else:
        order = np.lexsort((corners, owner))
        same = (owner[order][1:] == owner[order][:-1]) & (corners[order][1:] == corners[order][:-1])
        twice_cells = np.unique(owner[order][1:][same])
    if twice_cells.size:
        j = int(twice_cells[0])
        cell = corners[offsets[j]:offsets[j + 1]]
        values, seen = np.unique(cell, return_counts=True)
        first = int(offsets[j]) + int(np.flatnonzero(cell == values[seen > 1][0])[0])
        listed = corners[offsets[j]:offsets[j + 1]].tolist()
        raise RepeatedVertexError(
            f"{where}: {raw.where_face(j, name)} {listed} lists vertex {int(corners[first])} twice "
            f"({twice_cells.size} such {plural})"
        )
