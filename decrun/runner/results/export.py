"""Export of a run for other programs (the ``export`` config group): ParaView, MeshLab, any
OBJ reader. Written into the run directory beside ``result.h5`` after the run.

=============  ===========================================================================
``none``       nothing (the default)
``vtu``        ``result.vtu``: the mesh (triangles or tetrahedra) with every field on it —
               per vertex as point data, per top simplex as cell data, per edge (1-forms) as
               cell data of a second block of ``line`` cells (NaN on the other block), and
               the other arrays (e.g. eigenvalues) as field data
``xdmf``       ``series.xdmf`` + ``series.h5`` (HDF5 heavy data): the recorded series
               over the mesh as a time series (meshio's ``TimeSeriesWriter``; times from the
               series ``time`` when recorded, else ``step``), which ParaView plays as an
               animation; per-edge series (1-forms, e.g. the fluid's flux) in
               ``series_edges.xdmf`` on line cells (meshio cannot mix them with triangles in
               one time series); a run without such series gets its fields as one step at t = 0
``ply``        ``result.ply``: the triangles (of the border surface for tetrahedra) with
               per-vertex colours (``red``/``green``/``blue`` uint8) of one per-vertex field
               through a colormap, and that field itself, for MeshLab
``obj``        ``result.obj``: the triangles with texture coordinates ``vt`` from the field
               ``uv`` (the parametrization), faces ``f a/a b/b c/c``
=============  ===========================================================================

Arrays are exported as they are (float64, ints; bools as uint8); nothing is resampled.
"""

from __future__ import annotations

import logging
import os
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from decrun.errors import ConfigError
from decrun.runner.files import RunFiles
from decrun.runner.paths import check_file

__all__ = ["Export", "NoExport", "Vtu", "Xdmf", "Ply", "Obj", "classify_fields"]

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
    """Split ``fields`` (name → array, or a FieldOnEdges) by where they live:
    ``{"point": {...}, "cell": {...}, "edge": {...}, "other": {...}}``. A 1-form wrapped in
    FieldOnEdges goes to ``edge``; else the first axis decides (vertices first)."""
    from decrun.apps.base import FieldOnEdges

    out: dict[str, dict] = {"point": {}, "cell": {}, "edge": {}, "other": {}}
    for name, value in fields.items():
        if isinstance(value, FieldOnEdges):
            out["edge"][name] = _plain(value.values)
            continue
        array = np.asarray(value)
        if array.dtype.kind not in "biuf" or array.ndim == 0:
            out["other"][name] = np.atleast_1d(array) if array.dtype.kind in "biuf" else None
            continue
        if array.shape[0] == n_vertices:
            out["point"][name] = _plain(array)
        elif array.shape[0] == n_top:
            out["cell"][name] = _plain(array)
        elif n_edges is not None and array.shape[0] == n_edges and array.ndim == 1:
            out["edge"][name] = _plain(array)
        else:
            out["other"][name] = _plain(array)
    out["other"] = {k: v for k, v in out["other"].items() if v is not None}
    return out


def _blocks(simplices: np.ndarray, edges: np.ndarray | None, cell: dict, edge: dict):
    """meshio cells and cell_data: the top simplices, plus a ``line`` block when there are
    edge fields (each cell field NaN on the other block)."""
    top = _TOP[simplices.shape[1] - 1]
    cells = [(top, np.asarray(simplices, dtype=np.int64))]
    if not edge:
        return cells, {name: [value] for name, value in cell.items()}
    cells.append(("line", np.asarray(edges, dtype=np.int64)))
    data = {}
    for name, value in cell.items():
        data[name] = [value.astype(np.float64), np.full((len(edges), *value.shape[1:]), np.nan)]
    for name, value in edge.items():
        data[name] = [np.full((len(simplices), *value.shape[1:]), np.nan), value.astype(np.float64)]
    return cells, data


@dataclass
class Export:
    """Base of the export kinds (``export=<name>``): ``write`` puts files into the run directory."""

    name: ClassVar[str] = ""

    def write(self, files: RunFiles, result, mesh, K) -> list[Path]:  # pragma: no cover - abstract
        """Write the export files of ``result`` on ``mesh`` (``K``: its simplicial complex)
        into the run directory ``files.dir``, under the names of :class:`RunFiles`."""
        raise NotImplementedError


@dataclass
class NoExport(Export):
    """``export=none``: nothing."""

    name = "none"

    def write(self, files: RunFiles, result, mesh, K) -> list[Path]:
        return []


def _layout(result, mesh, K):
    edges = K.simplices(1) if K is not None else None
    groups = classify_fields(result.fields, len(mesh.vertices), len(mesh.simplices),
                             len(edges) if edges is not None else None)
    return groups, edges


@dataclass
class Vtu(Export):
    """``export=vtu``: ``result.vtu`` with every field (module docstring)."""

    name = "vtu"

    def write(self, files: RunFiles, result, mesh, K) -> list[Path]:
        import meshio

        groups, edges = _layout(result, mesh, K)
        cells, cell_data = _blocks(mesh.simplices, edges, groups["cell"], groups["edge"])
        path = check_file(files.vtu)
        meshio.write(str(path), meshio.Mesh(_points(mesh.vertices), cells, point_data=groups["point"],
                                            cell_data=cell_data, field_data=groups["other"]), binary=True)
        return [path]


@dataclass
class Xdmf(Export):
    """``export=xdmf``: the recorded series as an XDMF time series (module docstring)."""

    name = "xdmf"

    def write(self, files: RunFiles, result, mesh, K) -> list[Path]:
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
        if steps and (point or cell or edge):
            times = np.asarray(series["time"] if "time" in series else series["step"], dtype=np.float64)
            frames = [({k: _plain(v[i]) for k, v in point.items()}, {k: _plain(v[i]) for k, v in cell.items()},
                       {k: _plain(v[i]) for k, v in edge.items()}) for i in range(steps)]
        else:
            groups, edges = _layout(result, mesh, K)
            log.info("export=xdmf: the run recorded no series over the mesh; series.xdmf holds its fields as one "
                     "step at t = 0")
            times = np.zeros(1)
            frames = [(groups["point"], groups["cell"], groups["edge"])]
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
            with _working_directory(target.parent), meshio.xdmf.TimeSeriesWriter(target.name) as writer:
                writer.write_points_cells(points, cells)
                for t, frame in zip(times, frames):
                    if pick == (2,):
                        writer.write_data(float(t), cell_data={k: [v] for k, v in frame[2].items()})
                    else:
                        writer.write_data(float(t), point_data=frame[0], cell_data={k: [v] for k, v in frame[1].items()})
            written += [target, target.with_suffix(".h5")]
        return written


@contextmanager
def _working_directory(path: Path):
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
            raise ConfigError(f"export.colormap: unknown colormap {self.colormap!r}; use `export.colormap=viridis`")

    def values(self, result, mesh, K) -> tuple[str, np.ndarray]:
        """(name, (n0,) values) of the field that colours the vertices."""
        groups, _ = _layout(result, mesh, K)
        point = groups["point"]
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

    def write(self, files: RunFiles, result, mesh, K) -> list[Path]:
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
        meshio.write(str(path), meshio.Mesh(_points(mesh.vertices), [("triangle", _triangles(mesh, K))],
                                            point_data=point_data), binary=True)
        return [path]


@dataclass
class Obj(Export):
    """``export=obj``: triangles with texture coordinates from the field ``uv`` (n0, 2)."""

    name = "obj"
    uv: str = "uv"

    def write(self, files: RunFiles, result, mesh, K) -> list[Path]:
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
        return [path]
