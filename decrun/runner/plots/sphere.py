"""Longitude–latitude maps of fields on a sphere mesh, as the shallow-water papers draw them
(Williamson et al. 1992; Galewsky et al. 2004): filled contours with contour lines on the
equirectangular projection (1° of longitude as wide as 1° of latitude), graticules every 30°
labelled in degrees and no coastlines, a colour bar with the unit, and the time in days.

- :func:`sphere_map` — one field (per vertex, or per triangle such as the relative vorticity);
- :func:`error_map` — a field minus a reference (h − h_T), with Williamson's normalized l2 and
  l∞ errors (eq. 83–84) in the title.

Signed fields (vorticity, errors) get the diverging RdBu_r centred on 0 (white is 0), one-signed
ones the sequential viridis. The values are resampled on a regular grid by
:mod:`.lonlat` (linear interpolation in the triangle holding each grid point).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from matplotlib.ticker import MaxNLocator

from decrun.runner.plots.common import new_figure
from decrun.runner.plots.lonlat import lonlat_grid, regrid, sphere_radius

__all__ = ["sphere_map", "error_map", "contour_levels", "mapped", "DAY_SECONDS", "MAX_LEVELS"]

DAY_SECONDS = 86400.0
#: more contour levels than this is a mistake (an interval far below the range), not a picture
MAX_LEVELS = 200
#: graticule spacing (degrees)
GRATICULE = 30.0


def contour_levels(values: np.ndarray, signed: bool, levels: Sequence[float] | None = None,
                   value_range: Sequence[float] | None = None, interval: float | None = None) -> np.ndarray:
    """The contour levels (increasing): ``levels`` as given; ``value_range`` (lo, hi) cut every
    ``interval`` (lo, lo + interval, …, hi) or in 10 equal steps; ``interval`` alone: its
    multiples covering the finite ``values`` (symmetric about 0 when ``signed``); nothing: about
    12 round levels over the values' range (symmetric when ``signed``). ValueError beyond
    :data:`MAX_LEVELS` levels."""
    finite = np.asarray(values, dtype=np.float64)
    finite = finite[np.isfinite(finite)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 0.0)
    if signed:
        lo, hi = -max(abs(lo), abs(hi)), max(abs(lo), abs(hi))
    result: np.ndarray
    if levels is not None:
        result = np.asarray(levels, dtype=np.float64)
    elif value_range is not None:
        start, stop = (float(v) for v in value_range)
        steps = 10 if interval is None else int(round((stop - start) / interval))
        result = np.linspace(start, stop, steps + 1)
    elif interval is not None:
        first, last = np.floor(lo / interval), np.ceil(hi / interval)
        if last - first > MAX_LEVELS:
            raise ValueError(f"interval {interval:g} cuts the values' range {lo:.4g} … {hi:.4g} into "
                             f"{int(last - first)} levels (at most {MAX_LEVELS}); give a larger interval")
        result = interval * np.arange(first, max(last, first + 1) + 1)
    else:
        if hi <= lo:  # a constant field: one band around its value
            spread = max(abs(lo), 1.0) * 1e-3 if lo != 0 or not signed else 1.0
            lo, hi = lo - spread, hi + spread
        result = np.asarray(MaxNLocator(nbins=12, symmetric=signed).tick_values(lo, hi), dtype=np.float64)  # covers [lo, hi]
    if len(result) > MAX_LEVELS + 1 or len(result) < 2:
        raise ValueError(f"{len(result)} contour levels; a map needs 2 … {MAX_LEVELS + 1}")
    return result


def _degrees(value: float, east: str, west: str) -> str:
    """A graticule label: 30°E, 150°W, 0°, 180° (longitudes wrapped to (−180, 180])."""
    value = float(value)
    if east == "E":
        value = (value + 180.0) % 360.0 - 180.0
        value = 180.0 if value == -180.0 else value
    text = f"{abs(value):g}°"
    if value == 0 or (east == "E" and abs(value) == 180.0):
        return text
    return text + (east if value > 0 else west)


def _graticule(ax, longitudes: np.ndarray, latitudes: np.ndarray) -> None:
    """Lines and labels every :data:`GRATICULE` degrees inside the map's window."""
    lon_ticks = np.arange(np.ceil(longitudes[0] / GRATICULE), np.floor(longitudes[-1] / GRATICULE) + 1) * GRATICULE
    lat_ticks = np.arange(np.ceil(latitudes[0] / GRATICULE), np.floor(latitudes[-1] / GRATICULE) + 1) * GRATICULE
    ax.set_xticks(lon_ticks, [_degrees(v, "E", "W") for v in lon_ticks])
    ax.set_yticks(lat_ticks, [_degrees(v, "N", "S") for v in lat_ticks])
    ax.grid(True, color="0.35", linewidth=0.5, linestyle=":")
    ax.tick_params(labelsize=8, length=2)
    ax.set_xlim(longitudes[0], longitudes[-1])
    ax.set_ylim(latitudes[0], latitudes[-1])
    ax.set_aspect("equal")


def _when(time: float | None, time_unit: str) -> str:
    """``day 6`` for a time in seconds (``time_unit="s"``), ``t = 0.2`` otherwise, or nothing."""
    if time is None:
        return ""
    if time_unit == "s":
        return f"day {round(time / DAY_SECONDS, 3):g}"
    return f"t = {time:.4g}"


def mapped(K, values: np.ndarray, latitudes=(-90.0, 90.0), center_longitude: float = 0.0,
           resolution: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(longitudes (nx,), latitudes (ny,), grid (ny, nx))``: the per-vertex or per-triangle
    ``values`` on the sphere mesh of the complex ``K`` interpolated on the regular grid
    (:func:`.lonlat.lonlat_grid`, degrees). ValueError unless K is a triangle mesh on a
    sphere centred at the origin."""
    vertices = np.asarray(K.vertices, dtype=np.float64)
    if K.dim != 2 or sphere_radius(vertices) is None:
        raise ValueError("a longitude–latitude map needs a triangle mesh on a sphere centred at the origin "
                         "(e.g. the icosphere without noise)")
    longitudes, lats = lonlat_grid(latitudes, center_longitude, resolution)
    return longitudes, lats, regrid(vertices, K.simplices(2), values, longitudes, lats)


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _scaled(levels: np.ndarray) -> tuple[float, str]:
    """``(factor, text)``: colour-bar ticks are shown as value / factor and the label says
    ``10⁻⁵`` — for levels of magnitude below 1e-3 or above 1e5 (vorticity in s⁻¹), else (1, "")."""
    top = float(np.abs(levels).max())
    exponent = int(np.floor(np.log10(top))) if top > 0 else 0
    if -3 <= exponent <= 4:
        return 1.0, ""
    return 10.0 ** exponent, f"10{str(exponent).translate(_SUPERSCRIPT)}"


def _band_colours(levels: np.ndarray, signed: bool) -> list:
    """One colour per band between consecutive ``levels``: the colour map at the band's middle
    (RdBu_r symmetric about 0 when ``signed``, else viridis over the levels); a signed field's
    bands next to 0 are white, so that a zero background (outside a jet) is not painted as
    weakly negative or positive."""
    from matplotlib import colormaps

    middles = 0.5 * (levels[1:] + levels[:-1])
    if not signed:
        return [colormaps["viridis"](v) for v in np.linspace(0.0, 1.0, len(middles))]
    reach = max(abs(levels[0]), abs(levels[-1]))
    colours = [colormaps["RdBu_r"](0.5 + 0.5 * m / reach) for m in middles]
    for i in range(len(middles)):
        if levels[i] == 0 or levels[i + 1] == 0:
            colours[i] = (1.0, 1.0, 1.0, 1.0)
    return colours


def _draw(longitudes, latitudes, grid, levels, signed: bool, name: str, unit: str, title: str, outline=None):
    """The figure: filled contours at ``levels`` (the colour bar's ends extended, in the end
    colours, where values lie beyond), thin contour lines (negative ones dashed; the zero line of
    a signed field left to the colours, as the papers do), the graticule, the colour bar labelled
    ``name (unit)`` (``name (10⁻⁵ unit)`` for tiny or huge values) and, with ``outline = (grid, levels, text)``, that field's contours in grey, said in
    the title."""
    from matplotlib.colors import ListedColormap

    width_deg, height_deg = longitudes[-1] - longitudes[0], latitudes[-1] - latitudes[0]
    wide = width_deg / height_deg > 2.2
    width = 8.0 if wide else 9.0
    plot_width = width - (0.7 if wide else 1.6)  # the latitude labels; a vertical colour bar
    fig = new_figure(width, plot_width * height_deg / width_deg + (1.4 if wide else 1.0))
    ax = fig.add_subplot(1, 1, 1)
    finite = grid[np.isfinite(grid)]
    below = bool(finite.size) and finite.min() < levels[0]
    above = bool(finite.size) and finite.max() > levels[-1]
    extend = "both" if below and above else "min" if below else "max" if above else "neither"
    colours = _band_colours(levels, signed)
    cmap = ListedColormap(colours).with_extremes(under=colours[0], over=colours[-1])
    filled = ax.contourf(longitudes, latitudes, grid, levels=levels, cmap=cmap, extend=extend)
    lines = levels[levels != 0] if signed else levels
    if len(lines):
        ax.contour(longitudes, latitudes, grid, levels=lines, colors="k", linewidths=0.45)
    if outline is not None:
        ax.contour(longitudes, latitudes, outline[0], levels=outline[1], colors="0.25", linewidths=0.9,
                   linestyles="--")
        title = f"{title}\n{outline[2]}"
    _graticule(ax, longitudes, latitudes)
    ax.set_xlabel("longitude", fontsize=8)
    ax.set_ylabel("latitude", fontsize=8)
    factor, power = _scaled(levels)
    bar = fig.colorbar(filled, ax=ax, orientation="horizontal" if wide else "vertical",
                       shrink=0.7 if wide else 0.9, aspect=40 if wide else 25, pad=0.02)
    from matplotlib.ticker import FuncFormatter

    bar.formatter = FuncFormatter(lambda value, _: f"{value / factor:g}")
    bar.update_ticks()
    scale = " ".join(part for part in (power, unit) if part)
    bar.set_label(f"{name} ({scale})" if scale else name, fontsize=9)
    bar.ax.tick_params(labelsize=8)
    ax.set_title(title, fontsize=10)
    return fig


def sphere_map(K, values: np.ndarray, *, name: str = "", title: str = "", unit: str = "",
               time: float | None = None, time_unit: str = "s", levels: Sequence[float] | None = None,
               value_range: Sequence[float] | None = None, interval: float | None = None,
               latitudes: Sequence[float] = (-90.0, 90.0), center_longitude: float = 0.0,
               resolution: float = 0.5, outline: np.ndarray | None = None, outline_name: str = ""):
    """The longitude–latitude map of ``values`` — one per vertex (a 0-form, a depth per dual
    cell) or one per triangle (a dual 0-form: the relative vorticity) of the sphere mesh ``K`` —
    over ``latitudes`` (south, north; degrees) and 360° of longitude centred on
    ``center_longitude``, resampled every ``resolution`` degrees. Contour levels:
    :func:`contour_levels` (``levels``, or ``value_range`` cut every ``interval``). The title is
    ``title`` (default ``name``) with the ``time`` (seconds when ``time_unit="s"``: shown in
    days); the colour bar says ``name (unit)``. ``outline`` (same places as ``values``, e.g. the
    mountain b under a free surface) is drawn as dashed grey contours at a few round levels
    strictly inside its range, named in the title."""
    longitudes, lats, grid = mapped(K, values, latitudes, center_longitude, resolution)
    finite = grid[np.isfinite(grid)]
    signed = bool(finite.size) and finite.min() < 0 < finite.max()
    chosen = contour_levels(grid, signed, levels, value_range, interval)
    signed = signed or chosen[0] < 0 < chosen[-1]
    when = _when(time, time_unit)
    heading = ", ".join(part for part in (title or name, when) if part)
    drawn = None
    if outline is not None:
        outline_grid = mapped(K, outline, latitudes, center_longitude, resolution)[2]
        drawn = (outline_grid, *_outline_levels(np.asarray(outline, dtype=np.float64), outline_name, unit))
    return _draw(longitudes, lats, grid, chosen, signed, name, unit, heading, drawn)


def _outline_levels(values: np.ndarray, name: str, unit: str) -> tuple[np.ndarray, str]:
    """About four round levels strictly inside the range of ``values`` and the line saying so."""
    finite = values[np.isfinite(values)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 0.0)
    levels = np.asarray(MaxNLocator(nbins=4).tick_values(lo, hi) if hi > lo else [], dtype=np.float64)
    levels = levels[(levels > lo) & (levels < hi)]
    listed = ", ".join(f"{v:g}" for v in levels)
    return levels, (f"dashed: {name} = {listed}" + (f" {unit}" if unit else "")) if levels.size else \
        f"{name} is constant ({lo:g}): no outline"


def error_map(K, values: np.ndarray, reference: np.ndarray, areas: np.ndarray, *, name: str = "",
              reference_name: str = "", title: str = "", unit: str = "", time: float | None = None,
              time_unit: str = "s", levels: Sequence[float] | None = None,
              value_range: Sequence[float] | None = None, interval: float | None = None,
              latitudes: Sequence[float] = (-90.0, 90.0), center_longitude: float = 0.0,
              resolution: float = 0.5):
    """The map of ``values − reference`` (same places: per vertex or per triangle) in the
    diverging colours centred on 0, titled with Williamson's normalized errors over the cells
    of ``areas`` (the same places' areas): l2 = √(Σ A e²)/√(Σ A r²), l∞ = max|e|/max|r|
    (eq. 83–84). Other options as :func:`sphere_map`."""
    values, reference = np.asarray(values, dtype=np.float64), np.asarray(reference, dtype=np.float64)
    areas = np.asarray(areas, dtype=np.float64)
    if not (values.shape == reference.shape == areas.shape):
        raise ValueError(f"values {values.shape}, reference {reference.shape} and areas {areas.shape} must have "
                         "one entry per cell each")
    error = values - reference
    l2 = float(np.sqrt(areas @ error ** 2 / (areas @ reference ** 2)))
    linf = float(np.abs(error).max() / np.abs(reference).max())
    longitudes, lats, grid = mapped(K, error, latitudes, center_longitude, resolution)
    chosen = contour_levels(grid, True, levels, value_range, interval)
    difference = f"{name} − {reference_name}" if name and reference_name else "error"
    when = _when(time, time_unit)
    heading = ", ".join(part for part in (title or difference, when, f"l2 = {l2:.3g}, l∞ = {linf:.3g}") if part)
    return _draw(longitudes, lats, grid, chosen, True, difference, unit, heading)
