"""Hydra's own plugin test suites (``hydra.test_utils.launcher_common_tests``) against the
``decrun`` sweeper: ``LauncherTestSuite`` and ``IntegrationTestSuite`` over the basic,
joblib, submitit_local and ray launchers with ``hydra/sweeper=decrun``, parametrized as the
launchers' own test modules parametrize them, and ``BatchedSweeperTestSuite`` (the
sweeper's ``max_batch_size``) on the basic and joblib launchers. The default run has every
suite on basic and the launcher suites on joblib and submitit_local; ``-m slow`` adds the
integration suite on those two and everything on ray. The suites' fixtures reset
Hydra's singletons before each test, so every test also re-scans the plugins (the sweeper
must survive any number of scans). Launchers whose extra is not installed are skipped."""

from __future__ import annotations

import importlib.util

import pytest
from hydra.core.plugins import Plugins
from hydra.test_utils.launcher_common_tests import BatchedSweeperTestSuite, IntegrationTestSuite, LauncherTestSuite

SWEEPER = "hydra/sweeper=decrun"


@pytest.fixture(autouse=True)
def fresh_hydra(hydra_restore_singletons):
    """Hydra's state as in a new process, as the suites expect: an earlier test of this
    session that composed decrun's config (``version_base="1.3"``) would otherwise change
    Hydra's defaults, e.g. ``hydra.job.chdir``. Restored after the test."""
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.singleton import Singleton
    from hydra.version import VersionBase

    Singleton._instances.pop(VersionBase, None)
    GlobalHydra.instance().clear()


def _installed(plugin: str, extra: str):
    return pytest.mark.skipif(importlib.util.find_spec(f"hydra_plugins.{plugin}") is None,
                              reason=f"{plugin} is not installed (pip install 'decrun[{extra}]')")


#: launcher → (its Hydra name, the overrides its own test module passes, marks)
RAY_INIT = "+hydra.launcher.ray.init.object_store_memory=78643200"
LAUNCHERS = {
    "basic": ("basic", [], []),
    "joblib": ("joblib", [], [_installed("hydra_joblib_launcher", "parallel")]),
    "submitit_local": ("submitit_local", ["hydra.launcher.timeout_min=2"],
                       [_installed("hydra_submitit_launcher", "slurm")]),
    "ray": ("ray", [RAY_INIT, "+hydra.launcher.ray.init.num_cpus=2"],
            [_installed("hydra_ray_launcher", "ray"), pytest.mark.slow, pytest.mark.ray]),
}
#: the extra flags of each launcher's IntegrationTestSuite in its own test module
INTEGRATION_FLAGS = {
    "basic": ["hydra/launcher=basic", "hydra/hydra_logging=disabled", "hydra/job_logging=disabled"],
    "joblib": ["hydra/job_logging=hydra_debug", "hydra/job_logging=disabled", "hydra/launcher=joblib"],
    "submitit_local": ["hydra/hydra_logging=disabled", "hydra/job_logging=disabled", "hydra/launcher=submitit_local",
                       "hydra.launcher.gpus_per_node=0", "hydra.launcher.timeout_min=1"],
    "ray": ["hydra/launcher=ray", "hydra/hydra_logging=hydra_debug", "hydra/job_logging=disabled", RAY_INIT,
            "+hydra.launcher.ray.init.num_cpus=2"],
}


# Hydra's first plugin scan now, as each launcher's own test module triggers it by importing the
# launcher: some launchers register their config (hydra/launcher=ray) only when the scan first
# imports their private modules, and the suites' fixture restores Hydra's state to the one
# before each test, so a registration made inside a test would not outlive it
Plugins.instance()


def _launcher_params():
    return [pytest.param(name, [SWEEPER, *overrides], id=key, marks=marks)
            for key, (name, overrides, marks) in LAUNCHERS.items()]


@pytest.mark.parametrize("launcher_name, overrides", _launcher_params())
class TestDecrunSweeperWithLaunchers(LauncherTestSuite):
    """Hydra's launcher suite, each launcher driven by the decrun sweeper."""


@pytest.mark.parametrize("launcher_name, overrides",
                         [pytest.param(name, [SWEEPER, "hydra.sweeper.max_batch_size=2", *overrides], id=key,
                                       marks=marks)
                          for key, (name, overrides, marks) in LAUNCHERS.items() if key in ("basic", "joblib")])
class TestDecrunSweeperBatches(BatchedSweeperTestSuite):
    """Hydra's batched-sweeper suite: 6 jobs in 3 launcher calls of 2."""


#: the integration suite starts a task process per test (~3 s with the basic launcher); with
#: joblib and submitit it also starts the launcher's worker processes (~8 s a test, ~2 min a
#: launcher): those run with -m slow, as everything on ray (a local cluster: ~30 s to start)
SLOW_INTEGRATION = ("joblib", "submitit_local", "ray")


@pytest.mark.parametrize("task_launcher_cfg, extra_flags",
                         [pytest.param({}, ["-m", SWEEPER, *INTEGRATION_FLAGS[key]], id=key,
                                       marks=[*LAUNCHERS[key][2], *([pytest.mark.slow] if key in SLOW_INTEGRATION
                                                                    else [])])
                          for key in LAUNCHERS])
class TestDecrunSweeperIntegration(IntegrationTestSuite):
    """Hydra's integration suite (a task script run as a process), with the decrun sweeper."""

    @pytest.mark.skip(reason="starts a second sweep in the first one's hydra.sweep.dir, which the decrun sweeper "
                             "refuses by design (the jobs would mix in one manifest); the resumed variant below runs it")
    def test_to_absolute_path_multirun(self, tmpdir, task_launcher_cfg, extra_flags) -> None:
        pass

    def test_to_absolute_path_multirun_resumed(self, tmpdir, task_launcher_cfg, extra_flags) -> None:
        """Hydra's test, its second sweep resuming the first (``hydra.sweeper.resume=true``:
        a Hydra app writes no metrics.json, so its job is rerun in the same directory)."""
        super().test_to_absolute_path_multirun(tmpdir, task_launcher_cfg, [*extra_flags, "hydra.sweeper.resume=true"])
