"""How the DEC core finds a plugin by name (Hodge-star variants, boundary adaptations).

Every pluggable kind of decrun is a **dataclass whose fields are its options**. The runner
builds one from a config node naming it with ``_target_`` (Hydra's convention, see
:mod:`decrun.runner.job.plugins`); Python code may also pass an instance, or — for the
built-in plugins of the core — a short name, resolved here by module: the variant named
``x`` of kind ``decrun.core.stars`` is the class in module ``decrun.core.stars.x`` whose
``name`` is ``"x"``. A plugin outside decrun is passed as an instance or as a dotted path
``package.module.ClassName``.
"""

from __future__ import annotations

import importlib
import pkgutil
from typing import Any

from decrun.core.choices import closest
from decrun.errors import ConfigError

__all__ = ["resolve", "builtin_names"]


def builtin_names(package: str, base: type | None = None) -> list[str]:
    """Names of the built-in plugins of a kind: the modules of ``package`` that define a
    ``base`` subclass with ``name`` equal to the module name (all modules if ``base`` is None)."""
    module = importlib.import_module(package)
    names = sorted(info.name for info in pkgutil.iter_modules(module.__path__) if not info.name.startswith("_"))
    if base is None:
        return names
    found = []
    for name in names:
        members = vars(importlib.import_module(f"{package}.{name}")).values()
        if any(isinstance(c, type) and issubclass(c, base) and getattr(c, "name", None) == name for c in members):
            found.append(name)
    return found


def resolve(value: Any, base: type, package: str, key: str) -> Any:
    """An instance of ``base`` for ``value``: an instance (returned as is), a built-in name
    (module ``package.<name>``), or a dotted class path. ``key`` names the config key in
    error messages (e.g. ``operator``)."""
    if isinstance(value, base):
        return value
    if isinstance(value, type) and issubclass(value, base):
        return value()
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{key}: expected a name or a {base.__name__}, got {value!r}")
    if "." in value:
        module_name, _, class_name = value.rpartition(".")
        try:
            cls = getattr(importlib.import_module(module_name), class_name)
        except (ImportError, AttributeError) as exc:
            raise ConfigError(f"{key}: cannot import {value!r}: {exc}") from None
    else:
        try:
            module = importlib.import_module(f"{package}.{value}")
        except ModuleNotFoundError:
            names = builtin_names(package, base)
            choices = " | ".join(f"{key}={name}" for name in names)
            near = closest(value, names)
            hint = f"; did you mean {key}={near}?" if near is not None else ""
            raise ConfigError(f"{key}={value}: unknown {base.__name__}; choose one of {choices}{hint}") from None
        found = [c for c in vars(module).values() if isinstance(c, type) and issubclass(c, base)
                 and c is not base and getattr(c, "name", None) == value]
        if len(found) != 1:
            raise ConfigError(f"{key}: module {package}.{value} defines no {base.__name__} named {value!r}")
        cls = found[0]
    if not (isinstance(cls, type) and issubclass(cls, base)):
        raise ConfigError(f"{key}: {value!r} is not a {base.__name__}")
    return cls()
