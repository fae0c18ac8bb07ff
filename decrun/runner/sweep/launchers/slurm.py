"""SLURM job states for ``hydra/launcher=submitit_slurm`` sweeps without accounting.

submitit polls a sweep's job states with ``sacct``. On a cluster with accounting off
(``AccountingStorageType=accounting_storage/none``, as ``scripts/slurm_local.sh`` sets up)
``sacct`` fails on every poll: submitit prints a warning each time, and the state of every
job stays ``UNKNOWN``, so a job that ends without a result — cancelled (``scancel``), past
its time limit, its node lost — is waited for forever.

:func:`use_queue_states` (called by the ``decrun`` sweeper before a SLURM launcher runs)
replaces submitit's watcher by :class:`QueueWatcher`: ``sacct`` as long as it works; when it
fails, one line on stderr and the states from ``squeue --states=all`` (the controller
keeps an ended job ``MinJobAge`` seconds, 300 by default; a job it no longer lists has
ended: :data:`GONE`). :func:`wait_for_jobs` then waits for the sweep's other jobs when one
ended without a result (:func:`ended_without_result`), so the table has their rows: the
job's own row is ``killed`` (it died while recording) or ``missing``, and
``hydra.sweeper.resume=true`` reruns it.
"""

from __future__ import annotations

import subprocess
import sys
import time
from typing import Dict, Optional

from submitit.core.utils import UncompletedJobError
from submitit.slurm.slurm import SlurmInfoWatcher, SlurmJob

__all__ = ["QueueWatcher", "use_queue_states", "wait_for_jobs", "ended_without_result", "GONE"]

#: the state of a job the controller no longer lists (ended more than MinJobAge ago)
GONE = "ENDED_NOT_IN_QUEUE"
#: the header :meth:`QueueWatcher.read_info` expects (the columns of squeue's ``%i|%T|%N``)
_HEADER = "JobID|State|NodeList"


class QueueWatcher(SlurmInfoWatcher):
    """submitit's SLURM watcher, falling back to ``squeue`` when ``sacct`` fails.

    ``accounting``: None until the first poll, then whether ``sacct`` answered. The poll
    schedule, the registered and finished jobs and the state cache are submitit's."""

    accounting: Optional[bool] = None

    def update(self) -> None:
        """Poll the states of the registered jobs that have not finished (one command)."""
        pending = self._registered - self._finished
        if not pending:
            return
        self._num_calls += 1
        info = self._sacct(pending) if self.accounting is not False else None
        if info is None:
            info = self._squeue(pending)
        if info is not None:
            self._info_dict.update(info)
        self._last_status_check = time.time()
        for job_id in pending:
            if self.is_done(job_id, mode="cache"):
                self._finished.add(job_id)

    def _sacct(self, pending: set[str]) -> Optional[Dict[str, Dict[str, str]]]:
        """States from ``sacct``; None (and ``accounting = False``, said once) when it fails."""
        command = self._make_command()
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=60)
        except (OSError, subprocess.TimeoutExpired) as exc:
            why = str(exc)
        else:
            if done.returncode == 0:
                self.accounting = True
                return self.read_info(done.stdout)
            why = (done.stderr.strip() or f"exit status {done.returncode}").splitlines()[0]
        self.accounting = False
        print(f"decrun: SLURM accounting is off (sacct: {why}); job states come from squeue", file=sys.stderr)
        return None

    def _squeue(self, pending: set[str]) -> Optional[Dict[str, Dict[str, str]]]:
        """States from ``squeue --states=all``; a pending job it does not list is :data:`GONE`.
        None when squeue itself fails (the controller does not answer: the states stay as
        they were and the next poll asks again)."""
        ids = sorted({job_id.split("_")[0] for job_id in pending})
        command = ["squeue", "--noheader", "--states=all", "--format=%i|%T|%N", f"--jobs={','.join(ids)}"]
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=60)
        except (OSError, subprocess.TimeoutExpired):
            return None
        if done.returncode != 0:
            if "Invalid job id" not in done.stderr:  # all the asked jobs have been purged
                return None
            done.stdout = ""
        info = self.read_info(_HEADER + "\n" + done.stdout)
        for job_id in pending:
            info.setdefault(job_id, {"JobID": job_id, "State": GONE, "NodeList": ""})
        return info


def use_queue_states() -> QueueWatcher:
    """Make submitit's SLURM jobs of this process use a :class:`QueueWatcher` (once)."""
    if not isinstance(SlurmJob.watcher, QueueWatcher):
        SlurmJob.watcher = QueueWatcher(delay_s=600)
    return SlurmJob.watcher


def ended_without_result(exc: BaseException) -> bool:
    """Whether ``exc`` (raised by the submitit launcher) says a job ended without a result
    (cancelled, timed out, node lost): its row says so, the others go on."""
    return isinstance(exc, UncompletedJobError)


def wait_for_jobs(poll_s: float = 1.0) -> list[str]:
    """Wait until every SLURM job this process submitted has ended; their ids."""
    watcher = use_queue_states()
    jobs = sorted(watcher._registered)
    while not all(watcher.is_done(job_id, mode="standard") for job_id in jobs):
        time.sleep(poll_s)
    return jobs
