"""What a sweep that stops early leaves: each job's state read from its directory, the
jobs whose process died marked ``killed``, and the command that resumes the rest.

Two ways a sweep stops while its jobs run (:class:`~decrun.runner.sweep.sweeper.ManifestSweeper`):

* **a worker process dies** (SIGKILL, the OOM killer, a segfault): joblib's loky pool then
  raises ``TerminatedWorkerError`` for the whole batch and kills its other workers too
  (``terminate_broken``: their running jobs are lost with it); Ray raises
  ``WorkerCrashedError`` once its retries are spent. :func:`worker_died` recognises these,
  :func:`mark_killed` writes ``status: killed`` into the ``metrics.json`` of every job that
  had started and not finished, and the sweeper ends with one line naming them and
  :func:`resume_command`, after writing the table;
* **the sweep is interrupted** (Ctrl-C, SIGTERM): :func:`take_stock` says which jobs
  finished and which were running, for the ``decrun`` command's message
  (:func:`decrun.runner.command.task.main`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

from decrun.runner.io.files import RunFiles
from decrun.runner.io.interrupts import ignore_interrupts
from decrun.runner.sweep.manifest import job_dir_name, job_state

__all__ = ["Stock", "take_stock", "worker_died", "mark_killed", "resume_command", "job_list", "ignore_interrupts"]

#: exceptions a launcher raises when a worker process died under a job (by class name:
#: the launchers' packages are optional)
DIED = ("TerminatedWorkerError", "BrokenProcessPool", "WorkerCrashedError", "NodeDiedError")
#: job states of a job that ended by itself (it wrote its metrics.json)
ENDED = ("ok", "failed")


@dataclass
class Stock:
    """The jobs of one sweep run by what became of them (job numbers as strings)."""

    finished: list[str] = field(default_factory=list)
    #: the manifest entries of jobs that started (their directory exists) and did not finish
    running: list[dict[str, Any]] = field(default_factory=list)
    waiting: list[str] = field(default_factory=list)
    sweep_dir: Path = Path(".")

    def describe(self, verb: str) -> str:
        """``jobs 0, 1 finished; 2, 3 <verb>; 4 not started`` (empty parts left out)."""
        parts = [f"{job_list(self.finished)} finished" if self.finished else "no job finished"]
        if self.running:
            parts.append(f"{job_list(j['job'] for j in self.running)} {verb}")
        if self.waiting:
            parts.append(f"{job_list(self.waiting)} not started")
        return "; ".join(parts)


def job_list(jobs) -> str:
    """``job 3`` or ``jobs 0, 1, 2``."""
    jobs = list(jobs)
    return f"job{'s' if len(jobs) != 1 else ''} {', '.join(jobs)}"


def take_stock(sweep_dir: Path, jobs: Sequence[dict[str, Any]]) -> Stock:
    """Sort the manifest entries ``jobs`` (this run's) by their directory in ``sweep_dir``:
    finished (``metrics.json`` ok or failed), running (a directory, no such metrics.json)
    or waiting (no directory: never started)."""
    stock = Stock(sweep_dir=Path(sweep_dir))
    for job in jobs:
        where = Path(sweep_dir) / job_dir_name(job)
        if job_state(where, job["config_hash"])["status"] in ENDED:
            stock.finished.append(job["job"])
        elif where.is_dir():
            stock.running.append(job)
        else:
            stock.waiting.append(job["job"])
    return stock


def worker_died(exc: BaseException) -> bool:
    """True when ``exc`` is a launcher's "a worker process died" (:data:`DIED`)."""
    return any(cls.__name__ in DIED for cls in type(exc).__mro__)


def mark_killed(stock: Stock, cause: str, why: str | None = None) -> None:
    """Write ``{"status": "killed", "error": ..., "config_hash": ...}`` to the ``metrics.json``
    of each running job of ``stock`` (its process died: nothing else will), keeping what
    its journal says (how many steps were recorded). A job that wrote its own metrics.json
    meanwhile is left as it is. ``why``: what stopped it, instead of "its worker process
    died (<cause>)"."""
    from decrun.runner.results.provenance import write_metrics_json  # lazy: h5py (start-up speed)

    for job in stock.running:
        where = stock.sweep_dir / job_dir_name(job)
        state = job_state(where, job["config_hash"])
        if state["status"] in ENDED:
            continue
        detail = (state["error"].split(" (")[0] if state["status"] == "killed" else "killed before its first step")
        write_metrics_json(RunFiles(where).metrics, {"status": "killed",
                                                    "error": f"{detail}: {why or f'its worker process died ({cause})'}",
                                                    "config_hash": job["config_hash"]})


def resume_command(sweep_dir: Path, argv: Sequence[str] | None = None) -> str:
    """The command line that resumes this sweep: the ``decrun`` command as typed (``argv``,
    default ``sys.argv[1:]``) with ``hydra.sweep.dir=<sweep_dir> hydra.sweeper.resume=true``
    in place of any ``hydra.sweep.dir`` / ``hydra.sweeper.resume`` it had."""
    from decrun.runner.sweep.launchers import command_with

    return command_with(argv, [f"hydra.sweep.dir={sweep_dir}", "hydra.sweeper.resume=true"])

