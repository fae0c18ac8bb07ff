"""The ``decrun`` sweeper: Hydra's grid sweep (``key=a,b`` → the product of the values, the
same jobs in the same order as Hydra's basic sweeper) that

1. composes every planned job once before any runs (a bad override stops the sweep
   before anything is written) and writes the plan — each job's overrides and
   :func:`~decrun.runner.sweep.manifest.config_hash` — to ``<sweep dir>/manifest.json``;
2. refuses a sweep directory that is not empty, unless ``hydra.sweeper.resume=true``;
3. with ``resume=true`` checks that the planned jobs are the manifest's (same overrides,
   same config hash: same config files) and launches only the jobs that are not ``ok``
   (missing, failed, killed, stale), each in its own directory ``<sweep dir>/<job>``.

Job ``i`` always runs in ``<sweep dir>/<i>`` (the sweeper passes
``hydra.sweep.subdir=<i>``), so a resumed job lands where it was planned whatever the
launcher. Hydra loads sweepers only from the ``hydra_plugins`` namespace:
:mod:`hydra_plugins.decrun_sweeper` registers this one as ``hydra/sweeper=decrun``.
"""

from __future__ import annotations

import copy
import logging
import os
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import OverrideType
from hydra.errors import CompactHydraException
from omegaconf import OmegaConf

from decrun.errors import ConfigError
from decrun.runner.sweep.manifest import DONE, FORMAT, MANIFEST, config_hash, job_state, now, read_manifest, write_manifest

log = logging.getLogger("decrun")

__all__ = ["DecrunSweeper", "DecrunSweeperConf", "SweepError"]

#: what a job directory may hold that a resumed job must not inherit
_JOB_OUTPUTS = ("metrics.json", "result.h5", "result.h5.partial")


class SweepError(ConfigError, CompactHydraException):
    """A sweep that cannot start (the message starts with ``error:``)."""


def refuse(exc: SweepError) -> None:
    """Print the one-line message and exit 1 (Hydra would add a line about tracebacks);
    with HYDRA_FULL_ERROR=1 (``decrun -v``) raise it instead."""
    if os.environ.get("HYDRA_FULL_ERROR") == "1":
        raise exc
    print(exc, file=sys.stderr)
    sys.exit(1)


@dataclass
class DecrunSweeperConf:
    _target_: str = "hydra_plugins.decrun_sweeper.DecrunSweeper"
    #: jobs per launcher call (null: all at once, as Hydra's basic sweeper)
    max_batch_size: Optional[int] = None
    #: sweep parameters from the config, e.g. {app.dt: "0.1,0.2"} (as Hydra's basic sweeper)
    params: Optional[Dict[str, str]] = field(default=None)
    #: rerun the jobs of an existing hydra.sweep.dir that are not ok
    resume: bool = False


class DecrunSweeper(BasicSweeper):
    """See the module docstring."""

    def __init__(self, max_batch_size: Optional[int] = None, params: Optional[Dict[str, str]] = None,
                 resume: bool = False):
        super().__init__(max_batch_size=max_batch_size, params=params)
        self.resume = resume

    def plan(self, arguments: List[str]) -> list[dict[str, Any]]:
        """The jobs of the sweep, in Hydra's order: ``{"job", "overrides", "config_hash"}``.

        Composes each job once (this is also Hydra's validation of a batch) and hands the
        compositions to the launcher (:class:`PlannedConfigs`), which would compose each
        job again: composition is most of a small job's overhead."""
        loader = self.hydra_context.config_loader
        parser = OverridesParser.create(config_loader=loader)
        overrides = parser.parse_overrides(self._parse_config() + list(arguments))
        planned = [job for batch in self.split_arguments(overrides, None) for job in batch]
        composer = Composer(loader, self.config)
        launched = [(*job, f"hydra.sweep.subdir={i}") for i, job in enumerate(planned)]
        configs = composer.compose_all(launched)
        jobs = [{"job": str(i), "overrides": list(job), "config_hash": config_hash(configs[key])}
                for i, (job, key) in enumerate(zip(planned, launched))]
        if not isinstance(loader, PlannedConfigs):
            self.hydra_context.config_loader = PlannedConfigs(loader, configs)  # the launcher's too (same object)
        return jobs

    def sweep(self, arguments: List[str]) -> Any:
        try:
            return self._sweep(arguments)
        except SweepError as exc:
            refuse(exc)

    def _sweep(self, arguments: List[str]) -> Any:
        sweep_dir = Path(str(self.config.hydra.sweep.dir))
        subdir = OmegaConf.to_container(self.config.hydra.sweep, resolve=False)["subdir"]
        if subdir != "${hydra.job.num}":
            raise SweepError(f"error: hydra.sweep.subdir={subdir}: the decrun sweeper names job directories by job "
                             "number; drop the override, or use hydra/sweeper=basic (no manifest, no resume)")
        jobs = self.plan(arguments)
        manifest, todo = self._start(sweep_dir, jobs, arguments)
        sweep_dir.mkdir(parents=True, exist_ok=True)
        OmegaConf.save(self.config, sweep_dir / "multirun.yaml")
        write_manifest(sweep_dir, manifest)
        if self.resume and len(todo) < len(jobs):
            print("decrun: resume: {} of {} jobs are ok; running {}".format(
                len(jobs) - len(todo), len(jobs), ", ".join(j["job"] for j in todo) or "nothing"), file=sys.stderr)
        returns = []
        size = self.max_batch_size or max(len(todo), 1)
        for start in range(0, len(todo), size):
            batch = [[*j["overrides"], f"hydra.sweep.subdir={j['job']}"] for j in todo[start:start + size]]
            results = self.launcher.launch(batch, initial_job_idx=int(todo[start]["job"]))
            for r in results:
                _ = r.return_value  # re-raise a job's exception, as the basic sweeper does
            returns.append(results)
        manifest["runs"][-1]["finished"] = now()
        write_manifest(sweep_dir, manifest)
        return returns

    def _start(self, sweep_dir: Path, jobs: list[dict], arguments: Sequence[str]) -> tuple[dict, list[dict]]:
        """(manifest, jobs to launch): a new sweep, or the resumed one after its checks."""
        run = {"started": now(), "jobs": [j["job"] for j in jobs], "finished": None}
        entries = sorted(p.name for p in sweep_dir.iterdir()) if sweep_dir.is_dir() else []
        if not entries:
            return {"format": FORMAT, "created": now(), "overrides": list(arguments), "jobs": jobs, "runs": [run]}, jobs
        if not self.resume:
            raise SweepError(f"error: hydra.sweep.dir={sweep_dir} is not empty ({len(entries)} entries: "
                             f"{', '.join(entries[:4])}{', ...' if len(entries) > 4 else ''}); add "
                             "hydra.sweeper.resume=true to rerun its missing and failed jobs, or choose a new "
                             "hydra.sweep.dir")
        manifest = read_manifest(sweep_dir)
        if manifest is None:
            raise SweepError(f"error: hydra.sweeper.resume=true: {sweep_dir} has no {MANIFEST} (not started by "
                             "the decrun sweeper); choose a new hydra.sweep.dir")
        planned = manifest["jobs"]
        if len(planned) != len(jobs):
            raise SweepError(f"error: hydra.sweeper.resume=true: {sweep_dir} planned {len(planned)} jobs, this "
                             f"command plans {len(jobs)}; resume with the sweep's own overrides: "
                             f"{' '.join(manifest['overrides'])}")
        for old, new in zip(planned, jobs):
            if old["overrides"] != new["overrides"] or old["config_hash"] != new["config_hash"]:
                what = ("overrides " + " ".join(new["overrides"]) + " differ from " + " ".join(old["overrides"])
                        if old["overrides"] != new["overrides"] else
                        f"config hash {new['config_hash']} differs from {old['config_hash']} (a config file changed)")
                raise SweepError(f"error: hydra.sweeper.resume=true: job {old['job']}: {what}; resume with "
                                 "the same overrides and configs, or start a new sweep")
        todo = [j for j in jobs if job_state(sweep_dir / j["job"], j["config_hash"])["status"] not in DONE]
        for job in todo:
            _clear(sweep_dir / job["job"])
        run["jobs"] = [j["job"] for j in todo]
        manifest.setdefault("runs", []).append(run)
        return manifest, todo


class Composer:
    """Composes a sweep's jobs as Hydra does, faster: jobs that differ from an already
    composed one only in plain values (``app.dt=0.1`` → ``app.dt=0.2``: no config group,
    no ``+``/``~``, no dict or list) are derived from it — a copy with Hydra's own
    ``_apply_overrides_to_config`` and the override lists and ``override_dirname`` Hydra
    would write. A full Hydra composition costs ~0.3 s; the copy a few ms.

    Checked, not trusted: the last job of every template is also composed by Hydra, and if
    the two differ the template's jobs are all composed by Hydra (with a message)."""

    def __init__(self, loader, master):
        self.loader, self.master = loader, master
        self.parser = OverridesParser.create(config_loader=loader)

    def _plain(self, override) -> bool:
        return (override.type == OverrideType.CHANGE and override.package is None
                and not self.loader.repository.group_exists(override.key_or_group.replace(".", "/"))
                and isinstance(override.value(), (str, int, float, bool, type(None))))

    def compose_all(self, jobs: list[tuple[str, ...]]) -> dict[tuple[str, ...], Any]:
        groups: dict[tuple, list[tuple[tuple[str, ...], list]]] = {}
        for job in jobs:
            parsed = self.parser.parse_overrides(list(job))
            shape = tuple((o.key_or_group, None if self._plain(o) else o.input_line) for o in parsed)
            groups.setdefault(shape, []).append((job, parsed))
        configs = {}
        for members in groups.values():
            (first, _), rest = members[0], members[1:]
            template = self.loader.load_sweep_config(self.master, list(first))
            configs[first] = template
            if not rest:
                continue
            pristine = copy.deepcopy(template)
            for job, parsed in rest:
                configs[job] = self._derive(pristine, parsed)
            last, _ = rest[-1]
            fresh = self.loader.load_sweep_config(self.master, list(last))
            if OmegaConf.to_yaml(fresh) != OmegaConf.to_yaml(configs[last]):
                print(f"decrun: derived composition of {' '.join(last)} differs from Hydra's; composing "
                      f"each of its {len(members)} jobs with Hydra", file=sys.stderr)
                for job, _ in rest:
                    configs[job] = self.loader.load_sweep_config(self.master, list(job))
            configs[last] = fresh
        return configs

    def _derive(self, pristine, parsed):
        from hydra._internal.config_loader_impl import ConfigLoaderImpl, get_overrides_dirname

        cfg = copy.deepcopy(pristine)
        ConfigLoaderImpl._apply_overrides_to_config([o for o in parsed if self._plain(o)], cfg)
        hydra_lines = [o.input_line for o in parsed if o.is_hydra_override()]
        task = [o for o in parsed if not o.is_hydra_override()]
        fixed = list(cfg.hydra.overrides.hydra)[:len(cfg.hydra.overrides.hydra) - len(hydra_lines)]
        cfg.hydra.overrides.hydra = fixed + hydra_lines
        cfg.hydra.overrides.task = [o.input_line for o in task]
        dirname = cfg.hydra.job.config.override_dirname
        cfg.hydra.job.override_dirname = get_overrides_dirname(overrides=task, kv_sep=dirname.kv_sep,
                                                               item_sep=dirname.item_sep,
                                                               exclude_keys=dirname.exclude_keys)
        OmegaConf.copy_cache(from_config=self.master, to_config=cfg)
        return cfg


class PlannedConfigs:
    """Hydra's config loader, except that ``load_sweep_config`` of a planned job returns
    the composition made when planning (each once: the launcher sets its job number on
    it). Everything else, and any other job, goes to the wrapped loader. Picklable, so
    launchers that compose in their workers (joblib, submitit, ray) get it too."""

    def __init__(self, loader, configs: dict[tuple[str, ...], Any]):
        self._loader = loader
        self._configs = configs

    def load_sweep_config(self, master_config, sweep_overrides):
        config = self._configs.pop(tuple(sweep_overrides), None)
        return config if config is not None else self._loader.load_sweep_config(master_config, sweep_overrides)

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._loader, name)


def _clear(job_dir: Path) -> None:
    """Remove a job's outputs before it is rerun (its log and .hydra/ are rewritten)."""
    if not job_dir.is_dir():
        return
    for name in _JOB_OUTPUTS:
        (job_dir / name).unlink(missing_ok=True)
    for leftover in job_dir.glob(".result.h5*"):
        leftover.unlink(missing_ok=True)
    for figure in job_dir.glob("*.png"):
        figure.unlink()
    shutil.rmtree(job_dir / ".hydra", ignore_errors=True)
