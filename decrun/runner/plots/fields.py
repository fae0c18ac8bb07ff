"""Figures of tangent vector fields: arrows of the Whitney ♯ field with singularities
(``app=vector_field``) and the Hodge parts side by side (``app=hodge``)."""

from __future__ import annotations

import numpy as np

from decrun.core.geometry import embed3, face_normals, is_planar, triangle_areas
from decrun.runner.plots.common import new_figure, plot_surface

__all__ = ["arrow_length", "draw_field", "draw_volume_field", "field_figure", "hodge_parts_figure", "values_and_arrows"]

_VIEW = (25.0, -60.0)  # matplotlib elevation, azimuth (degrees)


def _view_direction(elev: float, azim: float) -> np.ndarray:
    e, a = np.radians(elev), np.radians(azim)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def _singular_points(K, vertex_index, face_index):
    """(S, 3) positions (vertices, face barycenters), (S,) indices and (S,) is-face flags."""
    x = embed3(K.vertices)
    vertices = np.flatnonzero(vertex_index)
    faces = np.flatnonzero(face_index)
    at_faces = x[K.simplices(2)[faces]].mean(axis=1)
    return (np.concatenate([x[vertices], at_faces]),
            np.concatenate([vertex_index[vertices], face_index[faces]]),
            np.concatenate([np.zeros(vertices.size, bool), np.ones(faces.size, bool)]))


def arrow_length(mean_edge_length: float, shown_area: float, arrows: int) -> float:
    """The length of every arrow (model units): 0.8 × the spacing of the arrows drawn — the
    side √(A / N) of the area A each of the N arrows stands for on the side shown — and at
    least 0.9 mean edge lengths. On a fine scanned mesh (the bunny: 70k triangles, 700
    arrows) one edge length is a speck at figure size; the spacing is what the eye sees."""
    spacing = float(np.sqrt(shown_area / arrows)) if arrows and shown_area > 0 else 0.0
    return max(0.9 * float(mean_edge_length), 0.8 * spacing)


def draw_field(ax, K, face_vectors: np.ndarray, vertex_index=None, face_index=None, *, max_arrows: int = 700,
               colour_by_magnitude: bool = True, title: str | None = None, seed: int = 0, view=_VIEW,
               vmax: float | None = None, min_magnitude: float = 0.0):
    """Draw the mesh coloured by |u| with arrows (unit direction, one length:
    :func:`arrow_length`) at face barycenters, at most ``max_arrows`` of them (a seeded subset; on 3-D meshes only faces
    turned towards the viewer), and the singularities (``vertex_index`` (n0,), ``face_index``
    (n2,)): index +1 red, −1 blue, others black (vertices as circles, faces as squares).
    ``vmax``: the top of the grey scale (default 2 × the 95th percentile of |u|; pass one value
    to several panels to compare them); arrows only where |u| > ``min_magnitude``."""
    faces = K.oriented_simplices()
    x = embed3(K.vertices)
    planar = is_planar(K.vertices)
    normals = face_normals(K.vertices, faces)
    magnitude = np.linalg.norm(face_vectors, axis=1)
    empty = not np.any(magnitude > min_magnitude)  # no arrows: draw the edges so the mesh shows
    mappable = plot_surface(ax, K.vertices if planar else x, faces, magnitude if colour_by_magnitude else None,
                            cmap="Greys", vmin=0.0, vmax=vmax or 2.0 * float(np.percentile(magnitude, 95)) or 1.0,
                            linewidth=0.3 if empty else 0.05, edgecolor="0.75" if empty else None, title=title)
    if mappable is not None:
        ax.field_clim = mappable.get_clim()  # the grey scale of this panel (read by tests)
    barycenters = x[faces].mean(axis=1)
    candidates = np.flatnonzero(magnitude > min_magnitude)
    if not planar:
        ax.view_init(*view)
        candidates = candidates[normals[candidates] @ _view_direction(*view) > 0.05]
    shown_area = float(triangle_areas(x, faces[candidates]).sum()) if candidates.size else 0.0
    if candidates.size > max_arrows:
        candidates = np.sort(np.random.default_rng(seed).choice(candidates, max_arrows, replace=False))
    length = arrow_length(K.mean_edge_length, shown_area, candidates.size)
    direction = face_vectors[candidates] / magnitude[candidates, None] * length
    start = barycenters[candidates] - 0.5 * direction
    if planar:
        ax.quiver(start[:, 0], start[:, 1], direction[:, 0], direction[:, 1], angles="xy", scale_units="xy",
                  scale=1.0, color="tab:orange", width=0.003, headwidth=4)
    else:
        lift = 0.02 * length * normals[candidates]
        ax.quiver(*(start + lift).T, *direction.T, color="tab:orange", linewidth=0.9, arrow_length_ratio=0.35,
                  zorder=4)
    if vertex_index is not None and face_index is not None:
        points, index, is_face = _singular_points(K, np.asarray(vertex_index), np.asarray(face_index))
        if not planar:  # only the singularities on the visible side
            visible = (points - x.mean(axis=0)) @ _view_direction(*view) > 0
            points, index, is_face = points[visible], index[visible], is_face[visible]
        colour = np.where(index > 0, "red", np.where(index < 0, "blue", "black"))
        for face_kind, marker in ((False, "o"), (True, "s")):
            sel = is_face == face_kind
            if sel.any():
                if planar:
                    ax.scatter(points[sel, 0], points[sel, 1], c=colour[sel], marker=marker, s=28, zorder=5)
                else:
                    ax.scatter(*points[sel].T, c=colour[sel], marker=marker, s=28, depthshade=False, zorder=5)
    return mappable


def field_figure(K, face_vectors, vertex_index=None, face_index=None, stroke_faces=None, *,
                 title="designed field", max_arrows=700, cluster_positions=None, cluster_indices=None,
                 source_vertices=None, source_divergences=None, vortex_faces=None):
    """The designed field with its singularities, the stroke faces (green dots), the sources
    and sinks (``source_vertices`` with their ``source_divergences``: triangles up / down) and
    the vortices (``vortex_faces``: stars): one panel for planar meshes, two opposite views
    for surfaces in 3-D, and a legend naming every kind of mark drawn. Singularity clusters
    (``cluster_positions`` (C, 3), ``cluster_indices`` (C,)) are circled and labelled with
    their summed index."""
    from matplotlib.lines import Line2D

    planar = is_planar(K.vertices)
    views = [None] if planar else [_VIEW, (-_VIEW[0], _VIEW[1] + 180.0)]
    fig = new_figure(6.0 * len(views), 6.4)
    mappable = None
    x = embed3(K.vertices)
    faces = K.simplices(2)
    marks = {}  # legend label -> handle, for the kinds of marks drawn
    sources = np.asarray(source_vertices if source_vertices is not None else [], dtype=np.int64)
    divergence = np.asarray(source_divergences if source_divergences is not None else [], dtype=np.float64)
    vortices = np.asarray(vortex_faces if vortex_faces is not None else [], dtype=np.int64)
    for i, view in enumerate(views):
        ax = fig.add_subplot(1, len(views), i + 1, **({} if planar else {"projection": "3d", "computed_zorder": False}))
        label = title if i == 0 else "opposite side"
        mappable = draw_field(ax, K, face_vectors, vertex_index, face_index, max_arrows=max_arrows, title=label,
                              **({} if planar else {"view": view}))

        def visible(points):
            if planar or not len(points):
                return np.ones(len(points), dtype=bool)
            return (points - x.mean(axis=0)) @ _view_direction(*view) > 0

        def mark(points, label_, **style):
            points = points[visible(points)]
            if len(points):
                ax.plot(*(points[:, :2].T if planar else points.T), linestyle="None", zorder=6, **style)
            marks.setdefault(label_, Line2D([], [], linestyle="None", **style))

        if stroke_faces is not None and len(stroke_faces):
            mark(x[faces[np.asarray(stroke_faces)]].mean(axis=1), "stroke faces", marker=".", color="tab:green",
                 ms=4)
        for sign, marker, name in ((1, "^", "source (divergence > 0)"), (-1, "v", "sink (divergence < 0)")):
            chosen = sources[np.sign(divergence) == sign] if sources.size else sources
            if chosen.size:
                mark(x[chosen], name, marker=marker, color="darkviolet", ms=9, markeredgecolor="white")
        if vortices.size:
            mark(x[faces[vortices]].mean(axis=1), "vortex (prescribed curl)", marker="*", color="darkviolet", ms=12,
                 markeredgecolor="white")
        if cluster_positions is not None and len(cluster_positions):
            _draw_clusters(ax, x, np.asarray(cluster_positions), np.asarray(cluster_indices), planar, view)
    arrow = Line2D([], [], color="tab:orange", marker=r"$\rightarrow$", linestyle="None", ms=14)
    handles = {"direction of u (arrows of one length)": arrow}
    if vertex_index is not None and face_index is not None:
        index = np.concatenate([np.asarray(vertex_index), np.asarray(face_index)])
        for sign, colour, name in ((1, "red", "+1"), (-1, "blue", "−1")):
            if np.any(index * sign > 0):
                handles[f"singularity of index {name} (● vertex, ■ face)"] = Line2D(
                    [], [], linestyle="None", marker="o", color=colour, ms=6)
    if cluster_positions is not None and len(cluster_positions):
        handles["cluster of singular sites (summed index)"] = Line2D([], [], linestyle="None", marker="o",
                                                                    markerfacecolor="none", color="red", ms=11)
    handles.update(marks)
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=min(3, len(handles)), fontsize=8,
               frameon=False)
    if mappable is not None:
        fig.colorbar(mappable, ax=fig.axes, shrink=0.6, label="|u| (Whitney ♯ at barycenters)")
    return fig


def _draw_clusters(ax, x, positions, indices, planar, view) -> None:
    """Open circles with the summed index beside them, on the visible side only."""
    if not planar:
        visible = (positions - x.mean(axis=0)) @ _view_direction(*view) > 0
        positions, indices = positions[visible], indices[visible]
    for p, i in zip(positions, indices):
        colour = "red" if i > 0 else "blue"
        if planar:
            ax.scatter([p[0]], [p[1]], s=220, facecolors="none", edgecolors=colour, linewidths=1.5, zorder=6)
            ax.annotate(f"{int(i):+d}", (p[0], p[1]), xytext=(8, 8), textcoords="offset points", color=colour)
        else:
            ax.scatter([p[0]], [p[1]], [p[2]], s=220, facecolors="none", edgecolors=colour, linewidths=1.5,
                       depthshade=False, zorder=6)
            ax.text(p[0], p[1], p[2], f" {int(i):+d}", color=colour, zorder=7)


#: arrows are drawn where |u| exceeds this fraction of the input's scale (2 × its 95th
#: percentile): a part of round-off size (energy ~1e-30) shows as an empty panel, not a field
ARROW_FLOOR = 1e-6


def hodge_parts_figure(K, vectors: dict, energy: dict, *, max_arrows: int = 500):
    """The input and its three Hodge parts side by side (arrows = direction, grey = |u|).

    ``vectors`` maps ``omega``/``exact``/``coexact``/``harmonic`` + ``_vectors`` to (n_top, 3)
    (per triangle, or per tetrahedron: :func:`draw_volume_field`), ``energy`` the parts to their
    energy share ‖part‖²/‖ω‖². On surfaces all panels share ω's grey scale (one colour bar)
    and draw arrows only where |u| > :data:`ARROW_FLOOR` × that scale, so a part that is zero
    to round-off is an empty panel; each title gives the energy share.
    """
    planar = is_planar(K.vertices)
    names = ("omega", "exact", "coexact", "harmonic")
    if K.dim == 3:
        fig = new_figure(4.0 * len(names), 4.4)
        for i, name in enumerate(names):
            ax = fig.add_subplot(1, len(names), i + 1, projection="3d", computed_zorder=False)
            share = "" if name == "omega" else f", {100 * energy.get(name, 0.0):.1f}% energy"
            draw_volume_field(ax, K, vectors[f"{name}_vectors"], max_arrows=max_arrows, title=f"{name}{share}")
        return fig
    fig = new_figure(4.0 * len(names) + 0.8, 4.4)
    scale = 2.0 * float(np.percentile(np.linalg.norm(vectors["omega_vectors"], axis=1), 95)) or 1.0
    axes, mappable = [], None
    for i, name in enumerate(names):
        ax = fig.add_subplot(1, len(names), i + 1, **({} if planar else {"projection": "3d", "computed_zorder": False}))
        share = energy.get(name, 0.0)
        label = ("" if name == "omega" else f", {100 * share:.1f}% energy" if share >= 1e-4 else
                 f", {100 * share:.1e}% energy" if share > ARROW_FLOOR ** 2 else
                 f"\n{100 * share:.0e}% energy: zero to round-off")
        m = draw_field(ax, K, vectors[f"{name}_vectors"], max_arrows=max_arrows, title=f"{name}{label}", vmax=scale,
                       min_magnitude=ARROW_FLOOR * scale)
        mappable = mappable or m
        axes.append(ax)
    if mappable is not None:
        fig.colorbar(mappable, ax=axes, shrink=0.6, label="|u| (one scale for all panels)")
    return fig


def draw_volume_field(ax, K, tet_vectors: np.ndarray, *, max_arrows: int = 500, title: str | None = None,
                      seed: int = 0, view=_VIEW):
    """A field inside a tetrahedral mesh: the border surface, translucent, coloured by |u| of
    the tetrahedron under each border triangle, and arrows of length ∝ |u| at a seeded subset
    of at most ``max_arrows`` tetrahedron barycenters."""
    from decrun.runner.plots.spectrum import border_triangles

    faces, owner = border_triangles(K)
    magnitude = np.linalg.norm(tet_vectors, axis=1)
    top = float(np.percentile(magnitude, 95)) or 1.0
    plot_surface(ax, K.vertices, faces, magnitude[owner], cmap="Greys", vmin=0.0, vmax=2.0 * top, linewidth=0.05,
                 title=title)
    for collection in ax.collections:
        collection.set_alpha(0.25)
    tets = K.simplices(3)
    chosen = np.arange(len(tets))
    if chosen.size > max_arrows:
        chosen = np.sort(np.random.default_rng(seed).choice(chosen, max_arrows, replace=False))
    centers = K.vertices[tets[chosen]].mean(axis=1)
    direction = tet_vectors[chosen] / top * 1.5 * K.mean_edge_length
    ax.quiver(*(centers - 0.5 * direction).T, *direction.T, color="tab:orange", linewidth=0.6,
              arrow_length_ratio=0.3, zorder=4)
    ax.view_init(*view)


def values_and_arrows(K, values: np.ndarray, vectors: np.ndarray, *, title: str | None = None,
                      colorbar_label: str | None = None, max_arrows: int = 600, seed: int = 0, view=_VIEW):
    """A scalar field in colour with a vector field's arrows over it (a model's ``plots``: Darcy's
    pressure and velocity). ``values``: per vertex (n0,) or per top simplex (n_n,); ``vectors``
    (n_n, d): one per top simplex, drawn at its barycentre with length ∝ |X| (the 95th percentile
    of |X| is 0.9 mean edge lengths), at most ``max_arrows`` of them (300 inside a volume; a seeded
    subset). Triangle
    meshes: the surface coloured (from above when planar); tetrahedral meshes: the border
    triangles, translucent, coloured by the value of the tetrahedron under each (or the vertex
    values), with arrows inside."""
    n = K.dim
    vectors = np.asarray(vectors, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    planar = n == 2 and is_planar(K.vertices)
    fig = new_figure(5.5, 5.0)
    ax = fig.add_subplot(1, 1, 1, **({} if planar else {"projection": "3d"}))
    if n == 3:
        from decrun.runner.plots.spectrum import border_triangles

        faces, owner = border_triangles(K)
        shown = values[owner] if values.shape[0] == K.num_simplices(3) else values
        mappable = plot_surface(ax, K.vertices, faces, shown, title=title, linewidth=0.05)
        for collection in ax.collections:
            collection.set_alpha(0.35)
        centres = K.vertices[K.simplices(3)].mean(axis=1)
    else:
        faces = K.oriented_simplices()
        mappable = plot_surface(ax, K.vertices if planar else embed3(K.vertices), faces, values, title=title,
                                linewidth=0.05)
        centres = (K.vertices if planar else embed3(K.vertices))[faces].mean(axis=1)
    magnitude = np.linalg.norm(vectors, axis=1)
    top = float(np.percentile(magnitude, 95)) if magnitude.size else 0.0
    chosen = np.flatnonzero(magnitude > 0)
    if n == 3:  # arrows inside a volume hide each other: fewer of them
        max_arrows = min(max_arrows, 300)
    if chosen.size > max_arrows:
        chosen = np.sort(np.random.default_rng(seed).choice(chosen, max_arrows, replace=False))
    if chosen.size and top > 0:
        direction = vectors[chosen] / top * 0.9 * K.mean_edge_length
        start = centres[chosen][:, : direction.shape[1]] - 0.5 * direction
        if planar:
            ax.quiver(start[:, 0], start[:, 1], direction[:, 0], direction[:, 1], angles="xy", scale_units="xy",
                      scale=1.0, color="white", edgecolor="black", linewidth=0.3, width=0.004, headwidth=4, zorder=4)
        else:
            start3, direction3 = embed3(start), embed3(direction)
            ax.quiver(*start3.T, *direction3.T, color="black", linewidth=0.6, arrow_length_ratio=0.3, zorder=4)
            ax.view_init(*view)
    if mappable is not None:
        fig.colorbar(mappable, ax=ax, shrink=0.6, label=colorbar_label)
    return fig
