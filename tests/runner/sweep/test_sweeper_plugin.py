"""The ``decrun`` sweeper as a Hydra plugin: it survives any number of Hydra plugin scans.

Hydra's scan re-executes every plugin module. When the sweeper subclassed Hydra's
``BasicSweeper`` (re-executed too), a class bound once to it failed after a re-scan with
``TypeError: super(type, obj)``; it is now on Hydra's public ``Sweeper`` (never re-executed),
and these tests keep it so. A re-scan happens after any reset of Hydra's singletons, when
the plugin module is imported before Hydra's first scan, and inside a sweep whose joblib
launcher runs its jobs in-process (``n_jobs=1``: each job restores Hydra's state and scans
again), before the next sweep of that process."""

from __future__ import annotations

import importlib
import importlib.util

import pytest
from hydra.core.plugins import Plugins
from hydra.core.singleton import Singleton

SWEEPER = "hydra_plugins.decrun_sweeper.DecrunSweeper"


@pytest.fixture(autouse=True)
def _locks_released():
    """Hydra's test runner runs the sweeper in this process and the process goes on: the sweep
    directories' locks, which the ``decrun`` command's exit releases, are released here, so a
    later test in the same worker (tests/runner/test_api.py checks it) finds none held."""
    from decrun.runner.io.locks import released_after

    with released_after():
        yield


def _rescan() -> Plugins:
    Singleton._instances.pop(Plugins, None)
    return Plugins.instance()


def test_the_sweeper_builds_after_any_number_of_scans(hydra_restore_singletons):
    importlib.import_module("hydra_plugins.decrun_sweeper")  # imported before the scan below
    for _ in range(3):
        cls = _rescan().class_name_to_class[SWEEPER]
        sweeper = cls(max_batch_size=2, resume=True)
        assert (sweeper.max_batch_size, sweeper.resume) == (2, True)


def _two_job_sweep(hydra_sweep_runner, tmp_path, name, launcher):
    return hydra_sweep_runner(calling_file=None, calling_module="hydra.test_utils.a_module", task_function=None,
                              config_path="configs", config_name="compose.yaml", temp_dir=tmp_path / name,
                              overrides=["hydra/sweeper=decrun", *launcher, "+a=0,1"])


@pytest.mark.skipif(importlib.util.find_spec("hydra_plugins.hydra_joblib_launcher") is None,
                    reason="hydra-joblib-launcher is not installed (pip install 'decrun[parallel]')")
def test_a_second_sweep_after_an_in_process_joblib_sweep(hydra_sweep_runner, hydra_restore_singletons, tmp_path):
    with _two_job_sweep(hydra_sweep_runner, tmp_path, "first", ["hydra/launcher=joblib", "hydra.launcher.n_jobs=1"]) as s:
        assert [r.overrides for r in s.returns[0]] == [["+a=0"], ["+a=1"]]
    with _two_job_sweep(hydra_sweep_runner, tmp_path, "second", ["hydra/launcher=basic"]) as s:
        assert [r.cfg.a for r in s.returns[0]] == [0, 1]


def _pid_task(cfg) -> int:
    import os

    return os.getpid()


@pytest.mark.skipif(importlib.util.find_spec("hydra_plugins.hydra_joblib_launcher") is None,
                    reason="hydra-joblib-launcher is not installed (pip install 'decrun[parallel]')")
def test_joblib_workers_start_while_the_sweep_is_planned_and_run_its_jobs(hydra_sweep_runner, hydra_restore_singletons,
                                                                           tmp_path, monkeypatch):
    """A task that registers its modules gets joblib's workers started (importing them)
    during planning; the launcher's jobs then run in those same processes."""
    from joblib.externals.loky import reusable_executor

    from decrun.runner.sweep import checks
    from decrun.runner.sweep.sweeper import ManifestSweeper

    if reusable_executor._executor is not None:  # workers of an earlier test: gone
        reusable_executor._executor.shutdown(wait=True)
    warmed = []
    hand_over = ManifestSweeper._hand_over

    def record(self, jobs):
        warmed.extend(reusable_executor._executor._processes)  # the workers, before the launcher runs
        return hand_over(self, jobs)

    monkeypatch.setattr(ManifestSweeper, "_hand_over", record)
    runner = hydra_sweep_runner(calling_file=None, calling_module="hydra.test_utils.a_module", task_function=_pid_task,
                                config_path="configs", config_name="compose.yaml", temp_dir=tmp_path / "s",
                                overrides=["hydra/sweeper=decrun", "hydra/launcher=joblib", "hydra.launcher.n_jobs=2",
                                           "+a=0,1,2,3"])
    monkeypatch.setitem(checks.WARM, runner, ("json",))  # the runner is the task function Hydra gets
    with runner as sweep:
        pids = {r.return_value for r in sweep.returns[0]}
    assert len(warmed) == 2 and pids <= set(warmed), (warmed, pids)
