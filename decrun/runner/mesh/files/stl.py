"""STL reader (binary and ASCII), vectorized; corners are merged into shared vertices.

Binary STL: an 80-byte header, a uint32 facet count m, then m records of 50 bytes
(normal 3×float32, corners 3×3 float32, uint16 attribute); the file size must be exactly
84 + 50·m. ASCII STL: ``solid name``, per facet ``facet normal nx ny nz / outer loop /
vertex x y z`` ×3 ``/ endloop / endfacet``, then ``endsolid``; one solid per file.

STL stores no connectivity: corners with bit-identical coordinates (after float64
conversion; -0.0 equals 0.0) become one vertex, numbered in order of first appearance —
what every loader does. Non-finite corners are rejected before merging (NaN never
compares equal), so the error can name the facet and line.
"""

from __future__ import annotations

import re

import numpy as np

from decrun.errors import MeshError, NonFiniteCoordinateError
from decrun.runner.mesh.files.checks import RawMesh
from decrun.runner.mesh.files.text import TextTokens, is_text

_BINARY_RECORD = np.dtype([("normal", "<f4", (3,)), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
# ASCII statements and the number of tokens each line must have
_FACET, _OUTER, _VERTEX, _ENDLOOP, _ENDFACET = range(5)
_PATTERN = np.array([_FACET, _OUTER, _VERTEX, _VERTEX, _VERTEX, _ENDLOOP, _ENDFACET])
_KEYWORDS = {b"facet": (_FACET, 5), b"outer": (_OUTER, 2), b"vertex": (_VERTEX, 4), b"endloop": (_ENDLOOP, 1), b"endfacet": (_ENDFACET, 1)}
_NAMES = {_FACET: "facet normal nx ny nz", _OUTER: "outer loop", _VERTEX: "vertex x y z", _ENDLOOP: "endloop", _ENDFACET: "endfacet"}


def read_stl(raw: bytes, where: str) -> RawMesh:
    """Parse STL bytes (binary when the size matches 84 + 50·m, else ASCII)."""
    if len(raw) >= 84:
        count = int(np.frombuffer(raw, dtype="<u4", count=1, offset=80)[0])
        if len(raw) == 84 + 50 * count:
            return _binary(raw, count, where)
    if not re.match(rb"\s*solid", raw):
        facets = (len(raw) - 84) / 50 if len(raw) >= 84 else 0
        raise MeshError(
            f"{where}: not an STL file: it does not start with 'solid' (ASCII) and its size {len(raw)} bytes "
            f"is not 84 + 50·(facet count in the header) (binary{'; it would hold %.2f facets' % facets if facets else ''})"
        )
    bad = is_text(raw)
    if bad >= 0:
        raise MeshError(f"{where}: starts with 'solid' but has binary content at byte {bad} and its size does not match a binary STL")
    return _ascii(raw, where)


def _binary(raw: bytes, count: int, where: str) -> RawMesh:
    records = np.frombuffer(raw, dtype=_BINARY_RECORD, count=count, offset=84)
    corners = records["corners"].reshape(-1, 3).astype(np.float64)
    return _merge(corners, None, None, "stl-binary", where)


def _ascii(raw: bytes, where: str) -> RawMesh:
    text = TextTokens(raw, where)
    lines = np.flatnonzero(text.line_token_count > 0)
    head = text.line_first_token[lines]
    keywords = text.gather(text.token_start[head], np.minimum(text.token_end[head], text.token_start[head] + 10))
    if keywords[0] != b"solid":
        raise MeshError(f"{where}: line {int(lines[0]) + 1}: expected 'solid <name>'")
    if keywords[-1] != b"endsolid" or len(lines) < 2:
        raise MeshError(f"{where}: line {int(lines[-1]) + 1}: the file does not end with 'endsolid'")
    inner, words = lines[1:-1], keywords[1:-1]
    code = np.full(len(inner), -1, dtype=np.int64)
    tokens = np.zeros(len(inner), dtype=np.int64)
    for keyword, (value, width) in _KEYWORDS.items():  # five keywords, not a loop over lines
        code[words == keyword] = value
        tokens[words == keyword] = width
    expected = _PATTERN[np.arange(len(inner)) % len(_PATTERN)]
    wrong = np.flatnonzero((code != expected) | (text.line_token_count[inner] != tokens))
    if wrong.size or len(inner) % len(_PATTERN):
        i = int(wrong[0]) if wrong.size else len(inner)
        line = int(inner[i]) if i < len(inner) else int(lines[-1])
        found = text.line_text(line)
        raise MeshError(f"{where}: line {line + 1}: expected '{_NAMES[int(_PATTERN[i % len(_PATTERN)])]}', got {found!r}")
    second = text.line_first_token[inner[code == _OUTER]] + 1
    if not (text.gather(text.token_start[second], text.token_end[second]) == b"loop").all():
        raise MeshError(f"{where}: an 'outer' line does not read 'outer loop'")
    normals = (text.line_first_token[inner[code == _FACET], None] + np.arange(2, 5)).ravel()
    text.token_numbers(normals, np.float64, "facet normal component")  # unused, but must be numbers
    vertex_lines = inner[code == _VERTEX]
    xyz = (text.line_first_token[vertex_lines, None] + np.arange(1, 4)).ravel()
    corners = text.token_numbers(xyz, np.float64, "vertex coordinate")
    return _merge(corners.reshape(-1, 3), vertex_lines + 1, inner[code == _FACET] + 1, "stl-ascii", where)


def _merge(corners: np.ndarray, corner_line: np.ndarray | None, facet_line: np.ndarray | None, format: str, where: str) -> RawMesh:
    """Facet corners (3m, 3) → shared vertices in order of first appearance + triangles."""
    finite = np.isfinite(corners).all(axis=1)
    if not finite.all():
        k = int(np.flatnonzero(~finite)[0])
        line = f"line {int(corner_line[k])}: " if corner_line is not None else ""
        raise NonFiniteCoordinateError(
            f"{where}: {line}facet {k // 3} corner {k % 3} has a non-finite coordinate {corners[k].tolist()} "
            f"({int((~finite).sum())} such corners)"
        )
    corners = corners + 0.0  # -0.0 → 0.0
    _, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # unique vertices by first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    triangles = rank[inverse.ravel()].reshape(-1, 3)
    m = len(triangles)
    return RawMesh(
        vertices=corners[first[order]], format=format,
        face_corners=triangles.ravel(), face_offsets=np.arange(m + 1, dtype=np.int64) * 3,
        vertex_line=None if corner_line is None else corner_line[first[order]],
        face_line=facet_line,
        counts={"facets": m, "vertices": len(order), "faces": m},
    )
