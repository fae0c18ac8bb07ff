"""The :class:`MeshSource` base of the mesh sources (the record :class:`Mesh` is in :mod:`decrun.runner.mesh.base`).

A mesh source (the ``mesh`` config group) is a dataclass subclassing :class:`MeshSource`:
its own fields are the source's options (e.g. ``subdiv`` of the icosphere), the inherited
ones the post-processing every source offers. ``conf/mesh/<name>.yaml`` names it with
``_target_`` (one module under :mod:`decrun.runner.mesh.sources` plus one YAML file per source).
:meth:`MeshSource.load` builds the mesh:

1. :meth:`MeshSource.make` — the source's vertices and triangles;
2. the post-processing steps listed in ``post``, in that order (the functions of
   :mod:`decrun.runner.mesh.post` of the same name; each is a no-op unless its option
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
- ``<step>_components`` / ``<step>_dropped_vertices`` / ``<step>_dropped_faces`` for the
  steps that keep the largest piece (``clean``, ``largest_component``, ``holes``): the pieces
  found and what was removed (only when the step ran; also metrics of the run, and a log line
  whenever something was dropped)
- ``repair``: the counts of :func:`decrun.runner.mesh.repair.repair_mesh` (only when repair ran)
- ``up_axis``: the axis rotated to +z (only when not z)
- ``holes``: the cut's counts, ``holes_removed_faces`` (only when holes were cut)
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import ClassVar, List

import numpy as np

from decrun.core.choices import closest
from decrun.core.geometry import mean_edge_length
from decrun.errors import ConfigError
from decrun.runner.mesh import post as post_steps
from decrun.runner.mesh.base import (
    HoleCut,
    HolePieces,
    Mesh,
    Orient,
    Refine,
    UpAxis,
    check_mesh,
    check_size,
    mesh_hash,
    require,
)
from decrun.runner.mesh.cut import SNAP

__all__ = ["MeshSource"]


def _default_post() -> List[str]:
    return ["repair", "up_axis", "clean", "largest_component", "holes", "refine", "normalize", "noise", "lloyd"]


@dataclass
class MeshSource:
    """Base of the mesh sources: the post-processing options every source offers.

    ``post`` lists the steps in the order they run (functions of
    :mod:`decrun.runner.mesh.post`); each is a no-op unless its option enables it.
    Lengths are in model units.
    """

    name: ClassVar[str] = ""
    post: List[str] = field(default_factory=_default_post)
    #: pymeshlab's repair filters (duplicates, non-manifold edges/vertices, unreferenced
    #: vertices, orientation), every change counted in meta['repair'] and the log
    repair: bool = False
    #: the model's up axis, rotated to +z: x | y | z | -x | -y | -z | auto (a sample's own);
    #: an :class:`~decrun.runner.mesh.base.UpAxis` once made (a string field: ``-x`` is no enum name)
    up_axis: str = "z"
    clean: bool = False  # drop unreferenced vertices, keep the largest component
    #: keep only the connected component (top simplices joined through shared vertices) with
    #: the most top simplices; the dropped counts go to the log and the metrics
    largest_component: bool = False
    #: holes: cut out balls [cx, cy, cz, r] and boxes [xmin, ymin, zmin, xmax, ymax, zmax]
    #: (2-D: [cx, cy, r], [xmin, ymin, xmax, ymax])
    hole_balls: List[List[float]] = field(default_factory=list)
    hole_boxes: List[List[float]] = field(default_factory=list)
    #: split: triangles split along the region borders (smooth holes) | whole_triangles:
    #: remove triangles whose centroid is inside (sawtooth borders, the earlier cut)
    hole_cut: HoleCut = HoleCut.split
    hole_snap: float = SNAP  # split: crossings this close (× edge length) to a vertex move it instead
    #: after the cut: keep the largest piece (what is dropped is logged and recorded) | all
    hole_pieces: HolePieces = HolePieces.largest
    refine: Refine = Refine.none  # none | loop | midpoint | isotropic
    refine_iterations: int = 1
    refine_target_edge: float = 0.0  # isotropic only; 0 = keep the mean edge length
    normalize: bool = False  # centre at the bounding-box centre, unit bounding-box diagonal
    noise: float = 0.0  # amplitude relative to the mean edge length, along vertex normals
    #: Lloyd's iteration towards the spherical centroidal Voronoi grid: at most this many steps (0: off)
    lloyd: int = 0
    lloyd_tolerance: float = 1e-12  # stop once no vertex moves by this times the sphere's radius
    seed: int = 0
    #: how the simplicial complex treats orientation: check (report) | fix (re-orient)
    orient: Orient = Orient.check

    def __post_init__(self):
        for step in self.post:
            if step not in post_steps.__all__:
                near = closest(step, post_steps.__all__)
                fixed = f"[{','.join(near if s == step else s for s in self.post)}]" if near is not None else None
                hint = f"; did you mean mesh.post={fixed}?" if fixed is not None else ""
                raise ConfigError(f"mesh.post: unknown step {step!r}; choose from {sorted(post_steps.__all__)}{hint}")
        self.hole_cut = HoleCut.of(self.hole_cut, "mesh.hole_cut")  # also for Python callers (strings)
        self.hole_pieces = HolePieces.of(self.hole_pieces, "mesh.hole_pieces")
        self.refine = Refine.of(self.refine, "mesh.refine")
        self.orient = Orient.of(self.orient, "mesh.orient")
        self.up_axis = UpAxis.of(self.up_axis, "mesh.up_axis")
        require(0 <= self.hole_snap < 0.5, "hole_snap", f"must be in [0, 0.5), got {self.hole_snap}")
        require(self.noise >= 0, "noise", f"must be >= 0, got {self.noise}")

    def auto_up_axis(self) -> str:
        """What ``up_axis: auto`` means for this source: ``z`` (a sample knows its own)."""
        return "z"

    def make(self) -> Mesh:  # pragma: no cover - abstract
        """The source's own mesh, before post-processing."""
        raise NotImplementedError

    def load(self) -> Mesh:
        """The mesh: :meth:`make`, then the ``post`` steps, checked and hashed.

        Returns a :class:`Mesh` with ``vertices (n0, 3)`` (``(n0, 2)`` for planar sources),
        ``simplices (n2, 3) int64`` and ``meta`` (module docstring). Raises
        :class:`ConfigError` for a bad option, :class:`MeshError` for a bad mesh.
        """
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
