"""Tetrahedral mesh sources: ``mesh=box`` (Kuhn-subdivided cells with tunnels and cavities)
and ``mesh=tetrahedralize`` (a closed surface filled with tetrahedra by TetGen).

TetGen (Hang Si, WIAS Berlin) is licensed under the AGPL-3.0; its Python wheel ``tetgen``
(PyVista, MIT wrapper) bundles it. decrun is MIT, so TetGen is an optional extra,
``pip install 'decrun[tet]'``, imported only when ``mesh=tetrahedralize`` runs: decrun itself
never links or ships it, and a user who installs the extra accepts TetGen's licence for
the combined program.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional

import numpy as np

from decrun.errors import ConfigError, MeshError
from decrun.runner.mesh.base import Mesh, require
from decrun.runner.mesh.source import MeshSource

__all__ = ["Box", "Tetrahedralize", "border_vertex_mask", "tetrahedralize_surface", "enclosed_volume",
           "estimated_tetrahedra"]

#: the most tetrahedra a source may produce (memory: ~1 kB per tetrahedron for complex and
#: operators; measured in benchmarks/bench_volumes.py); ``mesh.max_tetrahedra`` of
#: ``mesh=tetrahedralize`` moves it
MAX_TETRAHEDRA = 4_000_000

#: TetGen's tetrahedra per ``volume / max_volume`` with quality refinement: 1.79–1.84 once
#: max_volume binds (unit icosphere, torus, cube; 36k–180k tetrahedra), up to 2.9 on coarse
#: meshes, where the surface's triangles set the size. Each tetrahedron is at most
#: max_volume, so the count is never below volume / max_volume.
TETS_PER_MAX_VOLUME = 1.8
#: the ratio a suggested max_volume allows for (the coarse end of the range above)
TETS_PER_MAX_VOLUME_HIGH = 3.0


def enclosed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """|Σ_f v0 · (v1 × v2)| / 6 (divergence theorem): the volume (model units³) a closed,
    consistently oriented triangle surface ``(vertices (n, 3), faces (m, 3))`` encloses."""
    v0, v1, v2 = (vertices[faces[:, i]] for i in range(3))
    return abs(float(np.einsum("ij,ij->", v0, np.cross(v1, v2)))) / 6.0


def estimated_tetrahedra(volume: float, max_volume: float) -> float:
    """About how many tetrahedra TetGen's quality refinement makes in ``volume`` with the
    bound ``max_volume`` (:data:`TETS_PER_MAX_VOLUME` × volume / max_volume)."""
    return TETS_PER_MAX_VOLUME * volume / max_volume


def _round_up(value: float) -> float:
    """``value`` rounded up to two significant digits (a suggested bound that stays on the safe side)."""
    scale = 10.0 ** (np.floor(np.log10(value)) - 1)
    return float(np.ceil(value / scale) * scale)


def _border_triangles(tets: np.ndarray) -> np.ndarray:
    """(b, 3) sorted vertex triples of the triangles that lie in exactly one tetrahedron."""
    faces = np.sort(tets[:, [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]].reshape(-1, 3), axis=1)
    unique, counts = np.unique(faces, axis=0, return_counts=True)
    return unique[counts == 1]


def border_vertex_mask(tets: np.ndarray, n_vertices: int) -> np.ndarray:
    """(n_vertices,) bool: vertices of the triangles that lie in exactly one tetrahedron."""
    mask = np.zeros(n_vertices, dtype=bool)
    mask[_border_triangles(tets).ravel()] = True
    return mask


def _check_manifold_border(tets: np.ndarray) -> None:
    """MeshError when removed cells touch only along an edge (a border edge in four border
    triangles): the solid is then pinched there and its Betti numbers are not those of the
    holes."""
    border = _border_triangles(tets)
    edges = np.sort(border[:, [[0, 1], [1, 2], [0, 2]]].reshape(-1, 2), axis=1)
    edge, edge_counts = np.unique(edges, axis=0, return_counts=True)
    pinched = edge[edge_counts != 2]
    if len(pinched):
        raise MeshError(f"mesh.tunnels/mesh.cavities: the removed cells touch along {len(pinched)} edges (e.g. between "
                        f"vertices {pinched[0].tolist()}), which pinches the solid; move the boxes at least one cell "
                        "(1/mesh.cells of the size) apart")


def _inside(centers: np.ndarray, box) -> np.ndarray:
    lo, hi = np.asarray(box[:3], dtype=np.float64), np.asarray(box[3:], dtype=np.float64)
    return np.all((centers > lo) & (centers < hi), axis=1)


@dataclass
class Box(MeshSource):
    """The box [0, size_x] × [0, size_y] × [0, size_z] cut into ``cells``³ cells, each into the
    six Kuhn tetrahedra (:func:`decrun.core.primitives.kuhn_cube`), minus the cells whose
    centres lie in a ``tunnels`` or ``cavities`` box ([xmin, ymin, zmin, xmax, ymax, zmax]).

    A tunnel must run through the box along at least one axis (Betti_1 += 1); a cavity must
    lie inside it, away from its faces (Betti_2 += 1). ``jitter`` moves every vertex off the
    border surface by up to that fraction of a cell, uniformly (seeded by ``seed``): Kuhn
    cells have right angles, so their circumcentric ⋆1 and ⋆2 are zero on many simplices
    (use ``operator=whitney``), and jittered ones are not Delaunay (⋆ entries of both signs).
    """

    name = "box"
    cells: int = 6
    size: List[float] = field(default_factory=lambda: [1.0, 1.0, 1.0])
    tunnels: List[List[float]] = field(default_factory=list)
    cavities: List[List[float]] = field(default_factory=list)
    jitter: float = 0.0

    def __post_init__(self):
        super().__post_init__()
        require(self.cells >= 1, "cells", f"must be >= 1, got {self.cells}")
        require(6 * self.cells**3 <= MAX_TETRAHEDRA, "cells",
                f"would make {6 * self.cells**3:.3g} tetrahedra, more than decrun's limit {MAX_TETRAHEDRA:.0e}; "
                f"use mesh.cells={int((MAX_TETRAHEDRA / 6) ** (1 / 3))} or fewer")
        require(len(self.size) == 3 and all(s > 0 for s in self.size), "size",
                f"must be three positive lengths, got {list(self.size)}")
        require(0 <= self.jitter < 0.5, "jitter", f"must be in [0, 0.5) cells, got {self.jitter}")
        size = np.asarray(self.size, dtype=np.float64)
        for key, boxes in (("tunnels", self.tunnels), ("cavities", self.cavities)):
            for i, box in enumerate(boxes):
                require(len(box) == 6 and all(box[j] < box[j + 3] for j in range(3)), f"{key}[{i}]",
                        f"must be [xmin, ymin, zmin, xmax, ymax, zmax] with min < max, got {list(box)}")
                lo, hi = np.asarray(box[:3]), np.asarray(box[3:])
                through = (lo <= 0) & (hi >= size)
                if key == "tunnels":
                    require(through.any() and not through.all(), f"{key}[{i}]",
                            f"a tunnel must run through the box along one or two axes (from <= 0 to >= size "
                            f"{list(self.size)}), got {list(box)}")
                else:
                    require(bool(np.all(lo > 0) and np.all(hi < size)), f"{key}[{i}]",
                            f"a cavity must lie inside the box (0 < min, max < size {list(self.size)}), got {list(box)}")

    def make(self) -> Mesh:
        from decrun.core.primitives import kuhn_cube

        size = np.asarray(self.size, dtype=np.float64)
        holes = [*self.tunnels, *self.cavities]

        keys = [f"tunnels[{i}]" for i in range(len(self.tunnels))] + [f"cavities[{i}]" for i in range(len(self.cavities))]

        def keep(centers):
            centers = centers * size
            removed = np.zeros(len(centers), dtype=bool)
            for key, box in zip(keys, holes, strict=True):
                inside = _inside(centers, box)
                require(bool(inside.any()), key, f"{list(box)} contains no cell centre (cells of "
                        f"{(size / self.cells).round(6).tolist()}), so it would remove nothing: enlarge it")
                removed |= inside
            return ~removed

        vertices, tets = kuhn_cube(int(self.cells), keep_cell=keep if holes else None)
        if len(tets) == 0:
            raise MeshError("mesh=box: the tunnels and cavities remove every cell")
        vertices = vertices * size
        if holes:
            _check_manifold_border(tets)
        moved = 0
        if self.jitter > 0:
            interior = ~border_vertex_mask(tets, len(vertices))
            step = size / self.cells
            rng = np.random.default_rng(int(self.seed))
            vertices[interior] += self.jitter * step * rng.uniform(-1.0, 1.0, (int(interior.sum()), 3))
            moved = int(interior.sum())
        label = "box" + ("_tunnels" if self.tunnels else "") + ("_cavities" if self.cavities else "")
        meta = {"source": "box", "label": label, "box_cells": int(self.cells), "jittered_vertices": moved}
        return Mesh(vertices, tets, meta)


def tetrahedralize_surface(vertices: np.ndarray, faces: np.ndarray, *, quality: bool = True, min_ratio: float = 1.5,
                           min_dihedral_deg: float = 0.0, max_volume: float = 0.0, keep_surface: bool = False,
                           what: str = "mesh=tetrahedralize") -> tuple[np.ndarray, np.ndarray, dict]:
    """Fill the closed triangle surface ``(vertices (n, 3), faces (m, 3))`` with tetrahedra
    (TetGen's constrained Delaunay tetrahedralization, switches ``-p`` with ``-q`` for quality).

    Parameters
    ----------
    quality : refine until every radius–edge ratio is ≤ ``min_ratio`` (and dihedral angles
        ≥ ``min_dihedral_deg``), inserting Steiner points
    max_volume : largest tetrahedron volume (model units³), 0: no bound
    keep_surface : no Steiner points on the surface (``-Y``): the border stays the input

    Returns
    -------
    vertices (n', 3) float64 (the input vertices first), tetrahedra (t, 4) int64 positively
    oriented, counts {input_vertices, input_triangles, vertices, tetrahedra, steiner_vertices}
    """
    try:
        import tetgen
    except ImportError:
        raise ConfigError(f"{what} needs the optional package tetgen (TetGen, AGPL-3.0): install it with "
                          "pip install 'decrun[tet]' (or pip install tetgen)") from None
    generator = tetgen.TetGen(np.ascontiguousarray(vertices, dtype=np.float64),
                              np.ascontiguousarray(faces, dtype=np.int32))
    # steinerleft=-1: no cap on the Steiner points (the wheel's default, 100000, silently stops
    # the refinement at about 600k tetrahedra, whatever max_volume asks)
    options: dict[str, Any] = dict(quality=bool(quality), nobisect=bool(keep_surface), quiet=True, steinerleft=-1)
    if quality:
        options.update(minratio=float(min_ratio), mindihedral=float(min_dihedral_deg))
    if max_volume > 0:
        options.update(maxvolume=float(max_volume), fixedvolume=True)
    try:
        nodes, elements, *_ = generator.tetrahedralize(**options)
    except RuntimeError as exc:
        raise MeshError(f"{what}: TetGen cannot fill this surface ({str(exc).strip()[:200]}): it must be closed, "
                        "manifold and free of self-intersections") from None
    nodes = np.asarray(nodes, dtype=np.float64)
    tets = np.asarray(elements, dtype=np.int64)
    if len(tets) == 0:
        raise MeshError(f"{what}: TetGen made no tetrahedra (is the surface closed?)")
    p = nodes[tets]
    negative = np.linalg.det(p[:, 1:] - p[:, :1]) < 0
    tets[negative, 0], tets[negative, 1] = tets[negative, 1], tets[negative, 0].copy()
    counts = {"input_vertices": int(len(vertices)), "input_triangles": int(len(faces)), "vertices": int(len(nodes)),
              "tetrahedra": int(len(tets)), "steiner_vertices": int(len(nodes) - len(vertices))}
    return nodes, tets, counts


@dataclass
class Tetrahedralize(MeshSource):
    """A closed surface filled with tetrahedra (:func:`tetrahedralize_surface`).

    ``surface`` names the surface: a mesh file path, a pymeshlab sample (``bunny``, ``cow``, …;
    ``mesh=sample``'s names, repaired as there) or a surface source of the ``mesh`` group
    (``icosphere``, ``torus``, ``cube``, …) built with its class defaults (no noise) and
    ``surface_options`` (e.g. ``{subdiv: 2}``). The surface's own post steps do not run; this
    source's do (on the tetrahedra: those that work on volumes).
    """

    name = "tetrahedralize"
    surface: str = "icosphere"
    surface_options: Optional[Dict[str, Any]] = None  # e.g. {subdiv: 2} (null: none)
    quality: bool = True
    min_ratio: float = 1.5
    min_dihedral_deg: float = 0.0
    max_volume: float = 0.0
    keep_surface: bool = False
    max_tetrahedra: int = MAX_TETRAHEDRA  # the most tetrahedra TetGen may make (memory)

    def __post_init__(self):
        super().__post_init__()
        require(bool(self.surface), "surface", "is empty; give a file, a sample or a surface source, "
                                               "e.g. mesh.surface=icosphere")
        require(self.min_ratio > 1.0, "min_ratio", f"must be > 1 (TetGen's radius-edge bound), got {self.min_ratio}")
        require(0 <= self.min_dihedral_deg < 70, "min_dihedral_deg",
                f"must be in [0, 70) degrees, got {self.min_dihedral_deg}")
        require(self.max_volume >= 0, "max_volume", f"must be >= 0 (0: no bound), got {self.max_volume}")
        require(self.max_tetrahedra >= 1, "max_tetrahedra", f"must be >= 1, got {self.max_tetrahedra}")

    def surface_source(self) -> MeshSource:
        """The :class:`MeshSource` that makes the surface (class docstring)."""
        import dataclasses

        from decrun.runner.mesh.sources.files import SAMPLE_MESHES, File, Sample
        from decrun.runner.mesh.sources.primitives import Cube, Icosphere, Torus

        closed = {cls.name: cls for cls in (Icosphere, Torus, Cube)}
        options = dict(self.surface_options or {})
        if Path(str(self.surface)).expanduser().is_file():
            cls, options = File, {"path": str(self.surface), **options}
        elif self.surface in SAMPLE_MESHES:
            cls, options = Sample, {"sample": self.surface, **options}
        elif self.surface in closed:
            cls = closed[self.surface]
        else:
            raise ConfigError(f"mesh.surface: {self.surface!r} is neither a file nor a sample ({sorted(SAMPLE_MESHES)}) "
                              f"nor a closed surface source ({sorted(closed)}); use `mesh.surface=icosphere`")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise ConfigError(f"mesh.surface_options: {unknown} are not options of mesh={cls.name}; it has "
                              f"{sorted(known)}")
        return cls(**options)

    def check_count(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        """ConfigError before TetGen starts when ``max_volume`` would make more than
        ``max_tetrahedra`` tetrahedra (:func:`estimated_tetrahedra` of the volume the surface
        encloses), naming the ``mesh.max_volume`` that makes about half as many or fewer.
        Without quality refinement TetGen does not refine to max_volume: nothing to estimate."""
        if not (self.max_volume > 0 and self.quality):
            return
        volume = enclosed_volume(vertices, faces)
        estimate = estimated_tetrahedra(volume, self.max_volume)
        if estimate <= self.max_tetrahedra:
            return
        fits = _round_up(TETS_PER_MAX_VOLUME_HIGH * volume / self.max_tetrahedra)
        raise ConfigError(f"mesh.max_volume={self.max_volume:g}: the surface encloses a volume of {volume:.4g}, so "
                          f"TetGen would make about {estimate:.2g} tetrahedra ({TETS_PER_MAX_VOLUME:g} × volume / "
                          f"max_volume), more than mesh.max_tetrahedra={self.max_tetrahedra} (memory: about 1 kB "
                          f"each); use `mesh.max_volume={fits:.2g}` (about {estimated_tetrahedra(volume, fits):.2g} "
                          f"tetrahedra), or raise mesh.max_tetrahedra")

    def make(self) -> Mesh:
        surface = self.surface_source().load()
        if surface.simplices.shape[1] != 3:
            raise ConfigError(f"mesh.surface={self.surface}: is already tetrahedral; use mesh=file")
        vertices = surface.vertices if surface.vertices.shape[1] == 3 else np.column_stack(
            [surface.vertices, np.zeros(len(surface.vertices))])
        self.check_count(vertices, surface.simplices)
        nodes, tets, counts = tetrahedralize_surface(vertices, surface.simplices, quality=self.quality,
                                                     min_ratio=self.min_ratio, min_dihedral_deg=self.min_dihedral_deg,
                                                     max_volume=self.max_volume, keep_surface=self.keep_surface,
                                                     what=f"mesh=tetrahedralize mesh.surface={self.surface}")
        if len(tets) > self.max_tetrahedra:  # more than estimated: coarse meshes, where the surface sets the size
            coarser = "a larger mesh.max_volume or a coarser mesh.surface" if self.max_volume > 0 else "a coarser mesh.surface"
            raise ConfigError(f"mesh.max_volume={self.max_volume:g}: TetGen made {len(tets):.3g} tetrahedra, more than "
                              f"mesh.max_tetrahedra={self.max_tetrahedra} (memory: about 1 kB each); use {coarser}, or "
                              f"accept this mesh with `mesh.max_tetrahedra={len(tets)}`")
        meta = {"source": "tetrahedralize", "label": f"{surface.meta.get('label', self.surface)}_tets",
                "tetrahedralize": counts}
        if "path" in surface.meta:
            meta["surface_path"] = surface.meta["path"]
        return Mesh(nodes, tets, meta)
