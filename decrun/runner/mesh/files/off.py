"""OFF (Object File Format, geomview) reader, vectorized, with line numbers in every error.

Layout (geomview OFF spec): an optional keyword ``[ST][C][N]OFF``; ``n_vertices n_faces
n_edges`` (on the keyword line or the next one); ``n_vertices`` lines ``x y z`` followed by
the per-vertex extras the keyword announces (N: normal nx ny nz, C: colour of 3 or 4
values, ST: texture s t; read past); ``n_faces`` lines ``k i_1 ... i_k [colour]`` with
0-based indices and an optional colour of 3 or 4 values. ``#`` starts a comment; blank
lines are skipped. The counts must match the body exactly: a missing or an extra line is
an error. 4OFF and nOFF (other dimensions) are rejected.
"""

from __future__ import annotations

import re

import numpy as np

from decrun.errors import MeshError
from decrun.runner.mesh.files.checks import RawMesh, polygon_offsets
from decrun.runner.mesh.files.text import TextTokens


def read_off(raw: bytes, where: str) -> RawMesh:
    """Parse OFF bytes into a :class:`RawMesh` (faces as polygons, 0-based indices)."""
    text = TextTokens(raw, where, comment=b"#")
    lines = np.flatnonzero(text.line_token_count > 0)
    if lines.size == 0:
        raise MeshError(f"{where}: the file holds no OFF header, only blanks and comments")
    first = int(lines[0])
    keyword = text.token_text(int(text.line_first_token[first]))
    variant = re.fullmatch(r"(ST)?(C)?(N)?OFF", keyword)
    extras = {0}
    if variant:
        base = 3 * bool(variant[3]) + 2 * bool(variant[1])
        extras = {base + 3, base + 4} if variant[2] else {base}
        keyword = "OFF"
    if keyword == "OFF" and text.line_token_count[first] == 4:  # "OFF n_v n_f n_e"
        count_line, body = first, lines[1:]
        count_tokens = text.line_first_token[first] + np.arange(1, 4)
    elif keyword == "OFF" and text.line_token_count[first] == 1 and lines.size > 1:
        count_line, body = int(lines[1]), lines[2:]
        count_tokens = text.line_first_token[count_line] + np.arange(3)
        if text.line_token_count[count_line] != 3:
            raise MeshError(f"{where}: line {count_line + 1}: expected 'n_vertices n_faces n_edges', got {text.line_text(count_line)!r}")
    elif keyword == "OFF":
        raise MeshError(f"{where}: line {first + 1}: expected 'OFF' then 'n_vertices n_faces n_edges', got {text.line_text(first)!r}")
    elif keyword.endswith("OFF"):
        raise MeshError(f"{where}: line {first + 1}: OFF variant {keyword!r} is not supported (3-D [ST][C][N]OFF only)")
    elif text.line_token_count[first] == 3 and keyword.lstrip("+-").isdigit():  # no keyword (allowed)
        count_line, body = first, lines[1:]
        count_tokens = text.line_first_token[first] + np.arange(3)
    else:
        raise MeshError(f"{where}: line {first + 1}: not an OFF file: expected 'OFF', got {text.line_text(first)!r}")
    n_vertices, n_faces, _ = text.token_numbers(count_tokens, np.int64, "count").tolist()
    if n_vertices < 0 or n_faces < 0:
        raise MeshError(f"{where}: line {count_line + 1}: negative count in {text.line_text(count_line)!r}")
    if body.size < n_vertices + n_faces:
        kind, seen = ("vertices", body.size) if body.size < n_vertices else ("faces", body.size - n_vertices)
        total = n_vertices if kind == "vertices" else n_faces
        raise MeshError(
            f"{where}: the header (line {count_line + 1}) announces {total} {kind} but the file ends after {seen}"
        )
    if body.size > n_vertices + n_faces:
        extra = int(body[n_vertices + n_faces])
        raise MeshError(
            f"{where}: line {extra + 1}: unexpected content {text.line_text(extra)!r} after the "
            f"{n_vertices} vertices and {n_faces} faces the header (line {count_line + 1}) announces"
        )
    vertex_lines, face_lines = body[:n_vertices], body[n_vertices:]
    wrong = np.flatnonzero(~np.isin(text.line_token_count[vertex_lines] - 3, list(extras)))
    if wrong.size:
        line = int(vertex_lines[wrong[0]])
        expected = " or ".join(str(3 + e) for e in sorted(extras))
        raise MeshError(
            f"{where}: line {line + 1}: vertex {int(wrong[0])} should have {expected} values "
            f"(x y z and what {text.token_text(int(text.line_first_token[first]))!r} announces), got {text.line_text(line)!r}"
        )
    xyz = (text.line_first_token[vertex_lines, None] + np.arange(3)).ravel()
    vertices = text.token_numbers(xyz, np.float64, "vertex coordinate")
    corners, offsets = _faces(text, face_lines)
    return RawMesh(
        vertices=vertices.reshape(-1, 3), format="off", face_corners=corners, face_offsets=offsets,
        vertex_line=vertex_lines + 1, face_line=face_lines + 1,
        counts={"vertices": int(n_vertices), "faces": int(n_faces)},
    )


def _faces(text: TextTokens, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Face lines ``k i_1 ... i_k [r g b [a]]`` → (corners, offsets)."""
    where = text.where
    head = text.line_first_token[lines]
    sizes = text.token_numbers(head, np.int64, "face corner count")
    values = text.line_token_count[lines] - 1
    wrong = np.flatnonzero((sizes < 3) | ((values != sizes) & (values != sizes + 3) & (values != sizes + 4)))
    if wrong.size:
        j = int(wrong[0])
        line = int(lines[j])
        raise MeshError(
            f"{where}: line {line + 1}: face {j} should be 'k i_1 ... i_k [colour]' with k >= 3 "
            f"and k indices, got {text.line_text(line)!r}"
        )
    offsets = polygon_offsets(sizes)
    face = np.repeat(np.arange(len(lines), dtype=np.int64), sizes)
    tokens = head[face] + 1 + np.arange(offsets[-1], dtype=np.int64) - offsets[face]
    corners = text.token_numbers(tokens, np.int64, "vertex index")
    return corners, offsets
