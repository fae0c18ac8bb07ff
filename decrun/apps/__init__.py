"""Applications: one module per application, each an :class:`decrun.apps.base.App` dataclass
named by ``_target_`` in ``conf/app/<name>.yaml``. The contract (the context ``ctx``, what an
app declares, Result and Figure) is in :mod:`decrun.apps.base`."""
