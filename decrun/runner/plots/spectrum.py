"""The eigenforms figure of ``app=spectrum``: one panel per eigenform, coloured on the surface
(triangle meshes) or on the border surface of a tetrahedral mesh (each border triangle takes
the value of its tetrahedron, or the mean of its vertices' values for 0-forms)."""

from __future__ import annotations

import numpy as np

from decrun.runner.plots.common import new_figure, plot_surface


def border_triangles(K) -> tuple[np.ndarray, np.ndarray]:
    """(border triangles (b, 3), index of the tetrahedron each belongs to (b,)) of a
    tetrahedral complex."""
    index, _ = K.border_faces()
    faces = K.simplices(2)[index]
    incidence = K.boundary(3).tocsr()[index]  # a border face has exactly one tetrahedron
    return faces, incidence.indices[incidence.indptr[:-1]]


def eigenforms_figure(K, values: list, titles: list, degree: int):
    """Panels of ``values`` (each per vertex for 0-forms, else per top simplex) with ``titles``."""
    count = len(values)
    fig = new_figure(width=3.2 * count, height=3.4)
    three_d = K.embedding_dim == 3
    if K.dim == 3:
        faces, owner = border_triangles(K)
    else:
        faces, owner = K.simplices(2), None
    for i, (value, title) in enumerate(zip(values, titles, strict=True)):
        ax = fig.add_subplot(1, count, i + 1, projection="3d" if three_d else None)
        value = np.asarray(value)
        shown = value if degree == 0 or owner is None else value[owner]
        symmetric = degree == 0
        limit = float(np.abs(shown).max()) or 1.0
        plot_surface(ax, K.vertices, faces, shown, cmap="RdBu_r" if symmetric else "viridis",
                     vmin=-limit if symmetric else 0.0, vmax=limit, title=title)
    label = "eigenfunctions" if degree == 0 else f"|eigenforms| of degree {degree}"
    fig.suptitle(f"Δ_{degree}: {label}" + (" on the border surface" if K.dim == 3 else ""), fontsize=10)
    return fig
