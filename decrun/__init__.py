"""decrun — declarative, reproducible Discrete Exterior Calculus experiments."""

from decrun.errors import (  # noqa: F401
    ConfigError,
    DecrunError,
    MeshError,
    SolverError,
    TopologyError,
)

__version__ = "0.1.0"
