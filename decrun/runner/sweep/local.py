"""A sweep's jobs one after the other in this process, as Hydra's basic launcher runs them
(``hydra/launcher=basic``, the default), with Hydra's per-job bookkeeping done once where
Hydra 1.3's ``run_job`` does it twice.

Hydra's ``hydra.core.utils.run_job`` spends ~19 ms of a small sweep job (measured on the
project machine; the job itself ~20 ms): it makes the job's ``HydraConfig`` twice (once to
resolve the output directory, once after setting it, ~2.6 ms each), deep-copies that
``HydraConfig`` again for the job's record (~2.3 ms), and writes ``.hydra/*.yaml`` with
PyYAML's Python emitter (~5 ms). A job the decrun sweeper planned names its directory
with literals (``hydra.sweep.dir`` absolute, ``hydra.sweep.subdir='<dir>'``:
:meth:`~decrun.runner.sweep.sweeper.ManifestSweeper._hand_over`), which need no
``HydraConfig`` to resolve, so :func:`run_job` here

* sets ``hydra.runtime.output_dir`` first and makes the ``HydraConfig`` once;
* copies the job's config for its task by a pickle round trip (as the plan copies its
  templates: :meth:`~decrun.runner.sweep.planning.Template.copy`);
* records that ``HydraConfig`` as the job's ``hydra_cfg`` (a read-only copy made for this
  job only, replaced by the next job's: nothing changes it; its ``hydra`` node also
  resolves interpolations into the job's config, as ``HydraConfig.get()`` does);
* writes ``.hydra/config.yaml``, ``hydra.yaml`` and ``overrides.yaml`` through libyaml
  (:func:`decrun.runner.yaml_text.to_yaml`: the same text for decrun's configs).

Everything else is Hydra's, in Hydra's order: the job's task config (a copy without
``hydra``), its log configuration, ``hydra.job.env_set``, the callbacks, ``chdir``, the
``JobReturn``. A job whose directory keys interpolate, or a config that leaves
``hydra.job.chdir`` to the version base, goes through Hydra's own ``run_job``.
tests/runner/test_local_launcher.py runs the same jobs both ways and compares the files
and returns. ~10 ms less per job (~19 → ~9 ms): the 8-job / 1-job sweep of ``benchmarks/bench_sweeps.py``.
"""

from __future__ import annotations

import copy
import logging
import os
import pickle
from pathlib import Path
from typing import Any, List, Sequence

from hydra.core.hydra_config import HydraConfig
from hydra.core.utils import (JobReturn, JobRuntime, JobStatus, configure_log, env_override, filter_overrides,
                              run_job as hydra_run_job, setup_globals)
from omegaconf import DictConfig, OmegaConf, open_dict, read_write

from decrun.runner.yaml_text import to_yaml

__all__ = ["launch", "run_job", "literal_output_dir", "is_basic_launcher"]

#: Hydra's basic launcher, by name (its module is private to Hydra)
BASIC = ("hydra._internal.core_plugins.basic_launcher", "BasicLauncher")

#: the basic launcher's logger: its lines look and filter (``hydra.verbose=hydra``) the same
log = logging.getLogger("hydra._internal.core_plugins.basic_launcher")


def is_basic_launcher(launcher: Any) -> bool:
    """Whether ``launcher`` is Hydra's basic launcher itself (not a subclass, not another launcher)."""
    return (type(launcher).__module__, type(launcher).__qualname__) == BASIC


def launch(launcher: Any, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> List[JobReturn]:
    """``BasicLauncher.launch`` of Hydra 1.3 (``launcher`` is one, set up), each job through
    :func:`run_job`: the jobs' returns, in order."""
    setup_globals()
    config, context = launcher.config, launcher.hydra_context
    configure_log(config.hydra.hydra_logging, config.hydra.verbose)
    Path(str(config.hydra.sweep.dir)).mkdir(parents=True, exist_ok=True)
    log.info(f"Launching {len(job_overrides)} jobs locally")
    runs: List[JobReturn] = []
    for idx, overrides in enumerate(job_overrides):
        idx = initial_job_idx + idx
        log.info(f"\t#{idx} : {' '.join(filter_overrides(overrides))}")
        sweep_config = context.config_loader.load_sweep_config(config, list(overrides))
        with open_dict(sweep_config):
            sweep_config.hydra.job.id = idx
            sweep_config.hydra.job.num = idx
        runs.append(run_job(hydra_context=context, task_function=launcher.task_function, config=sweep_config,
                            job_dir_key="hydra.sweep.dir", job_subdir_key="hydra.sweep.subdir"))
        configure_log(config.hydra.hydra_logging, config.hydra.verbose)
    return runs


def literal_output_dir(config: DictConfig, job_dir_key: str, job_subdir_key: str | None) -> str | None:
    """The job's output directory when its keys hold plain strings (no interpolation: no
    ``HydraConfig`` is needed to read them), else None."""
    parts = []
    for key in (job_dir_key, job_subdir_key):
        if key is None:
            continue
        value = _raw(config, key)
        if not isinstance(value, str) or "${" in value:
            return None
        parts.append(value)
    return os.path.join(*parts) if parts else None


def _raw(config: DictConfig, key: str) -> Any:
    """The value at a dotted ``key`` as written (interpolations not resolved)."""
    parent, _, leaf = key.rpartition(".")
    node = OmegaConf.select(config, parent) if parent else config
    if not isinstance(node, DictConfig) or leaf not in node:
        return None
    return OmegaConf.to_container(node, resolve=False).get(leaf)


def run_job(hydra_context: Any, task_function: Any, config: DictConfig, job_dir_key: str,
            job_subdir_key: str | None, configure_logging: bool = True) -> JobReturn:
    """Hydra 1.3's ``run_job`` (same arguments and return) with one ``HydraConfig`` per job
    and libyaml writing ``.hydra/`` (module docstring); Hydra's own ``run_job`` for a job
    whose directory keys interpolate or whose ``hydra.job.chdir`` is unset."""
    output_dir = literal_output_dir(config, job_dir_key, job_subdir_key)
    if output_dir is None or config.hydra.job.chdir is None:
        return hydra_run_job(task_function=task_function, config=config, job_dir_key=job_dir_key,
                             job_subdir_key=job_subdir_key, hydra_context=hydra_context,
                             configure_logging=configure_logging)
    callbacks = hydra_context.callbacks
    old_cwd = os.getcwd()
    state = HydraConfig.instance()
    orig_hydra_cfg = state.cfg
    with read_write(config.hydra.runtime), open_dict(config.hydra.runtime):
        config.hydra.runtime.output_dir = os.path.abspath(output_dir)
    state.set_config(config)
    chdir = False
    try:
        ret = JobReturn()
        task_cfg = _copy(config)
        with read_write(task_cfg), open_dict(task_cfg):
            del task_cfg["hydra"]
        ret.cfg = task_cfg
        hydra_cfg = state.cfg  # this job's own read-only copy (set_config): Hydra deep-copies it once more
        ret.hydra_cfg = hydra_cfg
        ret.overrides = OmegaConf.to_container(config.hydra.overrides.task)
        Path(output_dir).mkdir(parents=True, exist_ok=True)
        chdir = bool(hydra_cfg.hydra.job.chdir)
        if chdir:
            os.chdir(output_dir)
            ret.working_dir = output_dir
        else:
            ret.working_dir = os.getcwd()
        if configure_logging:
            configure_log(config.hydra.job_logging, config.hydra.verbose)
        if config.hydra.output_subdir is not None:
            hydra_output = Path(config.hydra.runtime.output_dir) / Path(config.hydra.output_subdir)
            _save_config(task_cfg, "config.yaml", hydra_output)
            _save_config(hydra_cfg, "hydra.yaml", hydra_output)
            _save_config(config.hydra.overrides.task, "overrides.yaml", hydra_output)
        with env_override(hydra_cfg.hydra.job.env_set):
            callbacks.on_job_start(config=config, task_function=task_function)
            try:
                ret.return_value = task_function(task_cfg)
                ret.status = JobStatus.COMPLETED
            except Exception as exc:
                ret.return_value = exc
                ret.status = JobStatus.FAILED
        ret.task_name = JobRuntime.instance().get("name")
        _flush_loggers()
        callbacks.on_job_end(config=config, job_return=ret)
        return ret
    finally:
        state.cfg = orig_hydra_cfg
        if chdir:
            os.chdir(old_cwd)


def _copy(config: DictConfig) -> DictConfig:
    """A deep copy of ``config`` by a pickle round trip: the same nodes, values, metadata,
    flags and resolver cache as ``copy.deepcopy`` (which Hydra uses) in ~1.7 ms instead of
    ~3.8 ms for a decrun job (as :meth:`decrun.runner.sweep.planning.Template.copy`). A config
    that does not pickle (an object node) is deep-copied."""
    try:
        return pickle.loads(pickle.dumps(config, protocol=pickle.HIGHEST_PROTOCOL))
    except Exception:  # noqa: BLE001 — whatever pickle refuses, deepcopy copies as Hydra does
        return copy.deepcopy(config)


def _save_config(cfg: Any, filename: str, output_dir: Path) -> None:
    """``<output_dir>/<filename>``: ``OmegaConf.to_yaml(cfg)``'s text (Hydra's ``.hydra/`` files)."""
    output_dir.mkdir(parents=True, exist_ok=True)
    with open(output_dir / filename, "w", encoding="utf-8") as file:
        file.write(to_yaml(cfg))


def _flush_loggers() -> None:
    """Flush every handler of every logger (what Hydra does after a job, by its own means)."""
    loggers = [logging.getLogger(), *(v for v in logging.Logger.manager.loggerDict.values()
                                      if isinstance(v, logging.Logger))]
    for logger in loggers:
        for handler in logger.handlers:
            try:
                handler.flush()
            except Exception:  # as Hydra: a handler that cannot flush does not fail the job
                pass
