"""Figures shared by the applications (matplotlib, no pyplot: figures are plain
``matplotlib.figure.Figure`` objects rendered by the Agg canvas when saved, so nothing
depends on a display or on global pyplot state).

- :func:`plot_surface` — one triangle mesh on an axes: 3-D (shaded or coloured by a
  per-vertex / per-face value) or 2-D (planar meshes, or a 3-D mesh seen from above).
- :func:`before_after` — two meshes with the same triangles side by side (e.g. noisy and
  smoothed), sharing a colour scale.
- :func:`plot_series` — per-step curves (``Result.series``).
"""

from __future__ import annotations

from typing import Iterable, Sequence

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.figure import Figure

from decrun.runner.results import read_result

#: two contrasting colours for checkerboard textures (0 → dark blue, 1 → light sand)
CHECKER = ListedColormap([(0.16, 0.27, 0.52), (0.98, 0.93, 0.80)], name="checker")


def new_figure(width: float = 8.0, height: float = 4.0, dpi: int = 110) -> Figure:
    """A Figure not attached to pyplot (no GUI, garbage-collected normally)."""
    return Figure(figsize=(width, height), dpi=dpi, layout="constrained")


def _face_values(values: np.ndarray, faces: np.ndarray, n_vertices: int) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    if values.shape[0] == len(faces) and values.shape[0] != n_vertices:
        return values
    if values.shape[0] == n_vertices:
        return values[faces].mean(axis=1)
    raise ValueError(f"values must have one entry per vertex ({n_vertices}) or per face ({len(faces)}), got {values.shape}")


#: above this many triangles, edge lines in the default colour are not drawn (they would cover the faces)
EDGE_LINES_MAX_FACES = 2000
#: width of a triangle's edge in its own colour: covers the seam between two neighbours (points)
SEAM_WIDTH = 0.3


def _edges(n_faces: int, edgecolor: str | None, linewidth: float, default: str) -> tuple[str, float]:
    """(edge colour, width) of :func:`plot_surface`: the edge lines asked for, or — no lines
    (``linewidth`` 0, or more than :data:`EDGE_LINES_MAX_FACES` faces in the default colour) —
    each face's own colour at :data:`SEAM_WIDTH`."""
    if linewidth > 0 and (edgecolor is not None or n_faces <= EDGE_LINES_MAX_FACES):
        return edgecolor or default, linewidth
    return "face", SEAM_WIDTH


def plot_surface(ax, vertices: np.ndarray, faces: np.ndarray, values: np.ndarray | None = None, *,
                 cmap: str = "viridis", vmin: float | None = None, vmax: float | None = None,
                 edgecolor: str | None = None, linewidth: float = 0.1, title: str | None = None,
                 light: Sequence[float] = (0.4, 0.3, 1.0), shade: bool = False):
    """Draw the triangles ``faces (m, 3)`` over ``vertices (n, 2|3)`` on ``ax``.

    ``ax`` is a 3-D axes (``fig.add_subplot(projection="3d")``) or a 2-D one; a 3-D mesh on
    a 2-D axes is drawn from above (x, y). ``values`` (per vertex, averaged to faces, or per
    face) colour the triangles with ``cmap`` (``"checker"``: two contrasting colours);
    without values the surface is grey with Lambert shading from the direction ``light``,
    and with ``shade`` the value colours are shaded too (3-D axes). Edge lines are drawn
    (``linewidth`` > 0) when ``edgecolor`` is given or the mesh has at most
    :data:`EDGE_LINES_MAX_FACES` triangles; otherwise each triangle's edge takes its own colour
    (:func:`_edges`) and 2-D faces are drawn without anti-aliasing, which closes the seams between
    neighbours — without it a fine grid shows a moiré of light lines. Returns the ScalarMappable (for a colorbar) or None.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    mappable = None
    if values is not None:
        face_values = _face_values(values, faces, len(vertices))
        finite = face_values[np.isfinite(face_values)]
        lo = vmin if vmin is not None else (finite.min() if finite.size else 0.0)
        hi = vmax if vmax is not None else (finite.max() if finite.size else 1.0)
        norm = Normalize(lo, hi if hi > lo else lo + 1.0)
        colour_map = CHECKER if cmap == "checker" else colormaps[cmap]
        colours = colour_map(norm(face_values))
        from matplotlib.cm import ScalarMappable

        mappable = ScalarMappable(norm=norm, cmap=colour_map)
    is_3d = getattr(ax, "name", "") == "3d"
    if is_3d:
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        v3 = vertices if vertices.shape[1] == 3 else np.column_stack([vertices, np.zeros(len(vertices))])
        triangles = v3[faces]
        if values is None or shade:
            normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
            length = np.linalg.norm(normal, axis=1, keepdims=True)
            normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
            direction = np.asarray(light, dtype=np.float64) / np.linalg.norm(light)
            lambert = 0.35 + 0.65 * np.abs(normal @ direction)
            base = np.tile([0.75, 0.78, 0.85], (len(faces), 1)) if values is None else colours[:, :3]
            colours = np.column_stack([lambert[:, None] * base, np.ones(len(faces))])
        edges, widths = _edges(len(faces), edgecolor, linewidth, "none")
        own = colours if edges == "face" else edges  # "face" fails in 3-D before the axes draw (matplotlib)
        collection = Poly3DCollection(triangles, facecolors=colours, edgecolors=own, linewidths=widths)
        ax.add_collection3d(collection)
        _share_limits([ax], [v3])  # a cube around the mesh: equal aspect
        ax.set_box_aspect((1, 1, 1))
        ax.set_axis_off()
    else:
        from matplotlib.collections import PolyCollection

        triangles = vertices[:, :2][faces]
        if values is None:
            colours = (0.8, 0.82, 0.88, 1.0)
        edges, widths = _edges(len(faces), edgecolor, linewidth, "0.35")
        collection = PolyCollection(triangles, facecolors=colours, edgecolors=edges, linewidths=widths,
                                    antialiaseds=edges != "face")  # no half-covered pixels along the seams
        ax.add_collection(collection)
        ax.autoscale_view()
        ax.set_aspect("equal")
        ax.set_axis_off()
    if title:
        ax.set_title(title, fontsize=9)
    return mappable


def before_after(vertices_before: np.ndarray, vertices_after: np.ndarray, faces: np.ndarray,
                 values_before: np.ndarray | None = None, values_after: np.ndarray | None = None, *,
                 titles: tuple[str, str] = ("before", "after"), suptitle: str | None = None,
                 cmap: str = "viridis", colorbar_label: str | None = None, share_axes: bool = True) -> Figure:
    """Figure with two panels: the mesh before and after (same ``faces``), same colour scale.

    Meshes with 3-D vertices are drawn in 3-D, planar ones in 2-D. With ``share_axes`` both
    panels show the same box (the union of both meshes' bounding boxes, equal aspect), so a
    result that shrank, exploded or moved looks like it — unless their extents differ more
    than :data:`SHARE_EXTENT_RATIO`-fold: then the smaller one would be a dot, so each panel
    gets its own box and the larger one's title says by how much.
    """
    three_d = np.asarray(vertices_before).shape[1] == 3
    fig = new_figure(8.0, 4.0)
    kwargs = {"projection": "3d"} if three_d else {}
    axes = [fig.add_subplot(1, 2, i + 1, **kwargs) for i in range(2)]
    vmin = vmax = None
    if values_before is not None and values_after is not None:
        both = np.concatenate([np.ravel(values_before), np.ravel(values_after)])
        both = both[np.isfinite(both)]
        if both.size:
            vmin, vmax = float(both.min()), float(both.max())
    mappable = None
    for ax, vertices, values, title in zip(axes, (vertices_before, vertices_after), (values_before, values_after), titles, strict=True):
        m = plot_surface(ax, vertices, faces, values, cmap=cmap, vmin=vmin, vmax=vmax, title=title)
        mappable = mappable or m
    sets = [np.asarray(vertices_before), np.asarray(vertices_after)]
    ratio = _extent_ratio(*sets)
    if share_axes and ratio <= SHARE_EXTENT_RATIO:
        _share_limits(axes, sets)
    elif share_axes:  # one would be a dot beside the other: each on its own box, said in the title
        for ax, vertices in zip(axes, sets, strict=True):
            _share_limits([ax], [vertices])
        bigger = int(_extent(sets[1]) > _extent(sets[0]))
        axes[bigger].set_title(f"{titles[bigger]}\n(own scale: {ratio:.3g}× the other's extent)", fontsize=9)
    if mappable is not None:
        fig.colorbar(mappable, ax=axes, shrink=0.6, label=colorbar_label)
    if suptitle:
        fig.suptitle(suptitle, fontsize=10)
    return fig


#: with ``share_axes``, meshes whose extents differ more than this factor get their own boxes
SHARE_EXTENT_RATIO = 20.0


def _extent(vertices: np.ndarray) -> float:
    """Largest side of the bounding box of the finite vertices (0 when there are none)."""
    finite = vertices[np.isfinite(vertices).all(axis=1)]
    return float((finite.max(axis=0) - finite.min(axis=0)).max()) if len(finite) else 0.0


def _extent_ratio(a: np.ndarray, b: np.ndarray) -> float:
    """max/min of the two meshes' extents (inf when one is a point or empty)."""
    small, large = sorted((_extent(a), _extent(b)))
    return large / small if small > 0 else float("inf")


def _share_limits(axes, vertex_sets) -> None:
    """Give every axes the same cube (3-D) or rectangle (2-D): the union of the finite
    vertices' bounding boxes."""
    points = np.concatenate([v[np.isfinite(v).all(axis=1)] for v in vertex_sets])
    if not len(points):
        return
    lo, hi = points.min(axis=0), points.max(axis=0)
    center, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-12)
    for ax in axes:
        ax.set_xlim(center[0] - half, center[0] + half)
        ax.set_ylim(center[1] - half, center[1] + half)
        if getattr(ax, "name", "") == "3d":
            ax.set_zlim(center[2] - half, center[2] + half)


def surface_figure(vertices: np.ndarray, faces: np.ndarray, values: np.ndarray | None = None, *,
                   title: str | None = None, cmap: str = "viridis", colorbar_label: str | None = None) -> Figure:
    """One mesh (3-D or planar), optionally coloured by per-vertex or per-face ``values``; a
    planar mesh (also one given with z = 0) is drawn from above, not in perspective. With
    ``cmap="auto"`` values of both signs (an error, a signed field) get the diverging RdBu_r
    centred on 0 (white is 0), one-signed values viridis over their range."""
    from decrun.core.geometry import is_planar

    vmin = vmax = None
    if cmap == "auto":
        finite = np.asarray(values, dtype=np.float64) if values is not None else np.zeros(0)
        finite = finite[np.isfinite(finite)]
        cmap = "viridis"
        if finite.size and finite.min() < 0 < finite.max():
            cmap, vmax = "RdBu_r", float(np.abs(finite).max())
            vmin = -vmax
    fig = new_figure(5.0, 5.0)
    ax = fig.add_subplot(1, 1, 1, **({} if is_planar(np.asarray(vertices)) else {"projection": "3d"}))
    mappable = plot_surface(ax, vertices, faces, values, cmap=cmap, vmin=vmin, vmax=vmax, title=title)
    if mappable is not None:
        fig.colorbar(mappable, ax=ax, shrink=0.6, label=colorbar_label)
    return fig


def mesh_values(K, values: np.ndarray, *, title: str | None = None, cmap: str = "viridis",
                colorbar_label: str | None = None) -> Figure:
    """The complex's surface (its top simplices as oriented) coloured by per-vertex or per-face
    ``values`` (a 0-form or a dual 0-form): :func:`surface_figure` on ``K``."""
    return surface_figure(K.vertices, K.oriented_simplices(), values, title=title, cmap=cmap,
                          colorbar_label=colorbar_label)


def plot_series(series: dict[str, np.ndarray], names: Iterable[str] | None = None, *,
                xlabel: str = "step", relative: bool = True, title: str | None = None,
                floors: dict[str, tuple[float, str]] | None = None) -> Figure:
    """One figure with the per-step curves ``series[name]`` (divided by their first value
    when ``relative``); ``floors`` maps a curve's name to ``(value, label)``: a bound the
    curve cannot cross (on the same scale as it is drawn), dashed in its colour and named
    with its value in the legend — a finite positive value only. The legend sits under the
    axes, never over a curve (the figure grows by a line per entry)."""
    fig = new_figure(5.0, 3.2)
    ax = fig.add_subplot(1, 1, 1)
    for name in names or series:
        y = np.asarray(series[name], dtype=np.float64)
        if relative and y.size and np.isfinite(y[0]) and y[0] != 0:
            y = y / y[0]
        line, = ax.plot(np.arange(len(y)), y, label=name + (" / initial" if relative else ""))
        value, label = (floors or {}).get(name, (float("nan"), ""))
        if np.isfinite(value) and value > 0:
            ax.axhline(value, color=line.get_color(), linestyle="--", linewidth=1.0, label=f"{label} = {value:.3g}")
    ax.set_xlabel(xlabel)
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    fig.set_size_inches(5.0, 3.2 + 0.17 * len(labels))
    fig.legend(handles, labels, fontsize=8, loc="outside lower center", frameon=False)
    if title:
        ax.set_title(title, fontsize=9)
    return fig


def recorded_series(recorded, names: Iterable[str], *, times_name: str = "time", title: str | None = None) -> Figure:
    """The recorded per-step numbers ``names`` (e.g. a model's metrics) against ``times_name``,
    one panel each (their own scales: a mass conserved to round-off and an energy decaying by
    orders of magnitude share no axis)."""
    names = list(names)
    times = np.asarray(recorded[times_name], dtype=np.float64)
    fig = new_figure(4.2 * min(len(names), 3), 3.0 * int(np.ceil(len(names) / 3)))
    fig.set_layout_engine("constrained")
    for i, name in enumerate(names):
        ax = fig.add_subplot(int(np.ceil(len(names) / 3)), min(len(names), 3), i + 1)
        ax.plot(times, np.asarray(recorded[name], dtype=np.float64), marker="." if len(times) < 40 else None)
        ax.set_xlabel(times_name)
        ax.set_title(name, fontsize=9)
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


def save_figure(fig: Figure, path, dpi: int | None = None) -> None:
    """Save ``fig`` as PNG through the Agg canvas (works without any display), under a
    temporary name renamed onto ``path`` when complete; refused
    (:class:`~decrun.runner.io.paths.OutsideError`) when ``path`` is a symlink leaving its directory."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from decrun.runner.io.atomic import atomic_path

    FigureCanvasAgg(fig)
    with atomic_path(path) as temporary:  # renamed when complete: an interrupt leaves no truncated PNG
        fig.savefig(temporary, dpi=dpi or fig.dpi, format="png")


class RecordedSeries:
    """The series a run recorded with ``ctx.record``, read on first use from the run's
    ``result.h5`` or its journal (a mapping name → (records, *shape) array)."""

    def __init__(self, path, series: dict | None = None):
        self.path, self._series = path, series

    def __getitem__(self, name: str):
        if self._series is None:
            self._series = read_result(self.path).series
        return self._series[name]


def draw_figures(figures: dict, out_dir, K=None, series: dict | None = None) -> list:
    """Draw the :class:`decrun.apps.base.Figure` descriptions of a result into ``out_dir``:
    ``<name>.png`` for each (a drawing function may instead write its own file, e.g. an
    animation, and return its path). A drawing function may take ``K`` (the complex),
    ``recorded`` (:class:`RecordedSeries`: the series recorded during the run — ``series``
    when given, else read from ``out_dir/result.h5`` or its journal) and ``out_path``.
    Returns the written paths."""
    import importlib
    import inspect
    from pathlib import Path

    from decrun.runner.io.files import RunFiles

    files = RunFiles(out_dir)
    recorded = RecordedSeries(files.result, series)
    written = []
    for name, figure in figures.items():
        from decrun.runner.plots import FIGURE_KINDS

        module_name, _, function_name = FIGURE_KINDS.get(figure.draw, figure.draw).rpartition(".")
        draw = getattr(importlib.import_module(module_name), function_name)
        data = dict(figure.data)
        parameters = inspect.signature(draw).parameters
        if "K" in parameters:
            data["K"] = K
        if "recorded" in parameters:
            data["recorded"] = recorded
        if "out_path" in parameters:
            data["out_path"] = Path(out_dir) / name
        made = draw(**data)
        if isinstance(made, (str, Path)):
            written.append(Path(made))
        else:
            path = files.figure(name)
            save_figure(made, path)
            written.append(path)
    return written
