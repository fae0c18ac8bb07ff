"""Barycentric ⋆0: the lumped area |σ_top| / (n+1) of every incident top simplex.

Always positive; every other ⋆_k is circumcentric. Any dimension.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from decrun.core.stars.circumcentric import Circumcentric

__all__ = ["Barycentric", "barycentric_star0"]


def barycentric_star0(K) -> np.ndarray:
    """(n0,) Σ over the top simplices σ at each vertex of |σ| / (n+1)."""
    n = K.dim
    share = K.top_volumes / (n + 1)
    return np.bincount(K.simplices(n).ravel(), weights=np.repeat(share, n + 1), minlength=K.num_simplices(0))


@dataclass
class Barycentric(Circumcentric):
    """``operator=barycentric``: ⋆0 = lumped barycentric area (> 0), other stars circumcentric."""

    name = "barycentric"

    def diagonal(self, dec, k: int) -> np.ndarray:
        if k == 0:
            return barycentric_star0(dec.K)
        return super().diagonal(dec, k)
