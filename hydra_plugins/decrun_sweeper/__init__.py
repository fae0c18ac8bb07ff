"""The ``decrun`` Hydra sweeper (``hydra/sweeper=decrun``, decrun's default): Hydra's basic
grid sweeper plus a manifest and resume (:class:`decrun.runner.sweep.sweeper.ManifestSweeper`).

Hydra instantiates sweepers only from classes defined in the ``hydra_plugins`` namespace,
and every plugin scan re-executes this module and, before it, Hydra's
``basic_sweeper``: the class below is composed anew each time from the ``BasicSweeper``
of that scan, so it survives any number of scans (a reset of Hydra's singletons, a
joblib job restoring Hydra's state in-process)."""

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.config_store import ConfigStore

from decrun.runner.sweep.sweeper import DecrunSweeperConf, ManifestSweeper

__all__ = ["DecrunSweeper"]


class DecrunSweeper(ManifestSweeper, BasicSweeper):
    """Hydra's ``BasicSweeper`` with decrun's manifest, checks and resume."""


ConfigStore.instance().store(group="hydra/sweeper", name="decrun", node=DecrunSweeperConf, provider="decrun")
