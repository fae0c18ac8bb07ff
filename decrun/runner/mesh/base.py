"""Meshes for the runner: the :class:`Mesh` record and the :class:`MeshSource` base.

A mesh source (the ``mesh`` config group) is a dataclass subclassing :class:`MeshSource`:
its own fields are the source's options (e.g. ``subdiv`` of the icosphere), the inherited
ones the post-processing every source offers. ``conf/mesh/<name>.yaml`` names it with
``_target_`` (one module under :mod:`decrun.runner.sources` plus one YAML file per source).
:meth:`MeshSource.load` builds the mesh:

1. :meth:`MeshSource.make` — the source's vertices and triangles;
2. the post-processing steps listed in ``post``, in that order (the functions of
   :mod:`decrun.runner.post_steps` of the same name; each is a no-op unless its option
   enables it);
3. checks (non-empty, finite, triangles, indices in range) and a hash.

Deeper checks (manifold, orientation, degenerate triangles) are done by
:class:`decrun.core.complex.SimplicialComplex`; a bad mesh is reported, never silently
repaired: ``repair`` and ``clean`` are off by default for generated meshes and files (the
error names ``mesh.repair=true``), on for ``mesh=sample`` (pymeshlab's samples are raw scans
and models with known defects), and what they change is counted in ``meta``.

``Mesh.meta`` carries what the source knows and the complex does not, for the applications
(``ctx.meta``):

- ``source``, ``label`` (short human name), ``path`` (file/sample), ``steps`` (applied)
- ``hash``: sha256 of vertices and triangles (:func:`mesh_hash`)
- ``mean_edge_length``: of the final mesh
- ``clean_vertices``: ``(n0, d)`` positions before ``noise`` was added (only when noise > 0)
- ``noise_amplitude``: the absolute noise standard deviation (``noise * mean edge length``)
- ``dropped_vertices`` / ``dropped_faces``: what ``clean`` removed (only when clean ran)
- ``repair``: the counts of :func:`decrun.runner.mesh_repair.repair_mesh` (only when repair ran)
- ``up_axis``: the axis rotated to +z (only when not z)
- ``holes``: the cut's counts, ``holes_removed_faces`` (only when holes were cut)
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, List

import numpy as np

from decrun.core.geometry import mean_edge_length
from decrun.errors import ConfigError, IndexOutOfRangeError, MeshError, NonFiniteCoordinateError

__all__ = ["Mesh", "MeshSource", "mesh_hash", "require", "require_triangles", "require_surface", "MAX_TRIANGLES",
           "from_meshset", "to_meshset", "pymeshlab_primitive"]


@dataclass
class Mesh:
    """Vertices ``(n0, d) float64`` (d = 2 or 3), triangles ``(n2, 3) int64``, metadata."""

    vertices: np.ndarray
    simplices: np.ndarray
    meta: dict[str, Any] = field(default_factory=dict)
    #: the SimplicialComplex built from it and the run's result recorder (set by the runner)
    complex: Any = None
    recorder: Any = None

    @property
    def faces(self) -> np.ndarray:
        """Alias of ``simplices`` for triangle meshes."""
        return self.simplices


def mesh_hash(vertices: np.ndarray, simplices: np.ndarray) -> str:
    """sha256 hex digest of the shapes, the little-endian float64 vertices and int64 simplices."""
    h = hashlib.sha256()
    v = np.ascontiguousarray(vertices, dtype="<f8")
    s = np.ascontiguousarray(simplices, dtype="<i8")
    h.update(repr((v.shape, s.shape)).encode())
    h.update(v.tobytes())
    h.update(s.tobytes())
    return h.hexdigest()


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
    """A mesh made by a pymeshlab ``create_*`` filter."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    getattr(ms, filter_name)(**params)
    vertices, faces = from_meshset(ms, f"mesh={label}")
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


def check_size(mesh: Mesh, what: str) -> None:
    """MeshError unless the mesh's bounding-box diagonal lies in :data:`SIZE_RANGE`
    (coordinates of 1e300 otherwise give overflow warnings and a singular factorization)."""
    V = mesh.vertices
    extent = V.max(axis=0) - V.min(axis=0)
    scale = float(np.max(np.abs(extent)))
    diagonal = scale * float(np.sqrt(np.sum((extent / scale) ** 2))) if scale > 0 else 0.0
    lo, hi = SIZE_RANGE
    if not lo <= diagonal <= hi:
        raise MeshError(f"{what}: the mesh's size (bounding-box diagonal {diagonal:.3g}) is outside decrun's range "
                        f"[{lo:g}, {hi:g}] (lengths to the 4th and 6th power would under- or overflow float64): "
                        f"rescale it with mesh.normalize=true")


def _default_post() -> List[str]:
    return ["repair", "up_axis", "clean", "holes", "refine", "normalize", "noise"]


@dataclass
class MeshSource:
    """Base of the mesh sources: the post-processing options every source offers.

    ``post`` lists the steps in the order they run (functions of
    :mod:`decrun.runner.post_steps`); each is a no-op unless its option enables it.
    Lengths are in model units.
    """

    name: ClassVar[str] = ""
    post: List[str] = field(default_factory=_default_post)
    #: pymeshlab's repair filters (duplicates, non-manifold edges/vertices, unreferenced
    #: vertices, orientation), every change counted in meta['repair'] and the log
    repair: bool = False
    #: the model's up axis, rotated to +z: x | y | z | -x | -y | -z | auto (a sample's own)
    up_axis: str = "z"
    clean: bool = False  # drop unreferenced vertices, keep the largest component
    #: holes: cut out balls [cx, cy, cz, r] and boxes [xmin, ymin, zmin, xmax, ymax, zmax]
    #: (2-D: [cx, cy, r], [xmin, ymin, xmax, ymax])
    hole_balls: List[List[float]] = field(default_factory=list)
    hole_boxes: List[List[float]] = field(default_factory=list)
    #: split: triangles split along the region borders (smooth holes) | whole_triangles:
    #: remove triangles whose centroid is inside (sawtooth borders, the earlier cut)
    hole_cut: str = "split"
    hole_snap: float = 0.25  # split: crossings this close (× edge length) to a vertex move it instead
    refine: str = "none"  # none | loop | midpoint | isotropic
    refine_iterations: int = 1
    refine_target_edge: float = 0.0  # isotropic only; 0 = keep the mean edge length
    normalize: bool = False  # centre at the bounding-box centre, unit bounding-box diagonal
    noise: float = 0.0  # amplitude relative to the mean edge length, along vertex normals
    seed: int = 0
    #: how the simplicial complex treats orientation: check (report) | fix (re-orient)
    orient: str = "check"

    def __post_init__(self):
        from decrun.runner import post_steps

        for step in self.post:
            if step not in post_steps.__all__:
                raise ConfigError(f"mesh.post: unknown step {step!r}; choose from {sorted(post_steps.__all__)}")
        require(self.hole_cut in ("split", "whole_triangles"), "hole_cut",
                f"must be split or whole_triangles, got {self.hole_cut!r}")
        require(0 <= self.hole_snap < 0.5, "hole_snap", f"must be in [0, 0.5), got {self.hole_snap}")
        if self.orient not in ("check", "fix"):
            raise ConfigError(f"mesh.orient: must be check or fix, got {self.orient!r}")
        require(self.noise >= 0, "noise", f"must be >= 0, got {self.noise}")

    def make(self) -> Mesh:  # pragma: no cover - abstract
        """The source's own mesh, before post-processing."""
        raise NotImplementedError

    def load(self) -> Mesh:
        """The mesh: :meth:`make`, then the ``post`` steps, checked and hashed.

        Returns a :class:`Mesh` with ``vertices (n0, 3)`` (``(n0, 2)`` for planar sources),
        ``simplices (n2, 3) int64`` and ``meta`` (module docstring). Raises
        :class:`ConfigError` for a bad option, :class:`MeshError` for a bad mesh.
        """
        from decrun.runner import post_steps

        mesh = self.make()
        mesh = replace(mesh, simplices=np.asarray(mesh.simplices, dtype=np.int64),
                       vertices=np.asarray(mesh.vertices, dtype=np.float64))
        label = mesh.meta.get("label", self.name)
        if self.name == "file" and "path" in mesh.meta:  # name the file as the user gave it
            label = f"mesh.path={mesh.meta['path']!r}"
        else:
            label = f"mesh {label}"
        check_mesh(mesh, label)
        applied = []
        for step in self.post:
            before = mesh
            mesh = getattr(post_steps, step)(mesh, self)
            if mesh is not before:
                applied.append(step)
                check_mesh(mesh, f"{label} after the mesh.post step {step!r}")  # names the step that broke it
        check_size(mesh, label + (f" after {applied}" if applied else ""))
        mesh.meta.setdefault("source", self.name)
        mesh.meta["steps"] = applied
        if mesh.simplices.shape[1] == 3:
            mesh.meta["mean_edge_length"] = mean_edge_length(mesh.vertices, mesh.simplices)
        mesh.meta["hash"] = mesh_hash(mesh.vertices, mesh.simplices)
        return mesh
