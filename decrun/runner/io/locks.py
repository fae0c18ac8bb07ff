"""One decrun process at a time per output directory: an exclusive, non-blocking
``fcntl.flock`` on ``<dir>/.decrun.lock``.

Who holds what:

* a sweep directory — the submitting process of a ``decrun`` sweep, from the moment its
  jobs are planned (before the manifest is read or written, before a resume clears
  anything) until its table is written (:mod:`decrun.runner.sweep.sweeper`,
  :class:`decrun.runner.command.callbacks.OutputGuard`);
* a run directory — the process recording the run: a single run from before Hydra
  creates the directory (``on_run_start``) to its end; each sweep job in whatever process
  runs it (the basic launcher's, a joblib / submitit / ray worker) while it runs
  (:func:`decrun.runner.job.run.run`).

The lock file holds ``<pid> <what>``; a second process fails at once with
:class:`LockedError`, one line naming the directory and that pid, having touched nothing.
The kernel drops a ``flock`` when its process dies (even by SIGKILL), so a lock is never
stuck: a lock file left by a dead process is taken over. A released lock's file is
removed; the inode is checked after locking so that a process racing that removal never
shares a lock with the next one. Locks are re-entrant within a process (:func:`acquire`
returns False for a directory the process holds already) and not inherited by children.
"""

from __future__ import annotations

import atexit
import fcntl
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from decrun.errors import DecrunError
from decrun.runner.io.files import RunFiles
from decrun.runner.io.paths import OutsideError

__all__ = ["LOCK_NAME", "LockedError", "acquire", "release", "locked", "holds", "released_after"]

LOCK_NAME = RunFiles.LOCK
#: what a holder does, as the refusal names it
DOING = {"run": "a run recording there", "sweep": "a sweep running there"}

#: realpath of a locked directory → (fd, pid of the process that took it)
_held: dict[str, tuple[int, int]] = {}
_at_exit = []


class LockedError(DecrunError):
    """Another process holds the directory's lock; the message names its pid."""


def _key(directory: str | os.PathLike) -> str:
    return os.path.realpath(directory)


def holds(directory: str | os.PathLike) -> bool:
    """Whether this process holds ``directory``'s lock."""
    entry = _held.get(_key(directory))
    return entry is not None and entry[1] == os.getpid()


def acquire(directory: str | os.PathLike, what: str = "run", fix: str = "") -> bool:
    """Take the exclusive lock of the existing ``directory`` for this process (``what``:
    ``"run"`` or ``"sweep"``, recorded for the refusal). Returns True when taken now (the
    caller releases it), False when this process holds it already. :class:`LockedError`
    (``fix`` appended: the override that avoids the clash) when another process holds it;
    :class:`~decrun.runner.io.paths.OutsideError` when the lock file is a symlink."""
    if holds(directory):
        return False
    path = Path(directory) / LOCK_NAME
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            if os.path.islink(path):
                raise OutsideError(f"{path} is a symlink (to {os.path.realpath(path)}); decrun opens no lock "
                                   f"through a link: remove it") from exc
            raise
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode(errors="replace").split()
            os.close(fd)
            pid = holder[0] if holder else "?"
            doing = DOING.get(holder[1], holder[1]) if len(holder) > 1 else "starting"
            raise LockedError(f"{directory} is in use by decrun process {pid} ({doing}); wait for it to end"
                              f"{', or ' + fix if fix else ''}") from None
        try:
            same = os.stat(path, follow_symlinks=False).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)  # the file was removed by the holder releasing it: lock the new one
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()} {what}\n".encode(), 0)
    if not _at_exit:
        _at_exit.append(atexit.register(release_all))
    _held[_key(directory)] = (fd, os.getpid())
    return True


def release(directory: str | os.PathLike) -> None:
    """Remove ``directory``'s lock file and drop the lock, if this process holds it."""
    key = _key(directory)
    if not holds(key):
        return
    fd, _ = _held.pop(key)
    try:
        os.unlink(os.path.join(key, LOCK_NAME))
    except OSError:  # gone, or the directory too: the lock is dropped all the same
        pass
    os.close(fd)


def release_all() -> None:
    """Release every lock this process holds (at exit)."""
    for key in list(_held):
        release(key)


@contextmanager
def locked(directory: str | os.PathLike, what: str = "run", fix: str = "") -> Iterator[None]:
    """:func:`acquire` for the block; released after it when taken here."""
    taken = acquire(directory, what, fix)
    try:
        yield
    finally:
        if taken:
            release(directory)


@contextmanager
def released_after() -> Iterator[None]:
    """After the block, release every lock taken in it that is still held: a process that goes
    on after a run or sweep stopped early (:func:`decrun.run`, :func:`decrun.sweep`) leaves no
    directory locked, as the ``decrun`` command's exit does."""
    before = set(_held)
    try:
        yield
    finally:
        for key in [k for k in _held if k not in before]:
            release(key)
