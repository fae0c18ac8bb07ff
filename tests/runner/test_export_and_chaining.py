"""``export=vtu|xdmf|ply|obj`` (every file read back with meshio and compared with result.h5)
and ``mesh=result`` chaining, through the real CLI."""

from __future__ import annotations

import json
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
    tetra, lines = (block.data for block in mesh.cells)
    assert [block.type for block in mesh.cells] == ["tetra", "line"]
    np.testing.assert_array_equal(tetra, stored.mesh["simplices"])
    np.testing.assert_array_equal(lines, stored.mesh["edges"])
    for name in ("omega", "exact", "coexact", "harmonic"):  # 1-forms on the line block
        np.testing.assert_array_equal(mesh.cell_data[name][1], stored.fields[name])
        assert np.isnan(mesh.cell_data[name][0]).all()
    np.testing.assert_array_equal(mesh.cell_data["omega_vectors"][0], stored.fields["omega_vectors"])
    np.testing.assert_array_equal(mesh.point_data["alpha"], stored.fields["alpha"])


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


def test_export_of_a_missing_field_names_the_fix(decrun_cli, tmp_path):
    done = decrun_cli("app=spectrum", "mesh.subdiv=1", "export=obj", "figures=false")
    assert done.returncode != 0 and "use `export=vtu`" in done.stderr and "Traceback" not in done.stderr
    assert decrun_cli("app=spectrum", "mesh.subdiv=1", "export=vtu", "figures=false").returncode == 0
    done = decrun_cli("app=smoothing", "app.steps=1", "export=ply", "export.field=nothing", "figures=false")
    assert done.returncode != 0 and "use `export.field=auto`" in done.stderr
    assert decrun_cli("app=smoothing", "app.steps=1", "export=ply", "export.field=auto", "figures=false").returncode == 0
    done = decrun_cli("app=spectrum", "mesh.subdiv=1", "export=ply", "export.field=eigenforms:1", "figures=false")
    assert done.returncode == 0, done.stderr


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
    designed = run_dir(decrun_cli, tmp_path, "app=vector_field", "mesh.subdiv=2", "mesh.noise=0")
    out = run_dir(decrun_cli, tmp_path, "app=fluid", "app.initial=mesh_field", "mesh=result",
                  f"mesh.path={designed / 'result.h5'}", "mesh.field=omega", "app.steps=2", "app.animation=false")
    series = read_result(out / "result.h5").series
    omega = read_result(designed / "result.h5").fields["omega"]
    assert np.abs(series["vorticity"][0]).max() > 0 and np.abs(omega).max() > 0
    assert json.loads((out / "metrics.json").read_text())["stable"]


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
