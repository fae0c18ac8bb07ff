"""What the ``decrun`` sweeper checks and holds before it touches a sweep directory:
the sweep directory's lock (:mod:`decrun.runner.io.locks`), and on resume that every job
directory the manifest names — and the ``.hydra/`` files and log Hydra will write into it
(:func:`decrun.runner.io.paths.hydra_files`) — resolves inside the sweep directory, before
a job directory is cleared or launched (Hydra follows a symlinked job directory)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Sequence

from decrun.runner.io.locks import LockedError, acquire
from decrun.runner.io.paths import OutsideError, check_file, inside

__all__ = ["NEW_SWEEP", "lock_sweep", "check_job_dirs"]

NEW_SWEEP = "start a new sweep with hydra.sweep.dir=DIR"


def lock_sweep(sweep_dir: Path, error: type[Exception]) -> None:
    """Create ``sweep_dir`` if need be and take its lock for this process (kept until the
    sweep's table is written: :class:`decrun.runner.command.callbacks.OutputGuard` drops it). Another
    process's lock → ``error`` (a SweepError) naming its pid."""
    sweep_dir.mkdir(parents=True, exist_ok=True)
    try:
        acquire(sweep_dir, "sweep", fix=NEW_SWEEP)
    except (LockedError, OutsideError) as exc:
        raise error(f"error: hydra.sweep.dir={sweep_dir}: {exc}") from exc


def check_job_dirs(sweep_dir: Path, jobs: Sequence[dict[str, Any]], written: Sequence[str], manifest: Path,
                   error: type[Exception]) -> None:
    """``error`` (a SweepError naming ``manifest`` and the job) when a job's ``dir`` is not
    a directory strictly inside ``sweep_dir`` once resolved (``../victim``, an absolute
    path, a symlink leaving the sweep, the sweep directory itself), or when one of the
    ``written`` names in an existing job directory (``.hydra``, ``decrun.log``) is a symlink
    leading out of it. Cost per job: one ``realpath`` and one ``lstat`` per name."""
    root = os.path.realpath(sweep_dir)
    fix = f"remove the link, or {NEW_SWEEP}"
    for job in jobs:
        where = job["dir"]
        try:
            if not isinstance(where, str) or not where or os.path.isabs(where) or \
                    os.path.normpath(where).split(os.sep)[0] in ("..", "."):
                raise OutsideError(f"directory {where!r} is not a path inside the sweep directory (the manifest "
                                   f"was edited); {NEW_SWEEP}")
            job_dir = sweep_dir / where
            real = inside(sweep_dir, job_dir, what="sweep directory", fix=fix)
            if str(real) == root:
                raise OutsideError(f"directory {where!r} is the sweep directory itself; {NEW_SWEEP}")
            if real.is_dir():
                for name in written:
                    check_file(job_dir / name, fix=fix)
        except OutsideError as exc:
            raise error(f"error: hydra.sweeper.resume=true: {manifest}: job {job['job']}: {exc}") from exc
