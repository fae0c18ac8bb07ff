"""Wavefront OBJ reader with exact index checks, vectorized (no Python work per line).

Statements (Wavefront OBJ spec, Appendix B1 of the Advanced Visualizer manual):

- ``v x y z [w]`` or ``v x y z r g b`` (the common vertex-colour extension): a vertex;
  ``w`` must be 1 (rational weights belong to free-form geometry);
- ``f a b c ...`` with corners ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``: a polygon face.
  Indices are 1-based; a negative index ``-r`` is relative: the r-th most recent element
  of its kind *before this line*. Index 0, an index beyond the elements defined, a
  malformed corner are errors. ``vt``/``vn`` indices are checked the same way;
- ``vt``, ``vn``, ``vp`` are counted; ``l`` (polylines) and ``p`` (points) are counted and
  reported in ``counts`` (they carry no faces); ``g o s usemtl mtllib`` and the other
  display/grouping statements are counted and ignored;
- free-form geometry (``cstype curv surf ...``), line continuation (``\\``) and unknown
  statements are errors.
"""

from __future__ import annotations

import numpy as np

from decrun.errors import IndexOutOfRangeError, MeshError
from decrun.runner.mesh.files.checks import RawMesh
from decrun.runner.mesh.files.text import TextTokens

_VERTEX, _FACE, _TEXCOORD, _NORMAL, _IGNORED, _LINE, _POINT, _FREEFORM = range(8)
_STATEMENTS = {
    b"v": _VERTEX, b"f": _FACE, b"fo": _FACE, b"vt": _TEXCOORD, b"vn": _NORMAL, b"vp": _IGNORED,
    b"l": _LINE, b"p": _POINT,
    **{k: _IGNORED for k in (b"g", b"o", b"s", b"mg", b"usemtl", b"mtllib", b"lod", b"maplib", b"usemap",
                             b"shadow_obj", b"trace_obj", b"bevel", b"c_interp", b"d_interp", b"ctech", b"stech")},
    **{k: _FREEFORM for k in (b"cstype", b"deg", b"bmat", b"step", b"curv", b"curv2", b"surf", b"parm",
                              b"trim", b"hole", b"scrv", b"sp", b"end", b"con")},
}
_COUNT_NAMES = {_TEXCOORD: "texture_coordinates", _NORMAL: "normals", _LINE: "polylines", _POINT: "point_elements"}


def read_obj(raw: bytes, where: str) -> RawMesh:
    """Parse OBJ bytes into a :class:`RawMesh` (vertices (n, 3), polygon faces with 0-based
    indices, 1-based line numbers, counts of every statement kind)."""
    text = TextTokens(raw, where, comment=b"#")
    used = np.flatnonzero(text.line_token_count > 0)
    keyword_token = text.line_first_token[used]
    keyword_start = text.token_start[keyword_token]
    keyword_end = np.minimum(text.token_end[keyword_token], keyword_start + 11)
    keywords, kind_of = np.unique(text.gather(keyword_start, keyword_end), return_inverse=True)
    kinds = np.array([_STATEMENTS.get(bytes(k), -1) for k in keywords], dtype=np.int64)  # distinct keywords only
    kind = kinds[kind_of.ravel()] if used.size else np.zeros(0, dtype=np.int64)
    last_token = text.line_first_token[used] + text.line_token_count[used] - 1
    continued = text.buffer[text.token_end[last_token] - 1] == ord("\\")
    if continued.any():
        line = int(used[np.flatnonzero(continued)[0]]) + 1
        raise MeshError(f"{where}: line {line}: line continuation '\\' is not supported")
    _reject(text, used, kind)

    vertex_lines = used[kind == _VERTEX]
    vertices = _vertices(text, vertex_lines)
    # elements of each kind defined before every statement line (for negative indices)
    before = {k: np.cumsum(kind == k) - (kind == k) for k in (_VERTEX, _TEXCOORD, _NORMAL)}
    is_face = kind == _FACE
    face_lines = used[is_face]
    counts = {"vertices": len(vertex_lines), "faces": len(face_lines)}
    counts.update({name: int((kind == k).sum()) for k, name in _COUNT_NAMES.items()})
    totals = {_VERTEX: len(vertex_lines), _TEXCOORD: counts["texture_coordinates"], _NORMAL: counts["normals"]}
    corners, offsets = _faces(text, face_lines, {k: b[is_face] for k, b in before.items()}, totals)
    return RawMesh(
        vertices=vertices, format="obj", face_corners=corners, face_offsets=offsets,
        vertex_line=vertex_lines + 1, face_line=face_lines + 1, counts=counts,
    )


def _reject(text: TextTokens, used: np.ndarray, kind: np.ndarray) -> None:
    """Unknown statements and free-form geometry are errors (first one in the file)."""
    bad = np.flatnonzero((kind < 0) | (kind == _FREEFORM))
    if not bad.size:
        return
    i = int(bad[0])
    line = int(used[i])
    keyword = text.token_text(int(text.line_first_token[line]))
    if kind[i] == _FREEFORM:
        raise MeshError(f"{text.where}: line {line + 1}: free-form geometry ({keyword!r}) is not supported")
    raise MeshError(f"{text.where}: line {line + 1}: unknown OBJ statement {keyword!r} in {text.line_text(line)!r}")


def _vertices(text: TextTokens, lines: np.ndarray) -> np.ndarray:
    """``v`` lines → (n, 3) float64; checks the value count and w = 1."""
    values = text.line_token_count[lines] - 1
    wrong = np.flatnonzero(~np.isin(values, (3, 4, 6)))
    if wrong.size:
        line = int(lines[wrong[0]])
        raise MeshError(
            f"{text.where}: line {line + 1}: vertex {int(wrong[0])} has {int(values[wrong[0]])} values; "
            f"expected 'v x y z', 'v x y z w' or 'v x y z r g b'"
        )
    first = text.line_first_token[lines]
    xyz = (first[:, None] + np.arange(1, 4)).ravel()
    vertices = text.token_numbers(xyz, np.float64, "vertex coordinate").reshape(-1, 3)
    weighted = np.flatnonzero(values == 4)
    if weighted.size:
        w = text.token_numbers(first[weighted] + 4, np.float64, "vertex weight")
        off = np.flatnonzero(w != 1)
        if off.size:
            i = int(weighted[off[0]])
            raise MeshError(f"{text.where}: line {int(lines[i]) + 1}: vertex {i} has weight w={w[off[0]]:g}; only w = 1 is supported")
    colored = np.flatnonzero(values == 6)
    if colored.size:
        text.token_numbers((first[colored, None] + np.arange(4, 7)).ravel(), np.float64, "vertex colour")
    return vertices


def _faces(text: TextTokens, lines: np.ndarray, before: dict, totals: dict) -> tuple[np.ndarray, np.ndarray]:
    """``f`` lines → (corners 0-based, offsets); every v/vt/vn index checked exactly."""
    tokens, offsets = text.line_tokens(lines, skip=1)
    sizes = np.diff(offsets)
    small = np.flatnonzero(sizes < 3)
    if small.size:
        j = int(small[0])
        raise MeshError(f"{text.where}: line {int(lines[j]) + 1}: face {j} has {int(sizes[j])} corners; a face needs at least 3")
    start, end = text.token_start[tokens], text.token_end[tokens]
    face = np.repeat(np.arange(len(lines), dtype=np.int64), sizes)
    token_line = lines[face]  # 0-based line of every corner token
    lo, hi = (int(start[0]), int(end[-1])) if start.size else (0, 0)  # the bytes of all corners
    slashes = np.flatnonzero(text.buffer[lo:hi] == ord("/")) + lo
    slashes = np.append(slashes, [text.buffer.size] * 3)  # sentinels
    after = np.searchsorted(slashes, start)  # the first slash at or after each corner's start
    s1 = np.minimum(slashes[after], end)  # = end: no slash in this corner
    s2 = np.minimum(slashes[after + 1], end)
    s3 = np.minimum(slashes[after + 2], end)
    extra = np.flatnonzero(s3 < end)
    if extra.size:
        k = int(extra[0])
        raise MeshError(
            f"{text.where}: line {int(token_line[k]) + 1}: face {int(face[k])} corner {text.token_text(int(tokens[k]))!r} "
            f"has more than two '/'; expected v, v/vt, v//vn or v/vt/vn"
        )
    where = text.where
    vertex = _indices(text, start, s1, token_line, face, before[_VERTEX], totals[_VERTEX], "vertex", tokens)
    has_vt = (s1 < end) & (s1 + 1 < s2)
    has_vn = s2 < end
    empty_vt = (s1 < end) & ~has_vt & ~has_vn  # "v/" ; "v//vn" is fine
    empty_vn = has_vn & (s2 + 1 >= end)  # "v/vt/"
    bad = np.flatnonzero(empty_vt | empty_vn)
    if bad.size:
        k = int(bad[0])
        raise MeshError(
            f"{where}: line {int(token_line[k]) + 1}: face {int(face[k])} corner {text.token_text(int(tokens[k]))!r} "
            f"has an empty index; expected v, v/vt, v//vn or v/vt/vn"
        )
    for present, lo, hi, kind, name in ((has_vt, s1 + 1, s2, _TEXCOORD, "texture coordinate"), (has_vn, s2 + 1, end, _NORMAL, "normal")):
        sel = np.flatnonzero(present)
        if sel.size:
            _indices(text, lo[sel], hi[sel], token_line[sel], face[sel], before[kind], totals[kind], name, tokens[sel])
    return vertex, offsets


def _indices(text, start, end, token_line, face, before_per_face, total, name, tokens) -> np.ndarray:
    """Parse 1-based / negative-relative OBJ indices of kind ``name`` → 0-based."""
    where = text.where
    index = text.numbers(start, end, np.int64, f"{name} index")
    zero = np.flatnonzero(index == 0)
    if zero.size:
        k = int(zero[0])
        raise IndexOutOfRangeError(
            f"{where}: line {int(token_line[k]) + 1}: face {int(face[k])} references {name} 0 (OBJ indices start at 1)"
        )
    defined = before_per_face[face]
    resolved = np.where(index > 0, index - 1, defined + index)
    high = np.flatnonzero(index > total)
    if high.size:
        k = int(high[0])
        raise IndexOutOfRangeError(
            f"{where}: line {int(token_line[k]) + 1}: face {int(face[k])} references {name} {int(index[k])} "
            f"but the file defines {total} ({_plural(name)} are numbered 1..{total})"
        )
    low = np.flatnonzero(resolved < 0)
    if low.size:
        k = int(low[0])
        raise IndexOutOfRangeError(
            f"{where}: line {int(token_line[k]) + 1}: face {int(face[k])} references {name} {int(index[k])} "
            f"(relative) but only {int(defined[k])} {_plural(name)} are defined before this line"
        )
    return resolved


def _plural(name: str) -> str:
    return {"vertex": "vertices"}.get(name, name + "s")
