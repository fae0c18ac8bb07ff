"""Primitive mesh sources: icosphere, torus, sphere cap, annulus and cube from pymeshlab; the grid built here."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from decrun.runner.mesh.base import MAX_TRIANGLES, Mesh, pymeshlab_primitive, require, require_triangles
from decrun.runner.mesh.source import MeshSource

__all__ = ["Icosphere", "Torus", "SphereCap", "Annulus", "Grid", "Cube"]


@dataclass
class Icosphere(MeshSource):
    """Icosahedron subdivided ``subdiv`` times on the sphere of ``radius`` (10·4^subdiv + 2 vertices)."""

    name = "icosphere"
    subdiv: int = 3
    radius: float = 1.0

    def __post_init__(self):
        super().__post_init__()
        require(0 <= self.subdiv <= 8, "subdiv", f"must be in 0..8, got {self.subdiv}")
        require(self.radius > 0, "radius", f"must be > 0, got {self.radius}")

    def make(self) -> Mesh:
        mesh = pymeshlab_primitive("create_sphere", "icosphere", radius=float(self.radius), subdiv=int(self.subdiv))
        mesh.meta["label"] = f"icosphere{self.subdiv}"
        return mesh


@dataclass
class Torus(MeshSource):
    """Torus with ring radius ``major_radius``, tube radius ``minor_radius`` and the numbers
    of segments around the ring and the tube."""

    name = "torus"
    major_radius: float = 1.0
    minor_radius: float = 0.4
    major_segments: int = 32
    minor_segments: int = 16

    def __post_init__(self):
        super().__post_init__()
        require(self.major_radius > self.minor_radius > 0, "minor_radius", "need major_radius > minor_radius > 0")
        require(self.major_segments >= 3 and self.minor_segments >= 3, "major_segments", "need >= 3 segments each way")
        fits = int(np.sqrt(MAX_TRIANGLES / 2))
        require_triangles(2.0 * self.major_segments * self.minor_segments, "mesh.major_segments",
                          f"mesh.major_segments={fits} mesh.minor_segments={fits} or fewer")

    def make(self) -> Mesh:
        return pymeshlab_primitive("create_torus", "torus", hradius=float(self.major_radius),
                                   vradius=float(self.minor_radius), hsubdiv=int(self.major_segments),
                                   vsubdiv=int(self.minor_segments))


@dataclass
class SphereCap(MeshSource):
    """Cap of the unit sphere with polar opening angle ``cap_angle_deg`` (a disk)."""

    name = "sphere_cap"
    cap_angle_deg: float = 60.0
    subdiv: int = 3

    def __post_init__(self):
        super().__post_init__()
        require(0 < self.cap_angle_deg < 180, "cap_angle_deg", f"must be in (0, 180), got {self.cap_angle_deg}")
        require(0 <= self.subdiv <= 8, "subdiv", f"must be in 0..8, got {self.subdiv}")

    def make(self) -> Mesh:
        return pymeshlab_primitive("create_sphere_cap", "sphere_cap", angle=float(self.cap_angle_deg),
                                   subdiv=int(self.subdiv))


@dataclass
class Annulus(MeshSource):
    """Planar ring (z = 0) between ``inner_radius`` and ``outer_radius`` with ``sides`` sides
    (one band of triangles: refine it)."""

    name = "annulus"
    inner_radius: float = 0.5
    outer_radius: float = 1.0
    sides: int = 32

    def __post_init__(self):
        super().__post_init__()
        require(self.outer_radius > self.inner_radius > 0, "inner_radius", "need outer_radius > inner_radius > 0")
        require(self.sides >= 3, "sides", f"must be >= 3, got {self.sides}")
        require_triangles(2.0 * self.sides, "mesh.sides", f"mesh.sides={MAX_TRIANGLES // 2}")

    def make(self) -> Mesh:
        return pymeshlab_primitive("create_annulus", "annulus", internalradius=float(self.inner_radius),
                                   externalradius=float(self.outer_radius), sides=int(self.sides))


@dataclass
class Grid(MeshSource):
    """Triangulated ``nx`` × ``ny`` vertex grid of ``width`` × ``height`` in z = 0, centred."""

    name = "grid"
    nx: int = 16  # as conf/mesh/grid.yaml (was 10 here: `Grid()` and `decrun mesh=grid` differed)
    ny: int = 16
    width: float = 1.0
    height: float = 1.0

    def __post_init__(self):
        super().__post_init__()
        require(self.nx >= 2 and self.ny >= 2, "nx", f"need nx, ny >= 2, got {self.nx}, {self.ny}")
        require(self.width > 0 and self.height > 0, "width", "need width, height > 0")
        fits = int(np.sqrt(MAX_TRIANGLES / 2)) + 1
        require_triangles(2.0 * (self.nx - 1) * (self.ny - 1), "mesh.nx",
                          f"mesh.nx={fits} mesh.ny={fits} or fewer vertices per side")

    def make(self) -> Mesh:
        """Vertex (i, j) at x = width/2 − i·width/(nx−1), y = −height/2 + j·height/(ny−1), index
        j·nx + i, so the bounding box is centred on the origin exactly (with odd nx and ny the
        middle vertex is the origin). Each quad (k, k+1, k+nx+1, k+nx), k = j·nx + i, is split
        along its k–(k+nx+1) diagonal into (k+nx+1, k+1, k) and (k, k+nx, k+nx+1): pymeshlab's
        ``create_grid`` triangulation and vertex order, built here because that filter's
        ``center=True`` leaves the grid off centre by (−width/(2nx), height/(2ny)) and rounds
        positions to single precision."""
        nx, ny = int(self.nx), int(self.ny)
        x = self.width / 2 - self.width * np.arange(nx) / (nx - 1)
        y = -self.height / 2 + self.height * np.arange(ny) / (ny - 1)
        X, Y = np.meshgrid(x, y)
        vertices = np.column_stack([X.ravel(), Y.ravel(), np.zeros(nx * ny)])
        k = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
        faces = np.empty((2 * k.size, 3), dtype=np.int64)
        faces[0::2] = np.column_stack([k + nx + 1, k + 1, k])
        faces[1::2] = np.column_stack([k, k + nx, k + nx + 1])
        return Mesh(vertices, faces, {"source": "grid", "label": "grid"})


@dataclass
class Cube(MeshSource):
    """Cube of edge ``size`` centred at the origin (8 vertices, 12 triangles)."""

    name = "cube"
    size: float = 1.0

    def __post_init__(self):
        super().__post_init__()
        require(self.size > 0, "size", f"must be > 0, got {self.size}")

    def make(self) -> Mesh:
        return pymeshlab_primitive("create_cube", "cube", size=float(self.size))
