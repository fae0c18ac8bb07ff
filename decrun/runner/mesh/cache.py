"""A content-addressed cache of the meshes pymeshlab makes, so a run that made a mesh once
makes it again without importing pymeshlab.

Importing pymeshlab (its Qt and MeshLab libraries) costs about as much as a small run's whole
compute, and what its filters return is a function of their inputs and pymeshlab's version
alone. :func:`cached_mesh` keeps such a result under a key made of

- the generator's name (``pymeshlab.create_sphere``, ``repair_mesh``) and its parameters
  (for a step applied to a mesh, the input mesh's hash),
- pymeshlab's version, read from the package's metadata (without importing it),
- the sha256 of the decrun module that drives pymeshlab (a change there is a new key),

as one ``<key>.npz`` file holding the vertices (float64), the triangles (int64), a JSON
``extra`` (e.g. the repair counts), the key's own text and the arrays' sha256. The file is
written under a unique temporary name in the cache directory and renamed onto its place
(atomic on POSIX, also between processes of a sweep or SLURM jobs on one shared file
system: a reader sees a whole entry or none). Reading checks that the entry is a regular file
(a FIFO would block the run), the key's text, the arrays' dtypes and shapes, the arrays' sha256,
and what a hash recomputed by hand cannot vouch for: finite vertices, face indices in range, and
``extra`` a dict nested at most :data:`MAX_EXTRA_NESTING` levels. An entry that fails any check
is reported in the log (a warning naming the entry and the check) and rebuilt (overwritten),
never used. The arrays come back bit for bit, vertex order and all.

Where: ``$DECRUN_MESH_CACHE`` if set, else ``$XDG_CACHE_HOME/decrun/meshes``, else
``~/.cache/decrun/meshes``. ``DECRUN_MESH_CACHE=off`` (or ``0``, ``false``, ``no``, empty)
turns the cache off: every run calls pymeshlab. A cache directory that cannot be written is
reported in the log and the run goes on with the mesh it made.
"""

from __future__ import annotations

import json
import logging
import os
import stat
import tempfile
from pathlib import Path
from typing import Any, Callable

import numpy as np

from decrun.core.digest import Digest, file_record, text_sha256

__all__ = ["CACHE_ENV", "cache_dir", "cached_mesh", "entry_path", "content_hash"]

#: the environment variable naming the cache directory, or turning the cache off
CACHE_ENV = "DECRUN_MESH_CACHE"
#: values of :data:`CACHE_ENV` that turn the cache off
OFF = ("", "0", "off", "false", "no", "none")
#: the entry layout; a change of it is a new key
FORMAT = 1
_FIELDS = {"vertices", "faces", "extra", "spec", "hash"}
#: the deepest an entry's ``extra`` may nest (what decrun stores there is a flat dict of counts)
MAX_EXTRA_NESTING = 8

log = logging.getLogger("decrun")


def content_hash(vertices: np.ndarray, faces: np.ndarray) -> str:
    """sha256 hex digest of the shapes and the little-endian float64 vertices and int64 faces
    (or simplices of any size); :func:`decrun.runner.mesh.base.mesh_hash` is this function."""
    v = np.ascontiguousarray(vertices, dtype="<f8")
    f = np.ascontiguousarray(faces, dtype="<i8")
    return Digest().text(repr((v.shape, f.shape))).array(v, header=False).array(f, header=False).hexdigest()


class _Unusable(Exception):
    """An entry that fails a check on reading."""


def cache_dir() -> Path | None:
    """The cache directory (module docstring), None when :data:`CACHE_ENV` turns it off."""
    value = os.environ.get(CACHE_ENV)
    if value is not None:
        return None if value.strip().lower() in OFF else Path(value).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base).expanduser() / "decrun" / "meshes"


def _spec(generator: str, params: dict[str, Any], code: str | os.PathLike) -> str:
    """The key's text: generator, parameters, pymeshlab's version, the driving module's sha256."""
    from importlib.metadata import version

    return json.dumps({"format": FORMAT, "generator": generator, "params": params,
                       "pymeshlab": version("pymeshlab"),
                       "code": file_record(code)["sha256"]}, sort_keys=True)


def entry_path(directory: Path, generator: str, params: dict[str, Any], code: str | os.PathLike) -> Path:
    """``<directory>/<sha256 of the key's text>.npz``: where :func:`cached_mesh` keeps that mesh."""
    return _entry(directory, _spec(generator, params, code))


def _entry(directory: Path, spec: str) -> Path:
    """The entry of the key's text ``spec`` in ``directory`` (:func:`entry_path`)."""
    return directory / f"{text_sha256(spec)}.npz"


def _open_regular(path: Path):
    """``path`` opened for reading in binary, or :class:`_Unusable` when it is not a regular file
    (a FIFO, which would block the run until something writes to it; a device, a directory).
    Opened without blocking and checked on the open descriptor, so nothing can be swapped in
    between the check and the read."""
    descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    if not stat.S_ISREG(os.fstat(descriptor).st_mode):
        os.close(descriptor)
        raise _Unusable("not a regular file (a FIFO, a device or a directory)")
    return os.fdopen(descriptor, "rb")


def _nesting(value: Any) -> int:
    """How deeply the lists and dicts of a JSON value nest (0 for a scalar), counted without
    recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        item, depth = stack.pop()
        members = item.values() if isinstance(item, dict) else item if isinstance(item, list) else None
        if members is not None:
            deepest = max(deepest, depth + 1)
            stack.extend((member, depth + 1) for member in members)
    return deepest


def _read(path: Path, spec: str) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The entry's (vertices, faces, extra) after its checks; :class:`_Unusable` names the failed one."""
    try:
        with _open_regular(path) as stream, np.load(stream, allow_pickle=False) as data:
            if set(data.files) != _FIELDS:
                raise _Unusable(f"fields {sorted(data.files)}, expected {sorted(_FIELDS)}")
            arrays = {name: data[name] for name in _FIELDS}
    except _Unusable:
        raise
    except Exception as exc:  # a truncated or foreign file: zipfile, numpy and OS errors alike
        raise _Unusable(f"unreadable: {type(exc).__name__}: {exc}") from exc
    if str(arrays["spec"]) != spec:
        raise _Unusable("its key's text differs from the one asked for")
    vertices, faces = arrays["vertices"], arrays["faces"]
    if vertices.dtype != np.float64 or vertices.ndim != 2 or vertices.shape[1] not in (2, 3):
        raise _Unusable(f"vertices {vertices.dtype} {vertices.shape}, expected float64 (n, 2|3)")
    if faces.dtype != np.int64 or faces.ndim != 2 or faces.shape[1] != 3:
        raise _Unusable(f"faces {faces.dtype} {faces.shape}, expected int64 (m, 3)")
    if str(arrays["hash"]) != content_hash(vertices, faces):
        raise _Unusable("its mesh hash does not match its arrays")
    # the hash says the arrays are the ones written, not that what was written is a mesh
    if not np.isfinite(vertices).all():
        raise _Unusable("a vertex coordinate is not finite")
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise _Unusable(f"a face index is outside 0 … {len(vertices) - 1} (faces span {faces.min()} … {faces.max()})")
    try:
        extra = json.loads(str(arrays["extra"]))
    except (ValueError, RecursionError) as exc:
        raise _Unusable(f"extra is not JSON decrun reads: {type(exc).__name__}: {exc}") from exc
    if not isinstance(extra, dict) or _nesting(extra) > MAX_EXTRA_NESTING:
        raise _Unusable(f"extra is not a dict nested at most {MAX_EXTRA_NESTING} levels")
    return vertices, faces, extra


def _write(path: Path, spec: str, vertices: np.ndarray, faces: np.ndarray, extra: dict[str, Any]) -> None:
    """Write the entry under a unique temporary name beside ``path``, then rename it onto ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as out:
            np.savez(out, vertices=vertices, faces=faces, extra=np.array(json.dumps(extra)), spec=np.array(spec),
                     hash=np.array(content_hash(vertices, faces)))
        os.chmod(temporary, 0o644)  # mkstemp's 0600 would keep a shared cache from the group's other users
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def cached_mesh(generator: str, params: dict[str, Any], code: str | os.PathLike,
                build: Callable[[], tuple[np.ndarray, np.ndarray, dict[str, Any]]]
                ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """``build()``'s (vertices (n, 2|3) float64, faces (m, 3) int64, extra: a JSON-able dict),
    from the cache when an entry for (``generator``, ``params`` (JSON-able), pymeshlab's
    version, the sha256 of the file ``code``) passes its checks, else built and stored
    (module docstring). ``build`` is the only place pymeshlab is imported."""
    directory = cache_dir()
    if directory is None:
        return build()
    spec = _spec(generator, params, code)
    path = _entry(directory, spec)
    if path.exists():
        try:
            return _read(path, spec)
        except _Unusable as exc:
            log.warning("mesh cache: %s (%s) is unusable (%s); rebuilding it", path, generator, exc)
    vertices, faces, extra = build()
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    try:
        _write(path, spec, vertices, faces, extra)
    except (OSError, TypeError, ValueError) as exc:  # a full or read-only disk; an extra JSON cannot hold
        log.warning("mesh cache: cannot write %s (%s); the run goes on without it (%s=off turns the cache off)",
                    path, exc, CACHE_ENV)
    return vertices, faces, extra
