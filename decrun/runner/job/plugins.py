"""One registration mechanism for every pluggable kind: ``_target_`` + the dataclass schema.

A plugin — mesh source, Hodge-star variant, boundary adaptation, solver, application — is a
dataclass whose fields are its options, declared once. Its config file
``conf/<group>/<name>.yaml`` names it with Hydra's ``_target_`` key and sets defaults:

.. code-block:: yaml

    # conf/solver/cg.yaml
    _target_: decrun.core.solvers.cg.CGSolver
    tol: 1.0e-10

:func:`build` type-checks the composed node against the dataclass (unknown keys, wrong
types and the dataclass' own ``__post_init__`` checks become one :class:`ConfigError`
naming the key; so does a NaN, an infinity or a number beyond ±1e150 anywhere in the
node, see :func:`check_numbers`) and returns the instance — the same object
``hydra.utils.instantiate(node)`` would build. Nothing is registered in Python: a plugin
outside decrun is one module on the Python path plus one YAML file in a config directory
added with ``hydra.searchpath`` (docs/extending.md).

Because Hydra only reads YAML here, composing a config (``decrun --help``, completion,
every sweep job) imports no numerical code.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import importlib
import math
import typing
from typing import Any

from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import ConfigKeyError, OmegaConfBaseException, ValidationError

from decrun.core.choices import Choice, choice_error
from decrun.errors import ConfigError
from decrun.runner.job.config import GROUP, load_option

__all__ = ["target_class", "check_node", "build", "plain_values", "Rebuilt", "Recent"]


def target_class(node: Any, key: str, base: type) -> type:
    """The class named by ``node._target_``, checked to be a dataclass subclass of ``base``."""
    # item access: an interpolation that does not resolve names `<key>._target_` (get does not)
    target = node["_target_"] if isinstance(node, (dict, DictConfig)) and "_target_" in node else None
    if not target:
        raise ConfigError(f"{key}: the config node names no `_target_` (the {base.__name__} class to build), "
                          f"e.g. `_target_: decrun...`; choose a {key} option from conf/{key}/")
    module_name, _, class_name = str(target).rpartition(".")
    try:
        cls = getattr(importlib.import_module(module_name), class_name)
    except ImportError as exc:
        raise ConfigError(f"{key}._target_={target!r}: cannot import {module_name!r}: {exc}") from exc
    except AttributeError:
        raise ConfigError(f"{key}._target_={target!r}: module {module_name!r} has no {class_name!r}") from None
    if not (isinstance(cls, type) and issubclass(cls, base) and dataclasses.is_dataclass(cls)):
        raise ConfigError(f"{key}._target_={target!r} is not a {base.__name__} dataclass")
    return cls


def check_node(cls: type, node: Any, key: str) -> None:
    """The plugin class's checks of its unresolved config node (``cls.check_node(values, key)``,
    if it has one): what resolution hides — which file or override a value came from, e.g.
    whether a model set a constant or a part's interpolation did. ``values`` are plain Python
    containers with the interpolations unresolved (their ``${…}`` text), so the plugin needs
    no omegaconf."""
    check = getattr(cls, "check_node", None)
    if check is not None and isinstance(node, DictConfig):
        check(OmegaConf.to_container(node, resolve=False), key)


def plain_values(node: Any) -> dict:
    """The node's values as plain Python containers, without ``_target_``."""
    values = OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else dict(node)
    values.pop("_target_", None)
    return values


#: |value| above this is rejected in every option (the limit of mesh-file coordinates:
#: squares and products of two squares must stay far below the float64 maximum 1.8e308)
MAX_ABS_OPTION = 1e150


def check_numbers(value: Any, where: str) -> None:
    """Raise ConfigError naming ``where`` (``app.sources[0].point[2]``) for a NaN, an
    infinity or a number beyond ±MAX_ABS_OPTION anywhere in ``value`` (nested lists and
    dicts): such a value is never a meaningful length, weight or tolerance, and left in
    it would surface far away as a misleading error, an overflow or a silent no-op."""
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ConfigError(f"{where}: must be a finite number, got {value}")
        if abs(value) > MAX_ABS_OPTION:
            raise ConfigError(f"{where}: {value:g} is beyond ±{MAX_ABS_OPTION:g} (squares of it would overflow "
                              f"float64); give a number of sensible size")
    elif isinstance(value, dict):
        for name, item in value.items():
            check_numbers(item, f"{where}.{name}")
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            check_numbers(item, f"{where}[{i}]")


def _widen(hint, value):
    """``value`` with ints widened to floats wherever the type hint expects a float
    (``[[1, 0, 0, 0.5]]`` for List[List[float]]): the value is used as given, only its
    type changes. Recurses through lists, Optional and nested dataclasses."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is float:
        return float(value) if isinstance(value, int) and not isinstance(value, bool) else value
    if origin is typing.Union:
        for arg in args:
            if arg is not type(None) and value is not None:
                return _widen(arg, value)
        return value
    if origin in (list, typing.List) and isinstance(value, list) and args:
        return [_widen(args[0], item) for item in value]
    if dataclasses.is_dataclass(hint) and isinstance(value, dict):
        hints = _type_hints(hint)
        return {k: _widen(hints[k], v) if k in hints else v for k, v in value.items()}
    return value


@functools.lru_cache(maxsize=None)
def _type_hints(cls: type) -> dict:
    """``typing.get_type_hints(cls)``, once per class (it evaluates every annotation: a
    third of a plugin's build)."""
    return typing.get_type_hints(cls)


@functools.lru_cache(maxsize=None)
def _schema(cls: type) -> DictConfig:
    """``OmegaConf.structured(cls)``, made once per class (``OmegaConf.merge`` copies it; a
    sweep builds every plugin of every job twice: before the first starts, then in it)."""
    return OmegaConf.structured(cls)


def build(node: Any, key: str, base: type, typed: bool = False) -> Any:
    """Type-check ``node`` against the dataclass named by its ``_target_`` and build it.

    Parameters
    ----------
    node : DictConfig or dict with ``_target_`` and option values
    key : the config key in error messages (``mesh``, ``solver``, ``app`` ...)
    base : the plugin kind's base class (``MeshSource``, ``Solver``, ``App`` ...)
    typed : also return the schema-merged config the plugin was made from (``(plugin,
        typed)``, for :class:`Rebuilt`)

    Raises :class:`ConfigError` naming ``<key>.<option>`` for an unknown option, a value of the
    wrong type or a value the plugin's checks reject.
    """
    cls = target_class(node, key, base)
    check_node(cls, node, key)
    values = _widen(cls, plain_values(node))
    schema = _schema(cls)
    try:
        merged = OmegaConf.merge(schema, values)
        check_numbers(OmegaConf.to_container(merged), key)  # as converted ("nan" → nan)
        plugin = OmegaConf.to_object(merged)
        return (plugin, merged) if typed else plugin
    except ConfigKeyError as exc:
        name = exc.key if getattr(exc, "key", None) else str(exc).split("'")[1] if "'" in str(exc) else "?"
        owner, full = getattr(exc, "object_type", None), str(getattr(exc, "full_key", None) or "")
        if owner is not cls and dataclasses.is_dataclass(owner) and "." in full:  # a nested option's (app.plots.m.x)
            known = sorted(f.name for f in dataclasses.fields(owner))
            parent = f"{key}.{full.rpartition('.')[0]}"
            close = difflib.get_close_matches(str(name), known, n=1)
            raise ConfigError(f"{key}.{full}: unknown option of {parent}; it has {known}"
                              + (f"; did you mean {parent}.{close[0]}?" if close else "")) from None
        known = sorted(f.name for f in dataclasses.fields(cls))
        close = difflib.get_close_matches(str(name), known, n=1)
        raise ConfigError(f"{key}.{name}: unknown option of {key}={cls.name or cls.__name__}; it has {known}"
                          + (f"; did you mean {key}.{close[0]}?" if close else "")) from None
    except ValidationError as exc:
        where = getattr(exc, "full_key", None) or getattr(exc, "key", None) or "?"
        hint = typing.get_type_hints(cls).get(str(where))
        if isinstance(hint, type) and issubclass(hint, Choice):  # a closed set: name every choice
            raise choice_error(f"{key}.{where}", values.get(str(where)), hint) from None
        message = str(exc).splitlines()[0]
        raise ConfigError(f"{key}.{where}: {message}") from None
    except OmegaConfBaseException as exc:
        raise ConfigError(f"{key}: {str(exc).splitlines()[0]}") from None


class Rebuilt:
    """A plugin built by :func:`build`, kept with its typed (schema-merged) config so that a
    node differing from it only in some plain leaves is rebuilt by assigning those leaves
    (:meth:`with_leaves`): OmegaConf converts and checks an assigned value exactly as it
    does a merged one, and the dataclass's own checks run again in ``to_object``. A sweep
    of 10 000 ``app.dt`` values rebuilds ``app`` 10 000 times this way at a fraction of a
    full build's cost (no schema merge, no conversion of the untouched options)."""

    def __init__(self, node: Any, key: str, base: type):
        self.key, self.base = key, base
        self.plugin, self.typed = build(node, key, base, typed=True)

    def with_leaves(self, node: Any, leaves: dict[str, Any]) -> Any:
        """The plugin of ``node``, which equals the last node built here except at the
        option paths ``leaves`` (``{"dt": 0.1}``; plain values: numbers, str, bool, None).
        Any refusal is :func:`build`'s own, with its message (the node is built in full)."""
        try:
            for path, value in leaves.items():
                OmegaConf.update(self.typed, path, value, merge=True)
                check_numbers(OmegaConf.select(self.typed, path), f"{self.key}.{path}")
            self.plugin = OmegaConf.to_object(self.typed)
        except Exception:  # noqa: BLE001 — build names the key and says why, as a first build does
            self.plugin, self.typed = build(node, self.key, self.base, typed=True)
        return self.plugin


class Recent:
    """:func:`build` for the jobs of a sweep run one after the other in a process, keeping the
    last plugin built per config key with its typed (schema-merged) config. A node whose
    target class and values are those of the last one built for its key — in most sweeps
    every plugin but the swept one — gets a new instance made from that typed config by
    ``OmegaConf.to_object``, which runs the dataclass's own checks again; the schema merge,
    the conversion and the number checks of the same values are not redone (they were
    4 of a small job's 5 ms of checks). Any other node, and any refusal, is :func:`build`'s
    (its message). Each call returns its own instance: no state is shared between jobs."""

    def __init__(self):
        self._last: dict[str, tuple[type, str, DictConfig]] = {}

    def build(self, node: Any, key: str, base: type) -> Any:
        cls = target_class(node, key, base)
        check_node(cls, node, key)
        seen = repr(_widen(cls, plain_values(node)))  # repr: 1, 1.0 and True differ
        last = self._last.pop(key, None)
        if last is not None and last[0] is cls and last[1] == seen:
            try:
                plugin = OmegaConf.to_object(last[2])
            except Exception:  # noqa: BLE001 — build says why, naming the key, as it did the first time
                plugin = None
            if plugin is not None:
                self._last[key] = last
                return plugin
        plugin, typed = build(node, key, base, typed=True)
        self._last[key] = (cls, seen, typed)
        return plugin

    def clear(self) -> None:
        self._last.clear()


def option(group: str, name: str, **overrides) -> Any:
    """The plugin ``conf/<group>/<name>.yaml`` with ``overrides`` applied, built — e.g.
    ``option("mesh", "torus", noise=0.1).load()`` or ``option("solver", "cg", tol=1e-8)``.
    For notebooks and tests: the same defaults and checks as ``decrun <group>=<name>``."""
    if group not in GROUP:
        raise ConfigError(f"{group}: not a plugin group; choose one of {sorted(GROUP)}")
    node = OmegaConf.merge(load_option(group, name), overrides)
    return build(node, group, GROUP[group].base_class())
