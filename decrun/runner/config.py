"""The root config schema and where the YAML configs live.

The composed config has one node per plugin kind — ``mesh``, ``operator`` (Hodge-star
variant), ``boundary`` (boundary adaptation), ``app``, ``solver`` — each naming its class
with ``_target_`` (see :mod:`decrun.runner.plugins`), plus the run options below. Hydra
composes YAML only; the runner type-checks each node against its class before any work.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omegaconf import MISSING

from decrun.errors import ConfigError

__all__ = ["DecrunConfig", "PLUGIN_GROUPS", "register_configs", "config_dir", "load_option"]

#: config groups whose node is a plugin (built with ``_target_``)
PLUGIN_GROUPS = ("mesh", "operator", "boundary", "app", "solver")


@dataclass
class DecrunConfig:
    """Schema of the whole composed config (``conf/config.yaml`` extends it): unknown root
    keys (``+foo=1``) are rejected when the config is composed."""

    mesh: Any = MISSING
    operator: Any = MISSING
    boundary: Any = MISSING
    app: Any = MISSING
    solver: Any = MISSING
    #: show progress bars (only when stderr is a terminal)
    progress: bool = True
    #: render the application's figures to PNG
    figures: bool = True


_registered = False


def register_configs() -> None:
    """Store the root schema in Hydra's ConfigStore (idempotent)."""
    global _registered
    if _registered:
        return
    from hydra.core.config_store import ConfigStore

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
    machinery (fast; for ``decrun --help`` and :func:`decrun.runner.plugins.option`)."""
    from omegaconf import OmegaConf

    root = config_dir()
    path = root / group / f"{name}.yaml"
    if not path.is_file():
        raise ConfigError(f"{group}={name}: no such option (conf/{group}/{name}.yaml)")
    node = OmegaConf.load(path)
    parts = [load_option(group, entry) for entry in node.pop("defaults", []) if entry != "_self_"]
    return OmegaConf.merge(*parts, node)
