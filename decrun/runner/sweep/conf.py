"""The options of the ``decrun`` sweeper (``hydra.sweeper.*``: :class:`DecrunSweeperConf`),
apart from the sweeper itself (:mod:`decrun.runner.sweep.sweeper`): Hydra's plugin scan, which
runs at every start of the command — a single run too — registers them through
:mod:`hydra_plugins.decrun_sweeper` without importing the sweep machinery (the launchers'
module it reads a default from imports only the standard library)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, Optional

from decrun.runner.sweep.grid import MAX_JOBS
from decrun.runner.sweep.launchers import CONNECT_TIMEOUT

__all__ = ["DecrunSweeperConf"]


@dataclass
class DecrunSweeperConf:
    _target_: str = "hydra_plugins.decrun_sweeper.DecrunSweeper"
    #: jobs per launcher call (null: all at once, as Hydra's basic sweeper)
    max_batch_size: Optional[int] = None
    #: sweep parameters from the config, e.g. {app.dt: "0.1,0.2"} (as Hydra's basic sweeper)
    params: Optional[Dict[str, str]] = field(default=None)
    #: rerun the jobs of an existing hydra.sweep.dir that are not ok
    resume: bool = False
    #: the speed layer (decrun.runner.sweep.fast): jobs derived from their group's composition,
    #: the launcher's loader deriving them too, memoized checks, joblib workers warmed while
    #: planning; false: every job composed by Hydra's public API (the same jobs, ~180x slower
    #: to plan: benchmarks/bench_sweeps.py --only planning)
    fast: bool = True
    #: seconds to give up on a cluster that does not answer (a Ray address; decrun.runner.sweep.launchers)
    connect_timeout: float = CONNECT_TIMEOUT
    #: the most jobs a sweep may plan (each is composed, checked and hashed before the first starts);
    #: a larger grid is refused at once, naming this key
    max_jobs: int = MAX_JOBS
