"""``decrun.run`` and ``decrun.sweep`` (decrun.runner.api): the command called from Python goes
through the command's own composition, manifest, locks, resume and table; it can be called again
and again in one process, which it leaves as it found it; its errors are the command's lines.
Also the Python block of docs/running.md and ``examples/first_sweep.ipynb`` (executed on a real kernel)."""

from __future__ import annotations

import io
import json
import logging
import os
import re
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pandas as pd
import pytest

import decrun
from decrun.runner.io.locks import _held

ROOT = Path(__file__).resolve().parents[2]
HEAT = ["app=heat", "mesh.subdiv=1", "figures=false"]
SWEEP = ["app=heat", "app.constants.k=0.5,1", "mesh.subdiv=1", "figures=false"]


def _env(**extra) -> dict:
    """This checkout first on the path (a worktree's decrun, not the installed one)."""
    path = os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])
    return dict(os.environ, PYTHONPATH=path, MPLBACKEND="Agg", **extra)


def _command(*args, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "decrun", *args], cwd=cwd, env=_env(), capture_output=True,
                          text=True, timeout=240)


def _table_csv(sweep_dir: Path, cwd: Path) -> pd.DataFrame:
    """What ``decrun-table --csv`` prints for ``sweep_dir``, read by pandas."""
    out = subprocess.run([sys.executable, "-c", "import sys; from decrun.runner.command.table import table_main; "
                          "sys.exit(table_main(sys.argv[1:]))", "--csv", str(sweep_dir)], cwd=cwd, env=_env(),
                         capture_output=True, text=True, timeout=240)
    assert out.returncode == 0, out.stderr
    return pd.read_csv(io.StringIO(out.stdout))


@pytest.fixture
def here(tmp_path, monkeypatch):
    """The working directory is ``tmp_path``."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


@contextmanager
def leaves_the_process_alone():
    """The process state the calls must restore (what the command sets up for Hydra), and no
    directory left locked."""
    root = logging.getLogger()

    def state():
        return dict(os.environ), list(sys.argv), list(root.handlers), root.level, logging.raiseExceptions

    before, held = state(), set(_held)
    yield
    assert state() == before
    assert set(_held) <= held, "the call left a directory locked"  # (in-process Hydra suites may hold earlier ones)


def test_runs_and_sweeps_again_and_again_in_one_process_as_the_command(here):
    with leaves_the_process_alone():
        first = decrun.run(HEAT)
        second = decrun.run(HEAT + ["app.constants.k=0.5"], root="elsewhere")
    assert first.dir.parent == here / "outputs" / "runs" and first.dir.is_absolute()
    assert second.dir.parent == here / "elsewhere" / "runs"
    for run in (first, second):
        assert run.status == "ok" and (run.dir / ".hydra" / "config.yaml").is_file()
        assert run.metrics == json.loads((run.dir / "metrics.json").read_text())
        assert set(run.result().fields) == {"u"} and run.result().complete
    assert second.metrics["dirichlet_energy"] > first.metrics["dirichlet_energy"]  # slower diffusion: rougher

    with leaves_the_process_alone():
        named = decrun.sweep(SWEEP, dir="sweeps/k")
        stamped = decrun.sweep(SWEEP, root="elsewhere")
    assert named.attrs["sweep_dir"] == str(here / "sweeps" / "k")
    assert Path(stamped.attrs["sweep_dir"]).parent == here / "elsewhere" / "sweeps"
    for table in (named, stamped):
        sweep_dir = Path(table.attrs["sweep_dir"])
        assert (sweep_dir / "manifest.json").is_file()
        assert list(table["status"]) == ["ok", "ok"] and list(table["app.constants.k"]) == [0.5, 1.0]
        pd.testing.assert_frame_equal(table, _table_csv(sweep_dir, here))  # decrun-table's table
    # the same jobs as the command's, bit for bit (content hashes), in a directory the command chose
    command = _command("-m", *SWEEP, "hydra.sweep.dir=by_command", cwd=here)
    assert command.returncode == 0, command.stderr
    assert list(_table_csv(here / "by_command", here)["content_sha256"]) == list(named["content_sha256"])


def test_resume_reruns_only_the_jobs_that_are_not_ok_and_a_used_directory_is_refused(here):
    table = decrun.sweep(SWEEP, dir="sw")
    kept = here / "sw" / "0" / "result.h5"
    stamp = kept.stat().st_mtime_ns
    (here / "sw" / "1" / "metrics.json").unlink()  # job 1 never finished
    assert list(decrun.sweep(SWEEP, dir="sw", resume=True)["status"]) == ["ok", "ok"]
    assert kept.stat().st_mtime_ns == stamp  # job 0 was not rerun
    with leaves_the_process_alone(), \
            pytest.raises(decrun.RunError, match=r"hydra.sweep.dir=sw is not empty .*hydra.sweeper.resume=true") as info:
        decrun.sweep(SWEEP, dir="sw")
    assert info.value.code == 1 and info.value.dir == here / "sw"
    with pytest.raises(decrun.RunError, match=r"resume with the same overrides|planned 2 jobs"):
        decrun.sweep(SWEEP[:1] + ["app.constants.k=0.5,1,2"] + SWEEP[2:], dir="sw", resume=True)
    assert pd.read_csv(here / "sw" / "metrics.csv")["status"].tolist() == table["status"].tolist()


def test_errors_are_the_commands_lines(here):
    with leaves_the_process_alone(), pytest.raises(decrun.RunError) as info:
        decrun.run(["app.stpes=3"])
    command = _command("app.stpes=3", cwd=here)
    assert command.returncode == 1 and str(info.value) == command.stderr.strip()
    assert info.value.dir is None and not (here / "outputs").exists()

    with pytest.raises(decrun.RunError, match=r"^error: job 1 \(app=heat app.dt=fast"):  # the plan refuses it
        decrun.sweep(["app=heat", "app.dt=0.001,fast"], dir="bad")
    assert not (here / "bad" / "manifest.json").exists()

    with leaves_the_process_alone(), pytest.raises(decrun.RunError, match=r"^error: app.dt: must be > 0") as info:
        decrun.run(["app=heat", "app.dt=-1", "figures=false"])  # refused as bad input: no directory left
    assert info.value.dir is None and not (here / "outputs").exists()  # nor the outputs/runs made for it
    (here / "mine").mkdir()
    with leaves_the_process_alone(), pytest.raises(decrun.RunError, match=r"^error: app.dt: must be > 0") as info:
        decrun.run(["app=heat", "app.dt=-1", "figures=false"], dir="mine")  # a directory that was there stays
    assert '"status": "failed"' in (info.value.dir / "metrics.json").read_text()

    with pytest.raises(ValueError, match="decrun.sweep"):
        decrun.run(["-m", "app.dt=1,2"])
    with pytest.raises(ValueError, match="not both"):
        decrun.run(HEAT, dir="a", root="b")
    with pytest.raises(ValueError, match="hydra.run.dir is set both"):
        decrun.run([*HEAT, "hydra.run.dir=x"], dir="a")


def test_a_directory_another_process_uses_is_refused_and_left_alone(here):
    (here / "busy").mkdir()
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from decrun.runner.io.locks import acquire; "
                               "acquire('busy', 'run'); print('held', flush=True); time.sleep(60)"],
                              cwd=here, env=_env(), stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with leaves_the_process_alone(), \
                pytest.raises(decrun.RunError, match=rf"busy is in use by decrun process {holder.pid}") as info:
            decrun.run(HEAT, dir="busy")
        assert info.value.dir == here / "busy" and sorted(p.name for p in (here / "busy").iterdir()) == [".decrun.lock"]
    finally:
        holder.kill()
        holder.wait()
    assert decrun.run(HEAT, dir="busy").status == "ok"  # free again: this process kept no lock


def test_an_interrupted_run_is_a_keyboard_interrupt_and_recorded(tmp_path):
    script = ("import os, signal, threading, time, decrun\n"
              "def interrupt():  # Ctrl-C once the run records its steps\n"
              "    while not os.path.exists('long/result.h5.partial'):\n"
              "        time.sleep(0.05)\n"
              "    os.kill(os.getpid(), signal.SIGINT)\n"
              "threading.Thread(target=interrupt, daemon=True).start()\n"
              "try:\n"
              "    decrun.run(['app=heat', 'app.t_end=1e6', 'figures=false', 'hydra.run.dir=long'])\n"
              "except KeyboardInterrupt:\n"
              "    from decrun.runner.io.locks import _held\n"
              "    print('interrupted', not _held)\n")
    out = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, env=_env(), capture_output=True, text=True,
                         timeout=120)
    assert out.stdout.strip() == "interrupted True", out.stdout + out.stderr
    assert "decrun: interrupted (Ctrl-C)" in out.stderr
    assert '"status": "interrupted"' in (tmp_path / "long" / "metrics.json").read_text()


def test_a_sweep_on_another_launcher_gives_the_same_table(here):
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    basic = decrun.sweep(SWEEP, dir="basic")
    joblib = decrun.sweep([*SWEEP, "hydra.launcher.n_jobs=2"], launcher="joblib", dir="joblib")
    timing = [c for c in basic if "seconds" in c or c == "steps_per_second"]
    pd.testing.assert_frame_equal(basic.drop(columns=timing), joblib.drop(columns=timing))


def test_import_decrun_stays_light_until_run_or_sweep_is_used():
    probe = ("import sys, decrun\n"
             "assert 'hydra' not in sys.modules and 'decrun.runner' not in sys.modules, 'import decrun'\n"
             "decrun.run, decrun.sweep, decrun.Run, decrun.RunError\n"
             "assert 'hydra' not in sys.modules and 'pandas' not in sys.modules, 'decrun.run'\n")
    out = subprocess.run([sys.executable, "-c", probe], env=_env(), capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr


def test_the_docs_python_block_runs(tmp_path):
    block = re.search(r"<!-- python-api -->\n```python\n(.*?)```\n<!-- /python-api -->",
                      (ROOT / "docs" / "running.md").read_text(), flags=re.S)
    assert block, "docs/running.md: the <!-- python-api --> block"
    out = subprocess.run([sys.executable, "-c", block.group(1)], cwd=tmp_path, env=_env(), capture_output=True,
                         text=True, timeout=240)
    assert out.returncode == 0, out.stderr[-3000:]
    assert (tmp_path / "outputs" / "sweeps" / "k" / "manifest.json").is_file()


def test_the_first_sweep_notebook_runs_and_plots_its_table(tmp_path):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    notebook = nbformat.read(ROOT / "examples" / "first_sweep.ipynb", as_version=4)
    assert all(not cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code"), "stored outputs"
    env = {k: v for k, v in _env().items() if k != "MPLBACKEND"}  # the notebook's own (inline) backend
    start = time.monotonic()
    nbclient.NotebookClient(notebook, timeout=180, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute(env=env)
    assert time.monotonic() - start < 180
    outputs = [o for cell in notebook.cells if cell.cell_type == "code" for o in cell.outputs]
    assert any("image/png" in o.get("data", {}) for o in outputs), "the plot"
    sweeps = list((tmp_path / "outputs" / "sweeps").iterdir())
    assert len(sweeps) == 1 and pd.read_csv(sweeps[0] / "metrics.csv")["status"].tolist() == ["ok"] * 4


def _slug(heading: str) -> str:
    """A markdown heading's anchor as mkdocs (Python-Markdown's toc) makes it."""
    import re

    text = re.sub(r"[^\w\s-]", "", heading.strip().lower())
    return re.sub(r"[\s]+", "-", text).strip("-")


def test_every_section_the_notebook_cites_exists():
    """Issue 48: the notebook cited "README, *Sweeps from Python*", a section that does not exist.
    Every markdown link of its text resolves to a file and, with an anchor, to a heading there;
    every "(README, *Section*)" names a heading of README.md."""
    import re

    notebook = json.loads((ROOT / "examples" / "first_sweep.ipynb").read_text(encoding="utf-8"))
    text = "\n".join("".join(cell["source"]) for cell in notebook["cells"] if cell["cell_type"] == "markdown")
    links = re.findall(r"\]\(([^)\s]+)\)", text)
    assert links, "the notebook links its sources"
    for link in links:
        if link.startswith("http"):
            continue
        target, _, anchor = link.partition("#")
        page = (ROOT / "examples" / target).resolve()
        assert page.is_file(), link
        if anchor:
            headings = re.findall(r"^#+\s+(.*)$", page.read_text(encoding="utf-8"), flags=re.M)
            assert anchor in {_slug(h) for h in headings}, (link, headings)
    readme = {h.strip() for h in re.findall(r"^#+\s+(.*)$", (ROOT / "README.md").read_text(encoding="utf-8"), re.M)}
    for section in re.findall(r"README, \*([^*]+)\*", text):
        assert section in readme, f"README has no section {section!r}"


def test_a_second_call_from_another_thread_is_refused_and_the_first_finishes(here):
    """Issue 50, item 15: ``decrun.run`` from a second thread while the first runs is refused in one
    line naming the running call; the first run is untouched and finishes ok with its result."""
    import threading

    # pymeshlab loaded first in a thread that is not the main one aborts the process at its exit
    # (its PluginManager's destructor: "malloc_consolidate(): unaligned fastbin chunk detected"),
    # whatever decrun does; loaded here, in the main thread, the test's process ends cleanly
    pytest.importorskip("pymeshlab")
    outcome: dict = {}

    def first():
        try:
            outcome["run"] = decrun.run(["app=heat", "mesh.subdiv=3", "app.t_end=0.4", "figures=false"], dir="first")
        except BaseException as exc:  # noqa: BLE001 — reported by the assertions below
            outcome["error"] = exc

    worker = threading.Thread(target=first, name="first-call")
    worker.start()
    deadline = time.monotonic() + 120
    while not (here / "first" / ".hydra").is_dir() and worker.is_alive() and time.monotonic() < deadline:
        time.sleep(0.01)  # the first call is composing or running
    assert worker.is_alive(), outcome
    with pytest.raises(decrun.RunError) as info:
        decrun.run(HEAT, dir="second")
    message = str(info.value)
    assert "\n" not in message and "decrun.run in thread 'first-call' is running in this process" in message
    worker.join(240)
    assert "error" not in outcome, outcome
    run = outcome["run"]
    assert run.status == "ok" and run.metrics["steps_done"] == 400 and run.result_path.is_file()
    assert not (here / "second").exists()
    again = decrun.run(HEAT, dir="second")  # once the first returned, the next call runs
    assert again.status == "ok"


def test_a_directory_holding_an_interpolation_is_never_resolved(here, monkeypatch):
    """``dir='…${oc.env:X}'`` is not resolved to another directory (docs: "into exactly dir"):
    Hydra would resolve it again in its own paths, so it is refused in one line, nothing made."""
    monkeypatch.setenv("DECRUN_TEST_X", "resolved")
    for argument in ("dir", "root"):
        with leaves_the_process_alone(), pytest.raises(decrun.RunError, match=rf"^error: {argument}='out/\$\{{oc"):
            decrun.run(HEAT, **{argument: "out/${oc.env:DECRUN_TEST_X}"})
    assert not (here / "out").exists() and not (here / "outputs").exists()
