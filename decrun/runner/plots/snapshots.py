"""Time series of per-vertex fields: a grid of snapshots and an animation (GIF).

Used by time-dependent applications (``app=fluid``: vorticity over time). The frames are the
series the run recorded with ``ctx.record`` (``recorded[name]``: (records, n0)), read from the
run's result file after the run, so memory during the run stays flat.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from decrun.core.geometry import is_planar
from decrun.runner.paths import check_file
from decrun.runner.plots.common import new_figure, plot_surface

__all__ = ["snapshot_grid", "animation"]


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


def _colours(frames: np.ndarray, cmap: str, symmetric: bool, percentile: float) -> tuple[str, bool, float, float, str]:
    """``(cmap, symmetric, lo, hi, extend)``: with ``cmap="auto"`` a field of both signs gets the
    diverging RdBu_r centred on 0 and a one-signed field viridis over its range (a diverging map
    would give a meaningless midpoint a colour of its own); ``extend`` marks the colour bar's
    ends where values lie beyond the limits (drawn in the end colours), so nothing beyond them
    passes unseen."""
    finite = frames[np.isfinite(frames)]
    if cmap == "auto":
        signed = bool(finite.size) and finite.min() < 0 < finite.max()
        cmap, symmetric = ("RdBu_r", True) if signed else ("viridis", False)
    lo, hi = _scale(frames, symmetric, percentile)
    below = bool(finite.size) and finite.min() < lo
    above = bool(finite.size) and finite.max() > hi
    extend = "both" if below and above else "min" if below else "max" if above else "neither"
    return cmap, symmetric, lo, hi, extend


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
    one shared colour scale (symmetric about 0 for signed fields such as vorticity) to the
    ``percentile`` of the values (100: their whole range), the colour bar's ends extended where
    values lie beyond it; ``cmap="auto"`` chooses by sign (:func:`_colours`). 3-D surfaces are
    seen from the direction ``towards`` (e.g. where they were stirred)."""
    frames = np.asarray(recorded[name])
    times = np.asarray(recorded[times_name]) if times_name else np.arange(len(frames))
    picks = np.unique(np.linspace(0, len(frames) - 1, min(count, len(frames))).round().astype(int))
    planar = is_planar(K.vertices)
    cols = min(3, len(picks))
    rows = int(np.ceil(len(picks) / cols))
    fig = new_figure(4.0 * cols, 3.6 * rows if planar else 4.0 * rows)
    cmap, symmetric, lo, hi, extend = _colours(frames[picks], cmap, symmetric, percentile)
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
    return fig


def animation(K, recorded, out_path, name: str = "vorticity", *, times_name: str = "time", fps: int = 12,
              max_frames: int = 120, cmap: str = "RdBu_r", title: str = "", symmetric: bool = True,
              towards=None, percentile: float = 95.0) -> Path:
    """An animated GIF of ``recorded[name]`` over time (at most ``max_frames`` evenly spaced
    frames, one colour scale as :func:`snapshot_grid`'s), written with matplotlib's Pillow
    writer to ``out_path``.gif."""
    from matplotlib.animation import FuncAnimation, PillowWriter

    frames = np.asarray(recorded[name])
    times = np.asarray(recorded[times_name]) if times_name else np.arange(len(frames))
    picks = np.unique(np.linspace(0, len(frames) - 1, min(max_frames, len(frames))).round().astype(int))
    planar = is_planar(K.vertices)
    cmap, symmetric, lo, hi, _ = _colours(frames[picks], cmap, symmetric, percentile)
    faces = K.oriented_simplices()
    fig = new_figure(5.0, 4.0 if planar else 5.0, dpi=90)
    ax = _axes(fig, 1, 1, 1, planar)

    def draw(index):
        ax.clear()
        plot_surface(ax, K.vertices, faces, frames[picks[index]], cmap=cmap, vmin=lo, vmax=hi, linewidth=0.0,
                     title=f"{title} t = {times[picks[index]]:.3g}".strip())
        _look_at(ax, towards)
        return []

    path = check_file(Path(out_path).with_suffix(".gif"))
    FuncAnimation(fig, draw, frames=len(picks), blit=False).save(path, writer=PillowWriter(fps=fps))
    return path
