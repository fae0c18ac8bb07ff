"""Checked readers: every file decrun reads back is treated as hostile until checked.

A job directory can hold anything (a truncated copy, a file another tool wrote, one made
to hurt), and a reader must never crash, hang, allocate from a size the file merely
claims, or follow a path out of the file. The readers here raise one
:class:`~decrun.errors.CorruptFileError` naming the file instead:

* :func:`load_json` / :func:`load_yaml` -- unparsable text, nesting deeper than Python's
  recursion limit, YAML tags that would build Python objects (``!!python/object``);
* :func:`open_regular` -- anything that is not a regular file (a FIFO would block the reader),
  refused before it is read, by every reader here;
* :func:`open_h5` -- not an HDF5 file; :func:`check_group` / :func:`read_dataset` -- links
  to other files (external links), external storage (``Dataset.external``), virtual
  datasets, and datasets whose declared shape is more than their stored bytes can hold
  (shape (10^11, 3) in a 1 kB file), checked before any data is read;
* :func:`file_record` / :func:`check_record` -- the size and sha256 of ``result.h5`` that
  ``metrics.json`` records, so a truncated or altered result is never taken for complete.
"""

from __future__ import annotations

import json
import os
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from decrun.core import digest
from decrun.errors import CorruptFileError
from decrun.runner.io.files import RunFiles

__all__ = ["open_regular", "parse_json", "load_json", "load_yaml", "open_h5", "check_group", "checked_members", "check_dataset", "read_dataset", "file_record",
           "check_record", "MAX_DEFLATE_RATIO", "RESULT_RECORD", "CONTENT"]

#: the key of metrics.json recording its result.h5 (:func:`file_record`)
RESULT_RECORD = "result_h5"
#: the key of that record holding the hash of the result's content, equal for two runs of one
#: config (:func:`decrun.runner.results.provenance.content_sha256`)
CONTENT = "content_sha256"
#: deflate cannot shrink data more than 1032:1; a filtered dataset claiming more is refused
MAX_DEFLATE_RATIO = 1100
#: a dataset this small may be unallocated (read as its fill value) without harm
_SMALL_BYTES = 1 << 20


def open_regular(path: str | os.PathLike):
    """``path`` opened for binary reading, or :class:`CorruptFileError` naming it when it is not a
    regular file: a FIFO (reading it would wait for a writer forever), a device, a socket, a
    directory. The check is made on the open descriptor (opened without blocking, which a regular
    file ignores), so nothing can be swapped in between; ``FileNotFoundError`` when absent."""
    import stat

    descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    mode = os.fstat(descriptor).st_mode
    if not stat.S_ISREG(mode):
        os.close(descriptor)
        kind = "a FIFO" if stat.S_ISFIFO(mode) else "a directory" if stat.S_ISDIR(mode) else "a special file"
        raise CorruptFileError(f"{path}: not a regular file ({kind}); decrun reads only regular files")
    return os.fdopen(descriptor, "rb")


def _read_text(path: str | os.PathLike) -> str:
    """The text of ``path``: ``FileNotFoundError`` when absent (the caller's "missing"),
    :class:`CorruptFileError` naming it when it cannot be read, is not a regular file
    (:func:`open_regular`) or is not text."""
    try:
        with open_regular(path) as stream:
            return stream.read().decode()
    except FileNotFoundError:
        raise
    except (OSError, UnicodeDecodeError) as exc:
        raise CorruptFileError(f"{path}: unreadable ({exc})") from None


def load_json(path: str | os.PathLike) -> Any:
    """The JSON value in ``path`` (NaN/Infinity allowed, as decrun writes them).

    Raises ``FileNotFoundError`` when absent and :class:`CorruptFileError` naming the file
    when it cannot be read, is not JSON, or nests deeper than the recursion limit."""
    return parse_json(_read_text(path), str(path))


def parse_json(text: str | bytes, where: str) -> Any:
    """``json.loads(text)``, or :class:`CorruptFileError` starting with ``where`` (the
    file, or the file and attribute) for invalid JSON or nesting deeper than the
    recursion limit (100,000 nested brackets)."""
    try:
        return json.loads(text)
    except RecursionError:
        raise CorruptFileError(f"{where}: JSON nested too deeply to read") from None
    except ValueError as exc:  # JSONDecodeError and UnicodeDecodeError of bytes
        raise CorruptFileError(f"{where}: not valid JSON ({exc})") from None


def load_yaml(path: str | os.PathLike) -> Any:
    """The YAML value in ``path`` read with ``yaml.safe_load`` (no Python object tags).

    Raises ``FileNotFoundError`` when absent and :class:`CorruptFileError` naming the file
    for unreadable text, invalid YAML, a ``!!python/...`` tag, too deep nesting or an alias bomb
    (:func:`~decrun.runner.io.config_files.check_aliases`)."""
    import yaml

    from decrun.runner.io.config_files import check_aliases

    path = Path(path)
    text = _read_text(path)
    check_aliases(text, path)  # an alias bomb, before a reader walks its expansion
    try:
        return yaml.safe_load(text)
    except RecursionError:
        raise CorruptFileError(f"{path}: YAML nested too deeply to read") from None
    except yaml.YAMLError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise CorruptFileError(f"{path}: not YAML decrun reads ({first})") from None


@contextmanager
def open_h5(path: str | os.PathLike) -> Iterator[Any]:
    """``h5py.File(path, "r")``, or :class:`CorruptFileError` when it is not a readable
    HDF5 file (truncated, another format). HDF5 errors met while reading inside the block
    become a CorruptFileError naming the file too."""
    import h5py

    path = Path(path)
    try:
        open_regular(path).close()  # a FIFO would block HDF5's open
        f = h5py.File(path, "r")
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise CorruptFileError(f"{path}: not a readable HDF5 file ({_first_line(exc)})") from None
    try:
        with f:
            yield f
    except (OSError, KeyError, RuntimeError) as exc:  # h5py's errors on damaged metadata or data
        raise CorruptFileError(f"{path}: damaged HDF5 file ({_first_line(exc)})") from None


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def check_group(group, path: Path) -> None:
    """Refuse a group of ``path`` with a member that is not an ordinary (hard-linked)
    group or dataset: an external link (a path to another file), a soft link, or a
    dataset :func:`check_dataset` refuses. Recursive; reads metadata only."""
    for _ in checked_members(group, path):
        pass


def checked_members(group, path: Path) -> Iterator[tuple[str, Any]]:
    """``(name, member)`` of each member of a group of ``path``, each checked as
    :func:`check_group` checks it (a subgroup recursively) before it is yielded: a reader
    that reads some members as it checks them opens each once. :class:`CorruptFileError`
    at the first refused member."""
    import h5py

    for name in group:
        link = group.get(name, getlink=True)
        if not isinstance(link, h5py.HardLink):
            kind = "a link to another file" if isinstance(link, h5py.ExternalLink) else "a soft link"
            raise CorruptFileError(f"{path}: {group.name.rstrip('/')}/{name} is {kind}; refused (decrun "
                                   "writes only datasets inside the file)")
        member = group[name]
        if isinstance(member, h5py.Group):
            check_group(member, path)
        else:
            check_dataset(member, path)
        yield name, member


def check_dataset(dataset, path: Path) -> int:
    """Check a dataset of ``path`` before reading it; returns the bytes it decodes to.

    Refused (:class:`CorruptFileError`): external storage (``dataset.external``: raw data
    in another file), a virtual dataset (data mapped from other files), a non-numeric
    dtype, and a declared size the stored bytes cannot hold -- more than the stored bytes
    for unfiltered data, more than :data:`MAX_DEFLATE_RATIO` times them for compressed
    data (above 1 MiB), or stored bytes beyond the file's size."""
    where = f"{path}: dataset {dataset.name}"
    if dataset.external:
        raise CorruptFileError(f"{where} keeps its data in another file ({dataset.external[0][0]!r}); refused")
    if dataset.is_virtual:
        raise CorruptFileError(f"{where} is a virtual dataset (its data live in other files); refused")
    if dataset.dtype.kind not in "biufcS" or dataset.dtype.names is not None:
        raise CorruptFileError(f"{where} has dtype {dataset.dtype}, not a numeric array; refused")
    claimed = int(np.prod(dataset.shape, dtype=np.int64)) * dataset.dtype.itemsize if dataset.shape else \
        dataset.dtype.itemsize
    stored = dataset.id.get_storage_size()
    file_size = os.path.getsize(path)
    filtered = dataset.compression is not None or bool(dataset.id.get_create_plist().get_nfilters())
    bound = stored * MAX_DEFLATE_RATIO if filtered else stored
    if stored > file_size or (claimed > bound and claimed > _SMALL_BYTES):
        raise CorruptFileError(f"{where} claims shape {dataset.shape} ({claimed / 1e9:.3g} GB) but stores "
                               f"{stored} bytes in a file of {file_size}; refused (truncated or forged)")
    return claimed


def read_dataset(dataset, path: Path) -> np.ndarray:
    """The whole dataset as an array, after :func:`check_dataset`."""
    check_dataset(dataset, path)
    return dataset[()]


def file_record(path: str | os.PathLike) -> dict[str, Any]:
    """``{"bytes": size, "sha256": hex digest}`` of a file, as ``metrics.json`` records
    its ``result.h5`` (``result_h5``). Reads the file once (~1 GB/s on the project machine
    from the page cache: 0.26 s for 400 MB)."""
    return digest.file_record(path)


def check_record(path: str | os.PathLike, record: Any) -> None:
    """Check that ``path`` is the file ``record`` (:func:`file_record`) describes: it exists,
    has that size (compared first: a truncated file costs no read) and that sha256.
    :class:`CorruptFileError` naming the file otherwise, also for a malformed record."""
    path = Path(path)
    if not (isinstance(record, dict) and isinstance(record.get("bytes"), int)
            and isinstance(record.get("sha256"), str)):
        raise CorruptFileError(f"{path.parent / RunFiles.METRICS}: result_h5 is not a record of the result "
                               f"(bytes and sha256), got {str(record)[:80]!r}")
    try:
        size = os.path.getsize(path)
    except FileNotFoundError:
        raise CorruptFileError(f"{path}: missing (metrics.json records one of {record['bytes']} bytes)") from None
    if size != record["bytes"]:
        raise CorruptFileError(f"{path}: {size} bytes, metrics.json records {record['bytes']} (truncated or "
                               "altered)")
    if _sha256_once(path) != record["sha256"]:
        raise CorruptFileError(f"{path}: its sha256 differs from the one metrics.json records (altered)")


#: sha256 of the files :func:`check_record` hashed in this process, under what ``os.stat`` says of them
_HASHED: dict[tuple, str] = {}
#: a file is remembered only when its last change was this long before it was hashed (ns)
SETTLED_NS = 2_000_000_000


def _sha256_once(path: Path) -> str:
    """The sha256 of the file ``path``, read once per process while the file is unchanged: a
    sweep's table checks each job's result.h5 and its tracker then reads the same jobs.

    Remembered under its path, device, inode, size, modification and change times — a write,
    a truncation, a file renamed onto it or a ``touch`` back to the old modification time all
    set a new change time, which no process can set back — and only for a file whose last
    change was :data:`SETTLED_NS` before it was hashed, so that a change after it cannot fall
    in the same tick of the filesystem's clock and leave both times as they were."""
    before = os.stat(path)
    key = (os.path.abspath(path), before.st_dev, before.st_ino, before.st_size, before.st_mtime_ns,
           before.st_ctime_ns)
    if key in _HASHED:
        return _HASHED[key]
    started = time.time_ns()
    digest = file_record(path)["sha256"]
    if max(before.st_mtime_ns, before.st_ctime_ns) < started - SETTLED_NS:
        _HASHED[key] = digest
    return digest
