"""Sweeps: the ``decrun`` sweeper (:mod:`.sweeper`, registered for Hydra by
:mod:`hydra_plugins.decrun_sweeper`), the plan it writes and the job states it reads
(:mod:`.manifest`) and the sweep → table of :mod:`.tables` (``load_sweep``, ``stack``, ``decrun-table``).

Nothing is imported here: Hydra imports the sweeper at every start, and the tables need
pandas (start-up speed).
"""
