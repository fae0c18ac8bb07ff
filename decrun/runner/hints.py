"""Error hints as the command-line override that fixes them.

Lower layers know nothing of the CLI: a core error may carry a fix for Python callers
(``DecrunError.python_hint``, e.g. ``orient='fix'``). :func:`cli_message` turns such an
error into the message a ``decrun`` user reads — the Python hint replaced by the override
that fixes the same problem, written in backticks exactly as it is typed
(``… use `mesh.repair=true```). tests/runner/test_hints.py runs every override a hint
names and checks that it fixes the run.
"""

from __future__ import annotations

from decrun.errors import (
    DecrunError,
    DegenerateSimplexError,
    DuplicateSimplexError,
    NonManifoldError,
    NonOrientableError,
    OrientationError,
    RepeatedVertexError,
    UnreferencedVertexError,
)

__all__ = ["cli_hint", "cli_message", "PLUGIN_EXTRAS"]

#: Hydra group → option → (the plugin, the decrun extra that installs it)
PLUGIN_EXTRAS = {
    "hydra/launcher": {"joblib": ("hydra-joblib-launcher", "parallel"),
                       "submitit_local": ("hydra-submitit-launcher", "slurm"),
                       "submitit_slurm": ("hydra-submitit-launcher", "slurm"),
                       "ray": ("hydra-ray-launcher", "ray"), "ray_aws": ("hydra-ray-launcher", "ray")},
    "hydra/sweeper": {"optuna": ("hydra-optuna-sweeper", "optuna")},
}

#: error class → (the override that fixes it, what it does); first match wins
MESH_FIXES = (
    (NonOrientableError, None),
    (OrientationError, ("mesh.orient=fix", "re-orients each connected component")),
    ((UnreferencedVertexError, NonManifoldError, DuplicateSimplexError, DegenerateSimplexError,
      RepeatedVertexError), ("mesh.repair=true", "runs pymeshlab's repair filters, every change counted")),
)


#: overrides that fix triangle meshes only (pymeshlab's repair refuses tetrahedra)
SURFACE_ONLY = ("mesh.repair=true",)


def cli_hint(exc: DecrunError, mesh_source=None, dimension: int | None = None) -> str:
    """``"use `<override>` (<what it does>)"`` for a mesh error the config can fix, else ``""``.
    No hint when ``mesh_source`` already has that option on, nor a surface-only fix for a
    mesh of ``dimension`` 3."""
    for kinds, fix in MESH_FIXES:
        if isinstance(exc, kinds):
            if fix is None:
                return ""
            override, what = fix
            if dimension == 3 and override in SURFACE_ONLY:
                return ""
            key, _, value = override.partition("=")
            current = getattr(mesh_source, key.split(".", 1)[1], None) if mesh_source is not None else None
            if current is not None and str(current).lower() == value:
                return ""
            return f"use `{override}` ({what})"
    return ""


def cli_message(exc: DecrunError, mesh_source=None, dimension: int | None = None) -> str:
    """The error's message for the command line: its Python hint replaced by the CLI one
    (``dimension``: of the mesh, see :func:`cli_hint`)."""
    message = getattr(exc, "message", None) or str(exc)
    hint = cli_hint(exc, mesh_source, dimension)
    return f"{message}; {hint}" if hint else message
