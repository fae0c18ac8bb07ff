"""A small run through the real ``decrun`` command: its figures never cost it its result, and
it pays only for the imports it uses."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

from cli_processes import decrun, env


def test_a_figure_that_cannot_be_saved_keeps_the_result_and_metrics(tmp_path):
    """A figure that fails after the run (here: a directory is where smoothing.png goes) leaves
    result.h5 complete and metrics.json with every metric plus ``figures_error``; the command
    says so in one line naming ``figures`` and exits 1; the hint ``figures=false`` then runs."""
    import h5py

    run_dir = tmp_path / "run"
    (run_dir / "smoothing.png").mkdir(parents=True)
    done = decrun("app.steps=3", f"hydra.run.dir={run_dir}", cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and "figures:" in lines[0] and "figures=false" in lines[0], done.stderr
    assert "smoothing.png: Is a directory" in lines[0] and "keep its result and metrics" in lines[0]
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert metrics["status"] == "ok" and metrics["steps_done"] == 3 and metrics["stable"] is True
    assert metrics["figures_error"].startswith("figures: cannot write") and "result_h5" in metrics
    with h5py.File(run_dir / "result.h5", "r") as f:
        assert bool(f.attrs["complete"]) and f.attrs["status"] == "ok"
        assert len(f["fields"]) > 0

    fixed = decrun("app.steps=3", f"hydra.run.dir={run_dir}", "figures=false", cwd=tmp_path)
    assert fixed.returncode == 0, fixed.stderr
    again = json.loads((run_dir / "metrics.json").read_text())
    assert "figures_error" not in again and again["status"] == "ok"
    # the same computation: the result's content hash is the one the failed-figures run recorded
    assert again["result_h5"]["content_sha256"] == metrics["result_h5"]["content_sha256"]


def imported_modules(*args: str, cwd) -> set[str]:
    """The modules ``python -X importtime -m decrun *args`` imported (its import log on stderr)."""
    done = subprocess.run([sys.executable, "-X", "importtime", "-m", "decrun", *args], cwd=cwd, env=env(),
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return {m.group(1) for m in re.finditer(r"^import time:\s+\d+ \|\s+\d+ \|\s*(\S+)$", done.stderr, re.M)}


def test_a_single_run_imports_neither_figures_nor_sweep_machinery(tmp_path):
    """``decrun figures=false`` never imports matplotlib or pandas (the figures' and the sweep
    table's), nor decrun's sweeper, its sweep planning or tracking; with figures the run imports
    matplotlib and draws them itself, still without pandas; the second run reads its mesh from
    the mesh cache and imports no pymeshlab."""
    modules = imported_modules("figures=false", "app.steps=2", cwd=tmp_path)
    assert "decrun.runner.job.run" in modules and "h5py" in modules  # the log is read right
    unused = ["matplotlib", "pandas", "decrun.runner.plots.common", "decrun.runner.sweep.sweeper",
              "decrun.runner.sweep.fast", "decrun.runner.tracking", "decrun.runner.sweep.tables"]
    assert [m for m in unused if m in modules] == []
    drawn = imported_modules("app.steps=2", "hydra.run.dir=drawn", cwd=tmp_path)
    assert "matplotlib" in drawn and "decrun.runner.plots.common" in drawn and "pandas" not in drawn
    assert sorted(p.name for p in (tmp_path / "drawn").glob("*.png")) == ["smoothing.png", "smoothing_series.png"]
    # the icosphere the first run made comes from the mesh cache: pymeshlab is not imported again
    assert "decrun.runner.mesh.cache" in drawn and "pymeshlab" not in drawn


def test_a_figure_that_fails_while_its_file_is_written_leaves_no_partial_file(tmp_path):
    """The fluid's animation failing while its GIF is written (here: the disk is full after the
    first bytes) leaves neither a partial ``vorticity_animation.gif`` nor its temporary file;
    result.h5 is complete and metrics.json names the failure (``figures_error``), and the
    command's one line names ``figures=false``, whose run then succeeds."""
    plugin = tmp_path / "full_disk"
    plugin.mkdir()
    (plugin / "sitecustomize.py").write_text(
        "import errno, os\n"
        "from PIL import Image\n"
        "def save(self, fp, *args, **kwargs):\n"
        "    if '.gif' not in str(fp):\n"
        "        return SAVE(self, fp, *args, **kwargs)\n"
        "    with open(fp, 'wb') as handle:\n"
        "        handle.write(b'GIF89a partial')\n"
        "    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))\n"
        "SAVE, Image.Image.save = Image.Image.save, save\n")
    child = {**env(), "PYTHONPATH": os.pathsep.join([str(plugin), env().get("PYTHONPATH", "")])}
    args = ["app=fluid", "app.steps=4", "app.record_every=1", "hydra.run.dir=run"]
    done = subprocess.run([sys.executable, "-m", "decrun", *args], cwd=tmp_path, env=child, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 1, done.stderr
    [line] = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert "figures" in line and "No space left on device" in line and "figures=false" in line, line
    left = sorted(p.name for p in (tmp_path / "run").iterdir())
    assert "vorticity_animation.gif" not in left and not [name for name in left if ".tmp-" in name], left
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["status"] == "ok" and metrics["steps_done"] == 4 and "No space left" in metrics["figures_error"]
    from decrun.runner.results import read_result

    assert read_result(tmp_path / "run" / "result.h5").complete
    fixed = subprocess.run([sys.executable, "-m", "decrun", *args, "figures=false"], cwd=tmp_path, env=child,
                           capture_output=True, text=True, timeout=300)
    assert fixed.returncode == 0, fixed.stderr


def test_a_config_that_sets_hydra_mode_multirun_still_sweeps(tmp_path):
    """A user's config with ``hydra.mode: MULTIRUN`` makes ``decrun`` (no ``-m``) a sweep, as
    Hydra's command line does; a sweep override without ``-m`` or such a config stays refused
    with Hydra's message."""
    experiment = tmp_path / "conf" / "experiment"
    experiment.mkdir(parents=True)
    (experiment / "two.yaml").write_text("# @package _global_\nhydra:\n  mode: MULTIRUN\n  sweep:\n    dir: swept\n"
                                         "app:\n  steps: 2\nfigures: false\n")
    done = decrun("--config-dir", str(tmp_path / "conf"), "+experiment=two", "app.dt=0.001,0.002", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert sorted(json.loads((tmp_path / "swept" / job / "metrics.json").read_text())["dt"] for job in "01") == [0.001, 0.002]
    refused = decrun("app.dt=0.001,0.002", cwd=tmp_path)
    assert refused.returncode == 1 and "Ambiguous value for argument 'app.dt=0.001,0.002'" in refused.stderr


def test_a_single_run_ends_with_its_log_and_output_complete(tmp_path):
    """The command ends a single run's process without the interpreter's teardown: what it
    printed to a pipe and its log file are complete (the log's last line is the metrics), and
    a refused run still exits 1 with its one line."""
    done = decrun("figures=false", "app.steps=2", "hydra.run.dir=run", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == "decrun: wrote run/ (result.h5, metrics.json, decrun.log)"
    log_lines = (tmp_path / "run" / "decrun.log").read_text().splitlines()
    assert "metrics: " in log_lines[-1] and "steps_done=2" in log_lines[-1]
    refused = decrun("app.steps=-1", cwd=tmp_path)
    assert refused.returncode == 1 and refused.stderr.startswith("error: app.steps"), refused.stderr


def test_a_sweep_lists_a_job_whose_figures_failed(tmp_path, capsys, monkeypatch):
    """The sweep's closing lines count a job whose figures failed after its run (its metrics
    kept, ``figures_error`` among them) beside failed exports, and the sweep exits 1."""
    from omegaconf import OmegaConf

    from decrun.runner.command.callbacks import SweepTable

    done = decrun("-m", "app.steps=2,3", "figures=false", "hydra.sweep.dir=swept", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    metrics_path = tmp_path / "swept" / "1" / "metrics.json"
    metrics = json.loads(metrics_path.read_text())
    metrics["figures_error"] = "figures: cannot write swept/1/smoothing.png: Is a directory; figures=false runs without them"
    metrics_path.write_text(json.dumps(metrics))
    monkeypatch.setattr(SweepTable, "failed", 0)  # restored after the test
    SweepTable().on_multirun_end(OmegaConf.create({"hydra": {"sweep": {"dir": str(tmp_path / "swept")}}}))
    out, err = capsys.readouterr()
    assert "(0 not ok, 1 figures failed)" in out and SweepTable.failed == 1
    assert "decrun: job 1 figures failed: figures: cannot write swept/1/smoothing.png" in err


def test_an_interrupt_wrapped_in_an_extensions_import_error_is_an_interrupt(tmp_path, monkeypatch):
    """SIGTERM while matplotlib's C extensions initialize reaches the run as their
    ``ImportError: initialization failed`` with the interrupt as its cause: the run treats it
    as the interrupt (metrics.json says the figures were interrupted, status ok), never as a
    figure that failed."""
    import pytest

    import decrun as api
    from decrun.runner.job.failures import Terminated
    from decrun.runner.plots import common

    def importing(*args, **kwargs):
        try:
            raise Terminated("SIGTERM")
        except Terminated as cause:
            raise ImportError("initialization failed") from cause

    monkeypatch.setattr(common, "draw_figures", importing)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(KeyboardInterrupt):
        api.run(["app.steps=2"], dir=tmp_path / "run")
    record = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert record["status"] == "ok" and record["figures_interrupted"] == "interrupted (SIGTERM)", record
    assert "figures_error" not in record and sorted(record["figures_not_drawn"]) == ["smoothing", "smoothing_series"]
