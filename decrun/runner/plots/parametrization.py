"""Figures of a parametrization: the uv layout coloured by angle distortion (flipped
triangles highlighted) and the checkerboard texture mapped back onto the mesh."""

from __future__ import annotations

import numpy as np

from decrun.runner.plots.common import new_figure, plot_surface

__all__ = ["uv_layout", "checkerboard"]


def uv_layout(K, uv: np.ndarray, faces: np.ndarray, angle_distortion_deg: np.ndarray, flipped: np.ndarray, *,
              title: str = "") -> "Figure":  # noqa: F821
    """uv (n0, 2) triangles coloured by the mean angle distortion per triangle (degrees);
    flipped triangles drawn on top in cyan."""
    fig = new_figure(5.0, 5.0)
    ax = fig.add_subplot()
    mappable = plot_surface(ax, uv, faces, angle_distortion_deg, cmap="magma", vmin=0.0,
                            vmax=max(1.0, float(np.nanmax(angle_distortion_deg))), linewidth=0.15,
                            title=f"uv layout, {title}")
    flipped = np.asarray(flipped, dtype=bool)
    if flipped.any():
        plot_surface(ax, uv, faces[flipped], np.ones(int(flipped.sum())), cmap="cool", linewidth=0.3)
    fig.colorbar(mappable, ax=ax, shrink=0.7, label="angle distortion (deg, mean per triangle)")
    return fig


def checkerboard(K, uv: np.ndarray, faces: np.ndarray, *, squares: int = 10, title: str = "") -> "Figure":  # noqa: F821
    """The mesh textured with a ``squares`` × ``squares`` checkerboard in uv ∈ [0, 1]², seen
    along its area-weighted mean normal (the open side faces away)."""
    centroid = uv[faces].mean(axis=1)
    checker = (np.floor(centroid[:, 0] * squares) + np.floor(centroid[:, 1] * squares)) % 2
    fig = new_figure(5.0, 5.0)
    ax = fig.add_subplot(projection="3d" if K.vertices.shape[1] == 3 else None)
    plot_surface(ax, K.vertices, faces, checker, cmap="gray", vmin=-0.3, vmax=1.0, title=f"checkerboard, {title}")
    if K.vertices.shape[1] == 3:
        p = K.vertices[faces]
        normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]).sum(axis=0)
        if np.linalg.norm(normal) > 0:
            normal = normal / np.linalg.norm(normal)
            ax.view_init(elev=float(np.degrees(np.arcsin(np.clip(normal[2], -1, 1)))),
                         azim=float(np.degrees(np.arctan2(normal[1], normal[0]))))
    return fig
