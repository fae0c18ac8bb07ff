"""Planar channels with obstacles for the fluid of thesis ch. 7 (``mesh=channel``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import List

from decrun.runner.mesh.base import Mesh, require
from decrun.runner.mesh.source import MeshSource

__all__ = ["Channel"]


def _one_obstacle() -> List[List[float]]:
    return [[0.5, 0.5, 0.1]]


@dataclass
class Channel(MeshSource):
    """The channel [0, length] × [0, height] minus circular obstacles ``[cx, cy, r]``, meshed
    by :func:`decrun.core.channel_mesh.channel_mesh`: ``triangle`` with quality bounds and a size
    field graded from the obstacles (``refinement`` = far size / near size), then ODT smoothing
    with re-triangulation until no triangle is obtuse (§7.3: the circumcentric dual cells must
    not turn inside out). ``meta`` reports what is left (``obtuse_triangles``,
    ``max_angle_deg``). The outer border is the longest loop, every obstacle one more."""

    name = "channel"
    length: float = 2.0
    height: float = 1.0
    obstacles: List[List[float]] = field(default_factory=_one_obstacle)
    target_faces: int = 2800
    refinement: float = 3.0
    gradation: float = 0.25
    min_angle_deg: float = 30.0
    smoothing_rounds: int = 30

    def __post_init__(self):
        super().__post_init__()
        require(self.length > 0 and self.height > 0, "length", "need length, height > 0")
        require(100 <= self.target_faces <= 2_000_000, "target_faces", f"must be in 100..2e6, got {self.target_faces}")
        require(self.refinement >= 1, "refinement", f"must be >= 1, got {self.refinement}")
        for i, obstacle in enumerate(self.obstacles):
            require(len(obstacle) == 3 and obstacle[2] > 0, f"obstacles[{i}]", f"need [cx, cy, r] with r > 0, got {obstacle}")
            cx, cy, r = obstacle
            require(r < cx < self.length - r and r < cy < self.height - r, f"obstacles[{i}]",
                    f"the circle {obstacle} must lie inside the channel [0, {self.length}] x [0, {self.height}]")

    def make(self) -> Mesh:
        from decrun.core.channel_mesh import channel_mesh

        built = channel_mesh(self.length, self.height, [("circle", (cx, cy), r) for cx, cy, r in self.obstacles],
                             target_faces=int(self.target_faces), refinement=float(self.refinement),
                             gradation=float(self.gradation), min_angle=float(self.min_angle_deg),
                             smoothing_rounds=int(self.smoothing_rounds))
        meta = {"source": "channel", "label": f"channel{len(built.faces)}", "obtuse_triangles": int(built.obtuse),
                "max_angle_deg": float(built.max_angle_deg)}
        return Mesh(built.vertices, built.faces, meta)
