"""A per-process cache of what sweep jobs share: the mesh, its complex and its operators.

Jobs of a sweep that differ only in the app's options (``app.dt=...``) load the same mesh
and build the same complex and DEC. In one process (the basic launcher, or one joblib /
submitit / ray worker running several jobs) :func:`mesh_and_dec` builds them once, keyed
by the sha256 of the resolved config nodes that determine them:

* the mesh by ``cfg.mesh`` (sources are deterministic: noise is seeded by ``mesh.seed``;
  a ``mesh=file`` key also holds the file's size and modification time);
* the complex and DEC by the mesh key plus ``cfg.operator`` and ``cfg.boundary``.

The DEC computes its operators lazily and keeps them (:class:`decrun.core.cache.Cached`),
so a later job on the same key also reuses every operator — and anything an app stores
with ``dec.require`` (smoothing's critical time step, one eigen-solve). Cached objects are
shared read-only: every job gets its own :class:`~decrun.runner.mesh.Mesh` record (its
``meta`` a copy), the arrays are the same. At most :data:`SIZE` entries are kept
(least recently used dropped), so memory stays that of a couple of meshes.
"""

from __future__ import annotations

import json
import os
from collections import OrderedDict
from dataclasses import replace
from typing import Any, Callable

from omegaconf import DictConfig, OmegaConf

from decrun.core.digest import Digest

__all__ = ["mesh_and_dec", "clear", "SIZE", "stats"]

SIZE = 2
_entries: "OrderedDict[str, Any]" = OrderedDict()
#: hits and misses since the process started (for tests and the benchmark)
stats = {"hits": 0, "misses": 0}


def node_key(*nodes: Any) -> str:
    """sha256 of the resolved values of config nodes, as sorted JSON (plus a mesh file's size and
    mtime): equal values, equal keys (a YAML dump of each node, the former text, took ~1.5 ms a
    node — three per sweep job)."""
    h = Digest()
    for node in nodes:
        h.text(_resolved_text(node) if OmegaConf.is_config(node) else repr(node))
        path = node.get("path") if isinstance(node, DictConfig) else None
        if isinstance(path, str) and os.path.isfile(path):
            st = os.stat(path)
            h.text(f"{st.st_size}:{st.st_mtime_ns}")
    return h.hexdigest()


def _resolved_text(node: Any) -> str:
    """A config node's resolved values as sorted JSON (its resolved YAML where keys of several
    types cannot be sorted)."""
    try:
        return json.dumps(OmegaConf.to_container(node, resolve=True, enum_to_str=True), sort_keys=True, default=repr)
    except TypeError:
        return OmegaConf.to_yaml(node, resolve=True, sort_keys=True)


def _get(key: str, build: Callable[[], Any]) -> Any:
    if key in _entries:
        _entries.move_to_end(key)
        stats["hits"] += 1
        return _entries[key]
    stats["misses"] += 1
    value = build()
    _entries[key] = value
    while len(_entries) > SIZE:
        _entries.popitem(last=False)
    return value


class _Shared:
    """A cached complex and its DEC, built on the first call of :meth:`dec` (after the app
    checked the complex's dimension, :meth:`decrun.apps.base.App.validate`)."""

    def __init__(self, complex_: Any, build_dec: Callable[[Any], Any]):
        self.complex, self._build_dec, self._dec = complex_, build_dec, None

    def dec(self) -> Any:
        if self._dec is None:
            self._dec = self._build_dec(self.complex)
        return self._dec


def mesh_and_dec(cfg: DictConfig, load_mesh: Callable[[], Any], build_complex: Callable[[Any], Any],
                 build_dec: Callable[[Any], Any]) -> tuple[Any, Any, Callable[[], Any]]:
    """``(mesh, complex, dec)`` for ``cfg``, ``dec`` a function returning the DEC:
    ``load_mesh()``, ``build_complex(mesh)`` and ``build_dec(complex)`` run only when no
    earlier job of this process had the same mesh / operator / boundary config (the DEC on
    the first call of ``dec``). The mesh record returned is the job's own copy."""
    mesh_key = "mesh:" + node_key(cfg.mesh)
    mesh = _get(mesh_key, load_mesh)
    shared = _get("dec:" + node_key(mesh_key, cfg.mesh.get("orient", "check"), cfg.operator, cfg.boundary),
                  lambda: _Shared(build_complex(mesh), build_dec))
    return replace(mesh, meta=dict(mesh.meta)), shared.complex, shared.dec


def clear() -> None:
    """Forget every cached mesh and operator."""
    _entries.clear()
