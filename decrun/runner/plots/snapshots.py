"""Time series of per-vertex fields: a grid of snapshots and an animation (GIF).

Used by time-dependent applications (``app=fluid``: vorticity over time). The frames are the
series the run recorded with ``ctx.record`` (``recorded[name]``: (records, n0)), read from the
run's result file after the run, so memory during the run stays flat.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from decrun.core.geometry import is_planar
from decrun.runner.io.paths import check_file
from decrun.runner.plots.common import new_figure, plot_surface

__all__ = ["snapshot_grid", "animation", "colour_scale"]


def _scale(frames: np.ndarray, symmetric: bool, percentile: float = 95.0) -> tuple[float, float]:
    """Colour limits: the ``percentile`` of |values| (symmetric) or of the values, over all
    frames — the thin, strong layers at no-slip walls would otherwise wash out the wake;
    ``percentile`` 100: the whole range, zeros included."""
    finite = frames[np.isfinite(frames)]
    if percentile >= 100.0 and finite.size:
        hi = float(np.abs(finite).max()) if symmetric else float(finite.max())
        lo = -hi if symmetric else float(finite.min())
        return (lo, hi) if hi > lo else (lo - 1.0, lo + 1.0)
    nonzero = finite[finite != 0]
    finite = nonzero if nonzero.size else finite
    if not finite.size:
        return -1.0, 1.0
    hi = float(np.percentile(np.abs(finite), percentile)) if symmetric else float(np.percentile(finite, percentile))
    lo = -hi if symmetric else float(np.percentile(finite, 100.0 - percentile))
    return (lo, hi) if hi > lo else (lo - 1.0, lo + 1.0)


def _axes(fig, rows, cols, index, planar):
    return fig.add_subplot(rows, cols, index, **({} if planar else {"projection": "3d"}))


def _look_at(ax, towards):
    """Turn a 3-D axes to look at the surface from the direction ``towards`` (3,)."""
    if towards is not None and getattr(ax, "name", "") == "3d":
        x, y, z = np.asarray(towards, dtype=np.float64) / (np.linalg.norm(towards) or 1.0)
        ax.view_init(elev=float(np.degrees(np.arcsin(np.clip(z, -1, 1)))), azim=float(np.degrees(np.arctan2(y, x))))


def snapshot_grid(K, recorded, name: str = "vorticity", *, count: int = 6, times_name: str = "time",
                  cmap: str = "RdBu_r", title: str = "", symmetric: bool = True, towards=None,
                  percentile: float = 95.0):
    """``count`` evenly spaced recorded frames of ``recorded[name]`` (records, n0) side by side,
    one shared colour scale (:func:`colour_scale`: symmetric about 0 for signed fields such as
    vorticity, to the ``percentile`` of the values — 100: their whole range — at the interior
    vertices, said under the figure), the colour bar's ends extended where values lie beyond it;
    ``cmap="auto"`` chooses by sign. 3-D surfaces are seen from the direction ``towards`` (e.g.
    where they were stirred)."""
    frames = np.asarray(recorded[name])
    times = np.asarray(recorded[times_name]) if times_name else np.arange(len(frames))
    picks = np.unique(np.linspace(0, len(frames) - 1, min(count, len(frames))).round().astype(int))
    planar = is_planar(K.vertices)
    cols = min(3, len(picks))
    rows = int(np.ceil(len(picks) / cols))
    fig = new_figure(4.0 * cols, 3.6 * rows if planar else 4.0 * rows)
    cmap, lo, hi, extend, note = colour_scale(K, frames[picks], name, cmap, symmetric, percentile)
    faces = K.oriented_simplices()
    mappable = None
    for slot, index in enumerate(picks):
        ax = _axes(fig, rows, cols, slot + 1, planar)
        mappable = plot_surface(ax, K.vertices, faces, frames[index], cmap=cmap, vmin=lo, vmax=hi, linewidth=0.0,
                                title=f"t = {times[index]:.3g}") or mappable
        _look_at(ax, towards)
    fig.colorbar(mappable, ax=fig.axes, shrink=0.7, label=name, extend=extend)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.supxlabel(note, fontsize=8)
    return fig


def colour_scale(K, frames: np.ndarray, name: str, cmap: str = "RdBu_r", symmetric: bool = True,
                 percentile: float = 95.0) -> tuple[str, float, float, str, str]:
    """``(cmap, lo, hi, extend, note)`` for ``frames`` (F, n0): with ``cmap="auto"`` a field of
    both signs gets the diverging RdBu_r centred on 0 and a one-signed field viridis over its
    range (a diverging map would give a meaningless midpoint a colour of its own); the limits
    are :func:`_scale` of the values at interior vertices when the mesh has a border (the thin
    layers at walls and the odd-even pattern at an outflow border would otherwise set them);
    ``extend`` marks the colour bar's ends where values lie beyond (drawn in the end colours);
    ``note`` is one line saying how the limits were chosen and what lies beyond, for the figure."""
    frames = np.asarray(frames, dtype=np.float64)
    finite = frames[np.isfinite(frames)]
    if cmap == "auto":
        signed = bool(finite.size) and finite.min() < 0 < finite.max()
        cmap, symmetric = ("RdBu_r", True) if signed else ("viridis", False)
    interior = np.ones(frames.shape[1], dtype=bool)
    border = np.flatnonzero(K.border_vertices())
    interior[border] = False
    inside = frames[:, interior] if interior.any() else frames
    lo, hi = _scale(inside, symmetric, percentile)
    where = "the interior vertices (the border's left out)" if border.size else "all vertices"
    if percentile >= 100.0:
        rule = f"±{hi:.3g} = max |{name}|" if symmetric else f"{lo:.3g} … {hi:.3g} = the range of {name}"
    else:
        rule = (f"±{hi:.3g} = the {percentile:g}th percentile of |{name}|" if symmetric else
                f"{lo:.3g} … {hi:.3g} = the {100 - percentile:g}th … {percentile:g}th percentiles of {name}")
    below, above = bool(finite.size) and finite.min() < lo, bool(finite.size) and finite.max() > hi
    extend = "both" if below and above else "min" if below else "max" if above else "neither"
    outside = (finite > hi) | (finite < lo)
    if outside.any():
        largest = float(np.abs(finite).max())
        at = ""
        if border.size:
            at = " at the border" if np.abs(frames[:, border]).max() >= largest else " inside"
        rest = f"; {outside.mean():.1%} of the values lie beyond (up to {largest:.3g}{at}), in the end colours"
    else:
        rest = "; no value lies beyond"
    return cmap, lo, hi, extend, f"colours: {rule} at {where} over these frames{rest}"


def animation(K, recorded, out_path, name: str = "vorticity", *, times_name: str = "time", fps: int = 10,
              max_frames: int = 60, cmap: str = "RdBu_r", title: str = "", symmetric: bool = True,
              towards=None, percentile: float = 95.0) -> Path:
    """An animated GIF of ``recorded[name]`` over time: at most ``max_frames`` evenly spaced
    frames, one colour scale as :func:`snapshot_grid`'s, shown at ``fps`` frames per second;
    returns ``out_path``.gif.

    The surface is built once and only its face colours and the title change from frame to
    frame; each frame is rendered by the Agg canvas and quantised by Pillow to the palette of
    the first frame (the colour map's colours). The GIF is written to a hidden temporary name
    beside ``out_path`` and renamed onto it when complete: an interrupted drawing (SIGTERM,
    Ctrl-C) leaves no truncated GIF."""
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import Normalize
    from PIL import Image

    from decrun.runner.io.atomic import atomic_path
    from decrun.runner.plots.common import CHECKER

    frames = np.asarray(recorded[name])
    times = np.asarray(recorded[times_name]) if times_name else np.arange(len(frames))
    picks = np.unique(np.linspace(0, len(frames) - 1, min(max_frames, len(frames))).round().astype(int))
    planar = is_planar(K.vertices)
    cmap, lo, hi, _, _ = colour_scale(K, frames[picks], name, cmap, symmetric, percentile)
    faces = K.oriented_simplices()
    fig = new_figure(5.0, 4.0 if planar else 5.0, dpi=90)
    canvas = FigureCanvasAgg(fig)
    ax = _axes(fig, 1, 1, 1, planar)
    plot_surface(ax, K.vertices, faces, frames[picks[0]], cmap=cmap, vmin=lo, vmax=hi, linewidth=0.0, title=" ")
    _look_at(ax, towards)
    surface = ax.collections[-1]
    colour_map = CHECKER if cmap == "checker" else colormaps[cmap]
    norm = Normalize(lo, hi)
    images, palette = [], None
    for index in picks:
        surface.set_facecolor(colour_map(norm(frames[index][faces].mean(axis=1))))
        ax.set_title(f"{title} t = {times[index]:.3g}".strip(), fontsize=9)
        canvas.draw()
        image = Image.fromarray(np.asarray(canvas.buffer_rgba())[..., :3])
        if palette is None:
            palette = image.quantize(colors=255)
        images.append(image.quantize(palette=palette, dither=Image.Dither.NONE))
    path = check_file(Path(out_path).with_suffix(".gif"))
    with atomic_path(path) as temporary:
        images[0].save(temporary, format="GIF", save_all=True, append_images=images[1:], loop=0,
                       duration=int(round(1000 / fps)))
    return path
