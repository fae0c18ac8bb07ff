"""``mesh=result``: the mesh of a previous run's ``result.h5`` — and optionally one of its fields
as initial data — so that runs chain: a smoothed mesh feeds a parametrization, a designed
vector field feeds a fluid.

``vertices`` picks the positions: ``mesh`` (as stored: the run's input mesh), a field name
holding (n0, d) positions, or ``auto`` (``vertices_final`` when the run has it — the smoothed
mesh of ``app=smoothing`` — else the stored mesh). ``field`` names a field handed to the
next app as ``ctx.meta['field']`` = {name, values, on: vertices | edges | faces, path}; the
apps that take initial data say so (``app=fluid app.initial=mesh_field``). A field follows
the mesh only while its simplices stay the same: ``refine``, ``holes`` and ``clean`` are
refused together with it.

What is read is checked against the mesh it belongs to before use: the stored
simplices must be whole vertex indices of the stored vertices (floats with fractions are
not truncated, out-of-range indices not taken), a chained field finite; each refusal is a
ConfigError naming ``mesh.path`` or ``mesh.field``. A source result that is not complete
(a failed, interrupted or killed run, or a journal of one still running) is used with one
warning in the log and the metric ``chained_result_status`` (its status; absent when the
source is complete).

The source lives beside the run (not in :mod:`decrun.runner.mesh`) because it joins the two
layers below, the result files and the meshes (pyproject's runner layer contract).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from decrun.errors import ConfigError, CorruptFileError
from decrun.runner.io.files import RunFiles
from decrun.runner.mesh import Mesh, MeshSource, require
from decrun.runner.results import read_result
from decrun.runner.results.reading import CHAINED_STATUS, chained_status

__all__ = ["ResultMesh", "integral_simplices"]

def _count(n: int) -> str:
    return "1 simplex" if n == 1 else f"{n} simplices"


def integral_simplices(raw: np.ndarray, n_vertices: int, where: str) -> np.ndarray:
    """``raw`` (a stored simplex array) as (m, k+1) int64, or a ConfigError starting with
    ``where`` when it is not one: not 2-D, not numeric, an index with a fraction, NaN or
    ±inf (never truncated) or outside [0, n_vertices)."""
    raw = np.asarray(raw)
    if raw.ndim != 2 or raw.dtype.kind not in "iuf" or raw.shape[1] < 2:
        raise ConfigError(f"{where}: /mesh/simplices has dtype {raw.dtype} and shape {raw.shape}, not an (m, k+1) "
                          "array of vertex indices (not a result decrun wrote); chain another run's result")
    if raw.dtype.kind == "f":
        bad = np.flatnonzero((~np.isfinite(raw) | (raw != np.round(raw))).any(axis=1))
        if bad.size:
            row = raw[bad[0]].tolist()
            raise ConfigError(f"{where}: /mesh/simplices holds vertex indices that are not whole numbers in "
                              f"{_count(bad.size)} (e.g. simplex {bad[0]}: {row}); refused, not truncated (the "
                              "file was altered); chain another run's result")
    bad = np.flatnonzero(((raw < 0) | (raw >= n_vertices)).any(axis=1))
    if bad.size:
        row = raw[bad[0]].tolist()
        raise ConfigError(f"{where}: /mesh/simplices holds vertex indices outside [0, {n_vertices}) in "
                          f"{_count(bad.size)} (e.g. simplex {bad[0]}: {row}; the mesh has {n_vertices} vertices); chain "
                          "another run's result")
    return raw.astype(np.int64)


@dataclass
class ResultMesh(MeshSource):
    """Options of ``mesh=result`` (module docstring)."""

    name = "result"
    path: str = ""
    vertices: str = "auto"
    field: str = ""

    def __post_init__(self):
        super().__post_init__()
        require(bool(self.path), "path", "is empty; give a previous run's result file, e.g. "
                                         "mesh.path=outputs/runs/<stamp>/result.h5")
        if self.field:
            changing = [name for name, on in (("refine", self.refine != "none"), ("clean", self.clean),
                                              ("holes", bool(self.hole_balls or self.hole_boxes))) if on]
            if changing:
                raise ConfigError(f"mesh.field={self.field}: the field lives on the stored mesh's simplices, which "
                                  f"mesh.{changing[0]} changes; drop one of them")

    def make(self) -> Mesh:
        path = Path(str(self.path)).expanduser()
        if path.is_dir():
            path = RunFiles(path).result
        try:
            stored = read_result(path)
        except FileNotFoundError:
            raise ConfigError(f"mesh.path={str(self.path)!r}: no result file there (a run directory or its "
                              "result.h5)") from None
        except (OSError, CorruptFileError) as exc:
            raise ConfigError(f"mesh.path={str(self.path)!r}: cannot read it as a decrun result ({exc})") from None
        where = f"mesh.path={str(self.path)!r}"
        if "vertices" not in stored.mesh or "simplices" not in stored.mesh:
            raise ConfigError(f"{where}: the result holds no mesh")
        vertices, source = self._vertices(stored, path)
        simplices = integral_simplices(stored.mesh["simplices"], len(vertices), f"{where} ({path})")
        meta = {"source": "result", "label": f"result:{path.parent.name}", "path": str(path),
                "result_vertices": source, "result_status": stored.status}
        if self.field:
            meta["field"] = self._field(stored, path, len(vertices), len(simplices))
        status = chained_status(stored, where)  # after the refusals: a refused source needs no warning
        if status:
            meta[CHAINED_STATUS] = status
        return Mesh(vertices, simplices, meta)

    def _vertices(self, stored, path: Path) -> tuple[np.ndarray, str]:
        stored_vertices = np.asarray(stored.mesh["vertices"], dtype=np.float64)
        name = self.vertices
        if name == "auto":
            name = "vertices_final" if "vertices_final" in stored.fields else "mesh"
        if name == "mesh":
            return stored_vertices, "mesh"
        if name not in stored.fields:
            raise ConfigError(f"mesh.vertices={self.vertices}: {path} has no field {name!r} (its fields: "
                              f"{sorted(stored.fields)}); use `mesh.vertices=mesh`")
        values = np.asarray(stored.fields[name], dtype=np.float64)
        if values.shape != stored_vertices.shape:
            raise ConfigError(f"mesh.vertices={name}: the field has shape {values.shape}, not the mesh's vertex "
                              f"array {stored_vertices.shape}; use `mesh.vertices=mesh`")
        if not np.all(np.isfinite(values)):
            raise ConfigError(f"mesh.vertices={name}: the field has non-finite positions (a diverged run?); "
                              "use `mesh.vertices=mesh`")
        return values, name

    def _field(self, stored, path: Path, n_vertices: int, n_top: int) -> dict:
        if self.field not in stored.fields:
            raise ConfigError(f"mesh.field={self.field}: {path} has no such field (its fields: "
                              f"{sorted(stored.fields)})")
        values = np.asarray(stored.fields[self.field])
        if values.ndim == 0:
            raise ConfigError(f"mesh.field={self.field}: {path} stores it as one number, not a field on the mesh; "
                              f"chain another field (its fields: {sorted(stored.fields)})")
        on = stored.field_on.get(self.field)
        edges = stored.mesh.get("edges")
        if on == "mesh/edges" or (on is None and edges is not None and values.shape[:1] == (len(edges),)
                                  and values.shape[0] not in (n_vertices, n_top)):
            where = "edges"
        elif values.shape[0] == n_vertices:
            where = "vertices"
        elif values.shape[0] == n_top:
            where = "faces"
        else:
            raise ConfigError(f"mesh.field={self.field}: shape {values.shape} is neither per vertex ({n_vertices}), "
                              f"per edge nor per top simplex ({n_top})")
        if values.dtype.kind not in "biufc":
            raise ConfigError(f"mesh.field={self.field}: {path} stores it as {values.dtype}, not numbers; chain "
                              f"another field (its fields: {sorted(stored.fields)})")
        bad = np.flatnonzero(~np.isfinite(values.reshape(len(values), -1)).all(axis=1))
        if bad.size:
            raise ConfigError(f"mesh.field={self.field}: {path} holds NaN or ±inf in it on {bad.size} {where} (e.g. "
                              f"{dict(vertices='vertex', edges='edge', faces='face')[where]} {bad[0]}: the source run diverged?); chain a finite field, or none "
                              "(`mesh.field=''`, with app=fluid also `app.initial=random`)")
        field = {"name": self.field, "values": values, "on": where, "path": str(path)}
        if where == "edges":
            field["edges"] = np.asarray(edges, dtype=np.int64)
        return field
