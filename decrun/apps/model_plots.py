"""A model's ``plots:`` entries (``app.plots.<name>``): what each may ask for, the checks of its
options (before any mesh work) and of its names (when the model is compiled on the mesh), and
the figure each becomes (by kind: the runner draws it).

- ``{color: c, arrows: X}`` — the value ``c`` in colour with the vector field ``X``'s arrows;
- ``{map: f}`` — the longitude–latitude map of ``f`` on a sphere centred at the origin
  (filled contours, graticules every 30°, the time in days);
- ``{error_map: f, reference: g}`` — the map of f − g with Williamson's normalized l2 and l∞
  errors over the cells (areas: the circumcentric dual cells for values per vertex, the
  triangles for values per triangle).

A mapped value is a form with one value per vertex or per triangle: a 0-form or a dual 0-form
(pointwise), or a top form or dual top form (integrated over its cell: shown as the density,
⋆ of it — ``⋆2 ω`` per triangle, ``⋆0⁻¹ ρ`` per dual cell).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, List, Optional

import numpy as np

from decrun.errors import ConfigError

__all__ = ["PlotOptions", "check_plot_options", "check_plot_names", "plot_figure", "MAX_LEVELS"]

#: at most this many contour levels (an interval far below the range is a mistake, not a picture)
MAX_LEVELS = 200
#: the vertices of a sphere centred at the origin have radii equal to this (relative) tolerance
SPHERE_TOLERANCE = 1e-6
#: ``time_unit`` choices: the model's t in seconds (shown in days) or in its own units
TIME_UNITS = ("s", "model")


@dataclass
class PlotOptions:
    """``app.plots.<name>``: a figure ``<name>.png``; one of ``color`` (with ``arrows``), ``map``
    or ``error_map`` (with ``reference``); the map options below apply to ``map`` and
    ``error_map`` (module docstring)."""

    color: str = ""
    arrows: str = ""
    map: str = ""
    error_map: str = ""
    reference: str = ""
    #: a value drawn as dashed grey contours over a map (the mountain under a free surface)
    outline: str = ""
    #: the unit on the colour bar (``m``, ``s⁻¹``)
    unit: str = ""
    #: explicit contour levels, increasing
    levels: Optional[List[float]] = None
    #: ``[lo, hi]`` of the contour levels, cut every ``interval`` (or in 10 steps)
    range: Optional[List[float]] = None
    interval: Optional[float] = None
    #: the latitude window ``[south, north]`` (degrees)
    latitudes: List[float] = field(default_factory=lambda: [-90.0, 90.0])
    #: the longitude at the map's centre (degrees)
    center_longitude: float = 0.0
    #: the spacing of the longitude–latitude grid the values are resampled on (degrees)
    resolution: float = 0.5
    #: ``s``: the model's time is in seconds and the title shows days; ``model``: t as it is
    time_unit: str = "s"


#: the options that only a map or an error map takes, with their defaults
_MAP_DEFAULTS = {"outline": "", "unit": "", "levels": None, "range": None, "interval": None,
                 "latitudes": [-90.0, 90.0], "center_longitude": 0.0, "resolution": 0.5, "time_unit": "s"}


def _what(plot: PlotOptions, key: str) -> str:
    """The plot's kind (``color``, ``map``, ``error_map``), refusing none or several."""
    given = [kind for kind in ("color", "map", "error_map") if getattr(plot, kind)]
    if len(given) != 1:
        got = "none" if not given else " and ".join(given)
        raise ConfigError(f"{key}: a plot is one of color (with arrows), map or error_map (with reference), got "
                          f"{got}; e.g. `{key}.map=h`")
    return given[0]


def _check_levels(plot: PlotOptions, key: str) -> None:
    """``levels`` increasing, or ``range`` [lo < hi] cut by ``interval`` > 0 into ≤ MAX_LEVELS."""
    if plot.levels is not None:
        levels = np.asarray(plot.levels, dtype=np.float64)
        if plot.range is not None or plot.interval is not None:
            other = "range" if plot.range is not None else "interval"
            raise ConfigError(f"{key}.{other}: give either levels or range/interval, not both; e.g. "
                              f"`~{key}.{other}`")
        if levels.size < 2 or levels.size > MAX_LEVELS + 1 or not np.all(np.diff(levels) > 0):
            raise ConfigError(f"{key}.levels: must be 2 … {MAX_LEVELS + 1} increasing numbers, got {plot.levels}; "
                              f"e.g. `{key}.levels=[-1e-4,0,1e-4]`")
    if plot.interval is not None and not (plot.interval > 0):
        raise ConfigError(f"{key}.interval: must be > 0, got {plot.interval}; e.g. "
                          f"`{key}.interval={abs(plot.interval) or 1:g}`")
    if plot.range is not None:
        if len(plot.range) != 2 or not plot.range[0] < plot.range[1]:
            raise ConfigError(f"{key}.range: must be [lo, hi] with lo < hi, got {plot.range}; "
                              f"e.g. `{key}.range=[-1e-4,1e-4]`")
        if plot.interval is not None:
            steps = (plot.range[1] - plot.range[0]) / plot.interval
            if abs(steps - round(steps)) > 1e-6 * max(1.0, steps) or round(steps) > MAX_LEVELS:
                fitted = (plot.range[1] - plot.range[0]) / min(MAX_LEVELS, max(1, round(steps)))
                raise ConfigError(f"{key}.interval: {plot.interval:g} must cut range {plot.range} into a whole "
                                  f"number ≤ {MAX_LEVELS} of steps ({steps:.6g}); e.g. `{key}.interval={fitted:.6g}`")


def _check_window(plot: PlotOptions, key: str) -> None:
    """``latitudes``, ``center_longitude``, ``resolution`` and ``time_unit`` in their ranges."""
    lat = plot.latitudes
    if len(lat) != 2 or not (-90.0 <= lat[0] < lat[1] <= 90.0):
        raise ConfigError(f"{key}.latitudes: must be [south, north] with -90 <= south < north <= 90 (degrees), got "
                          f"{list(lat)}; e.g. `{key}.latitudes=[0,90]`")
    if not (-180.0 <= plot.center_longitude <= 180.0):
        raise ConfigError(f"{key}.center_longitude: must be in -180 … 180 (degrees), got {plot.center_longitude}; "
                          f"e.g. `{key}.center_longitude={(plot.center_longitude + 180.0) % 360.0 - 180.0:g}`")
    if not (0.05 <= plot.resolution <= 10.0):
        raise ConfigError(f"{key}.resolution: must be in 0.05 … 10 (degrees), got {plot.resolution}; "
                          f"e.g. `{key}.resolution=0.5`")
    if plot.time_unit not in TIME_UNITS:
        raise ConfigError(f"{key}.time_unit: must be one of {list(TIME_UNITS)}, got {plot.time_unit!r}; "
                          f"e.g. `{key}.time_unit=model`")


def check_plot_options(name: str, plot: PlotOptions, key: str = "app.plots") -> None:
    """ConfigError naming ``app.plots.<name>.<key>`` for an option out of place or out of range
    (before any mesh work; the names are :func:`check_plot_names`'s)."""
    key = f"{key}.{name}"
    what = _what(plot, key)
    if what == "color":
        for option, default in _MAP_DEFAULTS.items():
            if getattr(plot, option) != default:
                raise ConfigError(f"{key}.{option}: a map's option, but this plot is color/arrows; "
                                  f"e.g. `~{key}.{option}`")
        if plot.reference:
            raise ConfigError(f"{key}.reference: an error map's option, but this plot is color/arrows; "
                              f"e.g. `~{key}.reference`")
        return
    if plot.arrows:
        raise ConfigError(f"{key}.arrows: a color plot's option, but this plot is a {what}; e.g. `~{key}.arrows`")
    if what == "error_map" and not plot.reference:
        raise ConfigError(f"{key}.reference: an error map draws {plot.error_map} minus a reference; e.g. "
                          f"`+{key}.reference={plot.error_map}_exact`")
    if what == "map" and plot.reference:
        raise ConfigError(f"{key}.reference: a map has no reference (an error_map has); e.g. `~{key}.reference`")
    if what == "error_map" and plot.outline:
        raise ConfigError(f"{key}.outline: a map's option, not an error map's; e.g. `~{key}.outline`")
    for option in ("interval", "center_longitude", "resolution"):
        value = getattr(plot, option)
        if value is not None and not math.isfinite(value):
            raise ConfigError(f"{key}.{option}: must be a finite number, got {value}")
    _check_levels(plot, key)
    _check_window(plot, key)


def _sphere_problem(vertices: np.ndarray) -> str | None:
    """Why the vertices (n, d) are not on a sphere centred at the origin, or None."""
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        return f"its vertices have {vertices.shape[-1]} coordinates, not 3"
    radii = np.linalg.norm(vertices, axis=1)
    radius = float(radii.mean())
    if not radius > 0 or np.abs(radii - radius).max() > SPHERE_TOLERANCE * radius:
        return (f"its vertices' distances to the origin span {radii.min():.6g} … {radii.max():.6g} (centroid "
                f"{np.round(vertices.mean(axis=0), 6).tolist()})")
    return None


def _mappable(kind, dim: int) -> bool:
    """A form with one value per vertex or per triangle of a surface."""
    return dim == 2 and kind is not None and kind.is_form and kind.simplex_dimension(dim) in (0, dim)


def check_plot_names(name: str, plot: PlotOptions, kinds: dict, K, key: str = "app.plots") -> bool:
    """When the model is compiled on the mesh: a map's names are forms with one value per
    vertex or per triangle, an error map's value and reference on the same places, and the mesh
    a sphere centred at the origin; ConfigError naming ``app.plots.<name>.<key>`` and a name that
    fits. Returns False for a color/arrows plot (checked by the model's own rule)."""
    key = f"{key}.{name}"
    what = _what(plot, key)
    if what == "color":
        return False
    fits = sorted(n for n, kind in kinds.items() if _mappable(kind, K.dim) and n not in ("x", "y", "z"))
    for option in (what, "reference", "outline"):
        value = getattr(plot, option)
        if option != what and not value:
            continue
        if not _mappable(kinds.get(value), K.dim):
            got = f"a {kinds[value]}" if value in kinds else "not a name of the model"
            hint = f"`{key}.{option}={fits[0]}`" if fits else "a 0-form or dual 0-form of a triangle mesh"
            raise ConfigError(f"{key}.{option}: {value!r} is {got}, but a map shows a form with one value per vertex "
                              f"or per triangle of a surface (0, dual0, 2, dual2); e.g. {hint}")
    if what == "error_map":
        places = {option: kinds[getattr(plot, option)].simplex_dimension(K.dim) for option in ("error_map", "reference")}
        if places["error_map"] != places["reference"]:
            same = [n for n in fits if kinds[n].simplex_dimension(K.dim) == places["error_map"]]
            raise ConfigError(f"{key}.reference: {plot.reference!r} is a {kinds[plot.reference]}, on other cells than "
                              f"{plot.error_map!r} (a {kinds[plot.error_map]}); e.g. `{key}.reference={same[0]}`")
    problem = _sphere_problem(np.asarray(K.vertices, dtype=np.float64))
    if problem:
        raise ConfigError(f"{key}.{what}: a longitude–latitude map needs a mesh on a sphere centred at the origin, "
                          f"but {problem}; e.g. `mesh=icosphere_clean`")
    return True


def pointwise(dec, kind, values: np.ndarray) -> np.ndarray:
    """A mapped form's values as densities: a top form ⋆_n ω (per triangle), a dual top form
    ⋆_0⁻¹ ρ (per vertex); 0-forms and dual 0-forms as they are."""
    values = np.asarray(values, dtype=np.float64)
    n = dec.K.dim
    if kind.degree == n and not kind.dual:
        return np.asarray(dec.star(n) @ values, dtype=np.float64)
    if kind.degree == n and kind.dual:
        return np.asarray(dec.star_solve(0, values), dtype=np.float64)
    return values


def plot_figure(plot: PlotOptions, kinds: dict, env: dict, dec, title: str, time: float | None) -> dict:
    """The data of a map's figure (kind ``sphere_map``) or an error map's (kind ``error_map``);
    ``time`` the model's time (None for a static model)."""
    what = _what(plot, "app.plots")
    shown = plot.map or plot.error_map
    options: dict[str, Any] = dict(name=shown, unit=plot.unit, time=time, time_unit=plot.time_unit,
                                   levels=plot.levels, value_range=plot.range, interval=plot.interval,
                                   latitudes=tuple(plot.latitudes), center_longitude=float(plot.center_longitude),
                                   resolution=float(plot.resolution))
    values = pointwise(dec, kinds[shown], env[shown])
    if what == "map":
        if plot.outline:
            options.update(outline=pointwise(dec, kinds[plot.outline], env[plot.outline]), outline_name=plot.outline)
        return dict(values=values, title=f"{title}: {shown}", **options)
    on_vertices = kinds[shown].simplex_dimension(dec.K.dim) == 0
    areas = np.asarray(dec.dual_volumes(0) if on_vertices else dec.primal_volumes(dec.K.dim), dtype=np.float64)
    return dict(values=values, reference=pointwise(dec, kinds[plot.reference], env[plot.reference]),
                             areas=areas, reference_name=plot.reference, **options)
