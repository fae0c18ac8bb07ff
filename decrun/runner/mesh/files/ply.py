"""PLY reader (ASCII, binary little- and big-endian), vectorized, any element layout.

PLY (Turk 1994): a text header ``ply / format ... 1.0 / element <name> <count> /
property <type> <name> / property list <count type> <item type> <name> / end_header``,
then the elements in header order. ``vertex`` needs scalar ``x y z``; ``face`` needs a
list ``vertex_indices`` (or ``vertex_index``) of 0-based indices. Other properties and
other elements (``camera``, ``edge``, ``material``, ...) are read past and counted in
``counts``; nothing after the last element is allowed.

Binary records with lists have variable size. If every list of an element has the same
length (the usual all-triangle case) the records are one strided array; otherwise the
record starts are found by pointer doubling over "the next record would start at" for
every byte offset (O(log m) vectorized rounds; two int32 tables the size of the element's
bytes). ASCII records are one per line (as every writer does); an error names the line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from decrun.errors import MeshError
from decrun.runner.mesh.files.checks import RawMesh, polygon_offsets
from decrun.runner.mesh.files.text import TextTokens

_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_FORMATS = {"ascii": "", "binary_little_endian": "<", "binary_big_endian": ">"}
_INDEX_LISTS = ("vertex_indices", "vertex_index")
_CHUNK = 1 << 22  # byte offsets walked at once when records vary in size


@dataclass
class _Property:
    name: str
    type: str  # numpy type code without byte order ("f4"), or the item type of a list
    count_type: str | None = None  # numpy type code of the list length, None for scalars


@dataclass
class _Element:
    name: str
    count: int
    line: int  # 1-based header line
    properties: list[_Property]

    def index(self, name: str) -> int:
        return [p.name for p in self.properties].index(name)


def read_ply(raw: bytes, where: str) -> RawMesh:
    """Parse PLY bytes (any of the three encodings) into a :class:`RawMesh`."""
    header_end, header_lines, encoding, elements = _header(raw, where)
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is None:
        raise MeshError(f"{where}: the PLY header declares no 'vertex' element")
    for axis in "xyz":
        prop = next((p for p in vertex.properties if p.name == axis), None)
        if prop is None or prop.count_type is not None:
            raise MeshError(f"{where}: line {vertex.line}: the 'vertex' element has no scalar property {axis!r}")
    face = next((e for e in elements if e.name == "face"), None)
    if face is not None:
        lists = [p for p in face.properties if p.name in _INDEX_LISTS and p.count_type is not None]
        if not lists:
            raise MeshError(f"{where}: line {face.line}: the 'face' element has no 'vertex_indices' list property")
        if lists[0].type[0] == "f":
            raise MeshError(f"{where}: line {face.line}: face vertex indices have a floating-point type")
    reader = _AsciiBody(raw, header_end, header_lines, where) if encoding == "" else _BinaryBody(raw, header_end, encoding, where)
    vertices = np.zeros((0, 3))
    corners, offsets = np.zeros(0, dtype=np.int64), np.zeros(1, dtype=np.int64)
    vertex_line = face_line = None
    for element in elements:
        if element is vertex:
            vertices, vertex_line = reader.vertices(element)
        elif element is face:
            corners, offsets, face_line = reader.faces(element)
        else:
            reader.skip(element)
    reader.finish(elements)
    counts = {e.name if e.name != "vertex" else "vertices": e.count for e in elements}
    if face is not None:
        counts["faces"] = counts.pop("face")
    name = "ascii" if encoding == "" else ("binary_little_endian" if encoding == "<" else "binary_big_endian")
    return RawMesh(
        vertices=vertices, format=f"ply-{name}", face_corners=corners, face_offsets=offsets,
        vertex_line=vertex_line, face_line=face_line, counts=counts,
    )


def _header(raw: bytes, where: str):
    """(byte offset of the body, number of header lines, byte order ('' = ascii), elements)."""
    if not re.match(rb"ply\r?\n", raw):
        raise MeshError(f"{where}: not a PLY file: the first line is not 'ply'")
    match = re.search(rb"^end_header[ \t\r]*\n", raw, re.M)
    if match is None:
        raise MeshError(f"{where}: the PLY header has no 'end_header' line")
    try:
        lines = raw[:match.start()].decode("ascii").split("\n")[1:]
    except UnicodeDecodeError as exc:
        raise MeshError(f"{where}: the PLY header is not ASCII text (byte {exc.start})") from exc
    encoding, elements = None, []
    for number, line in enumerate(lines, start=2):  # the header is small: a loop is fine
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            if len(words) != 3 or words[1] not in _FORMATS or words[2] != "1.0":
                raise MeshError(f"{where}: line {number}: unsupported PLY format {line.strip()!r}")
            encoding = _FORMATS[words[1]]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise MeshError(f"{where}: line {number}: expected 'element <name> <count>', got {line.strip()!r}")
            if any(e.name == words[1] for e in elements):
                raise MeshError(f"{where}: line {number}: element {words[1]!r} declared twice")
            elements.append(_Element(words[1], int(words[2]), number, []))
        elif words[0] == "property":
            if not elements:
                raise MeshError(f"{where}: line {number}: property before any element")
            elements[-1].properties.append(_property(words, number, where))
            if [p.name for p in elements[-1].properties].count(words[-1]) > 1:
                raise MeshError(f"{where}: line {number}: property {words[-1]!r} declared twice")
        else:
            raise MeshError(f"{where}: line {number}: unknown PLY header keyword {words[0]!r}")
    if encoding is None:
        raise MeshError(f"{where}: the PLY header has no 'format' line")
    return match.end(), raw[:match.end()].count(b"\n"), encoding, elements


def _property(words: list[str], number: int, where: str) -> _Property:
    if len(words) == 5 and words[1] == "list" and words[2] in _TYPES and words[3] in _TYPES:
        if _TYPES[words[2]][0] == "f":
            raise MeshError(f"{where}: line {number}: a list length cannot be of type {words[2]!r}")
        return _Property(words[4], _TYPES[words[3]], _TYPES[words[2]])
    if len(words) == 3 and words[1] in _TYPES:
        return _Property(words[2], _TYPES[words[1]])
    raise MeshError(f"{where}: line {number}: expected 'property <type> <name>' or "
                    f"'property list <type> <type> <name>' with PLY types, got {' '.join(words)!r}")


# ------------------------------------------------------------------------------ binary


class _BinaryBody:
    """Reads elements one after the other from ``raw[offset:]``."""

    def __init__(self, raw: bytes, offset: int, order: str, where: str):
        self.raw, self.offset, self.order, self.where = raw, offset, order, where
        self.bytes = np.frombuffer(raw, dtype=np.uint8)

    def vertices(self, element: _Element):
        if any(p.count_type for p in element.properties):
            starts, _, _ = self._records(element)
            table = None
        else:
            table = self._table(element)
        if table is None:  # vertex element with list properties: gather x, y, z at their offsets
            _, offsets, _ = self._walk(element, starts)
            xyz = [self._read(offsets[element.index(a)], element.properties[element.index(a)].type) for a in "xyz"]
            return np.stack(xyz, axis=1).astype(np.float64), None
        return np.stack([table[a] for a in "xyz"], axis=1).astype(np.float64), None

    def faces(self, element: _Element):
        starts, offsets, counts = self._records(element)
        which = next(i for i, p in enumerate(element.properties) if p.name in _INDEX_LISTS and p.count_type)
        prop = element.properties[which]
        sizes = counts[which].astype(np.int64)
        face_offsets = polygon_offsets(sizes)
        face = np.repeat(np.arange(len(sizes), dtype=np.int64), sizes)
        item = np.dtype(prop.type).itemsize
        first = offsets[which] + np.dtype(prop.count_type).itemsize
        positions = first[face] + item * (np.arange(face_offsets[-1], dtype=np.int64) - face_offsets[face])
        return self._read(positions, prop.type).astype(np.int64), face_offsets, None

    def skip(self, element: _Element):
        if any(p.count_type for p in element.properties):
            self._records(element)
        else:
            self._table(element)

    def finish(self, elements):
        left = len(self.raw) - self.offset
        if left:
            raise MeshError(f"{self.where}: {left} bytes follow the last element ({elements[-1].name!r}) of the binary PLY body")

    # -- helpers

    def _table(self, element: _Element) -> np.ndarray:
        dtype = np.dtype([(p.name, self.order + p.type) for p in element.properties])
        need = element.count * dtype.itemsize
        if self.offset + need > len(self.raw):
            self._truncated(element, (len(self.raw) - self.offset) // max(dtype.itemsize, 1))
        table = np.frombuffer(self.raw, dtype=dtype, count=element.count, offset=self.offset)
        self.offset += need
        return table

    def _read(self, positions: np.ndarray, type_code: str) -> np.ndarray:
        """Values of ``type_code`` at byte ``positions`` (all inside the buffer)."""
        size = np.dtype(type_code).itemsize
        chars = self.bytes[positions[:, None] + np.arange(size)]
        return np.ascontiguousarray(chars).view(self.order + type_code).ravel()

    def _walk(self, element: _Element, starts: np.ndarray):
        """For records starting at ``starts``: (ends, per-property offsets, per-property list
        lengths); an end of ``len(raw) + 1`` marks a record that does not fit."""
        n = len(self.raw)
        invalid = n + 1
        position = starts.astype(np.int64).copy()
        offsets, counts = [], []
        for prop in element.properties:
            offsets.append(position.copy())
            if prop.count_type is None:
                counts.append(None)
                position += np.dtype(prop.type).itemsize
                continue
            size = np.dtype(prop.count_type).itemsize
            fits = position + size <= n
            length = np.zeros(len(position), dtype=np.int64)
            length[fits] = self._read(position[fits], prop.count_type)
            counts.append(length)
            position = np.where(fits & (length >= 0), position + size + length * np.dtype(prop.type).itemsize, invalid)
        return np.minimum(position, invalid), offsets, counts

    def _records(self, element: _Element):
        """Record starts, per-property offsets and list lengths of an element with lists."""
        n, count = len(self.raw), element.count
        smallest = sum(np.dtype(p.count_type or p.type).itemsize for p in element.properties)  # empty lists
        if self.offset + count * smallest > n:
            self._truncated(element, (n - self.offset) // max(smallest, 1))
        if count == 0:
            return np.zeros(0, dtype=np.int64), [np.zeros(0, dtype=np.int64)] * len(element.properties), [np.zeros(0, dtype=np.int64)] * len(element.properties)
        end0, _, counts0 = self._walk(element, np.array([self.offset]))
        size = int(end0[0]) - self.offset
        if end0[0] <= n and self.offset + count * size <= n:  # try: every record like the first
            starts = self.offset + size * np.arange(count, dtype=np.int64)
            ends, offsets, counts = self._walk(element, starts)
            same = all(c is None or (c == c0[0]).all() for c, c0 in zip(counts, counts0, strict=True))
            if same and (ends == starts + size).all():
                self.offset = int(ends[-1])
                return starts, offsets, counts
        starts = self._chain(element, count)
        ends, offsets, counts = self._walk(element, starts)
        self.offset = int(ends[-1])
        return starts, offsets, counts

    def _chain(self, element: _Element, count: int) -> np.ndarray:
        """Starts of ``count`` consecutive variable-size records by pointer doubling."""
        n = len(self.raw)
        span = n - self.offset
        index_type = np.int32 if span + 2 < 2**31 else np.int64
        # relative next-start for every byte offset; span = "exactly at the end", span + 1 = invalid
        jump = np.empty(span + 2, dtype=index_type)
        for lo in range(0, span, _CHUNK):  # blocks of byte offsets bound the walk's temporaries
            hi = min(lo + _CHUNK, span)
            ends, _, _ = self._walk(element, self.offset + np.arange(lo, hi, dtype=np.int64))
            jump[lo:hi] = np.minimum(ends - self.offset, span + 1)
        jump[span:] = span + 1
        record = np.arange(count, dtype=np.int64)
        starts = np.zeros(count, dtype=index_type)
        bit = 0
        while (1 << bit) < count:
            take = ((record >> bit) & 1).astype(bool)
            starts[take] = jump[starts[take]]
            jump = jump[jump]
            bit += 1
        bad = np.flatnonzero(starts >= span)
        if bad.size:
            self._truncated(element, int(bad[0]))
        last_end, _, _ = self._walk(element, np.array([self.offset + int(starts[-1])]))
        if last_end[0] > n:
            self._truncated(element, count - 1)
        return self.offset + starts.astype(np.int64)

    def _truncated(self, element: _Element, complete: int):
        raise MeshError(
            f"{self.where}: the binary PLY body ends inside element {element.name!r}: "
            f"{element.count} records declared, only about {complete} present"
        )


# ------------------------------------------------------------------------------ ascii


class _AsciiBody:
    """ASCII body: one record per line, elements in header order."""

    def __init__(self, raw: bytes, offset: int, header_lines: int, where: str):
        self.text = TextTokens(raw[offset:], where, first_line=header_lines + 1, first_byte=offset)
        self.where = where
        self.lines = np.flatnonzero(self.text.line_token_count > 0)
        self.next = 0  # index into self.lines

    def _take(self, element: _Element):
        """The element's record lines and, per property, the token index and list length."""
        text = self.text
        lines = self.lines[self.next:self.next + element.count]
        if len(lines) < element.count:
            raise MeshError(f"{self.where}: the file ends after {len(lines)} of the {element.count} "
                            f"{element.name!r} records the header (line {element.line}) declares")
        self.next += element.count
        end = text.line_first_token[lines] + text.line_token_count[lines]
        position = text.line_first_token[lines].copy()
        tokens, lengths = [], []
        for prop in element.properties:
            short = np.flatnonzero(position >= end)
            if short.size:
                self._bad_record(element, lines, short[0], "has too few values")
            tokens.append(position.copy())
            if prop.count_type is None:
                lengths.append(None)
                position = position + 1
                continue
            length = text.token_numbers(position, np.int64, f"{element.name} list length")
            negative = np.flatnonzero(length < 0)
            if negative.size:
                self._bad_record(element, lines, negative[0], "has a negative list length")
            lengths.append(length)
            position = position + 1 + length
        wrong = np.flatnonzero(position != end)
        if wrong.size:
            self._bad_record(element, lines, wrong[0], f"has {'too few' if position[wrong[0]] > end[wrong[0]] else 'too many'} values")
        return lines, tokens, lengths

    def _bad_record(self, element, lines, i, problem):
        line = int(lines[i])
        raise MeshError(f"{self.where}: line {self.text.line_number(line)}: {element.name} {int(i)} {problem} "
                        f"for the properties the header (line {element.line}) declares: {self.text.line_text(line)!r}")

    def vertices(self, element: _Element):
        text = self.text
        lines, tokens, _ = self._take(element)
        xyz = np.stack([tokens[element.index(a)] for a in "xyz"], axis=1).ravel()
        values = text.token_numbers(xyz, np.float64, "vertex coordinate")
        return values.reshape(-1, 3), text.line_number(lines)

    def faces(self, element: _Element):
        text = self.text
        lines, tokens, lengths = self._take(element)
        which = next(i for i, p in enumerate(element.properties) if p.name in _INDEX_LISTS and p.count_type)
        sizes = lengths[which]
        offsets = polygon_offsets(sizes)
        face = np.repeat(np.arange(len(lines), dtype=np.int64), sizes)
        index_tokens = tokens[which][face] + 1 + np.arange(offsets[-1], dtype=np.int64) - offsets[face]
        corners = text.token_numbers(index_tokens, np.int64, "vertex index")
        return corners, offsets, text.line_number(lines)

    def skip(self, element: _Element):
        self._take(element)

    def finish(self, elements):
        if self.next < len(self.lines):
            line = int(self.lines[self.next])
            raise MeshError(f"{self.where}: line {self.text.line_number(line)}: unexpected content "
                            f"{self.text.line_text(line)!r} after the last declared element")
