"""Boundary adaptations of the operators (the ``boundary`` config group).

An adaptation is a dataclass subclassing :class:`BoundaryAdaptation` that may replace the
codifferential δ_k near the border; :class:`decrun.core.dec.DEC` asks it and never branches
on its name. Each application declares the adaptations it supports
(``App.boundaries``); the runner rejects any other combination before work starts.

========  ===================================================================
module    adaptation
========  ===================================================================
``none``  the unadapted operators: d and δ adjoint, Hodge decomposition valid
``flux``  §6.4.4: δ_1 also counts the flux through border edges (eq. 6.10)
========  ===================================================================

The helpers :func:`border_edge_frames` and :func:`signed_edges` describe the border edges
of a triangle mesh for adaptations and methods alike. :mod:`decrun.core.boundary.conditions`
(not an adaptation) holds the Dirichlet, Neumann and Robin border conditions of 0-forms.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from decrun.core.connectivity import edge_owners

__all__ = ["BoundaryAdaptation", "boundary_adaptation", "border_edge_frames", "signed_edges"]


@dataclass
class BoundaryAdaptation:
    """Base of the boundary adaptations; subclasses are dataclasses whose fields are options."""

    name: ClassVar[str] = ""

    def check(self, K) -> None:
        """Raise :class:`decrun.errors.ConfigError` when the adaptation does not apply to ``K``."""

    def codifferential(self, dec, k: int):
        """The adapted δ_k (sparse (n_{k−1}, n_k)), or None to keep eq. 4.14 unchanged."""
        return None


def boundary_adaptation(value) -> BoundaryAdaptation:
    """A :class:`BoundaryAdaptation` from an instance, a built-in name or a dotted class path."""
    from decrun.core.plugins import resolve

    return resolve(value, BoundaryAdaptation, "decrun.core.boundary", "boundary")


def border_edge_frames(K):
    """Border edges of a triangle mesh with their triangle.

    Returns ``(edges, face, i, j, k)``, each (b,) int64: the border edge indices, the face
    each lies in, and the face's vertices with i → j the border edge in the face's
    orientation (the outside is to the right of i → j) and k the opposite vertex.
    """
    edges_idx, _ = K.border_faces()
    top_sorted = K.simplices(2)
    oriented = K.oriented_simplices()
    # a triangle of each edge and the slot of the edge in K.facet_indices(2): opposite sorted vertex `slot`
    owner, slot = edge_owners(K.facet_indices(2), K.num_simplices(1))
    face = owner[edges_idx]
    k_vertex = top_sorted[face, slot[edges_idx]]
    # position of k in the oriented tuple; i and j follow it cyclically
    pos = np.argmax(oriented[face] == k_vertex[:, None], axis=1)
    i_vertex = oriented[face, (pos + 1) % 3]
    j_vertex = oriented[face, (pos + 2) % 3]
    return edges_idx, face, i_vertex, j_vertex, k_vertex


def signed_edges(K, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Edge indices of the oriented pairs a → b and the sign (+1 when a < b, the reference
    orientation, −1 otherwise): w(a → b) = sign · w[index] for a 1-form w."""
    index = K.find_simplices(np.stack([a, b], axis=1))
    return index, np.where(a < b, 1.0, -1.0)
