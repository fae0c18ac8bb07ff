"""A run that runs out of memory ends as one line naming the size that failed and the
setting to lower, as an override that fixes it (issue 24, item 5)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pytest
from test_bad_input import assert_one_clear_line, decrun

from decrun.runner.job.config import compose_config
from decrun.runner.job.failures import find_memory_error, memory_error_text
from decrun.runner.job.hints import memory_hint


def _fix(line: str) -> list[str]:
    return re.search(r"`([^`]+)`", line).group(1).split()


def test_numpy_memory_errors_name_the_array_and_native_ones_say_so():
    import numpy as np

    try:
        np.empty((10**8, 10**8))
    except MemoryError as exc:
        assert memory_error_text(exc) == "could not allocate 71.1 PiB for an array of shape (100000000, 100000000) float64"
    wrapped = ValueError("while factorizing")
    wrapped.__cause__ = RuntimeError("std::bad_alloc")
    assert memory_error_text(find_memory_error(wrapped)) == "ran out of memory (std::bad_alloc)"
    assert find_memory_error(RuntimeError("Failed to resize matrix arrays!")) is None


def test_the_hint_names_options_that_are_dimensions_of_the_array_else_the_mesh_resolution():
    cfg = compose_config(["app=hodge", "app.quadrature_order=100000000", "mesh=grid", "mesh.nx=600"])
    assert memory_hint(cfg, (100000000, 100000000)) == ("lower app.quadrature_order (a dimension of that array): "
                                                        "use `app.quadrature_order=3` (the default)")
    assert memory_hint(cfg, (717602, 3)) == "use a coarser mesh: `mesh.nx=16` (the default)"
    planar = compose_config(["mesh=planar", "mesh.max_area=1e-7", "mesh.min_angle_deg=30"])
    assert memory_hint(planar, (10, 3)).startswith("use a coarser mesh: `mesh.max_area=")


def test_an_app_option_too_large_for_memory_is_one_line_and_its_fix_runs(tmp_path):
    proc = decrun("app=hodge", "app.quadrature_order=100000000", cwd=tmp_path)
    line = assert_one_clear_line(proc, "error: app=hodge on mesh=icosphere: could not allocate 71.1 PiB for an array "
                                       "of shape (100000000, 100000000) float64", "lower app.quadrature_order")
    assert _fix(line) == ["app.quadrature_order=3"]
    (metrics,) = tmp_path.rglob("metrics.json")
    assert json.loads(metrics.read_text()) == {"status": "failed", "error": line.removeprefix("error: ")}
    done = decrun("app=hodge", *_fix(line), "hydra.run.dir=fixed", cwd=tmp_path)
    assert done.returncode == 0, done.stderr


def test_a_sweep_job_out_of_memory_is_a_row_with_the_message(tmp_path):
    proc = decrun("-m", "app=hodge", "app.quadrature_order=3,100000000", "hydra.sweep.dir=sweep", cwd=tmp_path)
    assert proc.returncode == 1 and "Traceback" not in proc.stdout + proc.stderr
    assert "decrun: job 1 failed: app=hodge on mesh=icosphere: could not allocate 71.1 PiB" in proc.stderr
    assert json.loads((tmp_path / "sweep" / "0" / "metrics.json").read_text())["status"] == "ok"


def _limited(limit_bytes: int):
    def apply():
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (limit_bytes, limit_bytes))

    return apply


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS: Linux")
def test_a_mesh_too_fine_for_the_memory_there_is_one_line_and_its_fix_runs_in_that_memory(tmp_path):
    """A 1400 × 1400 grid (3.9M triangles, within decrun's 4e6 limit) in 1 GiB of address space:
    numpy's MemoryError becomes one line naming the array and the coarser mesh, which runs in
    the same 1 GiB. (The grid is built in numpy since it is centred exactly: 600 × 600 now fits
    in 1 GiB and smooths for minutes instead of failing.)"""
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}
    env.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1", MPLBACKEND="Agg")

    def run(*args):
        return subprocess.run([sys.executable, "-m", "decrun", "figures=false", *args], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=300, preexec_fn=_limited(2**30))

    proc = run("mesh=grid", "mesh.nx=1400", "mesh.ny=1400", "hydra.run.dir=big")
    line = assert_one_clear_line(proc, "error: app=smoothing on mesh=grid: could not allocate ", " for an array of shape (",
                                 "use a coarser mesh: `mesh.nx=16 mesh.ny=16` (the defaults)")
    done = run("mesh=grid", *_fix(line), "hydra.run.dir=fixed")
    assert done.returncode == 0, done.stderr[-2000:]
    assert json.loads((tmp_path / "fixed" / "metrics.json").read_text())["n_faces"] == 2 * 15 * 15
