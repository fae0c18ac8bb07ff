"""Mixed-area ⋆0 (Meyer, Desbrun, Schröder, Barr 2003, cited in §4.5.4 and §5.2.1).

⋆0 is the mixed Voronoi area: the Voronoi contribution in non-obtuse triangles; in an
obtuse triangle, half its area to the obtuse corner and a quarter to each other one —
always positive. Every other ⋆_k is circumcentric (so ⋆1 is still the cot formula and can be
negative).

Meyer et al.'s construction is planar; on tetrahedral meshes ``tetrahedra: barycentric`` (the
default, so that the default config runs on volumes) takes ⋆0 from the lumped barycentric
volume |σ|/4 of every incident tetrahedron (as ``operator=barycentric``; ``describe()`` says
so in tables), and ``tetrahedra: error`` refuses volumes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from decrun.core.choices import Choice
from decrun.core.geometry import corner_cotangents
from decrun.core.stars.circumcentric import Circumcentric
from decrun.errors import ConfigError

__all__ = ["MixedArea", "Tetrahedra", "mixed_area_star0"]


def mixed_area_star0(vertices: np.ndarray, triangles: np.ndarray, areas: np.ndarray) -> np.ndarray:
    """(n0,) mixed Voronoi areas (Meyer et al. 2003, Fig. 4) of the vertices of ``triangles``
    (m, 3) with areas (m,): Voronoi parts (|e_ij|² cot θ_l + |e_il|² cot θ_j) / 8 in
    non-obtuse triangles, area/2 to an obtuse corner and area/4 to the two others."""
    p = vertices[triangles]
    cot = corner_cotangents(vertices, triangles)
    # squared length of the edge opposite corner i
    sq = np.stack([np.einsum("md,md->m", p[:, (i + 2) % 3] - p[:, (i + 1) % 3], p[:, (i + 2) % 3] - p[:, (i + 1) % 3])
                   for i in range(3)], axis=1)
    contribution = np.empty_like(cot)
    for i in range(3):
        j, l = (i + 1) % 3, (i + 2) % 3
        contribution[:, i] = (sq[:, l] * cot[:, l] + sq[:, j] * cot[:, j]) / 8.0
    obtuse = cot < 0
    any_obtuse = obtuse.any(axis=1)
    contribution[any_obtuse] = np.where(obtuse[any_obtuse], 0.5, 0.25) * areas[any_obtuse, None]
    return np.bincount(triangles.ravel(), weights=contribution.ravel(), minlength=len(vertices))


class Tetrahedra(Choice):
    """``operator.tetrahedra`` of mixed_area: on tetrahedral meshes the ``barycentric`` ⋆0, or an
    ``error`` (volumes refused)."""

    barycentric = "barycentric"
    error = "error"


@dataclass
class MixedArea(Circumcentric):
    """``operator=mixed_area``: ⋆0 = mixed area (> 0), other stars circumcentric."""

    name = "mixed_area"
    tetrahedra: Tetrahedra = Tetrahedra.barycentric  # barycentric | error: ⋆0 on tetrahedral meshes

    def __post_init__(self):
        self.tetrahedra = Tetrahedra.of(self.tetrahedra, "operator.tetrahedra")  # also for Python callers

    def check(self, K) -> None:
        if K.dim == 3 and self.tetrahedra == "barycentric":
            self._volume = True
            return
        self._volume = False
        if K.dim != 2:
            raise ConfigError(f"operator=mixed_area is defined for triangle meshes, not dimension {K.dim}; "
                              "use `operator=barycentric` (or `operator=circumcentric`)")

    def diagonal(self, dec, k: int) -> np.ndarray:
        if k == 0 and dec.n == 3:
            from decrun.core.stars.barycentric import barycentric_star0

            return barycentric_star0(dec.K)
        if k == 0:
            return mixed_area_star0(dec.K.vertices, dec.K.simplices(2), dec.K.top_volumes)
        return super().diagonal(dec, k)

    def describe(self) -> str:
        return "mixed_area (barycentric ⋆0 on tetrahedra)" if getattr(self, "_volume", False) else self.name
