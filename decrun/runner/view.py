"""``decrun-view RUN``: a run's mesh and every field in polyscope, each as its own kind of quantity.

A run directory (or its ``result.h5``, or the journal of a run that was killed) is read back with
:func:`~decrun.runner.results.reading.read_result`; where each field lives comes from what the app
declared (:meth:`decrun.apps.base.App.outputs`, rebuilt from the configuration stored in the
result), else from its shape — the same placement as ``export=vtu``
(:func:`~decrun.runner.results.export.place_fields`). Then:

=======================  =====================================================================
field                    polyscope quantity
=======================  =====================================================================
0-form (per vertex)      vertex scalar; two columns (``uv``): a parameterization; three
                         columns: a vertex vector, or, named ``vertices_*``, a mesh of its own
                         at those positions (the smoothing's initial and final surfaces)
dual 0-form (per face)   face scalar (cell scalar of a volume mesh); three columns: face vectors
1-form (per edge)        a one-form (polyscope interpolates it with Whitney forms), with the
                         run's edge order and orientation passed to polyscope
vertex / face sets       point clouds at the vertices / face barycentres, with the values along
                         them (source divergences, stroke vectors)
points                   a point cloud (singularity clusters)
recorded series          the same kinds per step, with a step slider (``--step`` for a screenshot)
=======================  =====================================================================

Tetrahedra become a volume mesh (vertex and cell quantities). What has no polyscope quantity —
a 2-form on the triangles of a volume, eigenvalues — is named in one line, never dropped
silently. The placement (:func:`plan_view`) needs no polyscope; only :func:`show` imports it, so
``decrun-view`` without the ``view`` extra is one line saying how to install it.

``--screenshot FILE.png`` renders headless (EGL) with no window and exits; a scalar field's
screenshot has its colour bar beside the picture (:func:`with_colour_bar`: the field's name,
its range, viridis as the picture uses it).
"""

from __future__ import annotations

import argparse
import difflib
import logging
import os
import sys
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from decrun.errors import DecrunError
from decrun.runner.io.files import RunFiles
from decrun.runner.results.export import working_directory

__all__ = ["Quantity", "View", "plan_view", "edge_order", "show", "main"]

log = logging.getLogger(__name__)

INSTALL_HINT = "decrun-view needs polyscope: pip install 'decrun[view]' (or pip install polyscope)"

#: kinds of :class:`Quantity`, each drawn by one polyscope call in :func:`show`
KINDS = ("vertex_scalar", "cell_scalar", "vertex_vector", "cell_vector", "one_form", "parameterization",
         "positions", "vertex_set", "cell_set", "points")


#: arrows long and thick enough to read on a whole mesh (polyscope's lengths are relative to the
#: scene's size; the longest arrow is ``length``)
ARROWS = {"length": 0.04, "radius": 0.002}
#: the colour map of scalar quantities (set explicitly, so the screenshot's colour bar is the picture's)
SCALAR_MAP = "viridis"
#: width of the colour bar's strip beside a screenshot (pixels)
COLOUR_BAR_STRIP = 150


class ViewError(DecrunError):
    """A run that cannot be shown as asked (no such field or step, no headless renderer)."""


@dataclass(frozen=True)
class Quantity:
    """One field as a polyscope quantity.

    name : the field's name (series: ``"<name> (series)"``)
    kind : one of :data:`KINDS`
    values : the values, one row per vertex / top simplex / edge / set member / point; for a
        series, one such array per recorded step stacked on axis 0
    members : for ``vertex_set`` / ``cell_set``, the indices of the set (``values`` are then
        the values along it, or None)
    series : whether ``values`` has a leading step axis
    """

    name: str
    kind: str
    values: np.ndarray | None
    members: np.ndarray | None = None
    series: bool = False

    def at(self, step: int) -> np.ndarray | None:
        """The values at recorded step index ``step`` (the values themselves when not a series)."""
        return self.values[step] if self.series and self.values is not None else self.values


@dataclass
class View:
    """What :func:`show` draws: the mesh and its quantities, in the app's declared order.

    vertices : (n0, 3) float, planar meshes padded with z = 0
    cells : (nT, n + 1) int, the top simplices (triangles or tetrahedra)
    edges : (n1, 2) int, the run's edges in its order and orientation (1-forms are along them)
    quantities : the fields that have a polyscope quantity
    left_out : field name → why it has none (listed by :func:`show` in one line)
    steps : (T,) the recorded step numbers (None without series)
    scalars : (T,) per-step numbers of the series (energy, mass …), shown at the slider's step
    title : what the run was (app and status)
    """

    vertices: np.ndarray
    cells: np.ndarray
    edges: np.ndarray | None
    quantities: list[Quantity]
    left_out: dict[str, str]
    steps: np.ndarray | None = None
    scalars: dict[str, np.ndarray] = field(default_factory=dict)
    title: str = ""

    @property
    def dimension(self) -> int:
        """The dimension n of the top simplices (2: a surface, 3: a volume)."""
        return self.cells.shape[1] - 1

    def names(self) -> list[str]:
        """The names of the quantities, in order."""
        return [q.name for q in self.quantities]

    def find(self, name: str) -> Quantity:
        """The quantity called ``name``; a :class:`ViewError` with the closest names if none is."""
        for q in self.quantities:
            if q.name == name:
                return q
        if name in self.left_out:
            raise ViewError(f"--field {name}: {self.left_out[name]}")
        close = difflib.get_close_matches(name, self.names(), n=1)
        hint = f"; did you mean --field {close[0]!r}?" if close else ""
        raise ViewError(f"--field {name}: the run has no such field (it has {', '.join(self.names())}){hint}")


def _run_file(path: Path) -> Path:
    """``result.h5`` of a run directory, or ``path`` itself when it names the file (or its journal)."""
    if path.is_dir():
        return RunFiles(path).result
    if path.name.endswith(".partial"):
        return path.with_name(path.name[: -len(".partial")])
    return path


def _app(result) -> Any:
    """The run's app rebuilt from the configuration stored in its result (for its declared
    outputs), or None when it cannot be (a plugin app not on the path): shapes decide then."""
    text = result.provenance.get("config_yaml")
    if not text:
        return None
    try:
        from omegaconf import OmegaConf

        from decrun.apps.base import App
        from decrun.runner.job.plugins import build

        return build(OmegaConf.create(str(text)).app, "app", App)
    except Exception as exc:  # an app that cannot be rebuilt here: placed by shapes instead
        log.warning("decrun-view: the app of %s cannot be rebuilt (%s); fields are placed by their shapes",
                    result.source, str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        return None


def _simplex_counts(cells: np.ndarray, edges: np.ndarray | None, n_vertices: int) -> dict[int, int]:
    """Number of k-simplices for k = 0 … n, from the stored cells (the faces of tetrahedra counted
    as unique sorted vertex triples)."""
    n = cells.shape[1] - 1
    counts = {0: n_vertices, n: len(cells)}
    if n >= 2:
        counts[1] = len(edges) if edges is not None else -1
    if n == 3:
        faces = np.sort(cells[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3), axis=1)
        counts[2] = len(np.unique(faces, axis=0))
    return counts


def edge_order(triangles: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """polyscope's edge permutation and the run's edge orientations, for a one-form.

    polyscope numbers the edges of a triangle mesh in the order they are first met walking the
    triangles and, in each, its sides (v0 v1), (v1 v2), (v2 v0). ``permutation[i]`` is the run's
    index of polyscope's i-th edge (what ``set_edge_permutation`` takes); ``orientation[e]`` is
    True where the run's edge e runs from its lower to its higher vertex index (polyscope's
    canonical direction).

    triangles : (nT, 3) int; edges : (n1, 2) int, every side of every triangle exactly once.
    Returns (n1,) int64 and (n1,) bool.
    """
    triangles = np.asarray(triangles, dtype=np.int64)
    edges = np.asarray(edges, dtype=np.int64)
    sides = np.stack([triangles, np.roll(triangles, -1, axis=1)], axis=2).reshape(-1, 2)
    keys = np.sort(sides, axis=1)
    n = int(max(triangles.max(initial=0), edges.max(initial=0))) + 1
    side_key = keys[:, 0] * n + keys[:, 1]
    unique, first = np.unique(side_key, return_index=True)
    walked = unique[np.argsort(first, kind="stable")]          # polyscope's edges, as keys
    edge_sorted = np.sort(edges, axis=1)
    edge_key = edge_sorted[:, 0] * n + edge_sorted[:, 1]
    by_key = np.argsort(edge_key, kind="stable")
    position = np.searchsorted(edge_key[by_key], walked)
    position = np.minimum(position, len(by_key) - 1)
    if len(walked) != len(edges) or not np.array_equal(edge_key[by_key][position], walked):
        raise ViewError(f"the stored edges ({len(edges)}) are not the sides of the stored triangles "
                        f"({len(walked)} distinct sides): the 1-forms cannot be placed")
    return by_key[position], edges[:, 0] < edges[:, 1]


def _vertex_quantity(name: str, array: np.ndarray, series: bool = False) -> tuple[Quantity | None, str]:
    width = 1 if array.ndim == 1 + series else array.shape[-1]
    if array.ndim == 1 + series:
        return Quantity(name, "vertex_scalar", array, series=series), ""
    if width == 2 and not series:
        return Quantity(name, "parameterization", array), ""
    if width == 3 and name.startswith("vertices") and not series:
        return Quantity(name, "positions", array), ""
    if width == 3:
        return Quantity(name, "vertex_vector", array, series=series), ""
    return None, f"{width} values per vertex: no polyscope quantity (one value, uv or a 3-vector)"


def _cell_quantity(name: str, array: np.ndarray, series: bool = False) -> tuple[Quantity | None, str]:
    if array.ndim == 1 + series:
        return Quantity(name, "cell_scalar", array, series=series), ""
    if array.shape[-1] == 3:
        return Quantity(name, "cell_vector", array, series=series), ""
    return None, f"{array.shape[-1]} values per top simplex: no polyscope quantity (one value or a 3-vector)"


def _place(placed, counts: dict[int, int], n: int) -> tuple[list[Quantity], dict[str, str]]:
    """:class:`Quantity` objects for the fields placed by
    :func:`~decrun.runner.results.export.place_fields`, and what has none."""
    quantities: list[Quantity] = []
    left_out: dict[str, str] = {}

    def add(name: str, made: tuple[Quantity | None, str]) -> None:
        quantity, why = made
        if quantity is None:
            left_out[name] = why
        else:
            quantities.append(quantity)

    for name, array in placed.on[0].items():
        add(name, _vertex_quantity(name, array))
    for name, array in placed.on[n].items():
        add(name, _cell_quantity(name, array))
    for name, array in placed.on.get(1, {}).items() if n > 1 else ():
        if n == 2 and array.ndim == 1:
            quantities.append(Quantity(name, "one_form", array))
        else:
            left_out[name] = ("a 1-form on the edges of a volume: polyscope's volume meshes have no edge quantity"
                              if n == 3 else f"{array.shape[1:]} values per edge: no polyscope quantity")
    for k in range(2, n):
        for name in placed.on.get(k, {}):
            left_out[name] = f"a {k}-form on the {k}-simplices of a volume: polyscope has no quantity on them"
    along: dict[str, list[tuple[str, np.ndarray]]] = {}
    for name, (of, values) in placed.along.items():
        along.setdefault(of, []).append((name, values))
    for kind, sets in (("vertex_set", placed.vertex_sets), ("cell_set", placed.top_sets)):
        for name, members in sets.items():
            quantities.append(Quantity(name, kind, None, members=members))
            for value_name, values in along.get(name, []):
                quantities.append(Quantity(value_name, kind, values, members=members))
    for name, array in placed.other.items():
        if array.ndim == 2 and array.shape[1] == 3 and array.dtype.kind == "f" and len(array):
            quantities.append(Quantity(name, "points", array))
        else:
            left_out[name] = f"shape {array.shape}: not on the mesh (listed in metrics / result.h5 only)"
    for name in placed.unwritable:
        left_out[name] = "not a number array"
    return quantities, left_out


def _series(result, counts: dict[int, int], n: int) -> tuple[list[Quantity], dict[str, np.ndarray], dict[str, str]]:
    """The recorded series on the mesh (a leading step axis), and the per-step numbers."""
    quantities: list[Quantity] = []
    scalars: dict[str, np.ndarray] = {}
    left_out: dict[str, str] = {}
    for name, array in result.series.items():
        if name in ("step", "time"):
            continue
        array = np.asarray(array)
        label = f"{name} (series)"
        if array.ndim == 1:
            scalars[name] = array
        elif array.shape[1] in (counts[0], counts[n]):
            made = _vertex_quantity if array.shape[1] == counts[0] else _cell_quantity
            quantity, why = made(label, array, series=True)
            (quantities.append(quantity) if quantity else left_out.__setitem__(label, why))
        elif n == 2 and array.shape[1] == counts.get(1) and array.ndim == 2:
            quantities.append(Quantity(label, "one_form", array, series=True))
        else:
            left_out[label] = f"shape {array.shape}: not one row per vertex, edge or top simplex at each step"
    return quantities, scalars, left_out


def plan_view(path: str | Path) -> View:
    """The :class:`View` of the run at ``path`` (a run directory, its ``result.h5``, or the
    journal ``result.h5.partial`` of a killed run). Reads the file only; imports no polyscope.
    Raises ``FileNotFoundError`` naming the path, or the reader's ``CorruptFileError``."""
    from decrun.runner.results.export import place_fields
    from decrun.runner.results.reading import read_result

    result = read_result(_run_file(Path(path)))
    if "vertices" not in result.mesh or "simplices" not in result.mesh:
        raise ViewError(f"{result.source}: holds no mesh (/mesh/vertices, /mesh/simplices)")
    vertices = np.asarray(result.mesh["vertices"], dtype=np.float64)
    if vertices.shape[1] == 2:
        vertices = np.column_stack([vertices, np.zeros(len(vertices))])
    cells = np.asarray(result.mesh["simplices"], dtype=np.int64)
    edges = np.asarray(result.mesh["edges"], dtype=np.int64) if "edges" in result.mesh else None
    n = cells.shape[1] - 1
    if n not in (2, 3):
        raise ViewError(f"{result.source}: a mesh of {n}-simplices; decrun-view shows surfaces and volumes")
    counts = _simplex_counts(cells, edges, len(vertices))
    mesh = SimpleNamespace(vertices=vertices, simplices=cells)
    K = SimpleNamespace(num_simplices=lambda k: counts.get(k, -1))
    quantities, left_out = _place(place_fields(result, mesh, K, _app(result)), counts, n)
    series, scalars, series_left_out = _series(result, counts, n)
    steps = np.asarray(result.series["step"]) if "step" in result.series else None
    if steps is None and (series or scalars):
        lengths = {len(q.values) for q in series if q.values is not None} | {len(a) for a in scalars.values()}
        steps = np.arange(max(lengths))
    config = result.provenance.get("config_yaml") or ""
    app = next((line.split(":", 1)[1].strip() for line in str(config).splitlines()
                if line.startswith("  _target_:")), "")
    title = f"{Path(result.source or '').parent.name}: {app.rpartition('.')[2] or 'run'} ({result.status or 'ok'})"
    return View(vertices, cells, edges, quantities + series, {**left_out, **series_left_out}, steps, scalars, title)


# ----------------------------------------------------------------------------------
# polyscope
# ----------------------------------------------------------------------------------

def _init(ps, headless: bool) -> None:
    """Start polyscope: EGL (no window, no display) for screenshots, a window otherwise."""
    try:
        if headless:
            ps.set_allow_headless_backends(True)
            ps.init("openGL3_egl")
        else:
            ps.init()
    except Exception as exc:  # polyscope raises RuntimeError with a multi-line message
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ViewError(f"polyscope cannot start {'headless (EGL)' if headless else 'a window'}: {first}; "
                        + ("install Mesa's EGL (Debian: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri)"
                           if headless else "with no display, use --screenshot FILE.png")) from None


def _add(ps, view: View, structure, quantity: Quantity, step: int, enabled: bool, setup: dict) -> None:
    """Draw ``quantity`` (at recorded step index ``step``) on ``structure``."""
    values = quantity.at(step)
    kind, name = quantity.kind, quantity.name
    volume = view.dimension == 3
    on = "vertices" if kind.startswith("vertex_") else "cells" if volume else "faces"
    if kind in ("vertex_scalar", "cell_scalar"):
        structure.add_scalar_quantity(name, values, defined_on=on, enabled=enabled, cmap=SCALAR_MAP,
                                      vminmax=value_range(values))
    elif kind in ("vertex_vector", "cell_vector"):
        structure.add_vector_quantity(name, values, defined_on=on, enabled=enabled, **ARROWS)
    elif kind == "parameterization":
        structure.add_parameterization_quantity(name, values, defined_on="vertices", enabled=enabled)
    elif kind == "one_form":
        assert view.edges is not None  # a one-form is a quantity only where the run has its edges
        if "orientation" not in setup:
            permutation, setup["orientation"] = edge_order(view.cells, view.edges)
            structure.set_edge_permutation(permutation)
        structure.add_one_form_vector_quantity(name, values, setup["orientation"], enabled=enabled, **ARROWS)
    elif kind == "positions":
        other = ps.register_surface_mesh(name, values, view.cells, enabled=enabled) if not volume else \
            ps.register_volume_mesh(name, values, tets=view.cells, enabled=enabled)
        other.set_transparency(0.6 if not enabled else 1.0)
    elif kind in ("vertex_set", "cell_set"):
        members = quantity.members
        assert members is not None  # a set quantity has its members
        where = view.vertices[members] if kind == "vertex_set" else view.vertices[view.cells[members]].mean(axis=1)
        label = name if values is None else f"{name} (points)"
        cloud = ps.register_point_cloud(label, where, enabled=enabled or values is None and len(members) > 0)
        if values is not None and len(values):
            if values.ndim == 1:
                cloud.add_scalar_quantity(name, values, enabled=True)
            elif values.shape[1] == 3:
                cloud.add_vector_quantity(name, values, enabled=True)
    elif kind == "points":
        ps.register_point_cloud(name, values, enabled=True)


def value_range(values: np.ndarray | None) -> tuple[float, float]:
    """(min, max) of the finite values — the colour map's range (a constant field: ± 0.5 around it)."""
    finite = np.asarray(values if values is not None else [], dtype=np.float64)
    finite = finite[np.isfinite(finite)]
    if not finite.size:
        return (0.0, 1.0)
    low, high = float(finite.min()), float(finite.max())
    return (low, high) if high > low else (low - 0.5, high + 0.5)


def with_colour_bar(image: np.ndarray, name: str, low: float, high: float, path: Path) -> None:
    """Write ``image`` (h, w, 3|4 uint8, a screenshot) to the PNG ``path`` with a vertical colour
    bar of :data:`SCALAR_MAP` from ``low`` to ``high``, labelled ``name``, in a strip of
    :data:`COLOUR_BAR_STRIP` pixels on its right (never over the picture)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    height, width = image.shape[:2]
    total = width + COLOUR_BAR_STRIP
    figure = Figure(figsize=(total / 100, height / 100), dpi=100, facecolor="white")
    FigureCanvasAgg(figure)
    picture = figure.add_axes((0, 0, width / total, 1))
    picture.imshow(image, interpolation="nearest")
    picture.set_axis_off()
    bar = figure.add_axes(((width + 12) / total, 0.15, 18 / total, 0.7))
    figure.colorbar(ScalarMappable(norm=Normalize(low, high), cmap=SCALAR_MAP), cax=bar)
    bar.set_title(name, fontsize=9, loc="left")
    bar.tick_params(labelsize=8)
    figure.savefig(path, dpi=100, facecolor="white")


def left_out_line(left_out: dict[str, str]) -> str:
    """``left_out`` (name → why) in one line, the names that share a reason together."""
    by_reason: dict[str, list[str]] = {}
    for name, why in left_out.items():
        by_reason.setdefault(why, []).append(name)
    return "; ".join(f"{', '.join(names)} ({why})" for why, names in by_reason.items())


def _camera(ps, view: View) -> None:
    """A fixed view: a planar mesh seen from above (+z, y up); a 3-D one from the front with z up."""
    ps.set_ground_plane_mode("none")
    extent = np.ptp(view.vertices, axis=0)
    if extent[2] <= 1e-12 * max(extent.max(), 1e-300):
        ps.set_up_dir("y_up")
        ps.set_front_dir("z_front")
    else:
        ps.set_up_dir("z_up")
        ps.set_front_dir("neg_y_front")
    ps.reset_camera_to_home_view()


def show(view: View, field: str | None = None, step: int | None = None, screenshot: str | Path | None = None,
         size: tuple[int, int] = (1024, 768)) -> None:
    """Show ``view`` in polyscope: the quantity ``field`` enabled (default: the first), the series
    at recorded step index ``step`` (default: the last; a slider in the window). With
    ``screenshot``, render headless to that PNG and return without a window."""
    selected = view.find(field) if field is not None else next(
        (q for q in view.quantities if q.kind not in ("vertex_set", "cell_set", "points", "positions")), None)
    steps = len(view.steps) if view.steps is not None else 0
    if step is not None and not -steps <= step < max(steps, 1):
        raise ViewError(f"--step {step}: the run recorded {steps} steps (indices 0 … {steps - 1})")
    index = (step % steps) if step is not None and steps else max(steps - 1, 0)
    if view.left_out:
        log.warning("decrun-view: not shown: %s", left_out_line(view.left_out))
    try:
        import polyscope as ps
    except ImportError:
        raise ViewError(INSTALL_HINT) from None
    screenshot = Path(screenshot).resolve() if screenshot is not None else None
    with _settings_directory():  # ImGui writes imgui.ini into the working directory: not the user's
        try:
            _draw(ps, view, selected, index, screenshot, size)
        finally:
            if ps.is_initialized():
                ps.shutdown()


@contextmanager
def _settings_directory():
    """Work in decrun's cache folder while polyscope runs (its window settings file lands there)."""
    where = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "decrun" / "polyscope"
    where.mkdir(parents=True, exist_ok=True)
    with working_directory(where):
        yield


def _draw(ps, view: View, selected: Quantity | None, index: int, screenshot: Path | None,
          size: tuple[int, int]) -> None:
    """Start polyscope, register the mesh and the quantities, then screenshot or open the window."""
    ps.set_use_prefs_file(False)
    _init(ps, headless=screenshot is not None)
    ps.set_program_name("decrun-view")
    ps.set_window_size(*size)
    if view.dimension == 3:
        structure = ps.register_volume_mesh("mesh", view.vertices, tets=view.cells)
    else:
        structure = ps.register_surface_mesh("mesh", view.vertices, view.cells)
    setup: dict = {}
    for quantity in view.quantities:
        _add(ps, view, structure, quantity, index, quantity is selected, setup)
    _camera(ps, view)
    if screenshot is not None:
        if selected is not None and selected.kind in ("vertex_scalar", "cell_scalar"):
            low, high = value_range(selected.at(index))
            with_colour_bar(ps.screenshot_to_buffer(transparent_bg=False), selected.name, low, high, screenshot)
        else:  # arrows, a one-form, a parametrization: no colour scale to read
            ps.screenshot(str(screenshot), transparent_bg=False)
        return
    _slider(ps, view, structure, index, selected, setup)
    ps.show()


def _slider(ps, view: View, structure, index: int, selected: Quantity | None, setup: dict) -> None:
    """A step slider redrawing the series quantities, with the run's per-step numbers beside it."""
    import polyscope.imgui as psim

    series = [q for q in view.quantities if q.series]
    state = {"index": index}

    def callback():
        psim.TextUnformatted(view.title)
        if view.steps is None or not len(view.steps):
            return
        changed, state["index"] = psim.SliderInt("step", state["index"], v_min=0, v_max=len(view.steps) - 1)
        psim.TextUnformatted(f"step {int(view.steps[state['index']])}")
        for name, values in view.scalars.items():
            if state["index"] < len(values):
                psim.TextUnformatted(f"{name} = {values[state['index']]:.6g}")
        if changed:
            for quantity in series:
                structure.remove_quantity(quantity.name)
                _add(ps, view, structure, quantity, state["index"], quantity is selected, setup)

    ps.set_user_callback(callback)


def main(argv: list[str] | None = None) -> int:
    """Console script ``decrun-view RUN [--field NAME] [--step K] [--screenshot FILE.png]``.
    Exit 0; 2 with one line ``error: …`` for a run that cannot be read or shown, or no polyscope."""
    parser = argparse.ArgumentParser(prog="decrun-view", description=__doc__.split("\n\n")[0])
    parser.add_argument("run", help="a run directory (outputs/runs/<stamp>), its result.h5, or result.h5.partial")
    parser.add_argument("--field", help="the field shown first (default: the first one); --list names them")
    parser.add_argument("--step", type=int, help="the recorded step index of the series (default: the last)")
    parser.add_argument("--screenshot", metavar="FILE.png", help="render headless to FILE.png, no window")
    parser.add_argument("--size", default="1024x768", help="window / screenshot size WIDTHxHEIGHT")
    parser.add_argument("--list", action="store_true", help="list the fields and their polyscope quantities, then exit")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    try:
        width, _, height = args.size.partition("x")
        try:
            size = (int(width), int(height))
        except ValueError:
            raise ViewError(f"--size {args.size!r}: expected WIDTHxHEIGHT, e.g. --size 1024x768") from None
        view = plan_view(args.run)
        if args.list:
            for q in view.quantities:
                print(f"{q.name}\t{q.kind}")
            for name in view.scalars:
                print(f"{name}\tper-step number (beside the step slider)")
            for name, why in view.left_out.items():
                print(f"{name}\tnot shown: {why}")
            return 0
        show(view, field=args.field, step=args.step, screenshot=args.screenshot, size=size)
    except (DecrunError, OSError) as exc:
        print(f"error: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 2
    if args.screenshot:
        print(args.screenshot)
    return 0


if __name__ == "__main__":  # python -m decrun.runner.view (the decrun-view console script's twin)
    sys.exit(main())
