"""Mesh sources (the ``mesh`` config group): one module per source family, each a
:class:`decrun.runner.mesh.source.MeshSource` dataclass named by ``_target_`` in ``conf/mesh/<name>.yaml``."""
