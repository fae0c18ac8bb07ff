"""Planar polygonal domains with holes, meshed by Shewchuk's ``triangle``."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import List

import numpy as np

from decrun.errors import MeshError
from decrun.runner.meshes import Mesh, MeshSource, require

__all__ = ["Planar"]


def _polygon(points, key: str) -> np.ndarray:
    poly = np.asarray(points, dtype=np.float64)
    require(poly.ndim == 2 and poly.shape[1] == 2 and len(poly) >= 3, key, "a polygon needs >= 3 points [x, y]")
    require(bool(np.isfinite(poly).all()), key, "non-finite coordinate")
    x, y = poly[:, 0], poly[:, 1]
    signed_area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    require(abs(signed_area) > 0, key, "the polygon has zero area")
    return poly


def _ring_segments(start: int, count: int) -> np.ndarray:
    idx = np.arange(start, start + count)
    return np.column_stack([idx, np.roll(idx, -1)])


def _point_inside(poly: np.ndarray) -> np.ndarray:
    """A point strictly inside a simple polygon: centroid of one triangle of its triangulation."""
    import triangle

    t = triangle.triangulate({"vertices": poly, "segments": _ring_segments(0, len(poly))}, "p")
    return t["vertices"][t["triangles"][0]].mean(axis=0)


def _unit_square() -> List[List[float]]:
    return [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]


@dataclass
class Planar(MeshSource):
    """Polygon ``outer`` minus polygons ``holes`` (2-D vertices), meshed by ``triangle`` with
    minimum angle ``min_angle_deg`` and maximum triangle area ``max_area`` (Shewchuk's
    quality switches ``pq<angle>a<area>``)."""

    name = "planar"
    outer: List[List[float]] = field(default_factory=_unit_square)
    holes: List[List[List[float]]] = field(default_factory=list)
    min_angle_deg: float = 25.0
    max_area: float = 0.005

    def __post_init__(self):
        super().__post_init__()
        _polygon(self.outer, "outer")
        for i, hole in enumerate(self.holes):
            _polygon(hole, f"holes[{i}]")
        require(0 < self.min_angle_deg <= 34, "min_angle_deg",
                f"must be in (0, 34] (triangle's guarantee), got {self.min_angle_deg}")
        require(self.max_area > 0, "max_area", f"must be > 0, got {self.max_area}")

    def make(self) -> Mesh:
        import triangle

        outer = _polygon(self.outer, "outer")
        holes = [_polygon(h, f"holes[{i}]") for i, h in enumerate(self.holes)]
        rings = [outer, *holes]
        starts = np.cumsum([0] + [len(r) for r in rings[:-1]])
        domain = {
            "vertices": np.concatenate(rings),
            "segments": np.concatenate([_ring_segments(s, len(r)) for s, r in zip(starts, rings)]),
        }
        if holes:
            domain["holes"] = np.array([_point_inside(h) for h in holes])
        t = triangle.triangulate(domain, f"pq{float(self.min_angle_deg)}a{float(self.max_area)}")
        vertices = np.asarray(t["vertices"], dtype=np.float64)
        faces = np.asarray(t["triangles"], dtype=np.int64)
        if len(faces) == 0:
            raise MeshError("mesh.source=planar: triangle produced no triangles")
        # triangle lists the input points first; drop any it left unused (e.g. inside holes)
        used = np.zeros(len(vertices), dtype=bool)
        used[faces.ravel()] = True
        if not used.all():
            remap = np.cumsum(used) - 1
            vertices, faces = vertices[used], remap[faces]
        return Mesh(vertices, faces, {"source": "planar", "label": f"planar{len(holes)}h"})
