"""Files that appear whole or not at all: write under a temporary name, then rename.

Every file the runner writes for others to read while it may die (``result.h5``, its
journal's header, ``metrics.json``, a sweep's ``manifest.json``, ``metrics.csv`` /
``metrics.md``) goes through :func:`atomic_path`: a reader sees the old file or the whole
new one, never a half-written one, and a failed write leaves nothing behind. Neither the
file nor its temporary name may be a symlink leading out of their directory
(:func:`decrun.runner.paths.check_file`): such a write is refused before anything is written.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from decrun.runner.paths import check_file

__all__ = ["atomic_path", "write_text_atomic", "temporary_name"]


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
    :class:`~decrun.runner.paths.OutsideError` (nothing written) when ``path`` or the
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
