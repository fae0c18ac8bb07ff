"""``export=vtu|xdmf|ply|obj`` (every file read back with meshio and compared with result.h5)
and ``mesh=result`` chaining, through the real CLI."""

from __future__ import annotations

import json
import re
from pathlib import Path

import meshio
import numpy as np
import pytest

from decrun.runner.results import read_result


def run_dir(decrun_cli, tmp_path, *args) -> Path:
    before = set(tmp_path.glob("outputs/runs/*"))
    done = decrun_cli(*args, "figures=false")
    assert done.returncode == 0, done.stderr
    (new,) = set(tmp_path.glob("outputs/runs/*")) - before
    return new


def test_vtu_holds_mesh_and_every_field_of_a_volume_run(decrun_cli, tmp_path):
    out = run_dir(decrun_cli, tmp_path, "app=hodge", "mesh=box", "mesh.cells=3", "operator=whitney",
                  "app.input=random", "export=vtu")
    stored = read_result(out / "result.h5")
    mesh = meshio.read(out / "result.vtu")
    np.testing.assert_array_equal(mesh.points, stored.mesh["vertices"])
    tetra, triangles, lines = (block.data for block in mesh.cells)
    assert [block.type for block in mesh.cells] == ["tetra", "triangle", "line"]
    np.testing.assert_array_equal(tetra, stored.mesh["simplices"])
    np.testing.assert_array_equal(lines, stored.mesh["edges"])
    for name in ("omega", "exact", "coexact", "harmonic"):  # 1-forms on the line block
        np.testing.assert_array_equal(mesh.cell_data[name][2], stored.fields[name])
        assert np.isnan(mesh.cell_data[name][0]).all() and np.isnan(mesh.cell_data[name][1]).all()
    np.testing.assert_array_equal(mesh.cell_data["omega_vectors"][0], stored.fields["omega_vectors"])
    np.testing.assert_array_equal(mesh.point_data["alpha"], stored.fields["alpha"])
    # β, the 2-form potential, lives on the triangles of the volume: a block of its own
    assert len(triangles) == len(stored.fields["beta"])
    np.testing.assert_array_equal(mesh.cell_data["beta"][1], stored.fields["beta"])


def test_xdmf_time_series_of_a_fluid_run_reads_back_step_by_step(decrun_cli, tmp_path):
    out = run_dir(decrun_cli, tmp_path, "app=fluid", "mesh.subdiv=2", "mesh.noise=0", "app.initial=vortex_pair",
                  "app.steps=6", "app.record_every=2", "app.animation=false", "export=xdmf")
    series = read_result(out / "result.h5").series
    with meshio.xdmf.TimeSeriesReader(out / "series.xdmf") as reader:
        points, cells = reader.read_points_cells()
        assert reader.num_steps == len(series["step"]) == 4
        np.testing.assert_array_equal(cells[0].data, read_result(out / "result.h5").mesh["simplices"])
        for i in range(reader.num_steps):
            t, point_data, _ = reader.read_data(i)
            assert t == pytest.approx(series["time"][i])
            np.testing.assert_array_equal(point_data["vorticity"], series["vorticity"][i])
    with meshio.xdmf.TimeSeriesReader(out / "series_edges.xdmf") as reader:
        _, cells = reader.read_points_cells()
        assert cells[0].type == "line"
        _, _, cell_data = reader.read_data(3)
        np.testing.assert_array_equal(cell_data["flux"][0], series["flux"][3])


def test_ply_colours_follow_the_field_through_the_colormap(decrun_cli, tmp_path):
    from matplotlib import colormaps

    out = run_dir(decrun_cli, tmp_path, "app=smoothing", "app.steps=3", "export=ply", "export.field=displacement",
                  "export.colormap=plasma")
    stored = read_result(out / "result.h5")
    mesh = meshio.read(out / "result.ply")
    value = stored.fields["displacement"]
    np.testing.assert_allclose(mesh.point_data["displacement"], value)
    expected = np.round(255 * colormaps["plasma"]((value - value.min()) / np.ptp(value))[:, :3]).astype(np.uint8)
    got = np.column_stack([mesh.point_data[c] for c in ("red", "green", "blue")])
    assert got.dtype == np.uint8 and np.array_equal(got, expected)
    np.testing.assert_array_equal(mesh.cells_dict["triangle"], stored.mesh["simplices"])


def test_obj_carries_the_parametrization_uv_as_texture_coordinates(decrun_cli, tmp_path):
    out = run_dir(decrun_cli, tmp_path, "app=parametrization", "mesh.subdiv=2", "mesh.noise=0",
                  "mesh.hole_balls=[[0,0,1,0.6]]", "export=obj")
    stored = read_result(out / "result.h5")
    mesh = meshio.read(out / "result.obj")
    np.testing.assert_allclose(mesh.points, stored.mesh["vertices"], rtol=1e-15)
    np.testing.assert_allclose(mesh.point_data["obj:vt"], stored.fields["uv"], rtol=1e-15)
    np.testing.assert_array_equal(mesh.cells_dict["triangle"], stored.mesh["simplices"])
    import re

    face_lines = [line for line in (out / "result.obj").read_text().splitlines() if line.startswith("f ")]
    assert len(face_lines) == len(stored.mesh["simplices"])
    assert all(re.fullmatch(r"f (\d+)/\1 (\d+)/\2 (\d+)/\3", line) for line in face_lines)


def refused_before_any_work(decrun_cli, tmp_path, *args) -> str:
    """The one error line of a run refused from its config, before its mesh loads: the mesh
    is a file that would not load (its own error would come first), and no result is written."""
    bad = tmp_path / "not_a_mesh.obj"
    bad.write_text("garbage\n")
    assert "unknown OBJ statement" in one_error_line(decrun_cli("mesh=file", f"mesh.path={bad}", "figures=false"))
    before = set(tmp_path.glob("outputs/runs/*"))
    line = one_error_line(decrun_cli(*args, "mesh=file", f"mesh.path={bad}", "figures=false"))
    assert not any((new / "result.h5").exists() for new in set(tmp_path.glob("outputs/runs/*")) - before)
    return line


@pytest.mark.parametrize("args, says, fix", [
    (["app=spectrum", "export=obj"], "export.uv: app=spectrum writes no per-vertex field 'uv'", "export=vtu"),
    (["app=smoothing", "app.steps=1", "export=ply", "export.field=nothing"], "export.field: app=smoothing writes no per-vertex field "
     "'nothing' (those are ['displacement', 'vertices_final', 'vertices_initial'])", "export.field=auto"),
    (["app=spectrum", "export=ply"], "export.field=auto: app=spectrum writes no one-value-per-vertex field",
     "export.field=eigenforms:0"),
    (["app=spectrum", "export=ply", "export.field=eigenforms:12"], "export.field: 'eigenforms' has 10 columns",
     "export.field=eigenforms:0"),
    (["app=smoothing", "app.steps=1", "export=ply", "export.field=displacement:1"], "export.field: 'displacement' has one value per "
     "vertex, no columns", "export.field=displacement"),
], ids=["obj without uv", "ply missing field", "ply auto without a scalar", "ply column", "ply scalar column"])
def test_an_export_the_app_cannot_feed_is_refused_before_the_mesh_loads_and_the_fix_runs(decrun_cli, tmp_path, args,
                                                                                         says, fix):
    line = refused_before_any_work(decrun_cli, tmp_path, *args)
    assert line.startswith(f"error: {says}") and f"`{fix}`" in line, line
    out = run_dir(decrun_cli, tmp_path, *args, fix, "mesh.subdiv=1")
    assert json.loads((out / "metrics.json").read_text())["status"] == "ok"


def test_a_sweep_with_an_export_the_app_cannot_feed_runs_no_job(decrun_cli, tmp_path):
    done = decrun_cli("-m", "app=spectrum", "mesh.subdiv=1,2", "export=obj", "figures=false")
    assert done.returncode != 0 and "export.uv: app=spectrum writes no per-vertex field 'uv'" in done.stderr
    assert "nothing ran" in done.stderr and not list(tmp_path.glob("outputs/**/metrics.json"))
    done = decrun_cli("-m", "app=spectrum", "mesh.subdiv=1,2", "export=vtu", "figures=false")
    assert done.returncode == 0, done.stderr


def test_an_export_that_fails_after_the_run_keeps_its_metrics(decrun_cli, tmp_path):
    """A model's definitions are known once compiled: an export naming one that does not exist
    fails after the run — with the run's result and metrics kept, the error beside them."""
    args = ["app=heat", "mesh.subdiv=1", "app.t_end=0.002", "export=ply", "figures=false"]
    before = set(tmp_path.glob("outputs/runs/*"))
    line = one_error_line(decrun_cli(*args, "export.field=nothing"))
    (out,) = set(tmp_path.glob("outputs/runs/*")) - before
    assert line.startswith("error: export.field: 'nothing' is not a per-vertex field of this run") and \
        "`export.field=auto`" in line and "keep its result and metrics" in line, line
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "ok" and "mass" in metrics and metrics["steps_done"] == 2, metrics
    assert metrics["export_error"].startswith("export.field: 'nothing'")
    assert read_result(out / "result.h5").fields["u"].shape == (42,)
    assert decrun_cli(*args, "export.field=auto").returncode == 0


def test_a_smoothed_mesh_feeds_a_parametrization(decrun_cli, tmp_path):
    smoothed = run_dir(decrun_cli, tmp_path, "app=smoothing", "app.steps=5")
    final = read_result(smoothed / "result.h5").fields["vertices_final"]
    out = run_dir(decrun_cli, tmp_path, "app=parametrization", "mesh=result", f"mesh.path={smoothed}",
                  "mesh.hole_balls=[[0,0,1,0.5]]")
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["flipped_triangles"] == 0 and metrics["is_embedding"]
    from scipy.spatial import cKDTree

    cut = read_result(out / "result.h5").mesh["vertices"]
    initial = read_result(smoothed / "result.h5").fields["vertices_initial"]
    # the parametrized mesh is the smoothed one with a cap cut out (the cut adds border
    # vertices on the ball), not the noisy input
    kept = cKDTree(final).query(cut)[0] < 1e-12
    assert kept.mean() > 0.8 and (cKDTree(initial).query(cut)[0] < 1e-12).mean() < 0.05


def test_a_designed_field_feeds_a_fluid(decrun_cli, tmp_path):
    """A designed field with vortices starts the fluid with their vorticity (its ratios are
    measured); a curl-free one (sources and sinks only: a gradient) has vorticity at round-off,
    which is flagged, drawn with a word, and gives no ratios of round-off."""
    designed = run_dir(decrun_cli, tmp_path, "app=vector_field", "mesh.subdiv=2", "mesh.noise=0",
                       "app.vortices=[{point: [0, 0, 1], curl: 1.0}, {point: [0, 0, -1], curl: -1.0}]")
    out = run_dir(decrun_cli, tmp_path, "app=fluid", "app.initial=mesh_field", "mesh=result",
                  f"mesh.path={designed / 'result.h5'}", "mesh.field=omega", "app.steps=2", "app.animation=false")
    series = read_result(out / "result.h5").series
    omega = read_result(designed / "result.h5").fields["omega"]
    assert np.abs(series["vorticity"][0]).max() > 1 and np.abs(omega).max() > 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["stable"] and metrics["initial_vorticity_round_off"] is False
    assert 0 < metrics["enstrophy_ratio"] <= 1 and 0 < metrics["energy_ratio"] <= 1

    gradient = run_dir(decrun_cli, tmp_path, "app=vector_field", "mesh.subdiv=2", "mesh.noise=0")
    before = set(tmp_path.glob("outputs/runs/*"))
    done = decrun_cli("app=fluid", "app.initial=mesh_field", "mesh=result", f"mesh.path={gradient / 'result.h5'}",
                      "mesh.field=omega", "app.steps=2", "app.animation=false", "app.snapshots=2")
    assert done.returncode == 0, done.stderr
    (out,) = set(tmp_path.glob("outputs/runs/*")) - before
    assert "mesh.field=omega is round-off" in done.stderr and "energy_ratio and enstrophy_ratio are left out" \
        in done.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["initial_vorticity_round_off"] is True
    assert "energy_ratio" not in metrics and "enstrophy_ratio" not in metrics
    start = np.abs(read_result(out / "result.h5").series["vorticity"][0]).max()
    assert start < 1e-12
    assert (out / "vorticity.png").is_file()
    # one max |w0|: the metric is the start the fluid ran from (drawn in the figure), and the
    # log line and the figure's title say that number
    assert metrics["initial_vorticity_max_abs"] == start
    (said,) = re.findall(r"max \|w0\| = ([^,)]+)", done.stderr)
    assert said == f"{start:.1e}"
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    result = run_experiment(compose_config(["app=fluid", "app.initial=mesh_field", "mesh=result",
                                            f"mesh.path={gradient / 'result.h5'}", "mesh.field=omega", "app.steps=2",
                                            "app.animation=false", "app.snapshots=2"])).result
    assert result.metrics["initial_vorticity_max_abs"] == start
    assert result.figures["vorticity"].data["title"].endswith(f"round-off start (max |w0| = {said})")


def test_circulation_to_vorticity_converges_to_the_curl():
    """The rigid rotation e_z × x on the unit sphere has vorticity 2z: first-order convergence."""
    from decrun.apps.fluid import vorticity_of_field
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC
    from decrun.core.forms import sample_vector_field

    from meshes_for_tests import icosphere

    errors = []
    for subdiv in (2, 3, 4):
        K = SimplicialComplex(*icosphere(subdiv))
        omega = sample_vector_field(K, lambda x: np.cross([0.0, 0.0, 1.0], x))
        w = vorticity_of_field(DEC(K), dict(values=omega, on="edges", name="omega", edges=K.simplices(1)))
        errors.append(np.abs(w - 2 * K.vertices[:, 2]).max())
    assert errors[2] < 0.015 and errors[0] > 1.8 * errors[1] > 3.2 * errors[2], errors


def test_chaining_refusals_name_the_fix(decrun_cli, tmp_path):
    smoothed = run_dir(decrun_cli, tmp_path, "app=smoothing", "app.steps=2")
    done = decrun_cli("mesh=result", f"mesh.path={smoothed}", "mesh.vertices=nowhere", "figures=false")
    assert done.returncode != 0 and "`mesh.vertices=mesh`" in done.stderr
    done = decrun_cli("mesh=result", f"mesh.path={tmp_path / 'none'}", "figures=false")
    assert done.returncode != 0 and "no result file there" in done.stderr
    done = decrun_cli("app=fluid", "app.initial=mesh_field", "mesh.noise=0", "figures=false")
    assert done.returncode != 0 and "mesh=result" in done.stderr


# ---------------------------------------------------------------------------------------
# issue 34 item 2: what a chained run reads is checked against its mesh, and an incomplete
# source is used with a warning and a metric
# ---------------------------------------------------------------------------------------

def altered_copy(source: Path, to: Path, change) -> Path:
    """A copy of ``source``'s result.h5 in ``to`` with ``change(h5 file)`` applied."""
    import shutil

    import h5py

    to.mkdir()
    shutil.copy(source / "result.h5", to / "result.h5")
    with h5py.File(to / "result.h5", "r+") as f:
        change(f)
    return to / "result.h5"


def replace_dataset(f, name, values):
    del f[name]
    f.create_dataset(name, data=values)


def one_error_line(done) -> str:
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr[-3000:]
    (line,) = [line for line in done.stderr.splitlines() if line.strip()]
    return line


def chaining_log(out: Path) -> list[str]:
    return [line for line in (out / "decrun.log").read_text().splitlines() if "chained anyway" in line]


@pytest.mark.parametrize("alter, says", [
    (lambda s: s + np.where(np.arange(s.size).reshape(s.shape) == 4, 0.5, 0.0),
     "/mesh/simplices holds vertex indices that are not whole numbers in 1 simplex (e.g. simplex 1: [3.0, 0.5, 2.0]); "
     "refused, not truncated"),
    (lambda s: np.where(np.arange(s.size).reshape(s.shape) == 4, 10 ** 6, s),
     "/mesh/simplices holds vertex indices outside [0, 162) in 1 simplex (e.g. simplex 1: [3, 1000000, 2]; the mesh "
     "has 162 vertices)"),
    (lambda s: np.where(np.arange(s.size).reshape(s.shape) == 4, -1, s),
     "/mesh/simplices holds vertex indices outside [0, 162) in 1 simplex (e.g. simplex 1: [3, -1, 2]; the mesh has 162 "
     "vertices)"),
], ids=["fraction", "beyond the vertices", "negative"])
def test_chained_simplices_that_are_not_vertex_indices_are_refused_naming_mesh_path(decrun_cli, tmp_path, alter, says):
    source = run_dir(decrun_cli, tmp_path, "app=smoothing", "mesh.subdiv=2", "app.steps=2")
    altered = altered_copy(source, tmp_path / "altered", lambda f: replace_dataset(
        f, "mesh/simplices", alter(f["mesh/simplices"][()].astype(np.float64 if "whole" in says else np.int64))))
    line = one_error_line(decrun_cli("app=smoothing", "app.steps=1", "mesh=result", f"mesh.path={altered}",
                                     "figures=false"))
    assert line.startswith(f"error: mesh.path='{altered}' ({altered}): {says}") and "chain another run's result" in line
    assert decrun_cli("app=smoothing", "app.steps=1", "mesh=result", f"mesh.path={source}",  # the fix: another result
                      "figures=false").returncode == 0


def test_whole_simplices_stored_as_floats_are_used(decrun_cli, tmp_path):
    source = run_dir(decrun_cli, tmp_path, "app=smoothing", "mesh.subdiv=2", "app.steps=2")
    altered = altered_copy(source, tmp_path / "altered", lambda f: replace_dataset(
        f, "mesh/simplices", f["mesh/simplices"][()].astype(np.float64)))
    out = run_dir(decrun_cli, tmp_path, "app=smoothing", "app.steps=1", "mesh=result", f"mesh.path={altered}")
    np.testing.assert_array_equal(read_result(out / "result.h5").mesh["simplices"],
                                  read_result(source / "result.h5").mesh["simplices"])


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    """A vector_field run (its ``omega``) and a copy of it with NaN in omega."""
    import subprocess
    import sys

    root = tmp_path_factory.mktemp("designed")
    done = subprocess.run([sys.executable, "-m", "decrun", "app=vector_field", "mesh.subdiv=2", "mesh.noise=0",
                           "figures=false", f"hydra.run.dir={root / 'run'}"], cwd=root, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr

    def nan(f):
        omega = f["fields/omega"][()]
        omega[[3, 7]] = np.nan
        f["fields/omega"][...] = omega

    return root / "run", altered_copy(root / "run", root / "nan", nan)


def test_a_chained_field_with_nan_is_refused_naming_mesh_field_and_the_hint_runs(decrun_cli, tmp_path, designed):
    _, nan = designed
    args = ["app=fluid", "mesh=result", f"mesh.path={nan}", "app.steps=2", "app.animation=false", "figures=false"]
    line = one_error_line(decrun_cli(*args, "app.initial=mesh_field", "mesh.field=omega"))
    assert line == (f"error: mesh.field=omega: {nan} holds NaN or ±inf in it on 2 edges (e.g. edge 3: the source run "
                    "diverged?); chain a finite field, or none (`mesh.field=''`, with app=fluid also "
                    "`app.initial=random`)"), line
    done = decrun_cli(*args, "app.initial=random", "mesh.field=''")
    assert done.returncode == 0, done.stderr


def test_a_decomposed_input_with_nan_is_refused_naming_app_input_field(decrun_cli, tmp_path):
    source = run_dir(decrun_cli, tmp_path, "app=hodge", "mesh.subdiv=2", "app.input=random")

    def nan(f):
        omega = f["fields/omega"][()]
        omega[5] = np.inf
        f["fields/omega"][...] = omega

    altered = altered_copy(source, tmp_path / "altered", nan)
    args = ["app=hodge", "mesh.subdiv=2", "figures=false"]
    line = one_error_line(decrun_cli(*args, "app.input=result", f"app.input_path={altered}"))
    assert line == (f"error: app.input_field: 'omega' in {altered} holds NaN or ±inf on 1 1-simplices (e.g. [5]: the "
                    "source run diverged?); decompose a finite field, e.g. `app.input=random`"), line
    assert decrun_cli(*args, "app.input=random").returncode == 0


def interrupted(f):
    """As ``abort`` marks a run stopped by SIGTERM (status interrupted, complete false)."""
    f.attrs["complete"] = False
    f.attrs["status"] = "interrupted"


def test_chaining_from_an_incomplete_result_warns_once_and_says_it_in_a_metric(decrun_cli, tmp_path):
    source = run_dir(decrun_cli, tmp_path, "app=smoothing", "mesh.subdiv=2", "app.steps=2")
    complete = run_dir(decrun_cli, tmp_path, "app=smoothing", "app.steps=1", "mesh=result", f"mesh.path={source}")
    assert "chained_result_status" not in json.loads((complete / "metrics.json").read_text())
    assert chaining_log(complete) == []

    stopped = altered_copy(source, tmp_path / "stopped", interrupted)
    out = run_dir(decrun_cli, tmp_path, "app=smoothing", "app.steps=1", "mesh=result", f"mesh.path={stopped}")
    assert json.loads((out / "metrics.json").read_text())["chained_result_status"] == "interrupted"
    (line,) = chaining_log(out)
    assert line.endswith(f"mesh.path='{stopped}': the result is not complete (status interrupted, 3 steps "
                         "recorded); chained anyway, metric chained_result_status=interrupted"), line


def test_decomposing_an_incomplete_result_warns_once_and_says_it_in_a_metric(decrun_cli, tmp_path):
    source = run_dir(decrun_cli, tmp_path, "app=hodge", "mesh.subdiv=2", "app.input=random")
    stopped = altered_copy(source, tmp_path / "stopped", interrupted)
    out = run_dir(decrun_cli, tmp_path, "app=hodge", "mesh.subdiv=2", "app.input=result", f"app.input_path={stopped}")
    assert json.loads((out / "metrics.json").read_text())["chained_result_status"] == "interrupted"
    (line,) = chaining_log(out)
    assert line.endswith(f"app.input_path='{stopped}': the result is not complete (status interrupted, 0 steps "
                         "recorded); chained anyway, metric chained_result_status=interrupted"), line


# ---------------------------------------------------------------------------------------
# exports hold every field: sets as vertex cells or indicators, eigenvectors by column,
# arrays with no place on the mesh as field data; what a format cannot hold is one log line
# ---------------------------------------------------------------------------------------

def export_log(out: Path, export: str) -> list[str]:
    return [line for line in (out / "decrun.log").read_text().splitlines() if f"export={export}:" in line]


def test_vtu_holds_every_field_of_a_designed_field(decrun_cli, tmp_path):
    out = run_dir(decrun_cli, tmp_path, "app=vector_field", "mesh.subdiv=2", "mesh.noise=0",
                  "app.strokes=[{points:[[1,0,0.1],[0.7,0.7,0.1]]}]", "app.vortices=[{point:[0,0,1],curl:1.0}]",
                  "app.region_normal=[0,0,1]", "export=vtu")
    stored = read_result(out / "result.h5")
    mesh = meshio.read(out / "result.vtu")
    assert [block.type for block in mesh.cells] == ["triangle", "line", "vertex"]
    top = 0
    held = set(mesh.point_data) | set(mesh.cell_data) | set(mesh.field_data)
    assert held == set(stored.fields), set(stored.fields) - held  # all 15, none left out
    assert export_log(out, "vtu") == []
    vertex_cells = mesh.cells[2].data[:, 0]
    for name, along in (("singular_vertices", None), ("source_vertices", "source_divergences")):
        on = ~np.isnan(mesh.cell_data[name][2])  # the vertex cells of this set
        np.testing.assert_array_equal(vertex_cells[on], stored.fields[name])
        assert np.isnan(mesh.cell_data[name][top]).all()
        if along:
            np.testing.assert_array_equal(mesh.cell_data[along][2][on], stored.fields[along])
    for name in ("singular_faces", "vortex_faces", "stroke_faces", "region_faces"):  # 1 on the set's triangles
        assert len(stored.fields[name]) > 0
        np.testing.assert_array_equal(np.flatnonzero(mesh.cell_data[name][top] == 1), np.sort(stored.fields[name]))
    vectors = mesh.cell_data["stroke_vectors"][top]
    np.testing.assert_array_equal(vectors[stored.fields["stroke_faces"]], stored.fields["stroke_vectors"])
    assert np.isnan(np.delete(vectors, stored.fields["stroke_faces"], axis=0)).all()
    for name in ("cluster_positions", "cluster_indices"):  # points off the vertices: field data, every digit
        np.testing.assert_array_equal(mesh.field_data[name], stored.fields[name])
    np.testing.assert_array_equal(mesh.cell_data["omega_without_strokes"][1], stored.fields["omega_without_strokes"])


@pytest.mark.parametrize("degree", [0, 1])
def test_vtu_of_a_spectrum_names_each_eigenvector_and_keeps_the_eigenvalues(decrun_cli, tmp_path, degree):
    out = run_dir(decrun_cli, tmp_path, "app=spectrum", "mesh.subdiv=1", f"app.degree={degree}", "app.count=4",
                  "export=vtu")
    stored = read_result(out / "result.h5")
    mesh = meshio.read(out / "result.vtu")
    np.testing.assert_array_equal(mesh.field_data["eigenvalues"], stored.fields["eigenvalues"])
    for j in range(4):
        values = mesh.point_data[f"eigenforms_{j}"] if degree == 0 else mesh.cell_data[f"eigenforms_{j}"][1]
        np.testing.assert_array_equal(values, stored.fields["eigenforms"][:, j])
    assert "eigenforms" not in mesh.point_data and "eigenforms" not in mesh.cell_data


@pytest.mark.parametrize("mesh_args, blocks", [(["mesh.subdiv=1"], ["triangle", "line"]),
                                               (["mesh=box", "mesh.cells=2"], ["tetra", "triangle", "line"])])
def test_vtu_holds_a_models_fields_by_their_declared_names(decrun_cli, tmp_path, mesh_args, blocks):
    out = run_dir(decrun_cli, tmp_path, "app=heat", *mesh_args, "app.t_end=0.002", "+app.fields.A={form:1,initial:[y,x,1]}",
                  "+app.fields.B={form:2,initial:1}", "+app.fields.r={form:dual0,initial:x}", "export=vtu")
    stored = read_result(out / "result.h5")
    mesh = meshio.read(out / "result.vtu")
    assert [block.type for block in mesh.cells] == blocks
    np.testing.assert_array_equal(mesh.point_data["u"], stored.fields["u"])  # primal 0-form: per vertex
    np.testing.assert_array_equal(mesh.cell_data["r"][0], stored.fields["r"])  # dual 0-form: per top simplex
    np.testing.assert_array_equal(mesh.cell_data["A"][blocks.index("line")], stored.fields["A"])  # 1-form: per edge
    np.testing.assert_array_equal(mesh.cell_data["B"][blocks.index("triangle")], stored.fields["B"])  # per triangle


def test_xdmf_of_a_smoothing_is_the_final_state_on_its_cells_and_says_what_it_cannot_hold(decrun_cli, tmp_path):
    out = run_dir(decrun_cli, tmp_path, "app=smoothing", "mesh.subdiv=2", "app.steps=3", "export=xdmf")
    stored = read_result(out / "result.h5")
    with meshio.xdmf.TimeSeriesReader(out / "series.xdmf") as reader:
        _, cells = reader.read_points_cells()
        assert reader.num_steps == 1
        t, point_data, cell_data = reader.read_data(0)
    assert t == stored.series["step"][-1] == 3
    assert cell_data == {}  # the oriented faces are the cells, not a cell array
    np.testing.assert_array_equal(point_data["vertices_final"], stored.fields["vertices_final"])
    (line,) = [line for line in export_log(out, "xdmf") if "cannot hold" in line]
    assert line.endswith("series.xdmf cannot hold series area, series distortion, series roughness, series volume; "
                         "they are in result.h5"), line
    (line,) = [line for line in export_log(out, "xdmf") if "one step" in line]
    assert line.endswith("`app.record_vertices=true` records the positions at every step"), line


def test_xdmf_of_a_smoothing_with_recorded_vertices_holds_every_step(decrun_cli, tmp_path):
    """With app.record_vertices=true the flow is a time series: step n's positions, the input
    at step 0 and the smoothed mesh at the end, on the input's triangles (the cells)."""
    out = run_dir(decrun_cli, tmp_path, "app=smoothing", "mesh.subdiv=2", "app.steps=3", "app.record_vertices=true",
                  "export=xdmf")
    stored = read_result(out / "result.h5")
    positions = stored.series["vertices"]
    assert positions.shape == (4, len(stored.mesh["vertices"]), 3)
    np.testing.assert_array_equal(positions[0], stored.fields["vertices_initial"])
    np.testing.assert_array_equal(positions[-1], stored.fields["vertices_final"])
    assert np.abs(positions[1] - positions[0]).max() > 0  # the mesh moves step by step
    with meshio.xdmf.TimeSeriesReader(out / "series.xdmf") as reader:
        _, cells = reader.read_points_cells()
        assert reader.num_steps == 4 and [block.type for block in cells] == ["triangle"]
        np.testing.assert_array_equal(cells[0].data, stored.mesh["simplices"])
        for i in range(4):
            t, point_data, cell_data = reader.read_data(i)
            assert t == stored.series["step"][i] == i and cell_data == {}
            np.testing.assert_array_equal(point_data["vertices"], positions[i])
    (line,) = [line for line in export_log(out, "xdmf") if "cannot hold" in line]
    assert "faces" not in line, line  # the connectivity is the cells


def test_ply_and_obj_say_in_one_line_what_they_leave_out(decrun_cli, tmp_path):
    args = ("app=smoothing", "app.steps=1", "export=ply", "export.field=displacement", "figures=false")
    proc = decrun_cli(*args)
    assert proc.returncode == 0 and "Warning" not in proc.stderr, proc.stderr  # no writer's stray cast warning
    (out,) = tmp_path.glob("outputs/runs/*")
    (line,) = export_log(out, "ply")
    assert line.endswith("result.ply (the triangles, colours of displacement) cannot hold vertices_initial, "
                         "vertices_final; they are in result.h5 (export=vtu holds every field)"), line  # faces: the cells


@pytest.mark.parametrize("overrides", [
    ["app=parametrization", "mesh.subdiv=2", "mesh.noise=0", "mesh.hole_balls=[[0,0,1,0.6]]"],
    ["app=smoothing", "mesh.subdiv=1", "app.steps=1"],
    ["app=spectrum", "mesh.subdiv=1", "app.degree=1", "app.count=3"],
    ["app=vector_field", "mesh.subdiv=2", "mesh.noise=0", "app.strokes=[{points:[[1,0,0.1],[0.7,0.7,0.1]]}]",
     "app.vortices=[{point:[0,0,1],curl:1.0}]", "app.region_normal=[0,0,1]"],
    ["app=hodge", "mesh=box", "mesh.cells=2", "operator=whitney", "app.input=random", "app.degree=2"],
    ["app=fluid", "mesh.subdiv=1", "mesh.noise=0", "app.steps=1", "app.animation=false"],
    ["app=heat", "mesh.subdiv=1", "app.t_end=0.002", "+app.fields.A={form:1,initial:[y,x,1]}",
     "+app.fields.r={form:dual0,initial:x}"],
], ids=lambda overrides: overrides[0])
def test_each_app_writes_the_fields_it_declares_where_it_declares_them(overrides):
    """The declarations the exports are checked against before any work (App.outputs) are
    what the app writes: every field declared (a model's definitions aside), each with the
    rows of its place."""
    from decrun.apps.base import FieldOnEdges
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    done = run_experiment(compose_config([*overrides, "figures=false"]))
    app, K, fields = done.experiment.app, done.complex, done.result.fields
    outputs = app.outputs()
    if app.outputs_complete:
        assert set(fields) <= set(outputs), set(fields) - set(outputs)
    for name, output in outputs.items():
        if name not in fields:
            continue
        value = fields[name]
        array = np.asarray(value.values if isinstance(value, FieldOnEdges) else value)
        k = output.simplex_dimension(K.dim)
        if k is not None:
            assert len(array) == K.num_simplices(k), (name, output, array.shape)
        elif output.on in ("vertex_set", "top_set"):
            top = K.num_simplices(0 if output.on == "vertex_set" else K.dim)
            assert array.ndim == 1 and array.dtype.kind in "iu" and ((0 <= array) & (array < top)).all(), name
        elif output.on.startswith("along:"):
            assert len(array) == len(fields[output.on.partition(":")[2]]), name
        elif output.on == "connectivity":
            assert array.shape == done.mesh.simplices.shape, name
        if output.width is not None and output.on != "global":
            assert (array.shape[1] if array.ndim == 2 else 1) == output.width, (name, output, array.shape)


def test_a_sweep_says_which_jobs_exports_failed_and_keeps_their_rows(decrun_cli, tmp_path):
    args = ["-m", "app=heat", "mesh.subdiv=1", "app.t_end=0.002,0.004", "export=ply", "figures=false"]
    done = decrun_cli(*args, "export.field=nothing")
    assert done.returncode == 1 and "(0 not ok, 2 export failed)" in done.stdout, done.stdout
    assert "decrun: job 1 export failed: export.field: 'nothing'" in done.stderr
    (table,) = tmp_path.glob("outputs/sweeps/*/metrics.csv")
    import pandas as pd

    rows = pd.read_csv(table)
    assert list(rows["status"]) == ["ok", "ok"] and rows["mass"].notna().all() and rows["export_error"].notna().all()
    done = decrun_cli(*args, "export.field=auto")
    assert done.returncode == 0 and "export failed" not in done.stdout, done.stderr


def test_a_rerun_leaves_no_export_file_of_the_earlier_run(decrun_cli, tmp_path):
    """A rerun into a finished run's directory removes the export files the earlier run wrote
    (they hold the earlier result) before its own export writes: a 3-step result keeps no
    10-step result.vtu beside it, with export=none too."""
    args = ("app=smoothing", "mesh.subdiv=1", "figures=false", "hydra.run.dir=run")
    assert decrun_cli(*args, "app.steps=10", "export=vtu").returncode == 0
    run = tmp_path / "run"
    again = decrun_cli(*args, "app.steps=3", "export=ply", "export.field=displacement")
    assert again.returncode == 0, again.stderr
    assert not (run / "result.vtu").exists() and (run / "result.ply").is_file()
    assert "removed the earlier run's export files result.vtu (they do not hold this result)" in again.stderr
    np.testing.assert_allclose(meshio.read(run / "result.ply").point_data["displacement"],
                               read_result(run / "result.h5").fields["displacement"])
    assert decrun_cli(*args, "app.steps=2").returncode == 0
    assert not (run / "result.ply").exists() and (run / "result.h5").is_file()
