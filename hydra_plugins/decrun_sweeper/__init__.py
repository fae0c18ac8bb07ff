"""The ``decrun`` Hydra sweeper (``hydra/sweeper=decrun``, decrun's default): Hydra's grid
sweep plus a manifest, checks and resume (:class:`decrun.runner.sweep.sweeper.ManifestSweeper`,
on Hydra's public ``Sweeper`` API).

Hydra instantiates sweepers only from classes defined in the ``hydra_plugins`` namespace, and
its plugin scan imports (and re-executes) this module at every start of a command — a single
run, ``--cfg``, a bad override too. So this module holds only what the scan registers: the
options (:class:`~decrun.runner.sweep.conf.DecrunSweeperConf`) and :class:`DecrunSweeper`, a
front that imports the sweep machinery and makes its :class:`ManifestSweeper` when Hydra
builds the sweeper for a sweep. Each scan makes a new ``DecrunSweeper`` class; the
``ManifestSweeper`` it hands the work to is never re-executed."""

from hydra.core.config_store import ConfigStore
from hydra.plugins.sweeper import Sweeper

from decrun.runner.sweep.conf import DecrunSweeperConf

__all__ = ["DecrunSweeper"]


class DecrunSweeper(Sweeper):
    """decrun's sweeper as Hydra's plugin scan finds it (``hydra/sweeper=decrun``): built with
    the options of :class:`DecrunSweeperConf`, it makes a
    :class:`~decrun.runner.sweep.sweeper.ManifestSweeper` of them, which does the work
    (:meth:`setup`, :meth:`sweep`); the ManifestSweeper's attributes (``resume``,
    ``max_batch_size``, ``config``...) read and set through this object."""

    def __init__(self, **options) -> None:
        from decrun.runner.sweep.sweeper import ManifestSweeper  # lazy: only a sweep needs the machinery

        vars(self)["sweeper"] = ManifestSweeper(**options)
        super().__init__()

    def setup(self, *, hydra_context, task_function, config) -> None:
        """:meth:`ManifestSweeper.setup <decrun.runner.sweep.sweeper.ManifestSweeper.setup>`."""
        self.sweeper.setup(hydra_context=hydra_context, task_function=task_function, config=config)

    def sweep(self, arguments):
        """:meth:`ManifestSweeper.sweep <decrun.runner.sweep.sweeper.ManifestSweeper.sweep>`: the sweep's returns."""
        return self.sweeper.sweep(arguments)

    def __getattr__(self, name: str):
        sweeper = vars(self).get("sweeper")
        if sweeper is None:
            raise AttributeError(name)
        return getattr(sweeper, name)

    def __setattr__(self, name: str, value) -> None:
        setattr(self.sweeper, name, value)


ConfigStore.instance().store(group="hydra/sweeper", name="decrun", node=DecrunSweeperConf, provider="decrun")
