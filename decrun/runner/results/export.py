"""Export of a run for other programs (the ``export`` config group): ParaView, MeshLab, any
OBJ reader. Written into the run directory beside ``result.h5`` after the run.

=============  ===========================================================================
``none``       nothing (the default)
``vtu``        ``result.vtu``: the mesh (triangles or tetrahedra) with every field on it —
               per vertex as point data, per top simplex as cell data, per edge (1-forms) and
               per triangle of a volume (2-forms) as cell data of a block of ``line`` /
               ``triangle`` cells (NaN on the other blocks); a set of vertices (singular
               vertices, sources) as a block of ``vertex`` cells carrying 1 under its name and
               the values along it (source divergences); a set of top simplices (singular,
               vortex, stroke faces) as an indicator on them (1 on its members), the values
               along it on its members; a multi-column field whose columns are fields of
               their own (eigenvectors) as ``name_0``, ``name_1`` …; arrays with no place on the
               mesh (eigenvalues, singularity clusters) as VTK field data
``xdmf``       ``series.xdmf`` + ``series.h5`` (HDF5 heavy data): the recorded series
               over the mesh as a time series (meshio's ``TimeSeriesWriter``; times from the
               series ``time`` when recorded, else ``step``), which ParaView plays as an
               animation; per-edge series (1-forms, e.g. the fluid's flux) in
               ``series_edges.xdmf`` on line cells (meshio cannot mix them with triangles in
               one time series); a run without such series gets its fields as one step at
               the end of the run (sets as indicators, as in vtu)
``ply``        ``result.ply``: the triangles (of the border surface for tetrahedra) with
               per-vertex colours (``red``/``green``/``blue`` uint8) of one per-vertex field
               through a colormap, and that field itself, for MeshLab
``obj``        ``result.obj``: the triangles with texture coordinates ``vt`` from the field
               ``uv`` (the parametrization), faces ``f a/a b/b c/c``
=============  ===========================================================================

Where a field goes is what the app declares (:meth:`decrun.apps.base.App.outputs`), else
its shape; a field that is the cells themselves (the smoothing's oriented ``faces``) is the
cells. What a format cannot hold is named in one log line (``export=<name>: <file> cannot
hold …``). ``obj`` and ``ply`` check their options against the declared fields when the
config is checked, before any mesh loads (:meth:`Export.check`); an export that fails after
the run leaves ``result.h5`` and ``metrics.json`` as the run wrote them, with
``export_error`` added. Arrays are exported as they are (float64, ints; bools as uint8);
nothing is resampled.
"""

from __future__ import annotations

import logging
import os
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from decrun.core.choices import closest
from decrun.errors import ConfigError, DecrunError
from decrun.runner.io.files import RunFiles
from decrun.runner.io.paths import check_file

__all__ = ["Export", "NoExport", "Vtu", "Xdmf", "Ply", "Obj", "ExportFailed", "classify_fields", "place_fields"]

log = logging.getLogger(__name__)

_TOP = {2: "triangle", 3: "tetra"}


def _points(vertices: np.ndarray) -> np.ndarray:
    vertices = np.asarray(vertices, dtype=np.float64)
    return vertices if vertices.shape[1] == 3 else np.column_stack([vertices, np.zeros(len(vertices))])


def _plain(array: np.ndarray) -> np.ndarray:
    array = np.asarray(array)
    if array.dtype == bool:
        return array.astype(np.uint8)
    if array.ndim > 2:
        return array.reshape(array.shape[0], -1)
    return array


def classify_fields(fields: dict, n_vertices: int, n_top: int, n_edges: int | None) -> dict[str, dict]:
    """Split ``fields`` (name → array, or a FieldOnEdges) by where their shapes say they live:
    ``{"point": {...}, "cell": {...}, "edge": {...}, "other": {...}}``. A 1-form wrapped in
    FieldOnEdges goes to ``edge``; else the first axis decides (vertices first). What is not
    a number array goes nowhere (:func:`place_fields` lists it)."""
    from decrun.apps.base import FieldOnEdges

    out: dict[str, dict] = {"point": {}, "cell": {}, "edge": {}, "other": {}}
    for name, value in fields.items():
        if isinstance(value, FieldOnEdges):
            out["edge"][name] = _plain(value.values)
            continue
        array = np.asarray(value)
        if array.dtype.kind not in "biuf":
            continue
        if array.ndim == 0:
            out["other"][name] = np.atleast_1d(array)
        elif array.shape[0] == n_vertices:
            out["point"][name] = _plain(array)
        elif array.shape[0] == n_top:
            out["cell"][name] = _plain(array)
        elif n_edges is not None and array.shape[0] == n_edges and array.ndim == 1:
            out["edge"][name] = _plain(array)
        else:
            out["other"][name] = _plain(array)
    return out


@dataclass
class Placed:
    """The fields of a run by where they go in a file (:func:`place_fields`).

    ``on``: simplex dimension → {name: (n_k, ...) array} (0: the vertices, n: the top
    simplices); ``vertex_sets`` / ``top_sets``: {name: indices}; ``along``: {name: (set name,
    (len(set), ...) values)}; ``other``: {name: array} with no place on the mesh (field data);
    ``cells``: names that are the top simplices themselves (written as the cells);
    ``unwritable``: names no file format holds (not number arrays)."""

    on: dict[int, dict[str, np.ndarray]]
    vertex_sets: dict[str, np.ndarray]
    top_sets: dict[str, np.ndarray]
    along: dict[str, tuple[str, np.ndarray]]
    other: dict[str, np.ndarray]
    cells: list[str]
    unwritable: list[str]


def _columns(name: str, array: np.ndarray, split: bool) -> dict[str, np.ndarray]:
    """``{name: array}``, or with ``split`` one array per column, ``name_0`` … (the eigenvectors)."""
    if not split or array.ndim != 2:
        return {name: array}
    return {f"{name}_{j}": np.ascontiguousarray(array[:, j]) for j in range(array.shape[1])}


def _parity(rows: np.ndarray) -> np.ndarray:
    """The parity of each row's order (its inversion count mod 2)."""
    m = rows.shape[1]
    return sum((rows[:, i] > rows[:, j]).astype(np.int64) for i in range(m) for j in range(i + 1, m)) % 2


def _same_oriented_cells(array: np.ndarray, simplices: np.ndarray) -> bool:
    """Whether ``array`` lists the simplices of ``simplices``, row by row, each in an order of
    the same orientation (a rotation of a triangle): the cells themselves, nothing to add."""
    simplices = np.asarray(simplices)
    if array.shape != simplices.shape or array.dtype.kind not in "iu":
        return False
    return bool(np.array_equal(np.sort(array, axis=1), np.sort(simplices, axis=1))
                and np.array_equal(_parity(array), _parity(simplices)))


def _cells(result, mesh, app) -> list[str]:
    """The fields ``app`` declares as the connectivity that are the mesh's cells (written as them)."""
    outputs = (app.outputs() if app is not None else None) or {}
    return [name for name, output in outputs.items() if output.on == "connectivity" and name in result.fields
            and _same_oriented_cells(np.asarray(result.fields[name]), mesh.simplices)]


def place_fields(result, mesh, K, app=None) -> Placed:
    """Where each field of ``result`` goes: by what ``app`` declares (:meth:`App.outputs`),
    checked against the shapes, else by its shape (:func:`classify_fields`); nothing is left
    out without being listed in ``unwritable``."""
    from decrun.apps.base import FieldOnEdges

    n = mesh.simplices.shape[1] - 1
    counts = {0: len(mesh.vertices), n: len(mesh.simplices)}
    for k in range(1, n):
        counts[k] = K.num_simplices(k) if K is not None else -1
    declared = (app.outputs() if app is not None else None) or {}
    placed = Placed({k: {} for k in range(n + 1)}, {}, {}, {}, {}, [], [])
    guessed = {}
    for name, value in result.fields.items():
        output = declared.get(name)
        array = np.asarray(value.values if isinstance(value, FieldOnEdges) else value)
        if array.dtype.kind not in "biuf":
            placed.unwritable.append(name)
            continue
        array = _plain(array) if array.ndim else np.atleast_1d(array)
        k = output.simplex_dimension(n) if output is not None else None
        if output is None:
            guessed[name] = value
        elif k is not None and k in counts and len(array) == counts[k]:
            placed.on[k].update(_columns(name, array, output.columns))
        elif output.on == "connectivity" and _same_oriented_cells(array, mesh.simplices):
            placed.cells.append(name)
        elif output.on == "connectivity" and len(array) == counts[n]:
            placed.on[n][name] = array  # the same simplices in another vertex order: kept as cell data
        elif output.on in ("vertex_set", "top_set") and array.ndim == 1 and array.dtype.kind in "iu" \
                and len(np.unique(array)) == len(array):
            (placed.vertex_sets if output.on == "vertex_set" else placed.top_sets)[name] = array.astype(np.int64)
        elif output.on.startswith("along:"):
            placed.along[name] = (output.on.partition(":")[2], array)
        else:  # global, or not as declared: kept as it is
            placed.other[name] = array
    for name, (of, values) in list(placed.along.items()):
        members = placed.vertex_sets.get(of, placed.top_sets.get(of))
        if members is None or len(members) != len(values):
            placed.other[name] = values
            del placed.along[name]
    if guessed:
        groups = classify_fields(guessed, counts[0], counts[n], counts.get(1) if n > 1 else None)
        placed.on[0].update(groups["point"])
        placed.on[n].update(groups["cell"])
        if n > 1:
            placed.on[1].update(groups["edge"])
        for name, array in groups["other"].items():
            match = [k for k in range(1, n) if k != 1 and len(array) == counts[k]]
            (placed.on[match[0]] if match else placed.other)[name] = array
    return placed


def _vtu_blocks(mesh, K, placed: Placed):
    """meshio cells and cell_data for ``placed``: the top simplices, then a block of lower
    simplices for every dimension with fields (``triangle`` on a volume, ``line``), then one
    block of ``vertex`` cells per non-empty vertex set. A cell array is NaN on the blocks it
    is not on (float64 then); a set of top simplices is an indicator (1 on its members) and
    the values along it sit on its members; a vertex set's cells carry 1 under its name."""
    n = mesh.simplices.shape[1] - 1
    names = {1: "line", 2: "triangle", 3: "tetra"}
    blocks = [(names[n], np.asarray(mesh.simplices, dtype=np.int64), n, None)]
    for k in range(n - 1, 0, -1):
        if placed.on[k]:
            blocks.append((names[k], np.asarray(K.simplices(k), dtype=np.int64), k, None))
    for name, members in placed.vertex_sets.items():
        if len(members):
            blocks.append(("vertex", members[:, None], 0, name))
    per_block: dict[str, dict[int, np.ndarray]] = {}
    for index, (_, cells, k, vset) in enumerate(blocks):
        if vset is None:
            for name, value in placed.on[k].items() if k else ():
                per_block.setdefault(name, {})[index] = value
            for name, value in _on_sets(len(cells), placed.top_sets, placed.along).items() if k == n else ():
                per_block.setdefault(name, {})[index] = value
        else:
            per_block.setdefault(vset, {})[index] = np.ones(len(cells), dtype=np.uint8)
            for name, (of, values) in placed.along.items():
                if of == vset:
                    per_block.setdefault(name, {})[index] = values
    cell_data = {}
    for name, on in per_block.items():
        if len(blocks) == 1:
            cell_data[name] = [on[0]]
            continue
        shape = next(iter(on.values())).shape[1:]
        cell_data[name] = [on[i].astype(np.float64) if i in on else np.full((len(cells), *shape), np.nan)
                           for i, (_, cells, _, _) in enumerate(blocks)]
    return [(kind, cells) for kind, cells, _, _ in blocks], cell_data


def _on_sets(size: int, sets: dict[str, np.ndarray], along: dict[str, tuple[str, np.ndarray]]) -> dict:
    """Each set of ``sets`` as an indicator over ``size`` simplices (1 on its members, uint8),
    and the values ``along`` it on its members (NaN elsewhere)."""
    out: dict[str, np.ndarray] = {}
    for name, members in sets.items():
        out[name] = np.zeros(size, dtype=np.uint8)
        out[name][members] = 1
        for value_name, (of, values) in along.items():
            if of == name:
                out[value_name] = np.full((size, *values.shape[1:]), np.nan)
                out[value_name][members] = values
    return out


def _add_field_data(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Add ``arrays`` as the VTK ``FieldData`` of the UnstructuredGrid in ``path`` (meshio's
    VTU writer drops field data; its reader and ParaView read it): ASCII, all digits."""
    if not arrays:
        return
    import xml.etree.ElementTree as ET

    types = {"f": "Float64", "i": "Int64", "u": "UInt64", "b": "UInt8"}
    tree = ET.parse(path)
    grid = tree.getroot().find("UnstructuredGrid")
    data = ET.Element("FieldData")
    for name, array in arrays.items():
        array = np.asarray(array)
        kind = array.dtype.kind
        element = ET.SubElement(data, "DataArray", type=types[kind], Name=name, NumberOfTuples=str(len(array)),
                                format="ascii")
        if array.ndim == 2:
            element.set("NumberOfComponents", str(array.shape[1]))
        flat = array.reshape(-1)
        # an empty array keeps a blank (an element without text is not read as one)
        element.text = " ".join(repr(float(v)) if kind == "f" else str(int(v)) for v in flat) or " "
    grid.insert(0, data)
    tree.write(path)


def report_left_out(export: str, names: list[str], where: str = "") -> None:
    """The one log line of what a format cannot hold (``names``), and where it is instead."""
    if names:
        log.info("export=%s: %s cannot hold %s; they are in result.h5%s", export, where or "the file",
                 ", ".join(names), "" if export in ("vtu", "xdmf") else " (export=vtu holds every field)")


class ExportFailed(DecrunError):
    """An export that failed after a finished run (its metrics are kept; ``cause`` the error)."""

    def __init__(self, message: str, cause: BaseException | None = None):
        super().__init__(message)
        self.cause = cause


@dataclass
class Export:
    """Base of the export kinds (``export=<name>``): ``write`` puts files into the run directory."""

    name: ClassVar[str] = ""

    def check(self, app) -> None:
        """ConfigError before any work when the fields ``app`` declares
        (:meth:`~decrun.apps.base.App.outputs`) cannot give this export what it needs."""

    def write(self, files: RunFiles, result, mesh, K, app=None) -> list[Path]:  # pragma: no cover - abstract
        """Write the export files of ``result`` on ``mesh`` (``K``: its simplicial complex)
        into the run directory ``files.dir``, under the names of :class:`RunFiles`; ``app``
        (its declared outputs) places the fields."""
        raise NotImplementedError


@dataclass
class NoExport(Export):
    """``export=none``: nothing."""

    name = "none"

    def write(self, files: RunFiles, result, mesh, K, app=None) -> list[Path]:
        return []


@dataclass
class Vtu(Export):
    """``export=vtu``: ``result.vtu`` with every field (module docstring)."""

    name = "vtu"

    def write(self, files: RunFiles, result, mesh, K, app=None) -> list[Path]:
        import meshio

        placed = place_fields(result, mesh, K, app)
        cells, cell_data = _vtu_blocks(mesh, K, placed)
        other = dict(placed.other)
        for name, members in placed.vertex_sets.items():  # an empty set has no cells: field data
            if not len(members):
                other[name] = members
                other.update({a: values for a, (of, values) in placed.along.items() if of == name})
        path = check_file(files.vtu)
        meshio.write(str(path), meshio.Mesh(_points(mesh.vertices), cells, point_data=placed.on[0],
                                            cell_data=cell_data), binary=True)
        _add_field_data(path, other)
        report_left_out(self.name, placed.unwritable, path.name)
        return [path]


@dataclass
class Xdmf(Export):
    """``export=xdmf``: the recorded series as an XDMF time series (module docstring)."""

    name = "xdmf"

    def write(self, files: RunFiles, result, mesh, K, app=None) -> list[Path]:
        import meshio

        from decrun.runner.results.reading import read_result

        h5 = files.result
        series = read_result(h5).series if h5.exists() else dict(result.series)
        n0, n_top = len(mesh.vertices), len(mesh.simplices)
        edges = K.simplices(1) if K is not None else None
        n1 = len(edges) if edges is not None else -1
        steps = len(series.get("step", ()))
        point = {k: v for k, v in series.items() if v.ndim >= 2 and len(v) == steps and v.shape[1] == n0}
        cell = {k: v for k, v in series.items() if v.ndim >= 2 and len(v) == steps and v.shape[1] == n_top
                and k not in point}
        edge = {k: v for k, v in series.items() if v.ndim == 2 and len(v) == steps and v.shape[1] == n1
                and k not in point and k not in cell}
        path = files.xdmf  # TimeSeriesWriter puts its data in series.h5 beside it
        clock = series["time"] if "time" in series else series.get("step", np.zeros(0))
        if steps and (point or cell or edge):
            times = np.asarray(clock, dtype=np.float64)
            frames = [({k: _plain(v[i]) for k, v in point.items()}, {k: _plain(v[i]) for k, v in cell.items()},
                       {k: _plain(v[i]) for k, v in edge.items()}) for i in range(steps)]
            connectivity = _cells(result, mesh, app)  # the connectivity is the cells: held
            left = [name for name in result.fields if name not in series and name not in connectivity]
        else:
            frame, left = _one_frame(result, mesh, K, app)
            times = np.asarray(clock[-1:] if len(clock) else [0.0], dtype=np.float64)
            # an app that records its mesh per step on request (app=smoothing) names the option
            ask = "; `app.record_vertices=true` records the positions at every step" \
                if getattr(app, "record_vertices", None) is False else ""
            log.info("export=xdmf: the run recorded no series over the mesh; series.xdmf holds its fields as one "
                     "step at the end of the run (t = %g)%s", times[0], ask)
            frames = [frame]
        left += [f"series {k}" for k in series if k not in point and k not in cell and k not in edge
                 and k not in ("step", "time")]
        report_left_out(self.name, left, path.name)
        top = _TOP[mesh.simplices.shape[1] - 1]
        points = _points(mesh.vertices)
        written = []
        # meshio's TimeSeriesWriter cannot mix line cells with others (it writes them in place):
        # per-edge series (1-forms) go to a second time series on the edges
        for target, cells, pick in ((path, [(top, np.asarray(mesh.simplices, dtype=np.int64))], (0, 1)),
                                    (files.xdmf_edges, [("line", edges)], (2,))):
            if pick == (2,) and not any(frame[2] for frame in frames):
                continue
            check_file(target), check_file(target.with_suffix(".h5"))
            # the writer puts its HDF5 file in the working directory (by stem): write from out/
            with working_directory(target.parent), meshio.xdmf.TimeSeriesWriter(target.name) as writer:
                writer.write_points_cells(points, cells)
                for t, frame in zip(times, frames, strict=True):
                    if pick == (2,):
                        writer.write_data(float(t), cell_data={k: [v] for k, v in frame[2].items()})
                    else:
                        writer.write_data(float(t), point_data=frame[0], cell_data={k: [v] for k, v in frame[1].items()})
            written += [target, target.with_suffix(".h5")]
        return written


def _one_frame(result, mesh, K, app) -> tuple[tuple[dict, dict, dict], list[str]]:
    """The fields of ``result`` as one XDMF frame (point, top-cell, edge data) and the names
    it cannot hold: a set becomes an indicator (1 on its members) on the vertices or the
    top simplices, the values along it sit on its members (NaN elsewhere); the cells
    themselves are the cells."""
    placed = place_fields(result, mesh, K, app)
    n = mesh.simplices.shape[1] - 1
    point = {**placed.on[0], **_on_sets(len(mesh.vertices), placed.vertex_sets, placed.along)}
    cell = {**placed.on[n], **_on_sets(len(mesh.simplices), placed.top_sets, placed.along)}
    edge = placed.on[1] if n > 1 else {}
    left = [*placed.other, *placed.unwritable, *(name for k in range(2, n) for name in placed.on[k])]
    return (point, cell, edge), left


@contextmanager
def working_directory(path: Path):
    """Work in ``path`` for the block (a writer that writes beside itself), then return."""
    previous = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(previous)


def _triangles(mesh, K) -> np.ndarray:
    """The triangles to draw: the mesh's own, or the border surface of the tetrahedral mesh ``K``."""
    if mesh.simplices.shape[1] == 3:
        return np.asarray(mesh.simplices, dtype=np.int64)
    index, sign = K.border_faces()
    faces = K.simplices(2)[index].copy()
    flip = sign < 0
    faces[flip, 0], faces[flip, 1] = faces[flip, 1], faces[flip, 0].copy()
    return faces


@dataclass
class Ply(Export):
    """``export=ply``: triangles with per-vertex colours of ``field`` (module docstring).

    field : a per-vertex field of the run (one value per vertex; a column ``name:j`` of a
        multi-column one), or ``auto``: the first one-value-per-vertex field
    colormap : a matplotlib colormap name; the colour scale spans the field's min..max
    """

    name = "ply"
    field: str = "auto"
    colormap: str = "viridis"

    def __post_init__(self):
        from matplotlib import colormaps

        if self.colormap not in colormaps:
            near = closest(self.colormap, sorted(colormaps))
            fix = f"did you mean `export.colormap={near}`?" if near is not None else "use `export.colormap=viridis`"
            raise ConfigError(f"export.colormap: unknown colormap {self.colormap!r}; {fix}")

    def check(self, app) -> None:
        outputs = app.outputs()
        if outputs is None:
            return
        vertex = {name: o for name, o in outputs.items() if o.on == "0"}
        if self.field == "auto":
            if any(o.width == 1 and not o.columns for o in vertex.values()) or not app.outputs_complete:
                return
            wide = [name for name, o in vertex.items() if o.width != 1 or o.columns]
            fix = f"name a column, e.g. `export.field={wide[0]}:0`" if wide else "use `export=vtu`"
            raise ConfigError(f"export.field=auto: app={app.name} writes no one-value-per-vertex field to colour by "
                              f"(its per-vertex fields: {sorted(vertex)}); {fix}")
        name, colon, column = self.field.partition(":")
        if name not in vertex:
            if name in outputs or app.outputs_complete:
                raise ConfigError(f"export.field: app={app.name} writes no per-vertex field {name!r} (those are "
                                  f"{sorted(vertex)}); use `export.field=auto`")
            return
        width = vertex[name].width
        if width == 1 and not vertex[name].columns:
            if colon:
                raise ConfigError(f"export.field: {name!r} has one value per vertex, no columns; use "
                                  f"`export.field={name}`")
            return
        if not column.isdigit() or (width is not None and int(column) >= width):
            last = f"{name}:{width - 1}" if width is not None else f"{name}:<j>"
            raise ConfigError(f"export.field: {name!r} has {width if width is not None else 'several'} columns; "
                              f"name one as {name}:0 .. {last}, e.g. `export.field={name}:0`")

    def values(self, result, mesh, K) -> tuple[str, np.ndarray]:
        """(name, (n0,) values) of the field that colours the vertices."""
        point = classify_fields(result.fields, len(mesh.vertices), len(mesh.simplices), None)["point"]
        if self.field == "auto":
            scalar = [name for name, value in point.items() if value.ndim == 1]
            if not scalar:
                raise ConfigError(f"export=ply: the run has no per-vertex field to colour by (fields: "
                                  f"{sorted(result.fields)}); use `export=vtu`")
            return scalar[0], np.asarray(point[scalar[0]], dtype=np.float64)
        name, _, column = self.field.partition(":")
        if name not in point:
            raise ConfigError(f"export.field: {name!r} is not a per-vertex field of this run (those are "
                              f"{sorted(point)}); use `export.field=auto`")
        value = np.asarray(point[name], dtype=np.float64)
        if value.ndim == 2:
            if not column.isdigit() or int(column) >= value.shape[1]:
                raise ConfigError(f"export.field: {name!r} has {value.shape[1]} columns; name one as "
                                  f"{name}:0 .. {name}:{value.shape[1] - 1}")
            value = value[:, int(column)]
        return self.field, value

    def write(self, files: RunFiles, result, mesh, K, app=None) -> list[Path]:
        import meshio
        from matplotlib import colormaps
        from matplotlib.colors import Normalize

        name, value = self.values(result, mesh, K)
        finite = value[np.isfinite(value)]
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        rgba = colormaps[self.colormap](Normalize(lo, hi if hi > lo else lo + 1.0)(value))
        rgb = np.round(255 * rgba[:, :3]).astype(np.uint8)
        point_data = {"red": rgb[:, 0], "green": rgb[:, 1], "blue": rgb[:, 2], name.replace(":", "_"): value}
        path = check_file(files.ply)
        # PLY's vertex indices are 32-bit (meshio casts 64-bit ones itself, with a warning on stderr)
        triangles = _triangles(mesh, K).astype(np.int32)
        meshio.write(str(path), meshio.Mesh(_points(mesh.vertices), [("triangle", triangles)],
                                            point_data=point_data), binary=True)
        base, _, column = name.partition(":")
        left = [other if other != base else f"{base} (but column {column})" for other in result.fields
                if (other != base or column) and other not in _cells(result, mesh, app)]
        report_left_out(self.name, left, f"{path.name} (the triangles, colours of {name})")
        return [path]


@dataclass
class Obj(Export):
    """``export=obj``: triangles with texture coordinates from the field ``uv`` (n0, 2)."""

    name = "obj"
    uv: str = "uv"

    def check(self, app) -> None:
        outputs = app.outputs()
        if outputs is None or self.uv in outputs and outputs[self.uv].on == "0":
            return
        if self.uv in outputs or app.outputs_complete:
            fields = sorted(name for name, o in outputs.items() if o.on == "0")
            raise ConfigError(f"export.uv: app={app.name} writes no per-vertex field {self.uv!r} (its per-vertex "
                              f"fields: {fields}): texture coordinates come from app=parametrization; use `export=vtu`")

    def write(self, files: RunFiles, result, mesh, K, app=None) -> list[Path]:
        if self.uv not in result.fields:
            raise ConfigError(f"export.uv: the run has no field {self.uv!r} (its fields: {sorted(result.fields)}): "
                              "texture coordinates come from app=parametrization; use `export=vtu`")
        uv = np.asarray(result.fields[self.uv], dtype=np.float64)
        if uv.shape != (len(mesh.vertices), 2):
            raise ConfigError(f"export.uv: field {self.uv!r} has shape {uv.shape}, not (n_vertices, 2) = "
                              f"({len(mesh.vertices)}, 2)")
        faces = _triangles(mesh, K) + 1
        path = check_file(files.obj)
        with open(path, "w") as f:
            f.write(f"# decrun: {len(mesh.vertices)} vertices with texture coordinates {self.uv!r}\n")
            np.savetxt(f, _points(mesh.vertices), fmt="v %.17g %.17g %.17g")
            np.savetxt(f, uv, fmt="vt %.17g %.17g")
            np.savetxt(f, np.repeat(faces, 2, axis=1), fmt="f %d/%d %d/%d %d/%d")
        report_left_out(self.name, [name for name in result.fields if name != self.uv
                                    and name not in _cells(result, mesh, app)],
                        f"{path.name} (the triangles, texture coordinates {self.uv})")
        return [path]
