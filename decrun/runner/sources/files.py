"""Mesh files: any file pymeshlab reads, and the sample meshes shipped inside pymeshlab."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from decrun.errors import MeshError
from decrun.runner.meshes import Mesh, MeshSource, from_meshset, require

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
    """Directory of the sample meshes shipped inside the installed pymeshlab package."""
    import pymeshlab

    return Path(pymeshlab.__file__).resolve().parent / "tests" / "sample_meshes"


def read_file(path: Path, key: str, label: str) -> Mesh:
    """The triangle mesh in ``path`` (read by pymeshlab); ``key`` names the config key in errors."""
    import pymeshlab

    if not path.exists():
        raise MeshError(f"{key}={str(path)!r}: file not found")
    if not path.is_file():
        raise MeshError(f"{key}={str(path)!r}: not a file")
    if path.stat().st_size == 0:
        raise MeshError(f"{key}={str(path)!r}: the file is empty")
    ms = pymeshlab.MeshSet()
    try:
        ms.load_new_mesh(str(path))
    except Exception as exc:  # pymeshlab.PyMeshLabException and friends
        raise MeshError(f"{key}={str(path)!r}: pymeshlab cannot read it: {str(exc).strip()}") from exc
    vertices, faces = from_meshset(ms, f"{key}={str(path)!r}")
    return Mesh(vertices, faces, {"source": label, "label": path.stem, "path": str(path)})


@dataclass
class File(MeshSource):
    """Any triangle mesh pymeshlab reads (obj, ply, off, stl, ...), by ``path``."""

    name = "file"
    path: str = ""

    def __post_init__(self):
        super().__post_init__()
        require(bool(self.path), "path", "is empty; give the mesh file, e.g. mesh.path=/data/dragon.ply")

    def make(self) -> Mesh:
        return read_file(Path(str(self.path)).expanduser(), "mesh.path", "file")


@dataclass
class Sample(MeshSource):
    """A mesh shipped with pymeshlab, by name (:data:`SAMPLE_MESHES`)."""

    name = "sample"
    sample: str = "bunny10k_textured"

    def __post_init__(self):
        super().__post_init__()
        require(self.sample in SAMPLE_MESHES, "sample",
                f"unknown sample {self.sample!r}; choose one of {sorted(SAMPLE_MESHES)}")

    def make(self) -> Mesh:
        mesh = read_file(sample_mesh_dir() / SAMPLE_MESHES[self.sample], "mesh.sample", "sample")
        mesh.meta["label"] = self.sample
        return mesh
