"""The intrinsic Delaunay Laplacian (``operator=intrinsic_delaunay``), triangle surfaces.

Bobenko & Springborn 2007, Sharp & Crane 2020 (the field's reference implementation is the
``robust-laplacian`` package, which ``tests/core/test_intrinsic_delaunay.py`` compares
against): flip edges of the surface's *intrinsic* triangulation (same metric, other edges)
until every edge is Delaunay; its cotangent weights are non-negative, so the stiffness is an
M-matrix and maps built on it keep a maximum principle (:mod:`decrun.core.intrinsic_delaunay`).
⋆0 is the positive lumped (barycentric) area of the intrinsic triangles.

Its 1-forms live on the intrinsic edges, not on the mesh's: the variant provides 0-form
operators on the mesh's own simplices only (``form_degrees = (0,)``) — smoothing and
parametrization accept it, the 1-form applications reject it before any work. For what needs
more (the heat method's gradient and divergence), :meth:`IntrinsicDelaunay.calculus` gives d0,
⋆1, ♯ and ♭ of the intrinsic triangulation itself (:mod:`decrun.core.intrinsic_calculus`). ``mollify`` is Sharp & Crane's intrinsic
mollification factor δ/h̄ for near-degenerate triangles (0: off).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from decrun.core.intrinsic_calculus import IntrinsicCalculus
from decrun.core.intrinsic_delaunay import IntrinsicOperators, IntrinsicTriangulation, intrinsic_delaunay
from decrun.core.stars import HodgeStar
from decrun.errors import ConfigError

__all__ = ["IntrinsicDelaunay"]


@dataclass
class IntrinsicDelaunay(HodgeStar):
    """``operator=intrinsic_delaunay``: 0-form operators of the intrinsic Delaunay triangulation."""

    name = "intrinsic_delaunay"
    form_degrees = (0,)
    mollify: float = 0.0

    def __post_init__(self):
        if not self.mollify >= 0:
            raise ConfigError(f"operator.mollify: must be >= 0, got {self.mollify}")

    def check(self, K) -> None:
        if K.dim != 2:
            raise ConfigError(f"operator=intrinsic_delaunay needs a triangle mesh, not dimension {K.dim}; "
                              "use `operator=whitney` (or `operator=circumcentric`)")

    def triangulation(self, dec) -> IntrinsicTriangulation:
        """The intrinsic Delaunay triangulation of ``dec``'s mesh, flipped once."""
        return dec.require(("intrinsic_triangulation", self.mollify),
                           lambda: intrinsic_delaunay(dec.K.vertices, dec.K.oriented_simplices(), mollify=self.mollify))

    def operators(self, dec) -> IntrinsicOperators:
        """(stiffness, star0, flips, rounds) of ``dec``'s mesh, computed once."""
        def compute():
            T = self.triangulation(dec)
            return IntrinsicOperators(T.stiffness(), T.star0(), T.flips, T.rounds)
        return dec.require(("intrinsic_delaunay", self.mollify), compute)

    def calculus(self, dec) -> IntrinsicCalculus:
        """d0, ⋆1, ♯, ♭ of the intrinsic triangulation (its own edges and triangles), made once."""
        return dec.require(("intrinsic_calculus", self.mollify), lambda: IntrinsicCalculus(self.triangulation(dec)))

    def diagonal(self, dec, k: int) -> np.ndarray:
        return self.operators(dec).star0

    def stiffness(self, dec):
        return self.operators(dec).stiffness
