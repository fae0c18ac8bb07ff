"""Building a simplicial complex: every j-face of every top simplex, enumerated and numbered.

:func:`build` runs the steps of :class:`~decrun.core.complex.SimplicialComplex`'s
construction in order — input checks, face enumeration, degenerate simplices, facet pairs,
orientation, vertex stars — passing plain arrays from one step to the next and returning the
arrays the complex keeps (:class:`Faces`). The checks are in
:mod:`decrun.core.complex.checks`.
"""

from __future__ import annotations

from itertools import combinations
from typing import NamedTuple

import numpy as np

from decrun.core.complex import checks
from decrun.core.simplex_arrays import FaceRows, group_rows

__all__ = ["Built", "build", "enumerate_faces"]


class Faces(NamedTuple):
    """The face lists of a complex and how its top simplices use them.

    ``lists[j]``: (n_j, j+1) sorted j-simplices (lexicographic; the top simplices in input
    order); ``top_faces[j]``: (m, C(n+1, j+1)) index of every j-face of every top simplex,
    columns in the order of ``combinations(range(n+1), j+1)``; ``local[j]`` those local
    combinations; ``facet_order``/``facet_starts``: the facet slots ``(n+1)·t + c`` grouped by
    facet (members of facet g are ``facet_order[facet_starts[g]:facet_starts[g+1]]``).
    """

    lists: dict
    top_faces: dict
    local: dict
    facet_order: np.ndarray
    facet_starts: np.ndarray
    facet_pairs: tuple | None = None


class Built(NamedTuple):
    """What :func:`build` hands to the complex."""

    vertices: np.ndarray
    original_vertex_index: np.ndarray
    faces: Faces
    orientation: np.ndarray
    top_volumes: np.ndarray


def enumerate_faces(top_sorted: np.ndarray, n_vertices: int) -> Faces:
    """All j-faces of the (m, n+1) sorted top simplices, grouped and numbered (one stable
    grouping of the face slots per dimension: :func:`decrun.core.simplex_arrays.group_rows`)."""
    m, width = top_sorted.shape
    n = width - 1
    local = {j: list(combinations(range(n + 1), j + 1)) for j in range(n + 1)}
    lists = {n: top_sorted, 0: np.arange(n_vertices)[:, None]}
    top_faces = {n: np.arange(m)[:, None], 0: top_sorted}
    facet_order = facet_starts = found = None
    for j in range(1, n):
        if j == n - 1:  # the facets: grouped and paired in one call where the kernel runs
            (unique, inverse, order, starts), found = checks.group_facets(top_sorted, local[j], n_vertices)
            facet_order, facet_starts = order, starts
        else:
            unique, inverse, order, starts = group_rows(FaceRows(top_sorted, local[j]))
        lists[j] = unique
        top_faces[j] = inverse.reshape(m, len(local[j]))
    if n == 1:  # facets are the vertices themselves
        slots = top_sorted.ravel()
        facet_order = np.argsort(slots, kind="stable")
        ordered = slots[facet_order]
        facet_starts = np.append(np.flatnonzero(np.r_[True, ordered[1:] != ordered[:-1]]), slots.size)
    return Faces(lists, top_faces, local, facet_order, facet_starts, found)


def build(vertices, simplices, *, orient: str, unreferenced: str, check_manifold: bool,
          degenerate_tol: float) -> Built:
    """Validate the input and build the face lists, orientation and top volumes (see
    :class:`~decrun.core.complex.SimplicialComplex` for the parameters and errors)."""
    return _build(vertices, simplices, orient, unreferenced, check_manifold, degenerate_tol)


def _build(vertices, simplices, orient, unreferenced, check_manifold, degenerate_tol) -> Built:
    vertices, top_sorted, parity, original = checks.checked_input(vertices, simplices, unreferenced)
    n = top_sorted.shape[1] - 1
    faces = enumerate_faces(top_sorted, vertices.shape[0])
    volumes = checks.check_degenerate(vertices, top_sorted, degenerate_tol)
    pairs = checks.facet_pairs(faces.facet_order, faces.facet_starts, top_sorted, faces.lists[n - 1], check_manifold,
                               faces.facet_pairs)
    # the fans around all vertices and the orientation's consistency in one pass over the pairs
    found = checks.fan_roots_and_consistency(top_sorted, pairs, parity) if check_manifold and n >= 2 else None
    orientation = checks.orient(pairs, parity, orient, n, None if found is None else found[1])
    if check_manifold:
        checks.check_vertex_stars(top_sorted, faces.lists[n - 1], orientation, pairs, vertices.shape[0],
                                  None if found is None else found[0])
    return Built(vertices, original, faces, orientation, volumes)
