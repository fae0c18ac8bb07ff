"""Figures of a parametrization: the uv layout coloured by angle distortion (flipped
triangles highlighted) and the checkerboard texture mapped back onto the mesh."""

from __future__ import annotations

import numpy as np

from decrun.runner.plots.common import new_figure, plot_surface

__all__ = ["uv_layout", "checkerboard", "view_direction", "edge_widths"]


def _warn(fig, warning: str) -> None:
    """``warning`` (e.g. "not an embedding: 16 flipped triangles") in red at the foot of the
    figure, wrapped to its width."""
    if warning:
        import textwrap

        fig.text(0.5, 0.01, textwrap.fill(warning, 70), ha="center", va="bottom", color="red", fontsize=8,
                 fontweight="bold")


def uv_layout(K, uv: np.ndarray, faces: np.ndarray, angle_distortion_deg: np.ndarray, flipped: np.ndarray, *,
              title: str = "", warning: str = "") -> "Figure":  # noqa: F821
    """uv (n0, 2) triangles coloured by the mean angle distortion per triangle (degrees), their
    edges drawn where they are wide enough to see (:func:`edge_widths`); flipped triangles
    drawn on top in cyan; ``warning`` (a map that is not an embedding) in red."""
    fig = new_figure(5.0, 5.0)
    ax = fig.add_subplot()
    mappable = plot_surface(ax, uv, faces, angle_distortion_deg, cmap="magma", vmin=0.0,
                            vmax=max(1.0, float(np.nanmax(angle_distortion_deg))), linewidth=0.15,
                            title=f"uv layout, {title}")
    surface = ax.collections[-1]
    seen = edge_widths(uv, faces, 4.0 * fig.dpi) > 0  # edges of sub-pixel triangles take their face colour
    surface.set_edgecolors(np.where(seen[:, None], np.array([0.35, 0.35, 0.35, 1.0]), surface.get_facecolors()))
    surface.set_linewidths(np.where(seen, 0.15, 0.3))
    flipped = np.asarray(flipped, dtype=bool)
    if flipped.any():
        plot_surface(ax, uv, faces[flipped], np.ones(int(flipped.sum())), cmap="cool", linewidth=0.3)
    fig.colorbar(mappable, ax=ax, shrink=0.7, label="angle distortion (deg, mean per triangle)")
    _warn(fig, warning)
    return fig


def edge_widths(uv: np.ndarray, faces: np.ndarray, pixels: float, width: float = 0.15,
                min_pixels: float = 10.0) -> np.ndarray:
    """(m,) line widths of the triangles' edges in a uv layout drawn ``pixels`` wide: ``width``
    where a triangle spans at least ``min_pixels`` (its size √(2·area) times pixels per uv
    unit), 0 below. A free or conformal border squeezes part of a surface into a small region
    of uv (the far side of a sphere with a hole into the centre): there the edges of
    sub-pixel triangles drew over their colours and turned the region flat grey (their
    edges take their face colour instead, closing the anti-aliasing seams)."""
    uv = np.asarray(uv, dtype=np.float64)
    p = uv[faces]
    a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    span = float(np.ptp(uv, axis=0).max()) if len(uv) else 0.0
    size = np.sqrt(2.0 * area) * (pixels / span if span > 0 else 0.0)
    return np.where(size >= min_pixels, width, 0.0)


def checker_square_size(vertices: np.ndarray, uv: np.ndarray, faces: np.ndarray, squares: int) -> float:
    """Side (uv units) of the checker squares so that where the map has its median scale a
    square covers about 1/``squares`` of √(mesh area) — ``squares`` per side on an
    isometric map of a square patch, and still visible where a conformal map shrinks most
    of the surface into a small part of [0, 1]² (its area distortion varies over decades).
    Triangles are coloured whole, so a square spans at least 4 median uv edge lengths
    (coarse meshes get fewer, larger squares instead of noise).

    scale_t = √(uv area_t / mesh area_t) per triangle;
    side = max(median(scale) · √A / squares, 4 · median uv edge length).
    """
    from decrun.core.geometry import triangle_areas

    mesh_area = triangle_areas(vertices, faces)
    uv_area = np.abs(triangle_areas(uv, faces))
    good = mesh_area > 0
    scale = np.sqrt(uv_area[good] / mesh_area[good])
    median = float(np.median(scale)) if scale.size else 1.0
    side = median * np.sqrt(mesh_area.sum()) / squares
    edges = np.linalg.norm(uv[faces] - uv[np.roll(faces, -1, axis=1)], axis=2)
    side = max(side, 4.0 * float(np.median(edges)))
    return side if side > 0 and np.isfinite(side) else 1.0 / squares


def checkerboard(K, uv: np.ndarray, faces: np.ndarray, *, squares: int = 10, title: str = "",
                 warning: str = "") -> "Figure":  # noqa: F821
    """The mesh textured with a checkerboard in uv (squares sized by
    :func:`checker_square_size`), shaded by the light so the shape stays readable, seen
    from :func:`view_direction` (an open patch from its convex side, a nearly closed
    surface from its hole); ``warning`` in red."""
    side = checker_square_size(K.vertices, uv, faces, squares)
    centroid = uv[faces].mean(axis=1)
    checker = (np.floor(centroid[:, 0] / side) + np.floor(centroid[:, 1] / side)) % 2
    fig = new_figure(5.0, 5.0)
    ax = fig.add_subplot(projection="3d" if K.vertices.shape[1] == 3 else None)
    plot_surface(ax, K.vertices, faces, checker, cmap="checker", vmin=0.0, vmax=1.0, shade=True,
                 title=f"checkerboard (square {side:.3g} in uv), {title}")
    if K.vertices.shape[1] == 3:
        towards = view_direction(K.vertices, faces, K.border_vertices())
        if towards is not None:
            ax.view_init(elev=float(np.degrees(np.arcsin(np.clip(towards[2], -1, 1)))),
                         azim=float(np.degrees(np.arctan2(towards[1], towards[0]))))
    _warn(fig, warning)
    return fig


#: |Σ area-weighted normals| / area below which a surface is nearly closed (a sphere with a hole)
NEARLY_CLOSED = 0.25


def view_direction(vertices: np.ndarray, faces: np.ndarray, border: np.ndarray) -> np.ndarray | None:
    """(3,) unit direction the camera looks from at a parametrized surface, or None.

    An open patch (a cap, a half sphere) is seen along its area-weighted mean normal
    N = Σ_t n_t |t| (its open side faces away). A nearly closed surface (|N| / Σ|t| <
    :data:`NEARLY_CLOSED`: a sphere with a small hole, Fig. 5.8's T) has N ≈ minus the hole's
    own normal — looking along it shows the side away from the hole, where the map is least
    interesting — so it is seen from its border: along (border centroid − surface centroid),
    the hole in front. ``border``: (n0,) bool, the border vertices."""
    p = np.asarray(vertices, dtype=np.float64)[faces]
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    normal, area = cross.sum(axis=0), float(np.linalg.norm(cross, axis=1).sum())
    border = np.asarray(border, dtype=bool)
    if border.any() and np.linalg.norm(normal) < NEARLY_CLOSED * area:
        normal = np.asarray(vertices)[border].mean(axis=0) - np.asarray(vertices)[np.unique(faces)].mean(axis=0)
    length = float(np.linalg.norm(normal))
    return normal / length if length > 0 else None
