"""Simplicial complexes of any dimension (thesis §2.2–2.3).

=======================  ================================================================
module                   job
=======================  ================================================================
``simplicial_complex``   :class:`SimplicialComplex`: simplex lists, orientation, δ_j, lookups
``construction``         face enumeration and the order of the construction steps
``checks``               input, degeneracy, manifoldness, orientation and vertex-star checks
``topology``             components, the border ∂M and its loops, Betti numbers
=======================  ================================================================

The simplex-array kernels (row grouping, parity, volumes) are in
:mod:`decrun.core.simplex_arrays` and re-exported here.
"""

from decrun.core.complex.simplicial_complex import SimplicialComplex
from decrun.core.simplex_arrays import (  # noqa: F401  (re-exported)
    FaceRows,
    group_rows,
    inversion_parity,
    simplex_volumes,
    sort_rows,
    unique_rows,
    vertex_volumes,
)

__all__ = ["SimplicialComplex", "unique_rows", "inversion_parity", "simplex_volumes"]
