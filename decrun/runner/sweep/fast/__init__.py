"""The sweep speed layer: everything the ``decrun`` sweeper does only to be fast, behind one
switch, ``hydra.sweeper.fast`` (default true). With ``fast=false`` the sweeper plans and
launches every job on Hydra's public API alone; the jobs, their directories, their config
hashes and their results are the same either way (tests/runner/sweep/test_sweep_planning.py runs
sweeps both ways and compares them).

With the switch on (:class:`SpeedLayer`):

* **planning derivation** (:mod:`.planning`): a group of jobs that differ in plain values
  is composed by Hydra once (and its last job once more, to check the derivation); its
  other jobs are derived from that composition;
* **the config swap**: the launcher's config loader (``hydra_context.config_loader``) is
  replaced by :class:`~.planning.PlannedConfigs`, which derives each launched job from its
  group's composition instead of composing it again (Hydra's launchers, the basic one
  included, all call ``config_loader.load_sweep_config`` per job);
* **memo modes**: the task's check (:func:`~decrun.runner.sweep.checks.register_check`)
  gets a memo shared by the sweep's jobs (a plugin node already built is not built again)
  and, for a derived job, a :class:`JobDelta` naming what changed since the last job of
  its group;
* **worker warm-up**: with Hydra's joblib launcher, its loky workers start and import the
  task's modules while the sweep is planned;
* **a frozen heap**: the objects alive when the sweep starts are left out of Python's full
  garbage collections until it ends (``gc.freeze``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import logging
import threading
from typing import Any, Callable, Hashable, Iterator, Optional

from omegaconf import DictConfig

from decrun.runner.sweep.checks import import_modules
from decrun.runner.sweep.fast.planning import Composer, PlannedConfigs, Template, subdir_of
from decrun.runner.sweep.launchers import JOBLIB, is_launcher
from decrun.runner.sweep.manifest import config_hash

__all__ = ["SpeedLayer", "JobDelta"]

log = logging.getLogger("decrun")


@dataclasses.dataclass(frozen=True)
class JobDelta:
    """What a planned job's config shares with the job checked before it in its group (the
    sweeper derives a group's jobs from one composition, :mod:`.planning`): it equals the
    config last checked with the same ``group`` except at the dotted plain ``keys``
    (``("app.dt",)``) and anywhere in the root keys ``interpolated`` (their values may
    follow the changed keys)."""

    group: Hashable
    keys: tuple[str, ...]
    interpolated: frozenset[str]


class SpeedLayer:
    """The sweeper's speed layer (module docstring); ``enabled=False``: each method does
    what Hydra's public API does (every job composed by Hydra, the check without memo,
    no loader swap, no warm-up, the heap as it is)."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        #: the memo of the task's check: shared by every job the sweep plans
        self.memo: dict = {}
        self._templates: dict[tuple, Template] = {}

    def compose(self, loader: Any, master: DictConfig,
                jobs: list[tuple[str, ...]]) -> Iterator[tuple[tuple[str, ...], DictConfig, Optional[Template]]]:
        """``(job, config, template)`` of each job in order, as
        :meth:`~.planning.Composer.each` (``template`` None: composed by Hydra; always None
        when disabled). ``config`` is valid until the next job."""
        composer = Composer(loader, master, derive=self.enabled)
        self.memo = {}  # a group is known by its template's id: not across sweeps
        self._templates = composer.templates
        return composer.each(jobs)

    def check(self, check: Callable[..., Any], cfg: DictConfig, template: Optional[Template]) -> None:
        """The task's ``check`` of a planned job: ``check(cfg)`` when disabled, else with the
        sweep's memo and, for a derived job, its :class:`JobDelta`."""
        if not self.enabled:
            check(cfg)
        elif template is None:
            check(cfg, memo=self.memo)
        else:
            check(cfg, memo=self.memo, delta=JobDelta(id(template), template.varying_keys, template.interpolated))

    def job_dir(self, template: Optional[Template], num: int) -> Optional[str]:
        """Job ``num``'s ``hydra.sweep.subdir`` read off its group's pattern (literal text and
        the job number: no ``HydraConfig`` needed), or None when it must be resolved on the
        job's config."""
        if template is None or template.subdir is None or Composer.hydra_needed(template):
            return None
        return subdir_of(template.subdir, num)

    @staticmethod
    def config_hash(cfg: DictConfig, template: Optional[Template]) -> str:
        """:func:`~decrun.runner.sweep.manifest.config_hash` of a planned job: a derived job's
        from its group's YAML blocks, remaking only those that may differ."""
        return config_hash(cfg) if template is None else config_hash(cfg, template.blocks, template.fresh)

    @staticmethod
    def unwrap(hydra_context: Any) -> Any:
        """The context's config loader, Hydra's own again after an earlier sweep swapped it."""
        loader = hydra_context.config_loader
        if isinstance(loader, PlannedConfigs):
            loader = hydra_context.config_loader = loader.wrapped
        return loader

    def swap_loader(self, hydra_context: Any, extra: tuple) -> None:
        """Give the launcher (it shares ``hydra_context``) a config loader that derives the
        planned groups' jobs (:class:`~.planning.PlannedConfigs`); ``extra``: the shape of
        the override lines the sweeper appends to every job. Nothing when disabled."""
        if self.enabled:
            hydra_context.config_loader = PlannedConfigs(hydra_context.config_loader, self._templates, extra=extra)

    @contextlib.contextmanager
    def warming(self, launcher: Any, modules: tuple[str, ...]) -> Iterator[None]:
        """While the block runs (the sweep is planned), Hydra's joblib launcher's loky workers
        start, each importing ``modules``: the launcher's ``Parallel`` call with the same
        options reuses them (loky's reusable executor). Nothing for other launchers, without
        modules, or when disabled."""
        modules = (*modules, PlannedConfigs.__module__) if modules else ()  # what unpickles a job's loader
        thread = self._warm(launcher, modules) if self.enabled and modules else None
        try:
            yield
        finally:
            if thread is not None:
                thread.join()

    @staticmethod
    def _warm(launcher: Any, modules: tuple[str, ...]) -> Optional[threading.Thread]:
        options = getattr(launcher, "joblib", None)
        if not is_launcher(launcher, *JOBLIB) or not isinstance(options, dict):
            return None
        from joblib import Parallel, delayed, effective_n_jobs

        options = {**options, "backend": "loky"}
        if effective_n_jobs(options.get("n_jobs") or 1) <= 1:
            return None
        workers = effective_n_jobs(options.get("n_jobs") or 1)

        def start() -> None:
            try:
                Parallel(**options)(delayed(import_modules)(modules) for _ in range(workers))
            except Exception as exc:  # only time is lost: the jobs import what they need themselves
                log.debug("joblib workers not warmed: %s", exc)

        thread = threading.Thread(target=start, name="decrun-warm-workers", daemon=True)
        thread.start()
        return thread

    @contextlib.contextmanager
    def frozen_heap(self) -> Iterator[None]:
        """Python's cyclic garbage collector leaves the objects alive when the sweep starts
        (the imported numerical stack, Hydra's config store: ~100 000) out of its full
        collections until the sweep ends (``gc.freeze``): each job makes and drops tens of
        thousands of config nodes, and every full collection they trigger would scan the
        whole heap again. What the sweep itself makes is collected as before; the frozen
        objects are tracked again afterwards (``gc.unfreeze``). Nothing when disabled."""
        if not self.enabled:
            yield
            return
        gc.freeze()
        try:
            yield
        finally:
            gc.unfreeze()
