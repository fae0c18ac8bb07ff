"""Files that appear whole or not at all: write under a temporary name, then rename.

Every file the runner writes for others to read while it may die (``result.h5``, its
journal's header, ``metrics.json``, a sweep's ``manifest.json``, ``metrics.csv`` /
``metrics.md``) goes through :func:`atomic_path`: a reader sees the old file or the whole
new one, never a half-written one, and a failed write leaves nothing behind. Neither the
file nor its temporary name may be a symlink leading out of their directory
(:func:`decrun.runner.io.paths.check_file`): such a write is refused before anything is written.

HDF5 files written this way (``result.h5``, ``checkpoint.h5``) are written through
:class:`QuietFile` after :func:`check_free_space`: a full disk is one ``OSError`` raised
after HDF5 closed the file, never HDF5's own error path (which can leave the library's
file half-open and the process to segfault at exit), and the temporary file is removed.
"""

from __future__ import annotations

import errno as _errno
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from decrun.runner.io.paths import check_file

__all__ = ["atomic_path", "write_text_atomic", "temporary_name", "QuietFile", "check_free_space"]


def temporary_name(path: str | os.PathLike) -> Path:
    """``.<name>.tmp-<pid>`` beside ``path``: hidden, and left by a killed process only
    (:func:`decrun.runner.results.recover_result` removes such leftovers of ``result.h5``)."""
    path = Path(path)
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """The temporary name to write ``path`` under (:func:`temporary_name`): when the block
    ends it is renamed onto ``path`` (``os.replace``, atomic on POSIX); when the block or
    the rename raises, the temporary file is removed and the error goes on.
    :class:`~decrun.runner.io.paths.OutsideError` (nothing written) when ``path`` or the
    temporary name is a symlink leading out of its directory."""
    path = check_file(path)
    tmp = check_file(temporary_name(path))
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` through :func:`atomic_path`; returns ``path``."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)


class QuietFile:
    """The temporary file as h5py sees it (``h5py.File(fileobj)``): a write error is
    never reported to HDF5 -- it is kept in :attr:`error`, later writes are skipped, and
    the caller raises it once HDF5 has closed the file. Measured reason: when HDF5's own
    writes fail with ENOSPC, its file stays half-open and the process segfaults at exit
    (HDF5 2.0 / h5py 3.16)."""

    def __init__(self, path: Path):
        self._file = open(path, "w+b", buffering=0)
        self.error: OSError | None = None

    def write(self, data) -> int:
        view = memoryview(data).cast("B")
        if self.error is None:
            try:
                done = 0
                while done < len(view):
                    done += self._file.write(view[done:])
                return len(view)
            except OSError as exc:
                self.error = exc
        self._file.seek(len(view), os.SEEK_CUR)
        return len(view)

    def read(self, size: int = -1) -> bytes:
        data = self._file.read(size)
        if size > 0 and len(data) < size:  # a region whose write was skipped
            data += b"\0" * (size - len(data))
        return data

    def readinto(self, buffer) -> int:
        view = memoryview(buffer).cast("B")
        got = self._file.readinto(view) or 0
        view[got:] = b"\0" * (len(view) - got)
        return len(view)

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        return self._file.seek(offset, whence)

    def tell(self) -> int:
        return self._file.tell()

    def truncate(self, size: int | None = None) -> int:
        try:
            return self._file.truncate(size)
        except OSError as exc:
            self.error = self.error or exc
            return self._file.tell() if size is None else size

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self._file.close()


def check_free_space(directory: Path, needed: int) -> None:
    """Fail early (before HDF5 starts) when the disk cannot hold ``needed`` bytes."""
    stat = os.statvfs(directory)
    free = stat.f_bavail * stat.f_frsize
    if free < needed:
        raise OSError(_errno.ENOSPC, f"No space left on device (needs up to {needed / 1e6:.1f} MB, "
                                     f"{free / 1e6:.1f} MB free)")
