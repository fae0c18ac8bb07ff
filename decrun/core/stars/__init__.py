"""Hodge-star variants (the ``operator`` config group): one module per variant family.

A variant is a dataclass (its fields are its options) subclassing :class:`HodgeStar`;
:class:`decrun.core.dec.DEC` asks it for ⋆_k and never branches on its name.

========================  ====================================================
module                    variant
========================  ====================================================
``circumcentric``         the thesis' Voronoi dual (§4.5.2–4.5.5), any dimension
``mixed_area``            ⋆0 = Meyer et al.'s mixed area, the rest circumcentric
``barycentric``           ⋆0 = lumped barycentric area, the rest circumcentric
``whitney``               Galerkin: ⋆_k = the Whitney mass matrix M_k (SPD, not
                          diagonal), or its lumped diagonal (``lumped: true``)
``intrinsic_delaunay``    0-form operators of the intrinsic Delaunay triangulation
========================  ====================================================

A variant supplies either a diagonal (``diagonal(dec, k)`` returns the (n_k,) array) or a
general symmetric positive definite ⋆_k (``diagonal`` returns None and ``matrix`` the
sparse matrix; DEC then applies ⋆_k⁻¹ by a factorized solve, never by forming it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np
    import scipy.sparse as sp

    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC

__all__ = ["HodgeStar", "star_variant"]


@dataclass
class HodgeStar:
    """Base of the Hodge-star variants. Subclasses are dataclasses; their fields are options.

    Class attributes
    ----------------
    name : str
        The variant's name (``operator=<name>``; also its module name for built-ins).
    form_degrees : tuple[int, ...] | None
        Degrees k whose ⋆_k acts on the mesh's own k-simplices (None: all). A variant that
        works on another triangulation (intrinsic Delaunay) provides 0-form operators only;
        applications that need more reject it before any work.
    """

    name: ClassVar[str] = ""
    form_degrees: ClassVar[tuple[int, ...] | None] = None

    def check(self, K: "SimplicialComplex") -> None:
        """Raise :class:`decrun.errors.ConfigError` when the variant does not apply to ``K``."""

    def is_diagonal(self, K: "SimplicialComplex", k: int) -> bool:
        """Whether ⋆_k is diagonal (answered without computing it)."""
        return True

    def diagonal(self, dec: "DEC", k: int) -> "np.ndarray | None":
        """(n_k,) diagonal of ⋆_k, or None when this variant's ⋆_k is not diagonal."""
        raise NotImplementedError

    def matrix(self, dec: "DEC", k: int) -> "sp.csr_matrix":
        """⋆_k as a sparse symmetric (n_k, n_k) matrix (default: the diagonal)."""
        import scipy.sparse as sp

        return sp.diags(self.diagonal(dec, k)).tocsr()

    def stiffness(self, dec: "DEC") -> "sp.csr_matrix":
        """The 0-form stiffness ⋆0Δ0 = d0ᵀ ⋆1 d0 (n0, n0), symmetric PSD (default formula)."""
        return (dec.d(0).T @ dec.star(1) @ dec.d(0)).tocsr()

    def describe(self) -> str:
        """Short label for figures and tables, e.g. ``circumcentric``."""
        return self.name


def star_variant(value) -> HodgeStar:
    """A :class:`HodgeStar` from an instance, a built-in name or a dotted class path."""
    from decrun.core.plugins import resolve

    return resolve(value, HodgeStar, "decrun.core.stars", "operator")
