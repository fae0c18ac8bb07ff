"""Mesh file readers: :func:`read_mesh_file` (:mod:`.read`) dispatches to decrun's own
OBJ/OFF/PLY/STL readers (:mod:`.obj`, :mod:`.off`, :mod:`.ply`, :mod:`.stl`, on the
tokenizer :mod:`.text`) and meshio for volume formats (:mod:`.volume`); :mod:`.checks`
validates what each reader returns."""

from decrun.runner.mesh.files.read import MeshFile, read_mesh_file, supported_extensions

__all__ = ["MeshFile", "read_mesh_file", "supported_extensions"]
