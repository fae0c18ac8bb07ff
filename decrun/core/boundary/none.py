"""``boundary=none``: the unadapted operators of §4.5 (the default).

On a border vertex the dual cell is open and δ_1 counts only the flux through interior
dual edges, so δ w = 0 forbids flow through the border (fields come out tangential to it);
d and δ stay adjoint and the Hodge decomposition (Theorem 5) holds.
"""

from __future__ import annotations

from dataclasses import dataclass

from decrun.core.boundary import BoundaryAdaptation

__all__ = ["NoAdaptation"]


@dataclass
class NoAdaptation(BoundaryAdaptation):
    """The unadapted operators."""

    name = "none"
