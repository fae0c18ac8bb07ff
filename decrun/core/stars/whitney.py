"""Galerkin Hodge stars from Whitney forms (``operator=whitney``).

⋆_k is the Whitney k-form mass matrix M_k (:func:`decrun.core.whitney.whitney_mass_matrix`;
Bossavit 1988, Arnold–Falk–Winther 2006, PyDEC's ``whitney_innerproduct``): symmetric
positive definite on every non-degenerate mesh — right angles and obtuse triangles
included, where the circumcentric ⋆1 vanishes or turns negative. It is not diagonal: DEC
applies ⋆_k⁻¹ by a factorized solve and never forms it, so δ and Δ become operators
(LinearOperator), and the weak forms d_kᵀ M_{k+1} d_k are sparse. d0ᵀ M1 d0 is exactly the
cotangent stiffness (triangles) / the P1 stiffness (tetrahedra); M_n = diag(1/|σ_n|).

``lumped: true`` replaces every M_k by a positive diagonal (:func:`whitney_lumped_mass`:
row sums for k = 0 — the barycentric ⋆0 —, the diagonal of M_k for 0 < k < n, exactly
1/|σ| for k = n) for methods that need a diagonal star; the lumped ⋆_k (0 < k < n) is not
consistent (5/6 of the circumcentric ⋆1 on equilateral meshes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from decrun.core.stars import HodgeStar
from decrun.core.whitney import whitney_lumped_mass, whitney_mass_matrix
from decrun.errors import ConfigError

__all__ = ["Whitney"]


@dataclass
class Whitney(HodgeStar):
    """``operator=whitney``: ⋆_k = the Whitney mass matrix M_k (SPD), or its lumped diagonal."""

    name = "whitney"
    lumped: bool = False

    def check(self, K) -> None:
        if K.dim not in (2, 3):
            raise ConfigError(f"operator=whitney is implemented for triangle and tetrahedral meshes, not dimension "
                              f"{K.dim}")

    def is_diagonal(self, K, k: int) -> bool:
        return self.lumped or k == K.dim

    def diagonal(self, dec, k: int) -> np.ndarray | None:
        if self.lumped or k == dec.n:
            return whitney_lumped_mass(dec.K, k)  # k = n: exactly 1/|σ|
        return None

    def matrix(self, dec, k: int):
        return whitney_mass_matrix(dec.K, k)

    def describe(self) -> str:
        return "whitney (lumped)" if self.lumped else "whitney"
