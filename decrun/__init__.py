"""decrun — declarative, reproducible Discrete Exterior Calculus experiments.

Layers (each imports only the ones below it; ``tests/test_layers.py`` enforces it):

``decrun.core``     the DEC core: complexes, geometry, Hodge stars, boundary adaptations,
                    operators, forms, Hodge decomposition, linear solvers
``decrun.methods``  the thesis' methods as pure functions of the complex and operators
``decrun.apps``     thin adapters: typed config → method → Result
``decrun.runner``   the Hydra command line, configs, mesh sources, result files, tables, plots

``decrun.run(overrides)`` and ``decrun.sweep(overrides)`` are the ``decrun`` command called from
Python or a notebook (:mod:`decrun.runner.api`): a :class:`~decrun.runner.api.Run`, a sweep's
table. They, ``decrun.SimplicialComplex`` and ``decrun.DEC`` are imported lazily, so
``import decrun`` (and ``decrun --help``) stays fast. ``import decrun`` changes nothing in ``os.environ``: the
``decrun`` command bounds GNU OpenMP's and OpenBLAS's spinning (:func:`decrun.core.threads.bound_openmp_spin`,
:func:`decrun.core.threads.bound_blas_spin`) before anything loads libgomp or OpenBLAS, and a program of your own
may call them first too.
"""

from decrun.errors import (  # noqa: F401
    ConfigError,
    DecrunError,
    MeshError,
    SolverError,
    TopologyError,
)

__version__ = "0.1.0"

__all__ = ["run", "sweep", "Run", "RunError", "DEC", "SimplicialComplex", "ConfigError", "DecrunError", "MeshError", "SolverError", "TopologyError"]


def __getattr__(name: str):
    if name == "SimplicialComplex":
        from decrun.core.complex import SimplicialComplex

        return SimplicialComplex
    if name == "DEC":
        from decrun.core.dec import DEC

        return DEC
    if name in ("run", "sweep", "Run", "RunError"):
        # by name: a module that imports ``decrun`` for its version (results.provenance) does not
        # depend on the command's API, and the import-linter contracts see no such edge
        import importlib

        return getattr(importlib.import_module("decrun.runner.api"), name)
    raise AttributeError(f"module 'decrun' has no attribute {name!r}")
