"""The ``decrun`` Hydra sweeper (``hydra/sweeper=decrun``, decrun's default): Hydra's basic
grid sweeper plus a manifest and resume. Hydra instantiates sweepers only from classes
defined in the ``hydra_plugins`` namespace; the code is :mod:`decrun.runner.sweep.sweeper`."""

from hydra.core.config_store import ConfigStore

from decrun.runner.sweep import sweeper as _sweeper

__all__ = ["DecrunSweeper"]


class DecrunSweeper(_sweeper.DecrunSweeper):
    """:class:`decrun.runner.sweep.sweeper.DecrunSweeper`, under the name Hydra accepts."""


ConfigStore.instance().store(group="hydra/sweeper", name="decrun", node=_sweeper.DecrunSweeperConf, provider="decrun")
