"""``decrun-table`` for several sweeps, in the order asked, ``--plot`` and ``--compare`` (issue 48
item 12) through the real commands (``decrun`` and ``decrun-table`` child processes)."""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_tables import write_job  # noqa: E402

from decrun.runner.results import read_result
from decrun.runner.sweep.compare import compare_runs
from decrun.runner.sweep.manifest import FORMAT, MANIFEST
from decrun.runner.sweep.plot import draw_metric
from decrun.runner.sweep.tables import stack

from cli_processes import decrun, env

TABLE = str(Path(sys.executable).parent / "decrun-table")
FAST = ["figures=false", "progress=false"]


def decrun_table(*args: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([TABLE, *args], cwd=cwd, env=env(), capture_output=True, text=True, timeout=300)


def planned_sweep(root: Path, overrides: list[list[str]], metrics: list[dict]) -> Path:
    """A sweep directory (manifest + finished jobs) whose job i has ``overrides[i]`` and
    ``metrics[i]``."""
    root.mkdir(parents=True)
    jobs = [{"job": str(i), "overrides": o, "config_hash": f"h{i}"} for i, o in enumerate(overrides)]
    (root / MANIFEST).write_text(json.dumps({"format": FORMAT, "overrides": [], "jobs": jobs,
                                             "runs": [{"started": "t", "jobs": [j["job"] for j in jobs],
                                                       "finished": None}]}))
    (root / "multirun.yaml").write_text("hydra: {}\n")
    for i, values in enumerate(metrics):
        (root / str(i) / ".hydra").mkdir(parents=True)
        write_job(root / str(i), {"config_hash": f"h{i}", "status": "ok", **values})
    return root


def test_two_sweeps_show_the_union_of_their_swept_keys_and_metrics_in_the_order_asked(tmp_path):
    a = planned_sweep(tmp_path / "A", [["app.dt=0.1"], ["app.dt=0.2"]], [{"e": 1.0, "n": 3}, {"e": 2.0, "n": 4}])
    b = planned_sweep(tmp_path / "B", [["mesh.subdiv=1"], ["mesh.subdiv=2"]], [{"e": 3.0, "n": 5}, {"e": 4.0, "n": 6}])
    done = decrun_table(str(a), str(b), "--metrics", "n,e", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "| sweep | job | app.dt | mesh.subdiv | status | n | e | result |"
    keys = [tuple(cell.strip() for cell in line.strip("|").split("|")[2:4]) for line in lines[2:]]
    assert keys == [("0.1", ""), ("0.2", ""), ("", "1"), ("", "2")]  # every row told apart by its keys
    for args in (["--csv"], ["--all"], ["--sort", "e", "--descending"], ["--drop-constant", "--csv"]):
        done = decrun_table(str(a), str(b), "--metrics", "n,e", *args, cwd=tmp_path)
        header = [c.strip() for c in done.stdout.splitlines()[0].strip("|").split("," if "--csv" in args else "|")]
        assert header.index("n") + 1 == header.index("e"), (args, header)
        assert {"app.dt", "mesh.subdiv"} <= set(header) and header.index("mesh.subdiv") < header.index("status")


@pytest.fixture(scope="module")
def convergence_sweep(tmp_path_factory):
    """A real sweep: Δu = −6xy on the sphere, 3 refinements × 2 stars (l2_error_rel falls ~4× a step)."""
    root = tmp_path_factory.mktemp("sweep")
    proc = decrun("-m", "+experiment=poisson_sphere", "mesh.subdiv=1,2,3", "operator=circumcentric,barycentric",
                  *FAST, f"hydra.sweep.dir={root / 'S'}", cwd=root)
    assert proc.returncode == 0, proc.stderr
    return root / "S"


def test_plot_draws_a_metric_against_a_swept_key_grouped_by_the_others(convergence_sweep, tmp_path):
    out = tmp_path / "error.png"
    done = decrun_table(str(convergence_sweep), "--plot", "l2_error_rel", "--x", "mesh.subdiv", "-o", str(out),
                        cwd=tmp_path)
    assert done.returncode == 0 and f"wrote {out}" in done.stdout, done.stderr
    import matplotlib.image

    image = matplotlib.image.imread(out)
    assert image.shape[0] > 300 and image.shape[1] > 500 and image[..., :3].std() > 0.05  # drawn, not blank
    figure = draw_metric(stack([convergence_sweep]), "l2_error_rel", "mesh.subdiv")
    axes = figure.axes[0]
    labels = sorted(line.get_label() for line in axes.get_lines())
    assert labels == ["operator=barycentric", "operator=circumcentric"]
    assert axes.get_yscale() == "log" and axes.get_xscale() == "linear"  # errors span decades, subdiv 1..3 not
    for line in axes.get_lines():
        assert list(line.get_xdata()) == [1, 2, 3] and np.all(np.diff(line.get_ydata()) < 0)
    default = decrun_table(str(convergence_sweep), "--plot", "l2_error_rel", "--x", "mesh.subdiv", cwd=tmp_path)
    assert (convergence_sweep / "l2_error_rel_vs_mesh_subdiv.png").is_file(), default.stderr
    wrong = decrun_table(str(convergence_sweep), "--plot", "l2_error_rel", "--x", "app.dt", cwd=tmp_path)
    assert wrong.returncode == 2 and wrong.stderr.startswith("decrun-table: error: no swept key 'app.dt'")
    assert "mesh.subdiv" in wrong.stderr and len(wrong.stderr.strip().splitlines()) == 1


def test_compare_two_runs_field_by_field(convergence_sweep, tmp_path):
    """Jobs 4 and 5 (subdiv 3, circumcentric vs barycentric ⋆0): u differs by the two stars."""
    first, second = convergence_sweep / "4", convergence_sweep / "5"
    done = decrun_table("--compare", str(first), str(second), "--csv", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    table = pd.read_csv(io.StringIO(done.stdout))
    u_a, u_b = read_result(first).fields["u"], read_result(second).fields["u"]
    row = table.set_index("field").loc["u"]
    assert row["max_abs_difference"] == pytest.approx(np.abs(u_a - u_b).max(), rel=1e-12)
    assert row["l2_difference"] == pytest.approx(np.linalg.norm(u_a - u_b), rel=1e-12) and row["l2_difference"] > 0
    assert row["l2_difference_relative"] == pytest.approx(np.linalg.norm(u_a - u_b) / np.linalg.norm(u_a), rel=1e-12)
    same = compare_runs(first, first)  # the API
    assert (same["max_abs_difference"] == 0).all() and (same["note"] == "").all()
    shapes = compare_runs(convergence_sweep / "0", first).set_index("field").loc["u"]
    assert shapes["note"] == "shapes differ" and np.isnan(shapes["l2_difference"])
    markdown = decrun_table("--compare", str(first), str(second), cwd=tmp_path)
    assert markdown.stdout.startswith("| field | shape | max_abs_difference | l2_difference |")
    missing = decrun_table("--compare", str(first), str(tmp_path / "nowhere"), cwd=tmp_path)
    assert missing.returncode == 2 and len(missing.stderr.strip().splitlines()) == 1
