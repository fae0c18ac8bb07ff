"""The one kernel switch (decrun/core/jit/): ``app.kernels`` and ``DECRUN_NUMBA`` reach every
compiled kernel, the fluid's numba kernels and the core's compiled extension.

``numpy`` never imports numba (so no kernel can run); ``numba`` runs every numba kernel on the path
of a fluid run through the CLI (each kernel's numba dispatcher holds a compiled or cache-loaded
signature); both runs give the same numbers. The core has no numba kernel.
"""

from __future__ import annotations

import ctypes.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from decrun.core import jit
from decrun.core.jit import kernels
from decrun.errors import ConfigError


def test_the_switch_app_kernels_over_decrun_numba(monkeypatch):
    monkeypatch.delenv("DECRUN_NUMBA", raising=False)
    assert jit.mode() == "auto" and jit.enabled()
    for value, expected in [("1", "numba"), ("numba", "numba"), ("0", "numpy"), ("numpy", "numpy"),
                            ("auto", "auto"), ("", "auto")]:
        monkeypatch.setenv("DECRUN_NUMBA", value)
        assert jit.mode() == expected
    monkeypatch.setenv("DECRUN_NUMBA", "numba")
    assert jit.enabled() and not jit.enabled("numpy")  # a caller's own setting wins
    with jit.use("numpy"):
        assert jit.mode() == "numpy" and not jit.enabled()
        with jit.use("auto"):  # auto defers to the enclosing setting
            assert jit.mode() == "numpy"
    with jit.use("auto"):  # ... and to DECRUN_NUMBA
        assert jit.mode() == "numba"
    assert jit.mode() == "numba"


def test_bad_switch_values_are_refused_with_the_fix(monkeypatch):
    monkeypatch.setenv("DECRUN_NUMBA", "yes")
    with pytest.raises(ConfigError, match="DECRUN_NUMBA=auto"):
        jit.mode()
    with pytest.raises(ConfigError, match="app.kernels=auto"):
        with jit.use("fortran"):
            pass


#: a small fluid run through the CLI in one process, then: numba imported?, the kernels that ran,
#: the kernels loaded, the final metrics
PROBE = """
import contextlib, io, json, sys
from decrun.__main__ import console_main
sys.argv = ["decrun", *sys.argv[1:]]
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
    try:
        console_main()
    except SystemExit:
        pass
from decrun.core import jit
import glob
metrics = json.load(open(glob.glob("outputs/runs/*/metrics.json")[0]))
print(json.dumps({"numba": "numba" in sys.modules, "used": sorted(k.name for k in jit.KERNELS if k.used()),
                  "all": sorted(k.name for k in jit.KERNELS), "metrics": metrics}))
"""

RUN = ("app=fluid", "mesh=channel", "mesh.target_faces=300", "app.inflow=[1.0,0.0]", "app.steps=3",
       "app.animation=false", "figures=false", "progress=false")

#: the default (swept) rule sums the circulation of its border cells only (circulation_rows); every
#: cell's (circulation_sums) is the trapezoid rules' (tests/methods/test_fluid_kernels.py)
OFF_PATH_KERNELS = {"decrun.methods.fluid.compiled.circulation_sums"}


def helper(name: str) -> bool:
    """The fluid's ``_helper`` kernels run inside the entry kernels' machine code (loaded from the
    cache with them), so they hold no signature of their own."""
    module, function = name.rsplit(".", 1)
    return module == "decrun.methods.fluid.compiled" and function.startswith("_")


def probe(tmp_path, *args, env=None):
    run = tmp_path / args[-1].replace("=", "_")
    run.mkdir()
    environment = {k: v for k, v in os.environ.items() if k != "DECRUN_NUMBA"} | (env or {})
    out = subprocess.run([sys.executable, "-c", PROBE, *RUN, *args], cwd=run, env=environment, capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_numpy_runs_no_kernel_numba_runs_all_and_they_agree(tmp_path):
    numpy = probe(tmp_path, "app.kernels=numpy")
    assert not numpy["numba"] and numpy["used"] == []  # numba never imported: no kernel ran
    numba = probe(tmp_path, "app.kernels=numba")
    on_path = [name for name in numba["all"] if not helper(name) and name not in OFF_PATH_KERNELS]
    assert numba["numba"] and [n for n in numba["used"] if not helper(n)] == on_path  # every kernel on the path ran
    assert any(name.startswith("decrun.methods.fluid.compiled.") for name in on_path)
    assert not any(name.startswith("decrun.core.") for name in numba["all"])  # the core's are the extension's
    env = probe(tmp_path, "app.kernels=auto", env={"DECRUN_NUMBA": "0"})  # the environment reaches the fluid too
    assert not env["numba"] and env["used"] == []
    for key in ("kinetic_energy_final", "enstrophy_final", "max_abs_divergence", "stable"):
        assert numba["metrics"][key] == numpy["metrics"][key] == env["metrics"][key], key


def test_a_bad_decrun_numba_stops_the_cli_with_the_fix(decrun_cli, monkeypatch):
    base = ("app=smoothing", "mesh.subdiv=1", "app.steps=1", "figures=false", "progress=false")
    monkeypatch.setenv("DECRUN_NUMBA", "yes")
    bad = decrun_cli(*base, "hydra.run.dir=bad")
    assert bad.returncode != 0 and "DECRUN_NUMBA='yes'" in bad.stderr and "use DECRUN_NUMBA=auto" in bad.stderr
    monkeypatch.setenv("DECRUN_NUMBA", "auto")  # the fix the message names
    good = decrun_cli(*base, "hydra.run.dir=good")
    assert good.returncode == 0, good.stderr


THREADS_PROBE = """
import json, os, sys
if sys.argv[1] != "all":
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
from decrun.core import jit
import numba
print(json.dumps({"threads": jit.threads(), "layer": numba.threading_layer(), "cores": os.cpu_count(),
                  "numba_default": numba.config.NUMBA_NUM_THREADS}))
"""


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="no CPU affinity on this platform")
@pytest.mark.parametrize("cores, environment", [("all", {}), ("one", {}), ("one", {"NUMBA_NUM_THREADS": "2"}),
                                                ("all", {"NUMBA_THREADING_LAYER_PRIORITY": "workqueue omp tbb"})])
def test_the_parallel_kernels_take_the_cores_the_process_may_use(cores, environment):
    """numba's default is every core of the machine; a SLURM job with cpus_per_task=1 (CPU affinity
    one core) must not start a thread per core of the node: jit.threads() is the affinity's count,
    unless NUMBA_NUM_THREADS says otherwise (joblib sets it for its workers). OpenMP runs them
    where numba finds libgomp, else numba's own pool (workqueue)."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_NUM_THREADS", "NUMBA_THREADING_LAYER", "NUMBA_THREADING_LAYER_PRIORITY")} | environment
    out = subprocess.run([sys.executable, "-c", THREADS_PROBE, cores], env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    if "NUMBA_THREADING_LAYER_PRIORITY" in environment:  # the user's order wins
        assert got["layer"] == "workqueue"
    else:
        assert got["layer"] == ("omp" if ctypes.util.find_library("gomp") else "workqueue")
    usable = len(os.sched_getaffinity(0))
    if "NUMBA_NUM_THREADS" in environment:
        assert got["threads"] == min(2, got["numba_default"])
    else:
        assert got["threads"] == (min(usable, got["numba_default"]) if cores == "all" else 1)


CONCURRENT_PROBE = """
import threading
import numpy as np
from decrun.complex import SimplicialComplex
from decrun.core.solvers.direct import DirectSolver
from decrun.dec import DEC
from decrun.methods.fluid.initial import random_vorticity
from decrun.methods.fluid.simulation import VorticityFluid
import sys
sys.path.insert(0, "tests")
from meshes_for_tests import icosphere
dec = DEC(SimplicialComplex(*icosphere(3)))
w0 = random_vorticity(dec, 2, amplitude=5)
sims = [VorticityFluid(dec, DirectSolver, dt=0.5, viscosity=1e-3, initial_vorticity=w0, kernels="numba") for _ in range(3)]
def run(sim):
    for _ in range(4):
        sim.step()
threads = [threading.Thread(target=run, args=(sim,)) for sim in sims[1:]]
for t in threads: t.start()
for t in threads: t.join()
run(sims[0])
print(all(np.array_equal(sims[0].vorticity, sim.vorticity) for sim in sims[1:]))
"""


@pytest.mark.parametrize("layer", [None, "workqueue"])
def test_parallel_kernels_called_from_two_threads_at_once_wait_for_each_other(layer):
    """numba's workqueue pool (where OpenMP is not found) aborts the process when two threads
    enter it at once (a sweep on a thread pool, e.g. joblib's threading backend, would): the
    parallel kernels take one lock, so two fluids stepped on two threads finish, each with the
    bits of a run on its own — on decrun's layer and on workqueue."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    if layer is not None:
        env["NUMBA_THREADING_LAYER"] = layer
    out = subprocess.run([sys.executable, "-c", CONCURRENT_PROBE], cwd=root, capture_output=True, text=True,
                         timeout=600, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "True"


FORK_PROBE = """
import multiprocessing, sys
import numpy as np
from decrun.complex import SimplicialComplex
from decrun.core.solvers.direct import DirectSolver
from decrun.dec import DEC
from decrun.methods.fluid.initial import random_vorticity
from decrun.methods.fluid.simulation import VorticityFluid
sys.path.insert(0, "tests")
from meshes_for_tests import icosphere
import numba
dec = DEC(SimplicialComplex(*icosphere(3)))
sim = VorticityFluid(dec, DirectSolver, dt=0.5, viscosity=1e-3, initial_vorticity=random_vorticity(dec, 2, amplitude=5),
                     kernels="numba")
sim.step()  # a parallel region ran in this process
state = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in sim.state_dict().items()}
def child(queue):
    sim.load_state(state)
    sim.step()
    queue.put(sim.vorticity)
fork = multiprocessing.get_context("fork")
queue = fork.Queue()
process = fork.Process(target=child, args=(queue,))
process.start()
forked = None
while forked is None and (process.is_alive() or not queue.empty()):
    try:
        forked = queue.get(timeout=0.5)
    except Exception:  # queue.Empty: still stepping, or killed (then is_alive ends the loop)
        pass
process.join()
if forked is None:
    sys.exit(f"the forked child died (exit code {process.exitcode})")
sim.load_state(state)
sim.step()
print(numba.threading_layer(), process.exitcode, np.array_equal(forked, sim.vorticity))
"""


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_a_child_forked_after_a_parallel_step_steps_on_with_the_same_bits():
    """GNU OpenMP is not fork-safe (numba terminates a forked child that enters it after the
    parent did): a child forked after a fluid step runs the kernels' serial versions, which give
    the parent's bits."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = subprocess.run([sys.executable, "-c", FORK_PROBE], cwd=root, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    layer, exitcode, same = out.stdout.strip().splitlines()[-1].split()
    assert exitcode == "0" and same == "True", out.stdout


SIGNAL_PROBE = """
import sys
import numpy as np
from decrun.complex import SimplicialComplex
from decrun.core.solvers.direct import DirectSolver
from decrun.dec import DEC
from decrun.methods.fluid.initial import random_vorticity
from decrun.methods.fluid.simulation import VorticityFluid
sys.path.insert(0, "tests")
from meshes_for_tests import icosphere
dec = DEC(SimplicialComplex(*icosphere(3)))
sim = VorticityFluid(dec, DirectSolver, dt=0.5, viscosity=1e-3, initial_vorticity=random_vorticity(dec, 2, amplitude=5),
                     kernels="numba")
sim.step()
calls = 0
def interrupt_in_the_kernel(frame, event, arg):  # a signal handler raising there, deterministically
    global calls
    kernel = getattr(frame.f_back.f_locals.get("self"), "name", "") if frame.f_back is not None else ""
    # backtrack_points returns a tuple: numba boxed its arrays ignoring the error (velocity_points did not)
    if event == "call" and frame.f_code.co_name == "_numba_unpickle" and kernel.endswith(".backtrack_points"):
        calls += 1
        sys.setprofile(None)
        raise KeyboardInterrupt("Ctrl-C inside a kernel")
sys.setprofile(interrupt_in_the_kernel)
try:
    sim.step()
except KeyboardInterrupt as exc:
    print("KeyboardInterrupt", calls, exc)
"""


def test_ctrl_c_during_a_kernel_call_raises_keyboardinterrupt_not_systemerror():
    """A kernel returning an array runs one Python function at its end (numba boxing the array),
    where Python runs pending signal handlers: their exception (Ctrl-C, SIGTERM, submitit's exit
    after a USR2 checkpoint) is raised as itself, not as numba's SystemError ("returned a result
    with an exception set"), which failed a preempted SLURM job instead of requeueing it. The
    handler is played by a profile hook raising in that function."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = subprocess.run([sys.executable, "-c", SIGNAL_PROBE], cwd=root, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "KeyboardInterrupt 1 Ctrl-C inside a kernel"


SPIN_PROBE = """
import os, sys
sys.argv = ["decrun", "--help"]
import decrun.__main__ as entry
try:
    entry.console_main()  # the decrun command: --help prints and returns
except SystemExit:
    pass
import pymeshlab  # loads its bundled libgomp, which reads the variable now
print(os.environ.get("GOMP_SPINCOUNT"))
"""

IMPORT_PROBE = """
import os
before = dict(os.environ)
import decrun
import decrun.core.threads
assert dict(os.environ) == before, set(os.environ.items()) ^ set(before.items())
print("unchanged")
"""


@pytest.mark.parametrize("environment, expected", [({}, "10000"), ({"GOMP_SPINCOUNT": "500"}, "500"),
                                                   ({"OMP_WAIT_POLICY": "passive"}, "None")])
def test_the_decrun_command_bounds_openmp_spinning_unless_the_environment_says(environment, expected):
    """GNU OpenMP's idle threads spin 300,000 rounds by default, which cost 33 % on the fluid tests
    with more processes than cores: the ``decrun`` command sets GOMP_SPINCOUNT=10000 before anything
    loads libgomp, unless GOMP_SPINCOUNT or OMP_WAIT_POLICY is set."""
    env = {k: v for k, v in os.environ.items() if k not in ("GOMP_SPINCOUNT", "OMP_WAIT_POLICY")} | environment
    out = subprocess.run([sys.executable, "-c", SPIN_PROBE], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == expected


BLAS_PROBE = """
import os, sys, time
sys.argv = ["decrun", "--help"]
import decrun.__main__ as entry
assert "numpy" not in sys.modules  # OpenBLAS reads the variable when numpy loads it
try:
    entry.console_main()  # the decrun command: --help prints and returns
except SystemExit:
    pass
import numpy, scipy.linalg  # noqa: E401,F401  numpy's and scipy's OpenBLAS start their workers here
time.sleep(0.3)
ticks = os.sysconf("SC_CLK_TCK")
cpu = 0.0
for task in os.listdir("/proc/self/task"):
    if task != str(os.getpid()):  # the workers: every thread but the main one
        fields = open(f"/proc/self/task/{task}/stat").read().rsplit(")", 1)[1].split()
        cpu += (int(fields[11]) + int(fields[12])) / ticks
print(os.environ.get("OPENBLAS_THREAD_TIMEOUT"), len(os.listdir("/proc/self/task")) - 1, cpu)
"""


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads the threads' CPU time from /proc")
def test_the_decrun_command_bounds_openblas_spinning_unless_the_environment_says():
    """OpenBLAS's workers, started when numpy and scipy load, spin before they sleep (its default
    OPENBLAS_THREAD_TIMEOUT=28: 0.07-0.09 s of CPU between the two here); the ``decrun`` command
    sets 20 before numpy loads, and the workers (the same number) then use less than a clock tick between them; a value
    in the environment is kept, and with OpenBLAS's default the workers spin."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
    results = {}
    for name, extra in (("bounded", {}), ("default", {"OPENBLAS_THREAD_TIMEOUT": "28"})):
        out = subprocess.run([sys.executable, "-c", BLAS_PROBE], env=env | extra, capture_output=True, text=True,
                             timeout=300)
        assert out.returncode == 0, out.stderr[-2000:]
        value, workers, cpu = out.stdout.split()[-3:]
        results[name] = (value, int(workers), float(cpu))
    (value, workers, cpu), (kept, default_workers, spun) = results["bounded"], results["default"]
    if default_workers == 0:
        pytest.skip("OpenBLAS starts no worker threads on a single core")
    assert (value, kept) == ("20", "28") and workers == default_workers
    assert cpu <= 0.01 and spun >= 0.02, results  # one clock tick; two at least even on a loaded machine


def test_import_decrun_changes_nothing_in_the_environment():
    """A library import leaves the process environment as it found it (the spin bound is the
    command's)."""
    env = {k: v for k, v in os.environ.items() if k not in ("GOMP_SPINCOUNT", "OMP_WAIT_POLICY")}
    out = subprocess.run([sys.executable, "-c", IMPORT_PROBE], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "unchanged"



KERNEL_MODULE = """
from decrun.core.jit import njit


@njit
def plus_one(x):
    return x + 1
"""


def _load(path, name):
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_kernel_that_must_be_compiled_is_announced_once_and_a_cached_one_is_not(tmp_path, monkeypatch):
    """The first call of a kernel without machine code in numba's disk cache calls
    ``jit.compile_notice`` with its name (once per process); the same kernel loaded again, now
    cached beside its module, is not announced; without a notice nothing is said."""
    path = tmp_path / "fresh_kernels.py"
    path.write_text(KERNEL_MODULE)
    said = []
    monkeypatch.setattr(jit, "compile_notice", said.append)
    monkeypatch.setattr(kernels, "_noticed", False)
    assert _load(path, "fresh_kernels").plus_one(1) == 2
    assert said == ["fresh_kernels.plus_one"] and list((tmp_path / "__pycache__").glob("*.nbi"))
    assert _load(path, "fresh_kernels").plus_one(2) == 3 and said == ["fresh_kernels.plus_one"]  # once
    monkeypatch.setattr(kernels, "_noticed", False)
    assert _load(path, "fresh_kernels").plus_one(3) == 4 and said == ["fresh_kernels.plus_one"]  # cached
    path.write_text(KERNEL_MODULE.replace("x + 1", "x + 10"))  # a changed source compiles again
    assert _load(path, "fresh_kernels").plus_one(3) == 13 and said == ["fresh_kernels.plus_one"] * 2


HELPER_MODULE = """
from decrun.core.jit import njit


@njit
def minus_one(x):
    return x - 1


@njit
def plus_two(x):
    return x + 2
"""


def test_a_kernel_the_run_does_not_call_is_not_announced(tmp_path, monkeypatch):
    """Calling one kernel makes numba dispatchers for its module's other kernels too (so that
    kernels can call each other); one never called has no machine code in the disk cache, and
    nothing compiles it. Only a kernel called from Python is announced: on the first run, not
    on every later one, whose kernels load from the cache (a notice there would promise a wait
    of 10-150 s that never comes)."""
    path = tmp_path / "two_kernels.py"
    path.write_text(HELPER_MODULE)
    said = []
    monkeypatch.setattr(jit, "compile_notice", said.append)
    monkeypatch.setattr(kernels, "_noticed", False)
    assert _load(path, "two_kernels").plus_two(1) == 3
    assert said == ["two_kernels.plus_two"]
    monkeypatch.setattr(kernels, "_noticed", False)
    assert _load(path, "two_kernels").plus_two(2) == 4
    assert said == ["two_kernels.plus_two"]  # loaded from the cache; minus_one never ran: nothing said


def test_a_run_says_in_its_log_that_it_compiles_once(caplog):
    """The runner's notice (around every run's work): one log line saying that the kernels
    compile, that it happens once, and how long it takes; restored after the run."""
    from decrun.runner.job.run import compile_notice

    before = jit.compile_notice
    with caplog.at_level("INFO"), compile_notice():
        jit.compile_notice("decrun.methods.fluid.compiled.backtrack_points")
    assert jit.compile_notice is before
    (line,) = [r.getMessage() for r in caplog.records if "compiling" in r.getMessage()]
    assert "backtrack_points" in line and "once per install" in line and "10-150 s" in line
