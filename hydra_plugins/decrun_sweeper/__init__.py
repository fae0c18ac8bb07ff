"""The ``decrun`` Hydra sweeper (``hydra/sweeper=decrun``, decrun's default): Hydra's grid
sweep plus a manifest, checks and resume (:class:`decrun.runner.sweep.sweeper.ManifestSweeper`,
on Hydra's public ``Sweeper`` API).

Hydra instantiates sweepers only from classes defined in the ``hydra_plugins`` namespace
(its plugin scan re-executes this module: each scan makes a new ``DecrunSweeper`` of the
same ``ManifestSweeper``, which no scan re-executes). The module is imported here, not the
class, so that the scan registers ``DecrunSweeper`` alone."""

from hydra.core.config_store import ConfigStore

from decrun.runner.sweep import sweeper as _sweeper

__all__ = ["DecrunSweeper"]


class DecrunSweeper(_sweeper.ManifestSweeper):
    """decrun's sweeper as Hydra's plugin scan finds it (``hydra/sweeper=decrun``)."""


ConfigStore.instance().store(group="hydra/sweeper", name="decrun", node=_sweeper.DecrunSweeperConf, provider="decrun")
