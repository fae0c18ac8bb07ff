"""An append-only file of fixed-size, checksummed records: the crash-safe half of a run's
per-step series (the HDF5 half is :mod:`decrun.runner.results.recorder`).

Why not HDF5 directly: an HDF5 file updated in place is only consistent at the moments
its metadata has been flushed, and HDF5 promises nothing for a writer killed
mid-update. Measured here (HDF5 2.0, h5py 3.16; 300 random SIGKILLs each of a process
appending 400 steps to 4 datasets): ``flush()`` after every record left 5 files HDF5
cannot open, SWMR (``libver='latest'``, ``swmr_mode=True``, readers with ``swmr=True``)
left 4 -- those killed while the file was being created or before SWMR mode was on;
and a writer killed in a non-SWMR metadata update (which ``finish`` needs, to add
fields and attributes) has no guarantee at all. An append-only file of fixed-size
records has one failure mode only -- a short last record -- and its reader drops it,
which a kill test can prove.

Layout (all integers little-endian)::

    offset 0   b"DECRUNJ1"                         magic, 8 bytes
    offset 8   uint64 L                            length of the JSON header
    offset 16  JSON (L bytes), zero-padded to B = the next multiple of 8; every offset
               in it counts from B (blobs, D) or from the record start (columns):
               {"format": "decrun-journal-1", "record_size": R, "data_offset": D,
                "columns": [{"name", "dtype", "shape", "offset"}...],
                "blobs": {name: {"dtype", "shape", "offset"}}, "attrs": {...}}
    blobs      raw C-order arrays written once (e.g. the mesh)
    offset B+D record 0, record 1, ...             each exactly R bytes:
               uint32 crc32 of bytes [8, R) | uint32 0x52454344 ("DCER") |
               int64 step | each column's raw bytes at its offset (8-byte aligned)

The header and blobs are written to a temporary name and renamed, so a journal that
exists always has a whole header. Records are appended with one ``writev`` each; a
record is valid when it is whole and its checksum matches, and the valid records are the
longest such prefix. A failed append (disk full) truncates the file back to the last
whole record before the error is raised, so the file stays a valid journal.
"""

from __future__ import annotations

import json
import os
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from decrun.errors import CorruptFileError
from decrun.runner.io.atomic import atomic_path
from decrun.runner.results.checked import open_regular, parse_json

MAGIC = b"DECRUNJ1"
FORMAT = "decrun-journal-1"
RECORD_MARK = 0x52454344
_RECORD_HEAD = struct.Struct("<IIq")  # crc32, mark, step
_ALIGN = 8
#: the block of records read at a time when a journal is copied or read whole (bounds memory)
BLOCK_BYTES = 8 << 20


def journal_path(path: str | os.PathLike) -> Path:
    """The journal beside ``path``: ``result.h5`` → ``result.h5.partial``."""
    path = Path(path)
    return path.with_name(path.name + ".partial")


def _aligned(n: int) -> int:
    return -(-n // _ALIGN) * _ALIGN


@dataclass(frozen=True)
class Column:
    """One per-step value: its name, dtype and the shape of one record's value
    (``()`` for a scalar)."""

    name: str
    dtype: np.dtype
    shape: tuple[int, ...]

    @property
    def nbytes(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64)) * self.dtype.itemsize


def _layout(columns: list[Column]) -> tuple[list[int], int]:
    """Byte offset of each column inside a record, and the record size R."""
    offsets, at = [], _RECORD_HEAD.size
    for column in columns:
        offsets.append(at)
        at = _aligned(at + column.nbytes)
    return offsets, at


def record_dtype(columns: list[Column]) -> np.dtype:
    """The numpy structured dtype of one record (fields ``crc``, ``mark``, ``step`` and
    one per column), for reading blocks of records as arrays."""
    offsets, size = _layout(columns)
    names = ["crc", "mark", "step"] + [c.name for c in columns]
    formats = ["<u4", "<u4", "<i8"] + [(c.dtype, c.shape) if c.shape else c.dtype for c in columns]
    return np.dtype({"names": names, "formats": formats, "offsets": [0, 4, 8] + offsets, "itemsize": size})


class JournalWriter:
    """Creates a journal (header + blobs, atomically) and appends records to it.

    Parameters
    ----------
    path : the journal's final path; ``path`` is replaced if it exists.
    columns : the record layout (fixed for the life of the file).
    blobs : arrays written once after the header (e.g. ``mesh/vertices``).
    attrs : JSON-serialisable metadata stored in the header.
    """

    def __init__(self, path: str | os.PathLike, columns: list[Column], blobs: dict[str, np.ndarray], attrs: dict[str, Any]):
        self.path = Path(path)
        self.columns = list(columns)
        self._offsets, self.record_size = _layout(self.columns)
        self._pads = [self._offsets[i + 1] - self._offsets[i] - c.nbytes for i, c in enumerate(self.columns[:-1])]
        if self.columns:
            self._pads.append(self.record_size - self._offsets[-1] - self.columns[-1].nbytes)
        blobs = {name: np.ascontiguousarray(array) for name, array in blobs.items()}
        # offsets of blobs and records count from the first 8-byte boundary after the
        # JSON, so the JSON does not depend on its own length
        at, blob_specs = 0, {}
        for name, array in blobs.items():
            blob_specs[name] = {"dtype": array.dtype.str, "shape": list(array.shape), "offset": at}
            at = _aligned(at + array.nbytes)
        header = {"format": FORMAT, "record_size": self.record_size, "data_offset": at,
                  "columns": [{"name": c.name, "dtype": c.dtype.str, "shape": list(c.shape), "offset": o}
                              for c, o in zip(self.columns, self._offsets, strict=True)],
                  "blobs": blob_specs, "attrs": attrs}
        text = json.dumps(header).encode()
        base = _aligned(16 + len(text))
        with atomic_path(self.path) as tmp, open(tmp, "wb") as f:
            f.write(MAGIC + struct.pack("<Q", len(text)) + text)
            for name, array in blobs.items():
                f.write(b"\0" * (base + blob_specs[name]["offset"] - f.tell()))
                f.write(array.tobytes())
            f.write(b"\0" * (base + header["data_offset"] - f.tell()))
        header["data_offset"] += base
        self.data_offset = header["data_offset"]
        self.n_records = 0
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)

    @classmethod
    def reopen(cls, journal: "Journal", n_records: int) -> "JournalWriter":
        """Continue an existing journal (read and verified by :func:`read_journal`) after its
        first ``n_records`` records: the file is truncated there (the records after them are
        dropped, to be appended anew) and opened for appending. ValueError when the journal
        has fewer valid records."""
        if not 0 <= n_records <= journal.n_records:
            raise ValueError(f"{journal.path}: has {journal.n_records} valid records, cannot continue after {n_records}")
        self = cls.__new__(cls)
        self.path, self.columns = Path(journal.path), list(journal.columns)
        self._offsets, self.record_size = _layout(self.columns)
        self._pads = [self._offsets[i + 1] - self._offsets[i] - c.nbytes for i, c in enumerate(self.columns[:-1])]
        if self.columns:
            self._pads.append(self.record_size - self._offsets[-1] - self.columns[-1].nbytes)
        if self.record_size != journal.record_size:
            raise ValueError(f"{journal.path}: record size {journal.record_size} differs from its columns' {self.record_size}")
        self.data_offset, self.n_records = journal.data_offset, n_records
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        os.ftruncate(self._fd, self.data_offset + n_records * self.record_size)
        return self

    def append(self, step: int, values: list[np.ndarray]) -> None:
        """Append one record: ``values[i]`` is C-contiguous with ``columns[i]``'s dtype and
        shape (the caller checks). One ``writev``; on any error the file is truncated back
        to its last whole record and the error re-raised."""
        if self._fd is None:
            raise RuntimeError(f"{self.path}: the journal is closed")
        parts: list[Any] = []
        for value, pad in zip(values, self._pads, strict=True):
            parts.append(value.reshape(-1).view(np.uint8))
            if pad:
                parts.append(b"\0" * pad)
        crc = zlib.crc32(struct.pack("<q", step))
        for part in parts:
            crc = zlib.crc32(part, crc)
        parts.insert(0, _RECORD_HEAD.pack(crc, RECORD_MARK, step))
        if len(parts) > 512:  # writev takes at most IOV_MAX (1024 on Linux) buffers
            parts = [b"".join(bytes(p) for p in parts)]
        good_size = self.data_offset + self.n_records * self.record_size
        try:
            written = os.writev(self._fd, parts)
            while written < self.record_size:  # a short write: finish it (or hit the error)
                rest = b"".join(bytes(p) for p in parts)[written:]
                more = os.write(self._fd, rest)
                if more == 0:
                    raise OSError(28, os.strerror(28))
                written += more
        except BaseException:
            try:
                os.ftruncate(self._fd, good_size)
            except OSError:
                pass
            raise
        self.n_records += 1

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


@dataclass
class Journal:
    """A journal opened for reading: layout, attributes, blobs and the number of valid
    records (the longest prefix of whole records with matching checksums)."""

    path: Path
    columns: list[Column]
    record_size: int
    data_offset: int
    attrs: dict[str, Any]
    blobs: dict[str, np.ndarray]
    n_records: int

    def blocks(self, max_bytes: int = 16 << 20, stop: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
        """``(first_record_index, records)`` for consecutive blocks of at most
        ``max_bytes``, read into one reused buffer (memory stays flat; no mapping of the
        whole file). ``records`` is a structured array of :func:`record_dtype`."""
        stop = self.n_records if stop is None else stop
        per_block = max(1, max_bytes // self.record_size)
        buffer = np.empty(min(per_block, max(stop, 1)), dtype=record_dtype(self.columns))
        with open(self.path, "rb") as f:
            f.seek(self.data_offset)
            for start in range(0, stop, per_block):
                count = min(per_block, stop - start)
                view = memoryview(buffer[:count]).cast("B")
                got = f.readinto(view)
                if got != count * self.record_size:
                    raise OSError(f"{self.path}: journal shrank while being read")
                yield start, buffer[:count]


def _valid_prefix(f, data_offset: int, record_size: int, n_whole: int) -> int:
    """Number of leading records whose mark and checksum are right (reads in blocks)."""
    per_block = max(1, (8 << 20) // record_size)
    f.seek(data_offset)
    for start in range(0, n_whole, per_block):
        count = min(per_block, n_whole - start)
        data = f.read(count * record_size)
        for i in range(count):  # a loop over time steps, not mesh elements
            record = memoryview(data)[i * record_size:(i + 1) * record_size]
            crc, mark, _ = _RECORD_HEAD.unpack_from(record)
            if mark != RECORD_MARK or zlib.crc32(record[8:]) != crc:
                return start + i
    return n_whole


def read_journal(path: str | os.PathLike, *, verify: bool = True) -> Journal:
    """Open a journal: header, blobs and the count of valid records.

    ``verify`` checks every record's checksum (reads the whole file once); without it
    the count is the number of whole records (enough after a kill: appends only ever
    leave a short last record). Raises :class:`~decrun.errors.CorruptFileError` (a
    ``ValueError``) naming the file when ``path`` is not a journal or its header is not
    one decrun writes; every length, offset and shape in the header is checked against
    the file's size before anything is read or allocated.
    """
    path = Path(path)
    with open_regular(path) as f:  # a FIFO: refused, never waited on
        size = os.fstat(f.fileno()).st_size
        head = f.read(16)
        if len(head) < 16 or head[:8] != MAGIC:
            raise CorruptFileError(f"{path}: not a decrun journal (bad magic)")
        (length,) = struct.unpack("<Q", head[8:])
        if length > size - 16:
            raise CorruptFileError(f"{path}: the journal header claims {length} bytes, the file has {size}")
        header = parse_json(f.read(length), f"{path}: journal header")
        base = _aligned(16 + length)
        columns, blob_specs, record_size, data_offset, attrs = _checked_header(header, path, base, size)
        blobs = {}
        for name, (dtype, shape, offset) in blob_specs.items():
            f.seek(base + offset)
            count = int(np.prod(shape, dtype=np.int64))
            blobs[name] = np.frombuffer(f.read(count * dtype.itemsize), dtype=dtype).reshape(shape).copy()
        n_whole = max(0, size - data_offset) // record_size
        n = _valid_prefix(f, data_offset, record_size, n_whole) if verify else n_whole
    return Journal(path, columns, record_size, data_offset, attrs, blobs, n)


def _numeric(spec: dict) -> tuple[np.dtype, tuple[int, ...]]:
    dtype, shape = np.dtype(spec["dtype"]), tuple(spec["shape"])
    if dtype.kind not in "biufc" or dtype.names is not None or dtype.subdtype is not None:
        raise ValueError(f"dtype {spec['dtype']!r} is not numeric")
    if not all(isinstance(n, int) and not isinstance(n, bool) and 0 <= n for n in shape):
        raise ValueError(f"shape {spec['shape']!r} is not a shape")
    return dtype, shape


def _checked_header(header: Any, path: Path, base: int, size: int):
    """(columns, blobs {name: (dtype, shape, offset)}, record_size, data_offset, attrs) of a
    parsed header, each checked: the format, numeric dtypes, the record size equal to the
    columns' layout, blobs and records inside the file. CorruptFileError otherwise."""
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        found = header.get("format") if isinstance(header, dict) else type(header).__name__
        raise CorruptFileError(f"{path}: unknown journal format {found!r}")
    try:
        columns = [Column(str(c["name"]), *_numeric(c)) for c in header["columns"]]
        blobs = {}
        for name, spec in header["blobs"].items():
            dtype, shape = _numeric(spec)
            offset = spec["offset"]
            nbytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
            if not isinstance(offset, int) or offset < 0 or base + offset + nbytes > size:
                raise ValueError(f"blob {name!r} ({nbytes} bytes at {offset}) lies outside the file of {size} bytes")
            blobs[str(name)] = (dtype, shape, offset)
        record_size, data_offset = header["record_size"], header["data_offset"]
        if record_size != _layout(columns)[1]:
            raise ValueError(f"record size {record_size!r} does not match its columns ({_layout(columns)[1]})")
        if not isinstance(data_offset, int) or data_offset < 0 or base + data_offset > size:
            raise ValueError(f"data offset {data_offset!r} lies outside the file of {size} bytes")
        attrs = header["attrs"]
        if not isinstance(attrs, dict):
            raise ValueError("attrs is not an object")
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        what = f"no {exc}" if isinstance(exc, KeyError) else str(exc)
        raise CorruptFileError(f"{path}: malformed journal header ({what})") from None
    return columns, blobs, record_size, base + data_offset, attrs
