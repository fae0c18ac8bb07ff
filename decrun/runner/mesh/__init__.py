"""Meshes for the runner: the :class:`Mesh` record (:mod:`.base`), the :class:`MeshSource`
base (:mod:`.source`), the sources of the ``mesh`` group (:mod:`.sources`), the ``mesh.post``
steps (:mod:`.post`) with the hole cuts (:mod:`.cut`, :mod:`.holes`) and pymeshlab's repair
(:mod:`.repair`), the file readers (:mod:`.files`) and the cache of the meshes pymeshlab
makes (:mod:`.cache`).

Layers (tests/test_layers.py): ``sources > source > post > cut | holes | repair > base | files > cache``.
"""

from decrun.runner.mesh.base import (
                                     MAX_TRIANGLES,
                                     SIZE_RANGE,
                                     Mesh,
                                     check_mesh,
                                     check_size,
                                     from_meshset,
                                     mesh_hash,
                                     pymeshlab_primitive,
                                     require,
                                     require_surface,
                                     require_triangles,
                                     to_meshset,
)
from decrun.runner.mesh.source import MeshSource

__all__ = ["Mesh", "MeshSource", "mesh_hash", "check_mesh", "check_size", "require", "require_triangles",
           "require_surface", "MAX_TRIANGLES", "SIZE_RANGE", "from_meshset", "to_meshset", "pymeshlab_primitive"]
