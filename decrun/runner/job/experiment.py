"""The plugins of one run, built and checked from its config before any work, and how
errors name the config key they come from.

:func:`validate` builds an :class:`Experiment` — one plugin per row of
:data:`decrun.runner.job.config.GROUPS` — for a run (:func:`decrun.runner.job.run.prepare`) and for
every planned job of a sweep (memoized: :func:`validate`'s ``memo`` and ``delta``);
:func:`name_the_key` is the rule :meth:`decrun.runner.job.run.Run.naming_errors` applies.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import sys
from typing import TYPE_CHECKING, Any, Callable

from omegaconf import DictConfig, OmegaConf

from decrun.errors import ConfigError, DecrunError, MeshError, SolverError, TopologyError
from decrun.runner.job.config import GROUPS, CheckpointConfig, DecrunConfig, OptimizeConfig
from decrun.runner.job.hints import resolution_message
from decrun.runner.job.plugins import Rebuilt, Recent, build

if TYPE_CHECKING:  # the plugins' base classes, for the attributes' types only
    from decrun.apps.base import App
    from decrun.core.boundary import BoundaryAdaptation
    from decrun.core.solvers import Solver
    from decrun.core.stars import HodgeStar
    from decrun.runner.mesh import MeshSource
    from decrun.runner.results.export import Export
    from decrun.runner.tracking import Tracker

__all__ = ["Experiment", "validate", "name_the_key", "mesh_where", "check_root_keys", "root_options"]


class Experiment:
    """The plugins of one run, built and checked from ``cfg`` before any work.

    Attributes: ``mesh_source``, ``operator`` (Hodge-star variant), ``boundary``, ``app``,
    ``solver``, ``export``, ``tracker`` (None when ``cfg`` has no such node) — instances of the classes
    named by the config's ``_target_`` keys, one per row of
    :data:`decrun.runner.job.config.GROUPS` (built in its order). The app then checks the
    solver against what the config alone says of its systems (before any mesh is loaded:
    a sweep's plan is refused before its first job). ``checkpoint``: the
    :class:`~decrun.runner.job.config.CheckpointConfig` of a time-stepping run; ``optimize``: the
    :class:`~decrun.runner.job.config.OptimizeConfig` (:func:`root_options`). An interpolation
    that does not resolve (``${oc.env:NAME}`` unset, an unknown resolver, a key referring to
    itself) is a ConfigError naming its key (:func:`decrun.runner.job.hints.resolution_message`).
    """

    mesh_source: MeshSource
    operator: HodgeStar
    boundary: BoundaryAdaptation
    app: App
    solver: Solver
    export: Export | None
    tracker: Tracker | None
    checkpoint: CheckpointConfig
    optimize: OptimizeConfig

    def __init__(self, cfg: DictConfig, make: Callable[[Any, str, type], Any] = build):
        try:
            self._build(cfg, make)
        except Exception as exc:  # an interpolation that does not resolve: one line naming its key
            message = resolution_message(exc, cfg)
            if message is None or isinstance(exc, DecrunError):
                raise
            raise ConfigError(message) from exc

    def _build(self, cfg: DictConfig, make: Callable[[Any, str, type], Any]) -> None:
        check_root_keys(cfg)
        for group in GROUPS:
            plugin = None
            if not group.optional or group.key in cfg:
                plugin = make(cfg[group.key], group.key, group.base_class())  # e.g. a solver's missing package: SolverError
            setattr(self, group.attribute, plugin)
        self.app.check_solver(self.solver)
        check_model_config(self.app)
        if self.export is not None:  # what the app writes against what the export needs: before any mesh
            self.export.check(self.app)
        if self.tracker is not None:  # its package: refused before the first job, not at the sweep's end
            self.tracker.check()
        self.checkpoint = root_options(cfg, "checkpoint", CheckpointConfig)
        self.optimize = root_options(cfg, "optimize", OptimizeConfig)
        for key in ("progress", "figures"):  # plain root values: resolved here, not first in the run
            if key in cfg:
                cfg[key]  # noqa: B018 — item access names the key in OmegaConf's error (get does not)


def check_model_config(app: Any) -> None:
    """A declarative model's check of its config alone (:func:`decrun.runner.job.model_checks.check_model`:
    ``t_end`` against ``dt``, so a sweep is refused at planning); nothing for another app."""
    model_module = sys.modules.get("decrun.apps.model")  # a Model instance means it is loaded: another app never imports it
    if model_module is not None and isinstance(app, model_module.Model):
        from decrun.runner.job.model_checks import check_model

        check_model(app)


def root_options(cfg: DictConfig, key: str, cls: type) -> Any:
    """The dataclass ``cls`` (:class:`~decrun.runner.job.config.CheckpointConfig`,
    :class:`~decrun.runner.job.config.OptimizeConfig`) of the root node ``cfg[key]``, its
    defaults when absent. ConfigError naming ``<key>.<option>`` for an option ``cls`` does
    not have — ``+checkpoint._target_=…`` too: these nodes are plain options, not plugins."""
    if key not in cfg:
        return cls()
    values = OmegaConf.to_container(cfg[key], resolve=True)
    known = [f.name for f in dataclasses.fields(cls)]
    unknown = [name for name in values if name not in known]
    if unknown:
        name = unknown[0]
        what = (f"{key} holds plain options, it builds no class (only {', '.join(g.key for g in GROUPS)} name a "
                f"_target_)" if name == "_target_" else f"unknown option of {key}")
        close = difflib.get_close_matches(str(name), known, n=1)
        close_hint = f"; did you mean {key}.{close[0]}?" if close and name != "_target_" else ""
        raise ConfigError(f"{key}.{name}: {what}; {key} has {known}: drop +{key}.{name}=...{close_hint}")
    return cls(**values)


def check_root_keys(cfg: DictConfig) -> None:
    """ConfigError for a root key the schema :class:`decrun.runner.job.config.DecrunConfig` does
    not have: Hydra's ``+foo=1`` adds keys even to a struct config, and nothing would read it."""
    known = [f.name for f in dataclasses.fields(DecrunConfig)]
    unknown = [key for key in cfg if key not in known and key != "hydra"]  # hydra: a sweep job's own node
    if unknown:
        raise ConfigError(f"{unknown[0]}: unknown root key (nothing reads it); the config has {known}: "
                          f"drop +{unknown[0]}=..., or put the option under its group (e.g. +app.{unknown[0]}=...)")


#: a message starting with one of these names its config key already (the root keys but ``optimize``)
_KEYS = tuple(f.name for f in dataclasses.fields(DecrunConfig) if f.name != "optimize")


def name_the_key(exc: DecrunError, experiment: Experiment, where: str) -> DecrunError:
    """``exc`` with the config key it comes from in front, when its message (raised by the
    core, which knows no config) does not start with one: ``solver=<name>`` for solver
    errors, ``app=<name>`` otherwise. Mesh and topology errors always name the mesh
    (``where``: its file or sample, :func:`mesh_where`), also when they name an app key
    (``app=parametrization needs a border``); a bare ``mesh:`` becomes ``where``.
    Errors about files (an OSError such as ResultWriteError) name their file already."""
    message = str(exc)
    if isinstance(exc, OSError):
        return exc
    if isinstance(exc, (MeshError, TopologyError)):
        if message.startswith(("mesh.", "mesh=", "mesh ")):  # names the mesh already
            return exc
        message = message.removeprefix("mesh: ")
        prefix = where
    elif message.startswith(_KEYS):
        return exc
    elif isinstance(exc, SolverError):
        prefix = f"solver={experiment.solver.name} (app={experiment.app.name})"
    else:
        prefix = f"app={experiment.app.name}"
    try:
        return type(exc)(f"{prefix}: {message}")
    except TypeError:  # a subclass with another signature: keep it as it is
        return exc


def mesh_where(mesh) -> str:
    """How an error names the mesh: ``mesh.sample=<name>``, ``mesh.path='<file>'`` or ``mesh <label>``."""
    if mesh.meta.get("source") == "sample":
        return f"mesh.sample={mesh.meta.get('label', '')}"
    return f"mesh.path={mesh.meta['path']!r}" if "path" in mesh.meta else f"mesh {mesh.meta.get('label', '')}"


def validate(cfg: DictConfig, memo: dict | None = None, delta: Any = None, recent: Recent | None = None) -> Experiment:
    """Build and type-check every plugin node of ``cfg`` (ConfigError naming the key).

    ``recent`` (:class:`~decrun.runner.job.plugins.Recent`; a sweep's jobs run one after the
    other in a process): a plugin node equal to the last one built with it is made anew
    from that one's typed config, with the dataclass's checks (each job its own instances).

    ``memo`` (a sweep's plan, many jobs checked in a row): a plugin node whose resolved
    values equal those of a node already built with the same memo is not built again —
    its plugin, or its error, is the earlier one's (the same checks, once per distinct node).

    ``delta`` (:class:`~decrun.runner.sweep.fast.JobDelta`, with ``memo``): ``cfg`` equals
    the config last checked with the same ``delta.group`` except at the plain keys
    ``delta.keys`` (and in the roots ``delta.interpolated``, which are built as above). A
    root none of those keys is under keeps its plugin; a root they are under is rebuilt
    from its last typed config with those leaves assigned (:class:`~decrun.runner.job.plugins.Rebuilt`),
    so a 10 000-value sweep of ``app.dt`` checks each job in well under a millisecond."""
    if memo is None:
        return Experiment(cfg) if recent is None else Experiment(cfg, recent.build)

    def memoized(node, key: str, base: type):
        values = OmegaConf.to_container(node, resolve=True, enum_to_str=True) if OmegaConf.is_config(node) else node
        try:
            seen = (key, json.dumps(values, sort_keys=True))
        except TypeError:  # a value JSON cannot write: build it every time
            return build(node, key, base)
        if seen not in memo:
            try:
                memo[seen] = build(node, key, base)
            except DecrunError as exc:
                memo[seen] = exc
        if isinstance(memo[seen], DecrunError):
            raise memo[seen]
        return memo[seen]

    if delta is None:
        return Experiment(cfg, memoized)
    kept, rebuilt = memo.setdefault(("group", delta.group), ({}, {}))

    def make(node, key: str, base: type):
        if key in delta.interpolated:
            return memoized(node, key, base)
        leaves = {name.split(".", 1)[1]: OmegaConf.select(cfg, name) for name in delta.keys
                  if name.split(".", 1)[0] == key and "." in name}
        if not leaves:
            if key not in kept:
                kept[key] = memoized(node, key, base)
            return kept[key]
        if key not in rebuilt:
            rebuilt[key] = Rebuilt(node, key, base)
            return rebuilt[key].plugin
        return rebuilt[key].with_leaves(node, leaves)

    return Experiment(cfg, make)
