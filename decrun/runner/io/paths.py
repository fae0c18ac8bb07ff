"""Nothing decrun writes or deletes leaves its output directory.

Paths are judged the way the OS will follow them: :func:`os.path.realpath`, every symlink
in every component followed. Two checks:

* :func:`inside` — a directory or file decrun is about to use resolves inside its root: a
  sweep job's directory (from the plan or a resumed ``manifest.json``) inside the sweep
  directory; the ``.hydra/`` files and the log Hydra writes (:func:`hydra_files`) inside
  the run directory. Run while a sweep is planned or resumed and before a run starts,
  i.e. before Hydra writes anything.
* :func:`check_file` — a file decrun writes (every :func:`decrun.runner.io.atomic.atomic_path`
  write and its temporary name, figures, exports) is not a symlink that leads out of the
  directory it is written into. One ``lstat`` when there is no symlink (the usual case).

A refusal is an :class:`OutsideError`, one line: the path, where it leads, the root it
leaves and what fixes it. Nothing is followed, replaced or removed first.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Any

from decrun.errors import DecrunError

__all__ = ["OutsideError", "inside", "check_file", "hydra_files", "NEW_OUTPUT"]

#: the overrides that choose a fresh output directory (shared with failures.os_error_message)
NEW_OUTPUT = "choose another output directory with hydra.run.dir=DIR (hydra.sweep.dir=DIR with -m)"


class OutsideError(DecrunError, OSError):
    """A path decrun would write, rename or delete resolves outside its run or sweep
    directory (a symlink that leaves it, ``..``, an absolute path). An ``OSError`` too,
    so code that reports a failed write reports this one."""


def _within(target: str, root: str) -> bool:
    return target == root or target.startswith(root if root.endswith(os.sep) else root + os.sep)


def inside(root: str | os.PathLike, path: str | os.PathLike, *, what: str = "run directory",
           fix: str = "") -> Path:
    """``path`` resolved (every symlink of every component followed; it need not exist);
    :class:`OutsideError` when that is not ``root`` (resolved) or below it. ``what`` names
    the root in the message (``"sweep directory"``), ``fix`` replaces its default advice
    (remove the link, or :data:`NEW_OUTPUT`)."""
    real = os.path.realpath(path)
    real_root = os.path.realpath(root)
    if not _within(real, real_root):
        raise OutsideError(f"{path} resolves to {real}, outside the {what} {root}; "
                           f"{fix or 'remove the link, or ' + NEW_OUTPUT}")
    return Path(real)


def check_file(path: str | os.PathLike, fix: str = "") -> Path:
    """``path``, when writing it cannot leave its directory: it does not exist or is not a
    symlink (one ``lstat``), or it is a symlink resolving inside ``path.parent``. Else
    :class:`OutsideError` naming where it leads (``fix``: as for :func:`inside`)."""
    path = Path(path)
    try:
        mode = os.lstat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return path
    if stat.S_ISLNK(mode):
        inside(path.parent, path, what="directory it is written into,", fix=fix)
    return path


def hydra_files(hydra: Any) -> list[str]:
    """What Hydra writes into a job's output directory, relative to it: ``hydra.output_subdir``
    (``.hydra``) and its ``config.yaml``, ``hydra.yaml``, ``overrides.yaml``, and the log of
    ``hydra.job_logging.handlers.file.filename`` (``decrun.log``) when it lies in the output
    directory. ``hydra``: the config's ``hydra`` node (the master config's is enough: the
    names are the same for every job)."""
    from omegaconf import OmegaConf  # lazy: this module is imported before the config machinery

    names = []
    subdir = OmegaConf.select(hydra, "output_subdir")
    if subdir is not None:
        names += [str(subdir), *(f"{subdir}/{name}" for name in ("config.yaml", "hydra.yaml", "overrides.yaml"))]
    handler = OmegaConf.select(hydra, "job_logging.handlers.file", default=None)
    if handler is not None and "filename" in handler:
        raw = OmegaConf.to_container(handler, resolve=False)["filename"]
        prefix = "${hydra.runtime.output_dir}/"
        if isinstance(raw, str) and raw.startswith(prefix):
            name = raw[len(prefix):].replace("${hydra.job.name}", str(OmegaConf.select(hydra, "job.name")))
            if "${" not in name:
                names.append(name)
    return names
