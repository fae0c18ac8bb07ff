"""The mesh record every source and post step passes on, and the checks every mesh passes.

:class:`Mesh` holds vertices, simplices and ``meta`` (what the source knows and the complex
does not; the keys are listed in :mod:`decrun.runner.mesh.source`); :func:`check_mesh` and
:func:`check_size` are the checks :meth:`decrun.runner.mesh.source.MeshSource.load` runs
after the source and after each post step; ``require*`` raise the ConfigError naming a
``mesh.<key>``; :func:`to_meshset` / :func:`from_meshset` convert to and from pymeshlab.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from decrun.core.choices import Choice
from decrun.errors import ConfigError, IndexOutOfRangeError, MeshError, NonFiniteCoordinateError

__all__ = ["Mesh", "UpAxis", "HoleCut", "HolePieces", "Refine", "Orient", "mesh_hash", "check_mesh", "check_size", "bounding_diagonal", "SIZE_RANGE", "require", "require_triangles", "require_surface", "MAX_TRIANGLES",
           "from_meshset", "to_meshset", "pymeshlab_primitive"]


class UpAxis(Choice):
    """``mesh.up_axis``: the model's up axis, rotated to +z — ``x``, ``y``, ``z`` or the negative
    axes ``-x``, ``-y``, ``-z``; ``auto`` a sample's own (else ``z``). The negative axes are not
    Python names, so the config field stays a string checked by :meth:`Choice.of` when the
    source is made (its members' names are ``minus_x`` …, their values what the config says)."""

    auto = "auto"
    x = "x"
    y = "y"
    z = "z"
    minus_x = "-x"
    minus_y = "-y"
    minus_z = "-z"


class HoleCut(Choice):
    """``mesh.hole_cut``: ``split`` the triangles along the region borders (smooth holes) or
    remove the ``whole_triangles`` whose centroid is inside (sawtooth borders)."""

    split = "split"
    whole_triangles = "whole_triangles"


class HolePieces(Choice):
    """``mesh.hole_pieces``: after the cut keep the ``largest`` piece (triangles joined across
    edges; what was dropped is logged and recorded) or ``all`` of them."""

    largest = "largest"
    all = "all"


class Refine(Choice):
    """``mesh.refine``: ``none``, ``loop`` / ``midpoint`` subdivision, ``isotropic`` remeshing."""

    none = "none"
    loop = "loop"
    midpoint = "midpoint"
    isotropic = "isotropic"


class Orient(Choice):
    """``mesh.orient``: how the simplicial complex treats orientation: ``check`` (report) or ``fix`` (re-orient)."""

    check = "check"
    fix = "fix"


@dataclass
class Mesh:
    """Vertices ``(n0, d) float64`` (d = 2 or 3), triangles ``(n2, 3) int64``, metadata."""

    vertices: np.ndarray
    simplices: np.ndarray
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def faces(self) -> np.ndarray:
        """Alias of ``simplices`` for triangle meshes."""
        return self.simplices


def mesh_hash(vertices: np.ndarray, simplices: np.ndarray) -> str:
    """sha256 hex digest of the shapes, the little-endian float64 vertices and int64 simplices:
    the mesh cache's :func:`~decrun.runner.mesh.cache.content_hash`, one definition for both."""
    from decrun.runner.mesh.cache import content_hash

    return content_hash(vertices, simplices)


#: the most triangles a source or post step may produce: 4·10⁶ triangles are ~2 GB of
#: complex and operators; beyond that pymeshlab or triangle would be killed for memory
#: (a 10×10 grid refined 10 times, 162·4¹⁰ = 1.7·10⁸ triangles, was: exit 137, no message)
MAX_TRIANGLES = 4_000_000


def require_triangles(count: float, key: str, fix: str) -> None:
    """ConfigError naming ``key`` when ``count`` (the predicted number of triangles) exceeds
    :data:`MAX_TRIANGLES`; ``fix`` is the override that keeps it below."""
    if count > MAX_TRIANGLES:
        raise ConfigError(f"{key}: would make about {count:.3g} triangles, more than decrun's limit "
                          f"{MAX_TRIANGLES:.0e} (memory); use {fix}")


def require_surface(mesh: "Mesh", key: str, fix: str) -> None:
    """ConfigError naming ``key`` unless the mesh is made of triangles (a post step that
    works on surfaces, given a tetrahedral mesh); ``fix`` is the override that drops it."""
    if mesh.simplices.shape[1] != 3:
        raise ConfigError(f"{key}: needs a triangle surface; this mesh is made of "
                          f"{len(mesh.simplices)} tetrahedra: use {fix}")


def require(condition: bool, key: str, message: str) -> None:
    """Raise ``ConfigError("mesh.<key>: <message>")`` unless ``condition``."""
    if not condition:
        raise ConfigError(f"mesh.{key}: {message}")


def from_meshset(ms, what: str) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3) float64, faces (m, 3) int64) of a pymeshlab MeshSet's current mesh."""
    mesh = ms.current_mesh()
    vertices = np.array(mesh.vertex_matrix(), dtype=np.float64)
    faces = np.array(mesh.face_matrix(), dtype=np.int64).reshape(-1, 3)
    if faces.shape[0] == 0:
        raise MeshError(f"{what}: the mesh has no faces ({len(vertices)} vertices)")
    return vertices, faces


def to_meshset(vertices: np.ndarray, simplices: np.ndarray):
    """A pymeshlab MeshSet holding the mesh (2-D vertices get z = 0)."""
    import pymeshlab

    v3 = vertices if vertices.shape[1] == 3 else np.column_stack([vertices, np.zeros(len(vertices))])
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.ascontiguousarray(v3),
                               face_matrix=np.ascontiguousarray(simplices, dtype=np.int32)))
    return ms


def pymeshlab_primitive(filter_name: str, label: str, **params) -> Mesh:
    """A mesh made by a pymeshlab ``create_*`` filter with ``params`` (ints and floats): vertices
    ``(n, 3) float64`` and triangles ``(m, 3) int64`` in pymeshlab's order, kept in the mesh cache
    (:func:`decrun.runner.mesh.cache.cached_mesh`), so a later run with the same filter,
    parameters and pymeshlab version reads them back without importing pymeshlab."""
    from decrun.runner.mesh.cache import cached_mesh

    def build() -> tuple[np.ndarray, np.ndarray, dict]:
        import pymeshlab

        ms = pymeshlab.MeshSet()
        getattr(ms, filter_name)(**params)
        return (*from_meshset(ms, f"mesh={label}"), {})

    vertices, faces, _ = cached_mesh(f"pymeshlab.{filter_name}", params, __file__, build)
    return Mesh(vertices, faces, {"source": label, "label": label})


def check_mesh(mesh: Mesh, what: str = "mesh") -> None:
    """Basic checks every source must pass; raises :class:`MeshError` naming the culprit."""
    V, F = mesh.vertices, mesh.simplices
    if V.ndim != 2 or V.shape[1] not in (2, 3) or len(V) == 0:
        raise MeshError(f"{what}: vertices must be a non-empty (n, 2|3) array, got shape {V.shape}")
    if F.ndim != 2 or F.shape[1] not in (3, 4) or len(F) == 0:
        raise MeshError(f"{what}: need a non-empty (m, 3) triangle or (m, 4) tetrahedron array, got shape {F.shape}")
    bad = np.flatnonzero(~np.isfinite(V).all(axis=1))
    if len(bad):
        raise NonFiniteCoordinateError(f"{what}: vertex {int(bad[0])} has a non-finite coordinate {V[bad[0]].tolist()} ({len(bad)} such vertices)")
    out = np.flatnonzero(((F < 0) | (F >= len(V))).any(axis=1))
    if len(out):
        raise IndexOutOfRangeError(f"{what}: face {int(out[0])} {F[out[0]].tolist()} references a vertex outside [0, {len(V)})")


#: the range of mesh sizes (bounding-box diagonal, model units) decrun computes with: areas
#: squared (L⁴) and tetrahedron volumes squared (L⁶) stay inside float64's normal range
#: (1e-308 .. 1e308) with a wide margin; outside it they under- or overflow silently
SIZE_RANGE = (1e-30, 1e30)


def bounding_diagonal(vertices: np.ndarray) -> float:
    """The length of the bounding box's diagonal, scaled so that it neither under- nor
    overflows (``np.linalg.norm`` squares the extents: 0 for extents near 1e-300)."""
    extent = vertices.max(axis=0) - vertices.min(axis=0)
    scale = float(np.max(np.abs(extent)))
    return scale * float(np.sqrt(np.sum((extent / scale) ** 2))) if scale > 0 else 0.0


def check_size(mesh: Mesh, what: str) -> None:
    """MeshError unless the mesh's bounding-box diagonal lies in :data:`SIZE_RANGE`
    (coordinates of 1e300 otherwise give overflow warnings and a singular factorization).
    The fix it names, ``mesh.normalize=true``, works over float64's whole range
    (tests/runner/test_hints.py runs it at 1e-300); a mesh whose vertices all coincide has
    no size to rescale and is said to be one."""
    diagonal = bounding_diagonal(mesh.vertices)
    lo, hi = SIZE_RANGE
    if diagonal == 0:
        raise MeshError(f"{what}: all {len(mesh.vertices)} vertices coincide (bounding-box diagonal 0); the mesh has "
                        f"no extent")
    if not lo <= diagonal <= hi:
        raise MeshError(f"{what}: the mesh's size (bounding-box diagonal {diagonal:.3g}) is outside decrun's range "
                        f"[{lo:g}, {hi:g}] (lengths to the 4th and 6th power would under- or overflow float64): "
                        f"rescale it with `mesh.normalize=true`")
