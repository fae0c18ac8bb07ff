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

__all__ = ["cli_hint", "cli_message", "memory_hint", "plugin_name", "PLUGIN_EXTRAS", "resolution_error",
           "resolution_message", "default_override"]

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


# ----------------------------------------------------------------------------------
# out of memory
# ----------------------------------------------------------------------------------

#: mesh options that make more simplices when larger; and when smaller
MESH_SIZE_KEYS = ("subdiv", "nx", "ny", "cells", "major_segments", "minor_segments", "sides", "target_faces",
                  "refinement", "refine_iterations")
MESH_BOUND_KEYS = ("max_area",)


def plugin_name(cfg, group: str) -> str | None:
    """The ``name`` of the plugin class ``cfg[group]._target_`` names (``grid``, ``hodge``),
    or None when it names none that imports (a run that failed before it was built)."""
    import importlib

    module, _, cls = str(cfg[group].get("_target_", "")).rpartition(".") if group in cfg else ("", "", "")
    try:
        return getattr(importlib.import_module(module), cls).name or None
    except Exception:  # not importable: no name to give
        return None


def _option_defaults(cfg, group: str) -> dict:
    """The values of ``conf/<group>/<name>.yaml`` for the plugin ``cfg[group]`` names
    (:func:`plugin_name`), or {} when there is no such file."""
    from omegaconf import OmegaConf

    from decrun.runner.job.config import load_option

    name = plugin_name(cfg, group)
    try:
        return OmegaConf.to_container(load_option(group, name), resolve=True) if name else {}
    except Exception:  # a plugin outside conf/: no default to offer
        return {}


def _defaults(overrides: list[str]) -> str:
    return "the defaults" if len(overrides) > 1 else "the default"


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def memory_hint(cfg, shape: tuple | None = None) -> str:
    """The settings to lower after a run ran out of memory, as overrides that fix it
    (``""`` when none can be named): the integer options whose value is a dimension of the
    array that could not be allocated (``app.quadrature_order=100000000`` for a 10⁸ × 10⁸
    array), set back to their default; else the mesh's resolution options above their
    defaults (``mesh.nx``, ``mesh.subdiv``, …; ``mesh.max_area`` below it), set back to them."""
    from omegaconf import OmegaConf

    groups = [g for g in ("app", "mesh", "solver", "operator", "boundary") if g in cfg]
    dims = {int(d) for d in (shape or ()) if int(d) > 1}
    if dims:
        found = []
        for group in groups:
            values = OmegaConf.to_container(cfg[group], resolve=True)
            defaults = _option_defaults(cfg, group)
            for key, value in values.items():
                default = defaults.get(key)
                if _is_int(value) and value in dims and _is_int(default) and default < value:
                    found.append(f"{group}.{key}={default}")
        if found:
            keys = ", ".join(f.split("=")[0] for f in found)
            return f"lower {keys} (a dimension of that array): use `{' '.join(found)}` ({_defaults(found)})"
    if "mesh" not in cfg:
        return ""
    values = OmegaConf.to_container(cfg.mesh, resolve=True)
    defaults = _option_defaults(cfg, "mesh")
    coarser = [f"mesh.{key}={defaults[key]}" for key, value in values.items() if key in defaults and (
        (key in MESH_SIZE_KEYS and _is_int(value) and _is_int(defaults[key]) and value > defaults[key])
        or (key in MESH_BOUND_KEYS and isinstance(value, (int, float)) and 0 < value < defaults[key]))]
    if coarser:
        return f"use a coarser mesh: `{' '.join(coarser)}` ({_defaults(coarser)})"
    return "use a coarser mesh or smaller app options"


# ----------------------------------------------------------------------------------
# interpolations that do not resolve
# ----------------------------------------------------------------------------------


def resolution_error(exc: BaseException) -> BaseException | None:
    """``exc`` or the first exception in its chain that is OmegaConf's refusal to resolve
    an interpolation (an unset ``${oc.env:NAME}``, an unknown resolver, a key that refers
    to itself or to nothing, invalid ``${…}`` syntax), or None."""
    from omegaconf.errors import GrammarParseError, InterpolationResolutionError

    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, (InterpolationResolutionError, GrammarParseError)):
            return exc
        exc = exc.__cause__ or exc.__context__
    return None


def _raw_value(cfg, key: str):
    """The unresolved value at the dotted ``key`` of ``cfg`` (the ``${…}`` text), or None."""
    from omegaconf import OmegaConf

    parent, _, leaf = key.rpartition(".")

    try:
        node = OmegaConf.select(cfg, parent, throw_on_resolution_failure=False) if parent else cfg
        if not OmegaConf.is_config(node):
            return None
        container = OmegaConf.to_container(node, resolve=False)  # interpolations kept as their text
        if isinstance(container, list):
            return container[int(leaf)]
        return container.get(leaf) if isinstance(container, dict) else None
    except Exception:  # noqa: BLE001 — a key path OmegaConf cannot walk (list indices): no value to show
        return None


def _override_value(value) -> str | None:
    """``value`` as Hydra's override grammar types it (``null``, ``true``, ``0.5``, ``[1,2]``,
    a plain word), or None when it has no short plain spelling."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        import re

        return value if re.fullmatch(r"[A-Za-z_][\w./-]*", value) and value not in ("null", "true", "false") \
            else None
    if isinstance(value, list):
        items = [_override_value(v) for v in value]
        return None if any(i is None for i in items) else f"[{','.join(items)}]"
    return None


def default_override(cfg, key: str) -> str | None:
    """``<key>=<its default>`` (the value of the option file ``cfg``'s plugin names, or of the
    root schema for ``progress``, ``checkpoint.*``, ``optimize.*``), typed as on the command
    line; None when the key has no default (an option the command added with ``+``)."""
    from omegaconf import OmegaConf

    from decrun.runner.job.config import PLUGIN_GROUPS, DecrunConfig

    root, _, rest = key.partition(".")
    try:
        if root in PLUGIN_GROUPS:
            defaults = OmegaConf.create(_option_defaults(cfg, root))
            found = OmegaConf.select(defaults, rest, default="<absent>") if rest else "<absent>"
        else:
            found = OmegaConf.select(OmegaConf.structured(DecrunConfig), key, default="<absent>")
        found = OmegaConf.to_container(found) if OmegaConf.is_config(found) else found
    except Exception:  # noqa: BLE001 — not a path OmegaConf can walk: no default to offer
        return None
    if isinstance(found, dict) or (isinstance(found, str) and found == "<absent>"):
        return None
    value = getattr(found, "value", None)
    if isinstance(value, str):  # a Choice member
        found = value
    text = _override_value(found)
    return f"{key}={text}" if text is not None else None


#: the resolvers an interpolation may name: OmegaConf's (``oc.*``), Hydra's and decrun's; the
#: ones registered in this process are listed for an unknown one (OmegaConf has no public list)
KNOWN_RESOLVERS = ("oc.env", "oc.select", "oc.create", "oc.decode", "oc.deprecated", "oc.dict.keys",
                   "oc.dict.values", "hydra", "now", "python_version", "decrun.stamp")


def resolution_message(exc: BaseException, cfg=None) -> str | None:
    """``<key>='<value>': <why it does not resolve>; use `<key>=<default>` (the default)``
    for an interpolation OmegaConf could not resolve (:func:`resolution_error` in ``exc``'s
    chain), else None. ``cfg``: the config, for the raw value and the default."""
    import re

    error = resolution_error(exc)
    if error is None:
        return None
    from omegaconf import OmegaConf

    key = str(getattr(error, "full_key", "") or "") or "the config"
    text = " ".join(str(getattr(error, "msg", None) or error).split())
    text = text.split(" full_key:")[0]
    raw = _raw_value(cfg, key) if cfg is not None and key != "the config" else None
    where = f"{key}={raw!r}" if isinstance(raw, str) else key
    env = re.search(r"Environment variable '([^']+)' not found", text)
    resolver = re.search(r"Unsupported interpolation type (\S+)", text)
    missing = re.search(r"Interpolation key '([^']+)' not found", text)
    if env:
        cause = f"the environment variable {env.group(1)} is not set; set it, or give a default in the " \
                f"interpolation (${{oc.env:{env.group(1)},<default>}})"
    elif resolver:
        known = ", ".join(name for name in KNOWN_RESOLVERS if OmegaConf.has_resolver(name))
        cause = f"there is no resolver {resolver.group(1)!r} (resolvers: {known})"
    elif "Recursive interpolation" in text:
        cause = "the interpolation refers to itself (a cycle)"
    elif missing:
        cause = f"the interpolation refers to {missing.group(1)}, which the config does not have"
    else:
        cause = f"the interpolation cannot be resolved ({text})"
    fix = default_override(cfg, key) if cfg is not None and key != "the config" else None
    return f"{where}: {cause}; " + (f"use `{fix}` (the default)" if fix else
                                    f"drop the override of {key}, or give it a plain value")
