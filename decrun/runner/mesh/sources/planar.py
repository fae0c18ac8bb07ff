"""Planar polygonal domains with holes, meshed by Shewchuk's ``triangle``."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import List

import numpy as np

from decrun.core.connectivity import drop_unreferenced
from decrun.errors import ConfigError, MeshError
from decrun.runner.mesh.base import MAX_TRIANGLES, Mesh, require, require_triangles
from decrun.runner.mesh.source import MeshSource

__all__ = ["Planar"]


def _polygon(points, key: str) -> np.ndarray:
    poly = np.asarray(points, dtype=np.float64)
    require(poly.ndim == 2 and poly.shape[1] == 2 and len(poly) >= 3, key, "a polygon needs >= 3 points [x, y]")
    require(bool(np.isfinite(poly).all()), key, "non-finite coordinate")
    x, y = poly[:, 0], poly[:, 1]
    signed_area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    require(abs(signed_area) > 0, key, "the polygon has zero area")
    return poly


def _area(poly: np.ndarray) -> float:
    """|signed area| of a polygon (n, 2) by the shoelace formula."""
    x, y = poly[:, 0], poly[:, 1]
    return abs(0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))


def _orientation(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """sign of the cross product (b - a) × (c - a), broadcast over leading axes."""
    return np.sign((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))


def _inside(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """(p,) bool: points strictly inside the polygon (even-odd ray casting, vectorized)."""
    a, b = poly, np.roll(poly, -1, axis=0)
    px, py = points[:, None, 0], points[:, None, 1]
    straddles = (a[None, :, 1] > py) != (b[None, :, 1] > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[None, :, 0] + (py - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / (b[None, :, 1] - a[None, :, 1])
    return (straddles & (px < x_cross)).sum(axis=1) % 2 == 1


def check_domain(rings: list[np.ndarray], keys: list[str]) -> None:
    """ConfigError naming the ring's key unless the domain is what ``triangle`` can mesh
    without crashing or silently ignoring part of it: no point given twice, no two
    segments touching or crossing (each ring simple, the rings disjoint), every hole
    inside the outer polygon and outside the other holes. ``rings[0]`` is the outer
    polygon. Vectorized over all segment pairs (rings have tens of points)."""
    points = np.concatenate(rings)
    owner = np.repeat(np.arange(len(rings)), [len(r) for r in rings])
    local = np.concatenate([np.arange(len(r)) for r in rings])
    _, first, counts = np.unique(points, axis=0, return_index=True, return_counts=True)
    if (counts > 1).any():
        p = points[first[counts > 1][0]]
        twice = np.flatnonzero((points == p).all(axis=1))
        raise ConfigError(f"{keys[owner[twice[1]]]}[{local[twice[1]]}]: the point {p.tolist()} is given twice "
                          f"(also {keys[owner[twice[0]]]}[{local[twice[0]]}]); give every point once")
    a = points
    b = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
    n = len(a)
    i, j = np.triu_indices(n, k=1)
    same = owner[i] == owner[j]
    size = np.array([len(r) for r in rings])[owner[i]]
    adjacent = same & (((local[j] - local[i]) % size == 1) | ((local[i] - local[j]) % size == 1))
    i, j = i[~adjacent], j[~adjacent]
    o1, o2 = _orientation(a[i], b[i], a[j]), _orientation(a[i], b[i], b[j])
    o3, o4 = _orientation(a[j], b[j], a[i]), _orientation(a[j], b[j], b[i])
    lo_i, hi_i = np.minimum(a[i], b[i]), np.maximum(a[i], b[i])
    lo_j, hi_j = np.minimum(a[j], b[j]), np.maximum(a[j], b[j])
    boxes_meet = (lo_i <= hi_j).all(axis=1) & (lo_j <= hi_i).all(axis=1)
    hit = np.flatnonzero((o1 * o2 <= 0) & (o3 * o4 <= 0) & boxes_meet)
    if hit.size:
        s, t = i[hit[0]], j[hit[0]]
        what = "the polygon must be simple" if owner[s] == owner[t] else "the rings must not touch"
        raise ConfigError(f"{keys[owner[t]]}: segment {local[t]} {[a[t].tolist(), b[t].tolist()]} touches or crosses "
                          f"{keys[owner[s]]} segment {local[s]} {[a[s].tolist(), b[s].tolist()]}; {what}")
    for k in range(1, len(rings)):  # one vertex decides: the rings do not cross
        if not _inside(rings[k][:1], rings[0])[0]:
            raise ConfigError(f"{keys[k]}: the hole lies outside mesh.outer (its point {rings[k][0].tolist()}); "
                              f"a hole must be inside the outer polygon")
        for other in range(1, len(rings)):
            if other != k and _inside(rings[k][:1], rings[other])[0]:
                raise ConfigError(f"{keys[k]}: the hole lies inside {keys[other]}; holes must not be nested")


def _switch(value: float) -> str:
    """A number as triangle's switches read it: positional digits (``a5e-05`` would be
    read as area 5 followed by the switch ``e``)."""
    return np.format_float_positional(float(value), trim="-")


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
        check_domain(rings, ["mesh.outer", *(f"mesh.holes[{i}]" for i in range(len(holes)))])
        area = _area(outer) - sum(_area(h) for h in holes)
        # measured: triangle makes ≈ 1.6 × area / max_area triangles (unit square: 322 at 0.005)
        require_triangles(1.6 * area / self.max_area, "mesh.max_area",
                          f"mesh.max_area={1.1 * 1.6 * area / MAX_TRIANGLES:.2g}")
        starts = np.cumsum([0] + [len(r) for r in rings[:-1]])
        domain = {
            "vertices": np.concatenate(rings),
            "segments": np.concatenate([_ring_segments(s, len(r)) for s, r in zip(starts, rings, strict=True)]),
        }
        if holes:
            domain["holes"] = np.array([_point_inside(h) for h in holes])
        t = triangle.triangulate(domain, f"pq{_switch(self.min_angle_deg)}a{_switch(self.max_area)}")
        vertices = np.asarray(t["vertices"], dtype=np.float64)
        faces = np.asarray(t["triangles"], dtype=np.int64)
        if len(faces) == 0:
            raise MeshError("mesh.source=planar: triangle produced no triangles")
        # triangle lists the input points first; drop any it left unused (e.g. inside holes)
        vertices, faces, _ = drop_unreferenced(vertices, faces)
        return Mesh(vertices, faces, {"source": "planar", "label": f"planar{len(holes)}h"})
