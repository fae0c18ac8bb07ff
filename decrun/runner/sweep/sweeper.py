"""The ``decrun`` sweeper: Hydra's grid sweep (``key=a,b`` → the product of the values, the
same jobs in the same order as Hydra's basic sweeper) that

1. composes and checks every planned job before any runs (a bad override or value stops
   the sweep before anything is written, naming the job: :func:`~decrun.runner.sweep.checks.register_check`) and
   writes the plan — each job's directory, overrides and
   :func:`~decrun.runner.sweep.manifest.config_hash` — to ``<sweep dir>/manifest.json``;
2. refuses a sweep directory that is not empty, unless ``hydra.sweeper.resume=true``;
3. with ``resume=true`` checks that the planned jobs are the manifest's (same overrides,
   same config hash: same config files) and launches only the jobs that are not ``ok``
   (missing, failed, killed, stale), each in the directory the manifest recorded.

A job's directory is ``hydra.sweep.subdir`` (any pattern: ``${hydra.job.num}``,
``${hydra.job.override_dirname}``, ``run_${hydra.job.num}``...) resolved when the sweep is
planned and passed to the launcher as a literal ``hydra.sweep.subdir='<dir>'``, so a job
and its resumed rerun land where the manifest says whatever the launcher; two jobs with one
directory stop the sweep before it starts. The sweeper is built on Hydra's public plugin
API only (``hydra.plugins.sweeper.Sweeper``, ``Plugins.instantiate_launcher``, the
``OverridesParser``; the grid: :func:`~decrun.runner.sweep.grid.grid`). Hydra loads sweepers
only from the ``hydra_plugins`` namespace: :mod:`hydra_plugins.decrun_sweeper` registers
:class:`ManifestSweeper` there as ``hydra/sweeper=decrun``.
"""

from __future__ import annotations

import logging
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, cast

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.plugins import Plugins
from hydra.errors import CompactHydraException
from hydra.plugins.sweeper import Sweeper
from omegaconf import OmegaConf, open_dict, read_write

from decrun.errors import ConfigError, CorruptFileError, DecrunError
from decrun.runner.io.atomic import write_text_atomic
from decrun.runner.io.files import RunFiles, SweepFiles
from decrun.runner.io.locks import LOCK_NAME
from decrun.runner.io.paths import hydra_files
from decrun.runner.sweep.checks import CHECKS, WARM
from decrun.runner.sweep.conf import DecrunSweeperConf
from decrun.runner.sweep.fast import SpeedLayer
from decrun.runner.sweep.grid import MAX_JOBS, grid, grid_size
from decrun.runner.sweep.guard import check_job_dirs, lock_sweep
from decrun.runner.sweep.launchers import (
    CONNECT_TIMEOUT,
    NO_TIME_LIMIT,
    RAY,
    SLURM,
    connect_ray_as_is,
    is_launcher,
    joblib_timeout,
    launch_failure,
    launcher_choice,
    preflight,
    timed_out,
)
from decrun.runner.sweep.manifest import (
    DONE,
    FORMAT,
    MANIFEST,
    job_dir_name,
    job_state,
    now,
    read_manifest,
    write_manifest,
)
from decrun.runner.sweep.stops import ignore_interrupts, mark_killed, resume_command, take_stock, worker_died

log = logging.getLogger("decrun")

__all__ = ["ManifestSweeper", "DecrunSweeperConf", "SweepError"]



class SweepError(ConfigError, CompactHydraException):
    """A sweep that cannot start (the message starts with ``error:``)."""


def refuse(exc: SweepError) -> None:
    """Print the one-line message and exit 1 (Hydra would add a line about tracebacks);
    with HYDRA_FULL_ERROR=1 (``decrun -v``) raise it instead."""
    if os.environ.get("HYDRA_FULL_ERROR") == "1":
        raise exc
    from decrun.errors import shorten_words

    print(shorten_words(str(exc)), file=sys.stderr)
    sys.exit(1)


class ManifestSweeper(Sweeper):
    """The manifest, the checks and resume (module docstring) on Hydra's grid: the jobs
    and their order are those of Hydra's basic sweeper (``hydra.sweeper.params`` first,
    then the command line's overrides; :func:`~decrun.runner.sweep.grid.grid`), launched
    ``max_batch_size`` at a time. :mod:`hydra_plugins.decrun_sweeper` registers it with
    Hydra (``DecrunSweeper``, which makes one when Hydra builds the sweeper)."""

    def __init__(self, max_batch_size: Optional[int] = None, params: Optional[Dict[str, str]] = None,
                 resume: bool = False, fast: bool = True, connect_timeout: float = CONNECT_TIMEOUT,
                 max_jobs: int = MAX_JOBS) -> None:
        super().__init__()
        self.max_batch_size, self.params = max_batch_size, dict(params or {})
        self.resume, self.speed = resume, SpeedLayer(fast)
        self.connect_timeout = connect_timeout
        self.max_jobs = max_jobs
        #: (jobs planned, jobs to plan) while the sweep is planned
        self.planned = (0, 0)
        #: Hydra's context, the sweep's config and the launcher (:meth:`setup`)
        self.hydra_context: Any = None
        self.config: Any = None
        self.launcher: Any = None
        self.check: Optional[Callable[..., Any]] = None

    def setup(self, *, hydra_context: Any, task_function: Callable, config: Any) -> None:
        self.hydra_context, self.config = hydra_context, config
        self.launcher = Plugins.instance().instantiate_launcher(hydra_context=hydra_context,
                                                                task_function=task_function, config=config)
        self.check = CHECKS.get(task_function)
        # what a worker imports to unpickle its first job comes too: the task's module (decrun's
        # CLI: Hydra, its callbacks) (~0.1 s before the job could start)
        registered = WARM.get(task_function, ())
        self.warm = (*registered, task_function.__module__) if registered else ()

    def plan(self, arguments: List[str]) -> list[dict[str, Any]]:
        """The jobs of the sweep, in Hydra's order: ``{"job", "dir", "overrides",
        "config_hash"}`` (``dir``: the job's ``hydra.sweep.subdir``, resolved now).

        Composes each job once (this is also Hydra's validation of a batch; with
        ``hydra.sweeper.fast`` most jobs are derived from their group's composition,
        :mod:`~decrun.runner.sweep.fast`) and runs the ``check`` function on each, before
        any job starts."""
        loader = self.speed.unwrap(self.hydra_context)  # Hydra's own, after an earlier sweep
        parser = OverridesParser.create(config_loader=loader)
        overrides = parser.parse_overrides([f"{k}={v}" for k, v in self.params.items()] + list(arguments))  # params first
        try:
            size, swept = grid_size(overrides)
        except ValueError as exc:
            raise SweepError(f"error: {exc}") from exc
        if size > self.max_jobs:  # before a job is made: a grid may be too large to hold
            raise SweepError(_too_many(size, swept, self.max_jobs))
        planned = [tuple(job) for job in grid(overrides)]
        check = self.check
        jobs: list[dict[str, Any]] = []
        shown = PlanningProgress(len(planned), enabled=_terminal(self.config))
        self.planned = (0, len(planned))
        try:
            for i, (job, cfg, template) in enumerate(self.speed.compose(loader, self.config, planned)):
                self.planned = (i, len(planned))
                shown.update(i)
                if check is not None:
                    try:
                        self.speed.check(check, cfg, template)
                    except DecrunError as exc:
                        raise SweepError(f"error: job {i} ({' '.join(job)}): {exc}; nothing ran") from exc
                where = self.speed.job_dir(template, i)
                jobs.append({"job": str(i), "dir": self._job_dir(cfg, i) if where is None else where,
                             "overrides": list(job), "config_hash": self.speed.config_hash(cfg, template)})
        finally:
            shown.close()
        _check_dirs(jobs, cast(dict, OmegaConf.to_container(self.config.hydra.sweep, resolve=False))["subdir"])
        return jobs

    def _job_dir(self, cfg, num: int) -> str:
        """``hydra.sweep.subdir`` of job ``num`` as a launcher resolves it (``hydra.job.id``
        is the job number, as the basic launcher sets it)."""
        from hydra.core.hydra_config import HydraConfig

        with read_write(cfg.hydra), open_dict(cfg.hydra):
            cfg.hydra.job.num = num
            cfg.hydra.job.id = num
        if "${hydra:" not in cast(dict, OmegaConf.to_container(cfg.hydra.sweep, resolve=False))["subdir"]:
            return str(OmegaConf.select(cfg, "hydra.sweep.subdir"))
        state = HydraConfig.instance()
        before = state.cfg
        state.set_config(cfg)  # for ${hydra:...} in the pattern (as the launcher's job sees it)
        try:
            return str(OmegaConf.select(cfg, "hydra.sweep.subdir"))
        finally:
            OmegaConf.set_readonly(cfg.hydra, None)  # set_config froze it; the launcher sets the job's number
            state.cfg = before

    def _hand_over(self, jobs: list[dict]) -> list[list[str]]:
        """The launcher's job lists: each job's overrides plus its recorded directory
        (``hydra.sweep.subdir='<dir>'``, so it lands where the manifest says whatever
        the launcher or the clock) and the sweep directory as this process resolved it
        (``hydra.sweep.dir='<absolute>'``: a job run in another working directory — a Ray
        worker, a node of a cluster — writes into it, not into a directory of the same name
        where it runs). With ``hydra.sweeper.fast`` the launcher's config loader then
        derives the planned groups' jobs (:meth:`~decrun.runner.sweep.fast.SpeedLayer.swap_loader`)."""
        sweep_dir = _quoted(str(Path(str(self.config.hydra.sweep.dir)).absolute()))
        launched = [[*job["overrides"], f"hydra.sweep.dir={sweep_dir}", f"hydra.sweep.subdir={_quoted(job['dir'])}"]
                    for job in jobs]
        self.speed.swap_loader(self.hydra_context, extra=(("hydra.sweep.dir", None), ("hydra.sweep.subdir", None)))
        return launched

    def sweep(self, arguments: List[str]) -> Any:
        try:
            with self.speed.frozen_heap():
                return self._sweep(arguments)
        except SweepError as exc:
            refuse(exc)

    def _sweep(self, arguments: List[str]) -> Any:
        sweep_dir = Path(str(self.config.hydra.sweep.dir))
        if not self.connect_timeout or self.connect_timeout <= 0:
            raise SweepError(f"error: hydra.sweeper.connect_timeout={self.connect_timeout}: must be a number of "
                             f"seconds above 0; use hydra.sweeper.connect_timeout={CONNECT_TIMEOUT:g}")
        if is_launcher(self.launcher, *RAY):
            connect_ray_as_is(self.launcher)  # the options preflight connects with are the launcher's
        cannot = preflight(self.launcher, self.config, self.connect_timeout)  # before planning: nothing written
        if cannot:
            raise SweepError(cannot)
        try:
            with self.speed.warming(self.launcher, self.warm):
                jobs = self.plan(arguments)
        except KeyboardInterrupt as exc:  # the decrun command says where (decrun.runner.command.task.main)
            done, total = self.planned
            where = (f"while the sweep was planned ({done:,} of {total:,} jobs checked); nothing was written"
                     if total else "while the sweep was planned; nothing was written")
            exc.sweep_where = where  # type: ignore[attr-defined]  # read by command.task.main
            raise
        lock_sweep(sweep_dir, SweepError)  # before the manifest is read: one sweeping process per directory
        manifest, todo = self._start(sweep_dir, jobs, arguments)
        write_text_atomic(SweepFiles(sweep_dir).multirun, OmegaConf.to_yaml(self.config))
        write_manifest(sweep_dir, manifest)
        if self.resume and len(todo) < len(jobs):
            print("decrun: resume: {} of {} jobs are ok; running {}".format(
                len(jobs) - len(todo), len(jobs), ", ".join(j["job"] for j in todo) or "nothing"), file=sys.stderr)
        returns = []
        launched = self._hand_over(todo)
        for start, stop in _batches([int(j["job"]) for j in todo], self.max_batch_size):
            try:
                results = self._launch(launched[start:stop], int(todo[start]["job"]))
            except KeyboardInterrupt as exc:  # the decrun command says which jobs finished (decrun.runner.command.task.main)
                ignore_interrupts()  # a second Ctrl-C while the jobs are counted is ignored (the sweep is ending)
                exc.sweep_stock = take_stock(sweep_dir, todo)  # type: ignore[attr-defined]  # read by command.task.main
                raise
            except Exception as exc:
                if worker_died(exc):
                    self._end_early(sweep_dir, manifest, todo, exc, "killed",
                                    f"a worker process died ({type(exc).__name__})",
                                    f"resume the rest with: {resume_command(sweep_dir)}", table=True)
                if timed_out(self.launcher, exc):
                    limit = float(joblib_timeout(self.launcher))
                    self._end_early(sweep_dir, manifest, todo, exc, "killed",
                                    f"{launcher_choice(self.config)}: a job ran longer than hydra.launcher.timeout="
                                    f"{limit:g} s and joblib stopped the batch's workers",
                                    f"resume with no time limit: {NO_TIME_LIMIT.command(_resuming(sweep_dir))}",
                                    why=f"joblib stopped its worker (a job of its batch ran longer than "
                                        f"hydra.launcher.timeout={limit:g} s)", table=True)
                failure = launch_failure(self.launcher, self.config, exc)
                if failure is None:
                    raise
                what, fix = failure
                self._end_early(sweep_dir, manifest, todo, exc, "not finished", what,
                                f"resume here with: {fix.command(_resuming(sweep_dir))}")
            for r in results:
                _ = r.return_value  # re-raise a job's exception, as the basic sweeper does
            returns.append(results)
        manifest["runs"][-1]["finished"] = now()
        write_manifest(sweep_dir, manifest)
        return returns

    def _end_early(self, sweep_dir: Path, manifest: dict, todo: list[dict], exc: Exception, verb: str, what: str,
                   fix: str, why: Optional[str] = None, table: bool = False) -> None:
        """End the sweep after its launcher stopped (a worker died, a job over its time
        limit, jobs that could not be submitted): the jobs that had started and not
        finished marked ``killed`` (``why``: by what) and recorded in the manifest's run,
        the table written when a job of this run started (or ``table``), then one line
        ``error: <what>: <which jobs finished, which are <verb>>; <fix>`` (exit 1). The
        manifest stays: ``hydra.sweeper.resume=true`` reruns what is not ok."""
        stock = take_stock(sweep_dir, todo)
        if stock.running:
            mark_killed(stock, type(exc).__name__, why=why)
            manifest["runs"][-1]["killed"] = [j["job"] for j in stock.running]
        write_manifest(sweep_dir, manifest)
        callbacks = getattr(self.hydra_context, "callbacks", None)
        if callbacks is not None and (table or stock.running or stock.finished):
            callbacks.on_multirun_end(config=self.config)
        raise SweepError(f"error: {what}: {stock.describe(verb)}; {fix}") from exc

    def _launch(self, overrides: list[list[str]], first: int) -> Sequence[Any]:
        """The launcher's results for one batch. With submitit's SLURM launcher, job states
        come from squeue when accounting is off, and a job that ended without a result
        (``scancel``, time limit: :mod:`decrun.runner.sweep.launchers.slurm`) does not end the sweep:
        its other jobs are waited for, the table's row of that job says ``killed`` or
        ``missing``, and ``hydra.sweeper.resume=true`` reruns it."""
        if is_launcher(self.launcher, *RAY):
            connect_ray_as_is(self.launcher)
        if not is_launcher(self.launcher, *SLURM):
            return self.launcher.launch(overrides, initial_job_idx=first)
        from decrun.runner.sweep.launchers import slurm  # lazy: submitit

        slurm.use_queue_states()
        try:
            return self.launcher.launch(overrides, initial_job_idx=first)
        except Exception as exc:
            if launch_failure(self.launcher, self.config, exc) is not None or not slurm.ended_without_result(exc):
                raise  # nothing was submitted (sbatch refused): the sweep ends (_sweep)
            cause = str(exc).splitlines()[0]
            print(f"decrun: a SLURM job ended without a result ({cause}); waiting for the sweep's other jobs; "
                  "rerun it with hydra.sweeper.resume=true", file=sys.stderr)
            slurm.wait_for_jobs()
            return []

    def _start(self, sweep_dir: Path, jobs: list[dict], arguments: Sequence[str]) -> tuple[dict, list[dict]]:
        """(manifest, jobs to launch): a new sweep, or the resumed one after its checks."""
        run = {"started": now(), "jobs": [j["job"] for j in jobs], "finished": None}
        entries = sorted(p.name for p in sweep_dir.iterdir() if p.name != LOCK_NAME) if sweep_dir.is_dir() else []
        if not entries:
            return {"format": FORMAT, "created": now(), "overrides": list(arguments), "jobs": jobs, "runs": [run]}, jobs
        if not self.resume:
            raise SweepError(f"error: hydra.sweep.dir={sweep_dir} is not empty ({len(entries)} entries: "
                             f"{', '.join(entries[:4])}{', ...' if len(entries) > 4 else ''}); add "
                             "hydra.sweeper.resume=true to rerun its missing and failed jobs, or choose a new "
                             "hydra.sweep.dir")
        try:
            manifest = read_manifest(sweep_dir)
        except CorruptFileError as exc:
            raise SweepError(f"error: hydra.sweeper.resume=true: {exc}; its plan is lost: choose a new "
                             "hydra.sweep.dir") from exc
        if manifest is None:
            raise SweepError(f"error: hydra.sweeper.resume=true: {sweep_dir} has no {MANIFEST} (not started by "
                             "the decrun sweeper); choose a new hydra.sweep.dir")
        planned = manifest["jobs"]
        if len(planned) != len(jobs):
            raise SweepError(f"error: hydra.sweeper.resume=true: {sweep_dir} planned {len(planned)} jobs, this "
                             f"command plans {len(jobs)}; resume with the sweep's own overrides: "
                             f"{' '.join(manifest['overrides'])}")
        for old, new in zip(planned, jobs, strict=True):
            same = _identity(old["overrides"]) == _identity(new["overrides"])  # the tracker may change
            if not same or old["config_hash"] != new["config_hash"]:
                what = ("overrides " + " ".join(new["overrides"]) + " differ from " + " ".join(old["overrides"])
                        if not same else
                        f"config hash {new['config_hash']} differs from {old['config_hash']} (a config file changed)")
                raise SweepError(f"error: hydra.sweeper.resume=true: job {old['job']}: {what}; resume with "
                                 "the same overrides and configs, or start a new sweep")
        for old, new in zip(planned, jobs, strict=True):
            new["dir"] = job_dir_name(old)  # where it was planned (a pattern may resolve anew, e.g. ${now:})
        check_job_dirs(sweep_dir, jobs, hydra_files(self.config.hydra), sweep_dir / MANIFEST, SweepError)
        todo = [j for j in jobs if job_state(sweep_dir / j["dir"], j["config_hash"])["status"] not in DONE]
        for job in todo:
            _clear(sweep_dir / job["dir"])
        run["jobs"] = [j["job"] for j in todo]
        manifest.setdefault("runs", []).append(run)
        return manifest, todo


#: config roots whose overrides are not part of a job's identity on resume: where its runs are
#: logged (docs/tracking.md: a ``tracker=none`` sweep resumes with ``tracker=mlflow``, and back;
#: tests/runner/results/test_tracker.py::test_a_sweep_resumes_with_the_tracker_switched runs both ways)
NOT_IDENTITY = ("tracker",)


def _identity(overrides: Sequence[str]) -> list[str]:
    """A job's overrides without those of :data:`NOT_IDENTITY` (``tracker=mlflow``,
    ``tracker.uri=…``, ``+tracker.x=…``), in their order: what a resumed job must repeat."""
    def root(override: str) -> str:
        key = override.partition("=")[0].lstrip("+~").partition("@")[0]
        return key.replace("/", ".").partition(".")[0]

    return [o for o in overrides if root(str(o)) not in NOT_IDENTITY]


def _batches(nums: list[int], size: Optional[int]) -> list[tuple[int, int]]:
    """``[start, stop)`` index ranges of ``nums`` for the launcher calls: at most ``size``
    jobs each and consecutive job numbers only (a launcher numbers a call's jobs from its
    first one, so a resumed sweep's jobs keep their ``hydra.job.num``)."""
    ranges, start = [], 0
    for i in range(1, len(nums) + 1):
        if i == len(nums) or nums[i] != nums[i - 1] + 1 or (size and i - start == size):
            ranges.append((start, i))
            start = i
    return ranges


def _too_many(size: int, swept: list[tuple[str, int]], limit: int) -> str:
    """The refusal of a grid of ``size`` jobs over ``hydra.sweeper.max_jobs=limit``."""
    product = " × ".join(f"{key}: {n} values" for key, n in swept)
    return (f"error: hydra.sweeper.max_jobs={limit}: this sweep has {size:,} jobs ({product}), more than the "
            f"limit (every job is composed, checked and hashed before the first starts: ~1-3 ms a job); nothing "
            f"ran; plan them all with hydra.sweeper.max_jobs={size}, or sweep fewer values")


def _terminal(config) -> bool:
    """Whether to show progress: ``progress`` is on and stderr is a terminal (not under pytest).
    A ``progress`` that does not resolve counts as off here: the job's own check names it."""
    from omegaconf import OmegaConf

    progress = OmegaConf.select(config, "progress", default=True, throw_on_resolution_failure=False)
    return bool(progress) and sys.stderr.isatty() and "PYTEST_CURRENT_TEST" not in os.environ


class PlanningProgress:
    """``decrun: planning the sweep: <i> of <n> jobs checked (<p> %), ~<s> s left`` on one
    terminal line, redrawn at most every ``every`` seconds once planning has taken
    ``after`` seconds, and erased when planning ends (:meth:`close`). A no-op unless ``enabled``."""

    def __init__(self, total: int, enabled: bool, after: float = 0.5, every: float = 0.25, stream=None):
        self.total, self.enabled, self.after, self.every = total, enabled, after, every
        self.stream = stream if stream is not None else sys.stderr
        self.start = time.monotonic()
        self._next = self.start + after
        self._drawn = False
        self._first: Optional[tuple[float, int]] = None

    def update(self, done: int) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if now < self._next:
            return
        self._next = now + self.every
        if self._first is None:  # the rate from the first job checked (the groups' compositions come before it)
            self._first = (now, done)
        then, before = self._first
        left = (now - then) / (done - before) * (self.total - done) if done - before >= 5 else None
        eta = f", ~{left:.0f} s left" if left is not None else ""
        self.stream.write(f"\rdecrun: planning the sweep: {done:,} of {self.total:,} jobs checked "
                          f"({100 * done // max(self.total, 1)} %){eta}\033[K")
        self.stream.flush()
        self._drawn = True

    def close(self) -> None:
        if self._drawn:
            self.stream.write("\r\033[K")
            self.stream.flush()
            self._drawn = False


def _resuming(sweep_dir: Path) -> list[str]:
    """The overrides that resume the sweep in ``sweep_dir``."""
    return [f"hydra.sweep.dir={sweep_dir}", "hydra.sweeper.resume=true"]


def _quoted(text: str) -> str:
    """``text`` as one quoted value of a Hydra override."""
    return "'" + text.replace("\\", "\\\\").replace("'", "\\'") + "'"


def _check_dirs(jobs: list[dict], pattern: str) -> None:
    """SweepError when a job's directory is empty, outside the sweep directory or another
    job's: the manifest, the table and resume need one directory per job."""
    seen: dict[str, str] = {}
    for job in jobs:
        where = os.path.normpath(job["dir"])
        if not job["dir"] or where == "." or os.path.isabs(where) or where.split(os.sep)[0] == "..":
            raise SweepError(f"error: hydra.sweep.subdir={pattern}: job {job['job']} gets directory "
                             f"{job['dir']!r}, not one inside hydra.sweep.dir; use a relative pattern such as "
                             "${hydra.job.num} or ${hydra.job.override_dirname}")
        if where in seen:
            raise SweepError(f"error: hydra.sweep.subdir={pattern}: jobs {seen[where]} and {job['job']} both get "
                             f"directory {job['dir']!r}; use a pattern that differs per job, e.g. with "
                             "${hydra.job.num}")
        seen[where] = job["job"]


def _clear(job_dir: Path) -> None:
    """Remove a job's outputs before it is rerun (its log and .hydra/ are rewritten)."""
    if not job_dir.is_dir():
        return
    # a checkpoint of a time-stepping job and the journal it continues are kept: the rerun
    # continues from them when they are its config's (decrun.runner.results.checkpoint)
    kept = (RunFiles.JOURNAL,) if (job_dir / RunFiles.CHECKPOINT).is_file() else ()
    for name in RunFiles.JOB_OUTPUTS:
        if name not in kept:
            (job_dir / name).unlink(missing_ok=True)
    for leftover in job_dir.glob(RunFiles.RESULT_TEMPORARIES):
        leftover.unlink(missing_ok=True)
    for figure in job_dir.glob(RunFiles.FIGURES):
        figure.unlink()
    shutil.rmtree(job_dir / RunFiles.HYDRA, ignore_errors=True)
