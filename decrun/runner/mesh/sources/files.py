"""Mesh files: any file pymeshlab reads, and the sample meshes shipped inside pymeshlab."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from decrun.core.choices import choice_error
from decrun.runner.mesh.base import Mesh, require
from decrun.runner.mesh.files.read import read_mesh_file
from decrun.runner.mesh.source import MeshSource

__all__ = ["File", "Sample", "SAMPLE_MESHES", "sample_mesh_dir", "read_file"]

#: ``mesh.sample`` names → files under :func:`sample_mesh_dir`
SAMPLE_MESHES = {
    "bunny": "bunny.obj",
    "bunny10k_textured": "bunny10k_textured.obj",
    "cow": "cow.obj",
    "airplane": "airplane.obj",
    "colored_airplane": "colored_airplane.ply",
    "bone": "bone.ply",
    "face": "rangemaps/face000.ply",
    "cube": "cube.obj",
}


def sample_mesh_dir() -> Path:
    """Directory of the sample meshes shipped inside the installed pymeshlab package, found
    without importing pymeshlab (its import loads MeshLab's libraries; reading a sample needs
    none of them)."""
    from importlib.util import find_spec

    spec = find_spec("pymeshlab")
    if spec is None or not spec.submodule_search_locations:
        raise ModuleNotFoundError("mesh.sample: the pymeshlab package is not installed (pip install pymeshlab)")
    return Path(spec.submodule_search_locations[0]).resolve() / "tests" / "sample_meshes"


def read_file(path: Path, key: str, label: str) -> Mesh:
    """The mesh in ``path`` read and validated by :func:`decrun.runner.mesh.files.read.read_mesh_file`
    before anything native sees it (pymeshlab silently drops faces with a repeated vertex,
    NaN vertices, or crashes on OBJ index 0). Triangles (polygons split into fans, counted)
    or tetrahedra; ``meta`` records the format and what the file held (``file_counts``)."""
    found = read_mesh_file(path, key=key)
    meta = {"source": label, "label": Path(path).stem, "path": str(path), "file_format": found.format,
            "file_counts": dict(found.counts)}
    return Mesh(found.vertices, found.cells, meta)


@dataclass
class File(MeshSource):
    """A triangle or tetrahedral mesh file by ``path``: OBJ, OFF, PLY, STL (decrun's own
    validating readers) and the volume formats meshio reads (VTK, VTU, Gmsh, Medit, ...)."""

    name = "file"
    path: str = ""

    def __post_init__(self):
        super().__post_init__()
        require(bool(self.path), "path", "is empty; give the mesh file, e.g. mesh.path=/data/dragon.ply")

    def make(self) -> Mesh:
        return read_file(Path(str(self.path)).expanduser(), "mesh.path", "file")


@dataclass
class Sample(MeshSource):
    """A mesh shipped with pymeshlab, by name (:data:`SAMPLE_MESHES`). The samples are raw
    scans and models with known defects (unreferenced vertices, bowtie vertices), so
    ``repair`` and ``clean`` are on by default, and Y-up models are turned Z-up
    (``up_axis: auto``, :data:`decrun.runner.mesh.repair.UP_AXIS`)."""

    name = "sample"
    sample: str = "bunny10k_textured"
    repair: bool = True
    clean: bool = True
    up_axis: str = "auto"

    def __post_init__(self):
        super().__post_init__()
        if self.sample not in SAMPLE_MESHES:
            raise choice_error("mesh.sample", self.sample, sorted(SAMPLE_MESHES))

    def auto_up_axis(self) -> str:
        """The sample's own up axis (:data:`decrun.runner.mesh.repair.UP_AXIS`), else ``z``."""
        from decrun.runner.mesh.repair import UP_AXIS

        return UP_AXIS.get(self.sample, "z")

    def make(self) -> Mesh:
        mesh = read_file(sample_mesh_dir() / SAMPLE_MESHES[self.sample], "mesh.sample", "sample")
        mesh.meta["label"] = self.sample
        return mesh
