"""What the ``decrun`` sweeper knows of Hydra's launcher plugins, each known by its plugin
class (:func:`is_launcher`): launchers that cannot start, and a joblib job over its time
limit — one line naming the launcher, the cause and the command that fixes it, within a
bounded time. SLURM jobs that end without a result: :mod:`.slurm`.

* :func:`preflight`, before the sweep is planned (nothing is written when it refuses):
  ``hydra/launcher=submitit_slurm`` (or a config built on it) on a machine without ``srun``
  / ``sbatch`` — submitit would raise ``Could not detect "srun"`` — and a Ray launcher with
  ``hydra.launcher.ray.init.address`` set, whose cluster must answer within
  ``hydra.sweeper.connect_timeout`` seconds (20 by default): a TCP connection to the
  address first (a refused or unroutable address fails at once), then ``ray.init`` itself
  in a thread (Ray retries an address that answers but is no cluster for minutes). Its
  retry warnings are kept off the terminal while it tries; the last one is the cause.
* :func:`launch_failure`, after the manifest is written (a cluster lost between two
  batches, a submission refused by the controller): the message for an exception of the
  launcher's ``launch`` that says it could not start its jobs, or None. The sweeper then
  ends with that line and the command that resumes the sweep with the fix.
* :func:`timed_out`: joblib's ``TimeoutError`` for a job over ``hydra.launcher.timeout``
  (joblib then stops every worker of the batch: their jobs are ``killed``).

The fixes are commands, not advice: :func:`command_with` writes the command as typed with
the launcher (and its options the new one lacks) replaced."""

from __future__ import annotations

import contextlib
import os
import shlex
import shutil
import socket
import sys
import tempfile
import threading
import time
from typing import Any, Callable, Iterator, Optional, Sequence, cast

__all__ = ["CONNECT_TIMEOUT", "is_launcher", "SLURM", "RAY", "JOBLIB", "Fix", "preflight", "launch_failure", "timed_out", "launcher_choice", "command_with",
           "ray_address", "NO_TIME_LIMIT", "connect_ray_as_is"]

#: seconds to give up on a cluster that does not answer (``hydra.sweeper.connect_timeout``)
CONNECT_TIMEOUT = 20.0
#: the SLURM commands submitit needs on the submitting machine
SLURM_COMMANDS = ("srun", "sbatch")


def launcher_choice(config: Any) -> str:
    """``hydra/launcher=<choice>`` as the user chose it (``submitit_slurm``, ``slurm_example``)."""
    try:
        choice = config.hydra.runtime.choices.get("hydra/launcher")
    except Exception:  # noqa: BLE001 — a config without Hydra's runtime node (a test's)
        choice = None
    return f"hydra/launcher={choice or 'basic'}"


def command_with(argv: Sequence[str] | None = None, set_: Sequence[str] = (), drop: Callable[[str], bool] | None = None,
                 ) -> str:
    """The ``decrun`` command as typed (``argv``, default ``sys.argv[1:]``) with each override
    of ``set_`` (``key=value``) in place of any override of that key, and without the
    overrides whose key ``drop`` is true for."""
    argv = list(sys.argv[1:] if argv is None else argv)
    keys = {line.split("=", 1)[0] for line in set_}

    def key(arg: str) -> str:
        return arg.split("=", 1)[0].lstrip("+~") if "=" in arg else ""

    kept = [a for a in argv if key(a) not in keys and not (drop is not None and key(a) and drop(key(a)))]
    return shlex.join(["decrun", *kept, *set_])


#: Hydra's launcher plugins decrun knows, by their plugin classes (module, class name)
SLURM = ("hydra_plugins.hydra_submitit_launcher.submitit_launcher", "SlurmLauncher")
RAY = ("hydra_plugins.hydra_ray_launcher.ray_launcher", "RayLauncher")
JOBLIB = ("hydra_plugins.hydra_joblib_launcher.joblib_launcher", "JoblibLauncher")


def is_launcher(launcher: Any, module: str, name: str) -> bool:
    """Whether ``launcher`` is an instance of the plugin class ``module.name`` (or of a
    subclass). The plugin's module is not imported for it: an instance of its class means
    it is imported already, and a plugin that is not installed is no instance."""
    cls = getattr(sys.modules.get(module), name, None)
    return isinstance(cls, type) and isinstance(launcher, cls)


# ----------------------------------------------------------------------------------
# SLURM
# ----------------------------------------------------------------------------------

def _local_keys() -> set[str]:
    """The option names of ``hydra/launcher=submitit_local`` (the SLURM ones it lacks are dropped)."""
    import dataclasses

    from hydra_plugins.hydra_submitit_launcher.config import LocalQueueConf

    return {f.name for f in dataclasses.fields(LocalQueueConf)}


def _slurm_only(key: str) -> bool:
    """A launcher option ``hydra/launcher=submitit_local`` lacks (``hydra.launcher.partition``…)."""
    return key.startswith("hydra.launcher.") and key.split(".")[2] not in _local_keys()


# ----------------------------------------------------------------------------------
# Ray
# ----------------------------------------------------------------------------------

def ray_address(launcher: Any) -> Optional[str]:
    """``hydra.launcher.ray.init.address`` of a Ray launcher, None when unset (a local Ray)."""
    init = getattr(getattr(launcher, "ray_cfg", None), "init", None)
    address = init.get("address") if init is not None else None
    return str(address) if address not in (None, "", "local") else None


def _host_port(address: str) -> Optional[tuple[str, int]]:
    """``(host, port)`` of ``host:port`` or ``ray://host:port``; None for ``auto`` and the like."""
    bare = address.split("://", 1)[-1].rstrip("/")
    host, sep, port = bare.rpartition(":")
    if not sep or not host or not port.isdigit():
        return None
    return host.strip("[]"), int(port)


@contextlib.contextmanager
def _stderr_to(path: str) -> Iterator[None]:
    """File descriptor 2 (Ray's C++ warnings write there, not through ``sys.stderr``) into ``path``."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(path, "wb") as sink:
            os.dup2(sink.fileno(), 2)
        yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)


def _keep_off_terminal() -> None:
    """From now on, file descriptor 2 (Ray's C++ warnings) goes to /dev/null; ``sys.stderr``
    (this process's messages) to the terminal as before, through a copy of the descriptor."""
    sys.stderr.flush()
    terminal = os.dup(2)
    sink = os.open(os.devnull, os.O_WRONLY)
    os.dup2(sink, 2)
    os.close(sink)
    sys.stderr = os.fdopen(terminal, "w", buffering=1, errors="backslashreplace")


def _last_warning(path: str) -> str:
    """The last line Ray wrote while it tried, without its timestamp prefix."""
    try:
        with open(path, errors="replace") as text:
            lines = [line.strip() for line in text if line.strip()]
    except OSError:
        return ""
    if not lines:
        return ""
    line = lines[-1]
    return line.split("] ", 1)[1] if line.startswith("[") and "] " in line else line


def _ray_unreachable(config, launcher, address: str, cause: str) -> str:
    return (f"error: {launcher_choice(config)}: cannot reach the Ray cluster at "
            f"hydra.launcher.ray.init.address={address} ({cause}); nothing ran; start it (`ray start --head` "
            f"there) or run the sweep on a local Ray with: "
            f"{TO_LOCAL_RAY.command()}")


def connect_ray_as_is(launcher: Any) -> None:
    """With ``hydra.launcher.ray.init.address`` set (an existing Ray cluster), leave the
    cluster's object store as it is: hydra-ray-launcher otherwise passes its default
    ``object_store_memory`` (75 MiB) to ``ray.init``, which refuses it for an existing
    cluster (``ValueError: When connecting to an existing cluster, object_store_memory must
    not be provided``). An ``object_store_memory`` given on the command line is kept."""
    from omegaconf import OmegaConf, open_dict

    init = getattr(getattr(launcher, "ray_cfg", None), "init", None)
    if init is None or not init.get("address") or "object_store_memory" in init:
        return
    with open_dict(init) if OmegaConf.is_config(init) else contextlib.nullcontext():
        init["object_store_memory"] = None


def connect_ray(launcher: Any, config: Any, timeout: float) -> Optional[str]:
    """Connect this process to the Ray cluster of ``launcher`` (``ray.init`` with its init
    options: the launcher then finds Ray initialized), giving up after ``timeout`` seconds;
    the one-line error, or None when connected."""
    address = ray_address(launcher)
    if address is None:
        return None
    deadline = time.monotonic() + timeout
    target = _host_port(address)
    if target is not None:
        try:
            socket.create_connection(target, timeout=timeout).close()
        except OSError as exc:
            why = f"no answer within {timeout:g} s" if isinstance(exc, socket.timeout) else \
                (exc.strerror or str(exc) or type(exc).__name__).lower()
            if isinstance(exc, socket.timeout):
                why += f", hydra.sweeper.connect_timeout={timeout:g}"
            return _ray_unreachable(config, launcher, address, why)
    import ray
    from omegaconf import OmegaConf

    if ray.is_initialized():
        return None
    init = launcher.ray_cfg.init
    options = cast(dict, OmegaConf.to_container(init, resolve=True)) if OmegaConf.is_config(init) else dict(init)
    failure: list[BaseException] = []

    def init_ray() -> None:
        try:
            ray.init(**options)
        except BaseException as exc:  # noqa: BLE001 — reported by the thread that waits
            failure.append(exc)

    fd, log = tempfile.mkstemp(prefix="decrun-ray-", suffix=".log")
    os.close(fd)
    try:
        with _stderr_to(log):
            thread = threading.Thread(target=init_ray, name="decrun-ray-connect", daemon=True)
            thread.start()
            thread.join(max(deadline - time.monotonic(), 0.1))
        if thread.is_alive():  # Ray goes on trying until the process ends: its warnings go nowhere
            _keep_off_terminal()
            last = _last_warning(log)[:200]
            return _ray_unreachable(config, launcher, address,
                                    f"no Ray cluster answered within {timeout:g} s, hydra.sweeper.connect_timeout="
                                    f"{timeout:g}{'; Ray: ' + last if last else ''}")
        if failure:
            error = failure[0]
            cause = str(error).splitlines()[0] if str(error) else type(error).__name__
            return _ray_unreachable(config, launcher, address, f"{type(error).__name__}: {cause}")
        return None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(log)


# ----------------------------------------------------------------------------------
# the sweeper's entry points
# ----------------------------------------------------------------------------------

def preflight(launcher: Any, config: Any, timeout: float = CONNECT_TIMEOUT) -> Optional[str]:
    """The one-line error when ``launcher`` cannot start here (module docstring), before
    the sweep is planned; None when it can."""
    if is_launcher(launcher, *SLURM):
        missing = next((name for name in SLURM_COMMANDS if shutil.which(name) is None), None)
        if missing is not None:
            return (f"error: {launcher_choice(config)}: `{missing}` is not on PATH: this machine cannot submit SLURM "
                    f"jobs (not a SLURM login node); nothing ran; run the sweep on this machine with: "
                    f"{TO_SUBMITIT_LOCAL.command()}")
    if is_launcher(launcher, *RAY):
        return connect_ray(launcher, config, timeout)
    return None


class Fix:
    """What replaces the command's launcher options to fix a launcher that cannot start:
    the overrides ``set_`` and the keys ``drop`` is true for (see :func:`command_with`)."""

    def __init__(self, set_: Sequence[str], drop: Optional[Callable[[str], bool]] = None) -> None:
        self.set_, self.drop = list(set_), drop

    def command(self, extra: Sequence[str] = (), argv: Sequence[str] | None = None) -> str:
        return command_with(argv, [*self.set_, *extra], drop=self.drop)


def _chain(exc: BaseException | None) -> Iterator[BaseException]:
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        yield exc
        exc = exc.__cause__ or exc.__context__


def _submission_failed(exc: BaseException) -> bool:
    """Whether submitit could not submit (no ``srun``/``sbatch``, ``sbatch`` refused: its
    ``FailedJobError`` comes from the ``CalledProcessError`` of the submission command)."""
    import subprocess

    for link in _chain(exc):
        if type(link).__name__ == "FailedSubmissionError" or '"srun"' in str(link):
            return True
        if isinstance(link, FileNotFoundError) and os.path.basename(str(link.filename or "")) in SLURM_COMMANDS:
            return True
        if isinstance(link, subprocess.CalledProcessError):
            command = link.cmd if isinstance(link.cmd, (list, tuple)) else str(link.cmd).split()
            return bool(command) and os.path.basename(str(command[0])) in SLURM_COMMANDS
    return False


def launch_failure(launcher: Any, config: Any, exc: BaseException) -> Optional[tuple[str, Fix]]:
    """``("<launcher>: cannot … (<cause>)", fix)`` for an exception of a cluster launcher's
    ``launch`` that says its jobs could not be submitted (no SLURM commands, a refused
    submission, a Ray cluster not reached); None for any other exception (a job's own
    error, a bug)."""
    text = (str(exc).splitlines() or [type(exc).__name__])[0]
    if is_launcher(launcher, *SLURM) and _submission_failed(exc):
        last = str(exc).strip().splitlines()[-1:]  # the last line of what failed (sbatch's error)
        return f"{launcher_choice(config)}: cannot submit its jobs ({last[0] if last else text})", TO_SUBMITIT_LOCAL
    if is_launcher(launcher, *RAY) and isinstance(exc, ConnectionError):
        return (f"{launcher_choice(config)}: cannot reach the Ray cluster at hydra.launcher.ray.init.address="
                f"{ray_address(launcher)} ({text})", TO_LOCAL_RAY)
    return None


#: the fixes
TO_SUBMITIT_LOCAL = Fix(["hydra/launcher=submitit_local"], _slurm_only)
TO_LOCAL_RAY = Fix(["hydra.launcher.ray.init.address=local"])  # "local": a new Ray here, never a running one
NO_TIME_LIMIT = Fix(["hydra.launcher.timeout=null"])


def timed_out(launcher: Any, exc: BaseException) -> bool:
    """joblib's ``TimeoutError`` (``multiprocessing.TimeoutError`` from loky) for a job that
    ran longer than ``hydra.launcher.timeout``."""
    return is_launcher(launcher, *JOBLIB) and any(c.__name__ == "TimeoutError" for c in type(exc).__mro__)


def joblib_timeout(launcher: Any) -> Any:
    """``hydra.launcher.timeout`` of a joblib launcher."""
    return (getattr(launcher, "joblib", None) or {}).get("timeout")
