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

The source lives beside the run (not in :mod:`decrun.runner.mesh`) because it joins the two
layers below, the result files and the meshes (pyproject's runner layer contract).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from decrun.errors import ConfigError, CorruptFileError
from decrun.runner.files import RunFiles
from decrun.runner.mesh import Mesh, MeshSource, require
from decrun.runner.results import read_result

__all__ = ["ResultMesh"]


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
        if "vertices" not in stored.mesh or "simplices" not in stored.mesh:
            raise ConfigError(f"mesh.path={str(self.path)!r}: the result holds no mesh")
        simplices = np.asarray(stored.mesh["simplices"], dtype=np.int64)
        vertices, source = self._vertices(stored, path)
        meta = {"source": "result", "label": f"result:{path.parent.name}", "path": str(path),
                "result_vertices": source, "result_status": stored.status}
        if self.field:
            meta["field"] = self._field(stored, path, len(vertices), len(simplices))
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
        field = {"name": self.field, "values": values, "on": where, "path": str(path)}
        if where == "edges":
            field["edges"] = np.asarray(edges, dtype=np.int64)
        return field
