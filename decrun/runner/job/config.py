"""The root config schema and where the YAML configs live.

The composed config has one node per plugin kind — ``mesh``, ``operator`` (Hodge-star
variant), ``boundary`` (boundary adaptation), ``app``, ``solver`` — each naming its class
with ``_target_`` (see :mod:`decrun.runner.job.plugins`), plus the run options below. Hydra
composes YAML only; the runner type-checks each node against its class before any work.
"""

from __future__ import annotations

import functools
import io
import secrets
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, Optional

from omegaconf import MISSING, DictConfig, OmegaConf

from decrun.core.choices import Choice
from decrun.errors import ConfigError
from decrun.runner.io.config_files import check_aliases

__all__ = ["DecrunConfig", "OptimizeConfig", "Direction", "PluginGroup", "GROUPS", "GROUP", "PLUGIN_GROUPS", "register_configs", "config_dir", "load_option",
           "compose_config", "unique_stamp"]

@dataclass(frozen=True)
class PluginGroup:
    """One config group whose node is a plugin (the groups are listed once, in
    :data:`GROUPS`).

    ``key``: the config key (``cfg.<key>``, ``decrun <key>=<option>``), its options are
    ``conf/<key>/<option>.yaml`` (:meth:`conf_dir`), each option's node ``cfg.<key>``; ``base``: the dotted name of the class
    whose dataclass subclass every option names with ``_target_: <module>.<Class>``
    (:func:`decrun.runner.job.plugins.build` checks it); ``attribute``: where
    :class:`decrun.runner.job.experiment.Experiment` keeps the built plugin; ``builtins``: the module
    prefixes of decrun's own options (a plugin outside decrun names its own module)."""

    key: str
    base: str
    attribute: str
    builtins: tuple[str, ...]
    #: a config without this node is accepted (the plugin is then None)
    optional: bool = False

    def conf_dir(self) -> Path:
        """``conf/<key>/``: the group's option files."""
        return config_dir() / self.key

    def base_class(self) -> type:
        """The class :attr:`base` names (imported on the first call: composing a config imports
        no numerical code; then kept, as every job of a sweep asks for it)."""
        return _import(self.base)


@functools.lru_cache(maxsize=None)
def _import(dotted: str) -> type:
    import importlib

    module_name, _, class_name = dotted.rpartition(".")
    return getattr(importlib.import_module(module_name), class_name)


#: the plugin groups, in the order :class:`decrun.runner.job.experiment.Experiment` builds them (the
#: first refused node is the one reported)
GROUPS = (
    PluginGroup("app", "decrun.apps.base.App", "app", ("decrun.apps.",)),
    PluginGroup("operator", "decrun.core.stars.HodgeStar", "operator", ("decrun.core.stars.",)),
    PluginGroup("boundary", "decrun.core.boundary.BoundaryAdaptation", "boundary", ("decrun.core.boundary.",)),
    PluginGroup("solver", "decrun.core.solvers.Solver", "solver", ("decrun.core.solvers.",)),
    PluginGroup("mesh", "decrun.runner.mesh.MeshSource", "mesh_source", ("decrun.runner.mesh.sources.",
                                                                          "decrun.runner.job.chain.")),
    PluginGroup("export", "decrun.runner.results.export.Export", "export", ("decrun.runner.results.export.",),
                optional=True),
    PluginGroup("tracker", "decrun.runner.tracking.Tracker", "tracker", ("decrun.runner.tracking.",), optional=True),
)
#: the same by key
GROUP = {group.key: group for group in GROUPS}
#: the keys of :data:`GROUPS`
PLUGIN_GROUPS = tuple(GROUP)


class Direction(Choice):
    """``optimize.direction``: those of Hydra's optimising sweepers (hydra-optuna-sweeper's ``Direction``)."""

    minimize = "minimize"
    maximize = "maximize"


@dataclass
class OptimizeConfig:
    """``optimize``: what a job returns to an optimising Hydra sweeper
    (``hydra/sweeper=optuna``). Without ``metric`` a job returns its exit status."""

    #: name of the metric the job returns (e.g. ``dt``, ``distance_to_clean_rms``)
    metric: Optional[str] = None
    #: minimize | maximize; must agree with the sweeper's ``direction``
    direction: Direction = Direction.minimize
    #: name of a boolean metric that must be true (e.g. ``stable``); a job where it is false,
    #: or that failed, returns the worst value (+inf when minimizing, -inf when maximizing)
    require: Optional[str] = None

    def __post_init__(self):
        self.direction = Direction.of(self.direction, "optimize.direction")

    def objective(self, metrics: dict | None) -> float:
        """The value a job returns: ``metrics[metric]``, or the worst value when the job
        failed (``metrics`` None) or ``metrics[require]`` is false. A metric the job does
        not have is a ConfigError naming the metrics it has."""
        worst = float("inf") if self.direction == Direction.minimize else float("-inf")
        if metrics is None:
            return worst
        for key in (self.metric, self.require):
            if key is not None and key not in metrics:
                raise ConfigError(f"optimize: the run has no metric {key!r}; its metrics are {sorted(metrics)}")
        if self.require is not None and not metrics[self.require]:
            return worst
        value = float(metrics[self.metric])
        return value if value == value else worst  # NaN → worst


@dataclass
class CheckpointConfig:
    """``checkpoint``: how often a time-stepping app (smoothing, fluid) writes the run
    directory's ``checkpoint.h5`` (:mod:`decrun.runner.results.checkpoint`), from which a
    killed, timed-out or preempted run continues when rerun into the same directory. Not
    part of the config hash: changing it never changes a result."""

    #: write one every this many steps (null: not by steps)
    steps: Optional[int] = None
    #: write one when this many seconds passed since the last (null: not by time)
    seconds: Optional[float] = 60.0

    def __post_init__(self):
        if self.steps is not None and self.steps < 1:
            raise ConfigError(f"checkpoint.steps: must be >= 1 or null, got {self.steps}; e.g. checkpoint.steps=null")
        if self.seconds is not None and not self.seconds >= 0:
            raise ConfigError(f"checkpoint.seconds: must be >= 0 or null, got {self.seconds}; e.g. "
                              "checkpoint.seconds=60")


@dataclass
class DecrunConfig:
    """Schema of the whole composed config (``conf/config.yaml`` extends it): unknown root
    keys (``+foo=1``) are rejected when the config is composed."""

    mesh: Any = MISSING
    operator: Any = MISSING
    boundary: Any = MISSING
    app: Any = MISSING
    solver: Any = MISSING
    #: files for other programs (VTU, XDMF time series, PLY, OBJ): decrun.runner.results.export
    export: Any = MISSING
    #: an experiment tracker the sweep's jobs are logged to (MLflow): decrun.runner.tracking
    tracker: Any = MISSING
    #: show progress bars (only when stderr is a terminal)
    progress: bool = True
    #: render the application's figures to PNG
    figures: bool = True
    #: the metric a sweep job returns to an optimising sweeper (hydra/sweeper=optuna)
    optimize: OptimizeConfig = field(default_factory=OptimizeConfig)
    #: checkpoints of time-stepping runs (CheckpointConfig)
    checkpoint: CheckpointConfig = field(default_factory=CheckpointConfig)


_ISSUED_STAMPS: set[str] = set()


def unique_stamp() -> str:
    """``YYYY-mm-dd_HH-MM-SS_<6 hex>``: a timestamp plus 24 random bits, so two runs or
    sweeps started in the same second get different directories (two processes collide with
    probability 2⁻²⁴); within one process a stamp is never issued twice."""
    while True:
        stamp = f"{datetime.now():%Y-%m-%d_%H-%M-%S}_{secrets.token_hex(3)}"
        if stamp not in _ISSUED_STAMPS:
            _ISSUED_STAMPS.add(stamp)
            return stamp


_registered = False


def register_configs() -> None:
    """Store the root schema in Hydra's ConfigStore and register the ``decrun.stamp``
    resolver of the output directories (idempotent)."""
    global _registered
    if _registered:
        return
    from hydra.core.config_store import ConfigStore  # lazy: Hydra's config store only when composing (start-up speed)

    if not OmegaConf.has_resolver("decrun.stamp"):
        # cached: every job of a sweep (Hydra copies the resolver cache into each job's
        # config, also across joblib processes) sees the sweep's single stamp
        OmegaConf.register_new_resolver("decrun.stamp", unique_stamp, use_cache=True)
    ConfigStore.instance().store(name="base_config", node=DecrunConfig)
    _registered = True


def config_dir() -> Path:
    """Directory of the YAML configs: ``decrun/conf`` (a link to the repo's ``conf/`` in a
    checkout, a real copy inside a wheel)."""
    here = Path(__file__).resolve().parent.parent
    for candidate in (here / "conf", here.parent / "conf"):
        if (candidate / "config.yaml").is_file():
            return candidate.resolve()
    raise ConfigError(f"cannot find the decrun configs (config.yaml) next to {here}")


def load_option(group: str, name: str):
    """``conf/<group>/<name>.yaml`` as Hydra composes it on its own: the same-group files of
    its ``defaults`` list merged first (e.g. ``mesh/_post_processing``), without Hydra's
    machinery (fast; for ``decrun --help`` and :func:`decrun.runner.job.plugins.option`)."""
    root = config_dir()
    path = root / group / f"{name}.yaml"
    if not path.is_file():
        raise ConfigError(f"{group}={name}: no such option (conf/{group}/{name}.yaml)")
    text = path.read_text(encoding="utf-8")
    check_aliases(text, path, ConfigError)
    node = OmegaConf.load(io.StringIO(text))
    # same-group entries only: an override of another group (app/hodge's operator) is not part of this node;
    # a subgroup merged here (a composed model's `parts@_here_: [a, b]`: conf/app/parts/a.yaml …) is
    parts = []
    for entry in node.pop("defaults", []):
        if isinstance(entry, str) and entry != "_self_":
            parts.append(load_option(group, entry))
        elif isinstance(entry, DictConfig):
            for key, names in entry.items():
                sub, _, package = str(key).partition("@")
                if package == "_here_" and not sub.startswith(("/", "override ")):
                    for name_ in [names] if isinstance(names, str) else names:
                        parts.append(load_option(f"{group}/{sub}", name_))
    return OmegaConf.merge(*parts, node)


def compose_config(overrides: list[str] | None = None) -> DictConfig:
    """The config ``decrun <overrides>`` would run (same config dir, schemas and
    defaults; the ``hydra`` node left out). For tests and notebooks."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    register_configs()
    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(config_dir()), version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides or []))
