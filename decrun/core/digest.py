"""One home for identity: every sha256 decrun computes, stores or compares.

A digest is sha256 over a stream of **canonical forms**, fed by its caller in a fixed order
(:class:`Digest`):

* **text** (:meth:`Digest.text`): the UTF-8 bytes of a str;
* **canonical JSON** (:meth:`Digest.json`): ``json.dumps(value, sort_keys=True, default=str)``
  as text: a mapping's keys sorted, so equal values give equal text;
* **array** (:meth:`Digest.array`): the array's C-order bytes in a stated dtype (byte order
  included: ``"<f8"``), preceded by the text ``"<dtype.str> <shape> "`` unless the caller writes
  its own header (the shape and dtype are then in that header);
* **bytes** (:meth:`Digest.bytes`): raw bytes, for a caller's own canonical encoding;
* **file** (:func:`file_record`): the file's bytes, streamed in 1 MiB blocks (memory stays flat).

The identities built from them (a persisted one keeps its stream: changing it changes every
stored value, so a change is a new format version, and old entries are handled explicitly):

============================  ==========================================================  =============
identity                      stream                                                      persisted in
============================  ==========================================================  =============
mesh content (``mesh_hash``)  text ``repr((v.shape, f.shape))``, ``<f8`` vertices,        result.h5, mesh
                              ``<i8`` simplices (no array headers)                        cache entries
mesh cache key                text of the key's canonical JSON (with the generating       cache file
                              module's file sha256)                                       names
sweep config hash             resolved YAML text of the job's config (16 hex digits)      manifest,
                                                                                          checkpoints
checkpoint state              per leaf: text ``path\\0kind\\0dtype\\0shape\\0``, bytes       checkpoint.h5
result file record            the file                                                    metrics.json
result content                salt ``decrun content 1\\n``, attributes and datasets        metrics.json
                              (:func:`decrun.runner.results.provenance.content_sha256`)
tracking fingerprint          canonical JSON of the record, series arrays, artifacts      tracking store
job cache key                 canonical JSON of config nodes (+ a mesh file's size,       memory only
                              mtime)
matrix fingerprint            text ``repr(shape)``, CSR indptr, indices, data             memory only
============================  ==========================================================  =============

``tests/runner/results/test_identities.py`` pins each persisted stream's value on fixed inputs;
``tests/core/test_digest.py`` checks the forms.
"""

from __future__ import annotations

import hashlib
import json
import os
from typing import Any

import numpy as np

__all__ = ["Digest", "text_sha256", "file_record", "BLOCK_BYTES"]

#: a file is read in blocks of this many bytes
BLOCK_BYTES = 1 << 20


class Digest:
    """A running sha256 over canonical forms (module docstring); each method returns ``self``."""

    def __init__(self, salt: bytes = b""):
        self._sha = hashlib.sha256(salt)

    def text(self, text: str) -> Digest:
        """Feed the UTF-8 bytes of ``text``."""
        self._sha.update(text.encode())
        return self

    def json(self, value: Any) -> Digest:
        """Feed ``value`` as canonical JSON (sorted keys; what JSON cannot say as ``str``)."""
        return self.text(json.dumps(value, sort_keys=True, default=str))

    def bytes(self, data: bytes | bytearray | memoryview) -> Digest:
        """Feed raw bytes (a caller's own canonical encoding)."""
        self._sha.update(data)
        return self

    def array(self, array: Any, dtype: Any = None, *, header: bool = True) -> Digest:
        """Feed ``array`` as C-order bytes in ``dtype`` (None: its own), after the text
        ``"<dtype.str> <shape> "`` when ``header`` (else the caller's header says them)."""
        values = np.asarray(array, dtype=dtype, order="C")
        if header:
            self.text(f"{values.dtype.str} {values.shape} ")
        self._sha.update(values.reshape(-1).view(np.uint8).data)  # (a view: no copy)
        return self

    def hexdigest(self, digits: int | None = None) -> str:
        """The sha256 as hex: all 64 digits, or the first ``digits``."""
        return self._sha.hexdigest()[:digits]


def text_sha256(text: str) -> str:
    """sha256 hex of the UTF-8 bytes of ``text``."""
    return Digest().text(text).hexdigest()


def file_record(path: str | os.PathLike) -> dict[str, Any]:
    """``{"bytes": size, "sha256": hex digest}`` of a file, read once in blocks of
    :data:`BLOCK_BYTES` (~1 GB/s from the page cache)."""
    digest = Digest()
    buffer = bytearray(BLOCK_BYTES)
    view = memoryview(buffer)
    with open(path, "rb", buffering=0) as f:
        size = os.fstat(f.fileno()).st_size
        while got := f.readinto(view):
            digest.bytes(view[:got])
    return {"bytes": size, "sha256": digest.hexdigest()}
