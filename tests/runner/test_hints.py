"""Every error hint is the CLI override that fixes it: each case below makes ``decrun`` fail,
takes every override the message names in backticks, runs the same config with it and
checks that the run now works. A second test finds every backticked override in decrun's
sources and checks that a case here produces it (so a new hint comes with its case)."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import meshio
import numpy as np
import pytest

from decrun.core.primitives import kuhn_cube
from decrun.errors import DecrunError
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment

SOURCES = Path(__file__).resolve().parents[2] / "decrun"
#: `key=value` in single backticks (not the ``double`` ones of docstrings)
OVERRIDE = re.compile(r"(?<!`)`([A-Za-z_][\w./]*=[^`\s]+)`(?!`)")


def write_obj(path: Path, vertices, faces) -> str:
    lines = [f"v {x} {y} {z}" for x, y, z in vertices] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


SQUARE = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 0.2]]
FAN = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]


def files(tmp: Path) -> dict[str, str]:
    """Bad mesh files, each with one defect."""
    V, T = kuhn_cube(2)
    tets = tmp / "cube.vtu"
    meshio.write(str(tets), meshio.Mesh(V, [("tetra", T)]))
    bowtie_v = SQUARE + [[2, 0.5, 0.5], [2, 1, 0.5], [2, 0.5, 1]]
    return {
        "unreferenced": write_obj(tmp / "unused.obj", SQUARE + [[5, 5, 5]], FAN),
        "flipped": write_obj(tmp / "flipped.obj", SQUARE, FAN[:3] + [[0, 3, 4]]),
        "bowtie": write_obj(tmp / "bowtie.obj", bowtie_v, FAN + [[2, 5, 6], [2, 6, 7]]),
        "duplicate": write_obj(tmp / "duplicate.obj", SQUARE, FAN + [FAN[0]]),
        "degenerate": write_obj(tmp / "degenerate.obj", SQUARE + [[2, 0, 0]], FAN + [[0, 1, 5]]),
        "tets": str(tets),
        "result": _result_file(tmp),
        "model_result": _model_result_file(tmp),
        "two_pieces": _two_pieces(tmp),
        # issue 34.6: mesh.normalize=true was offered at 1e-300 and then found "all vertices coincide"
        "tiny": write_obj(tmp / "tiny.obj", np.asarray(OCTAHEDRON) * 1e-300, OCTAHEDRON_FACES),
    }


OCTAHEDRON = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
OCTAHEDRON_FACES = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]


def _two_pieces(tmp: Path) -> str:
    """A grid patch (grid_triangles(5): a disk) and, apart from it, the 4-triangle pyramid fan."""
    from decrun.core.primitives import grid_triangles

    V, F = grid_triangles(5)
    V3 = np.column_stack([V, np.zeros(len(V))])
    fan = np.asarray(SQUARE, dtype=float) + [3.0, 0.0, 0.0]
    return write_obj(tmp / "two_pieces.obj", np.vstack([V3, fan]), np.vstack([F, np.asarray(FAN) + len(V)]))


def _result_file(tmp: Path) -> str:
    """A finished run's result.h5 (a small spectrum run) for mesh=result."""
    from decrun.runner.job.run import write

    write(run_experiment(compose_config(["mesh.subdiv=1", "app=spectrum", "figures=false"])), tmp)
    return str(tmp / "result.h5")


def _model_result_file(tmp: Path) -> str:
    """A finished heat-method run's result.h5 (fields delta, u, phi, X, distance) for chaining."""
    from decrun.runner.job.run import write

    (tmp / "model").mkdir(exist_ok=True)
    write(run_experiment(compose_config(["app=heat_geodesics", "mesh.subdiv=1", "figures=false"])), tmp / "model")
    return str(tmp / "model" / "result.h5")


#: name → (overrides that fail, the overrides the hint must name)
CASES = {
    # the declarative models: an integrator that cannot take the model names one that can. Implicit
    # Euler steps a nonlinear term by Newton, but a number computed from u (mean(u)) couples all
    # its values: a dense Jacobian, refused; bdf/radau have no sparse Jacobian pattern through it
    "model_implicit_on_a_dense_jacobian": (["app=heat", "mesh.subdiv=2", "app.integrator=implicit_euler",
                                            "app.equations=['dt(u) = k*laplacian(u) - u*mean(u)']"],
                                           ["app.integrator=rk4"]),
    "model_bdf_without_a_sparse_pattern": (["app=heat", "mesh.subdiv=2", "app.integrator=bdf",
                                            "app.equations=['dt(u) = k*laplacian(u) - u*mean(u)']"],
                                           ["app.integrator=imex", "app.integrator=rk4"]),
    "model_symplectic_without_pairs": (["app=heat", "mesh.subdiv=2", "app.integrator=symplectic"],
                                       ["app.integrator=rk4", "app.integrator=crank_nicolson"]),
    "model_result_field_not_chained": (["mesh=result", "mesh.path={model_result}", "mesh.field=phi", "app=heat",
                                        "app.fields.u.initial=result:distance"], ["mesh.field=distance"]),
    # issue 27.4: a mesh of several pieces names the post step that keeps the largest
    "parametrization_of_two_pieces": (["mesh=file", "mesh.path={two_pieces}", "app=parametrization"],
                                      ["mesh.largest_component=true"]),
    "fluid_on_two_pieces": (["mesh=file", "mesh.path={two_pieces}", "app=fluid", "app.steps=2", "figures=false"],
                            ["mesh.largest_component=true"]),
    # issue 34 item 8: the default source and sink landed on different pieces (residual 0.13, status ok)
    "vector_field_on_two_pieces": (["mesh=file", "mesh.path={two_pieces}", "app=vector_field", "figures=false"],
                                   ["mesh.largest_component=true"]),
    "rescale_volume_on_open_mesh": (["mesh=grid", "app.rescale=volume", "app.steps=1"], ["app.rescale=auto"]),
    "critical_dt_off_without_dt": (["mesh.subdiv=1", "app.critical_dt=false", "app.scheme=explicit",
                                    "app.steps=20"], ["app.dt=", "app.critical_dt=true"]),
    "no_critical_step_on_a_scan": (["mesh=sample", "operator=circumcentric", "app.scheme=explicit", "app.steps=1"],
                                   ["operator=mixed_area"]),
    "spd_solver_for_unsymmetric_system": (["app=parametrization", "mesh=sphere_cap", "solver=cg"],
                                          ["solver=iterative", "solver=direct", "solver=pardiso", "app.border=circle"]),
    "nondiagonal_star": (["app=vector_field", "mesh.subdiv=2", "operator=whitney"],
                         ["operator.lumped=true", "operator=circumcentric"]),
    "zero_form_only_star": (["app=vector_field", "mesh.subdiv=2", "operator=intrinsic_delaunay"],
                            ["operator=mixed_area", "operator=circumcentric"]),
    "zero_form_only_star_for_hodge": (["app=hodge", "mesh=torus", "operator=intrinsic_delaunay"],
                                      ["operator=whitney"]),
    "precomputed_strokes_without_constraints": (
        ["app=vector_field", "mesh.subdiv=2", "app.sources=[]", "app.strokes=[{points:[[1,0,0],[0,1,0]]}]"],
        ["app.stroke_magnitude=fixed"]),
    "hodge_zero_star1": (["app=hodge", "mesh=torus", "operator=mixed_area"],
                         ["operator=whitney", "mesh.noise=0.05", "mesh.refine=isotropic"]),
    "hodge_nonpositive_star1_with_cg": (["app=hodge", "mesh=grid", "mesh.nx=8", "mesh.ny=8",
                                         "operator=circumcentric", "solver=cg"],
                                        ["operator=whitney", "operator.lumped=true"]),
    "hodge_negative_star1_with_cg": (["app=hodge", "mesh=grid", "mesh.nx=8", "mesh.ny=8", "mesh.noise=0.1",
                                      "operator=circumcentric", "solver=cg"], ["solver=iterative"]),
    "hodge_galerkin_with_cg": (["app=hodge", "mesh=torus", "mesh.noise=0.05", "operator=whitney", "solver=cg"],
                               ["solver=iterative", "solver=direct", "operator.lumped=true"]),
    "iterative_ilu_under_minres": (["app.steps=1", "solver=iterative", "solver.method=minres",
                                    "solver.preconditioner=ilu"], ["solver.preconditioner=jacobi"]),
    "filled_holes_under_a_free_border": (["app=parametrization", "mesh=sphere_cap", "app.border=free",
                                          "app.holes=fill"], ["app.holes=auto"]),
    "parametrization_of_a_closed_mesh": (["app=parametrization", "mesh.noise=0"], ["mesh.hole_balls="]),
    # a hole that removes nothing was silent (the parametrization ran on a closed mesh minus one cap)
    # a run's result.h5 given to mesh=file got "unsupported file extension '.h5'" and a list of formats
    "result_file_as_a_mesh_file": (["mesh=file", "mesh.path={result}", "app=spectrum"], ["mesh=result", "mesh.path="]),
    "hole_ball_off_the_surface": (["app=parametrization", "mesh.noise=0", "mesh.subdiv=2",
                                   "mesh.hole_balls=[[0,0,1,0.5],[0,0,3,0.5]]"], ["mesh.hole_balls="]),
    "hole_box_off_the_surface": (["app=parametrization", "mesh=planar", "mesh.hole_boxes=[[3,3,4,4]]"],
                                 ["mesh.hole_boxes="]),
    "up_axis_of_a_planar_mesh": (["mesh=planar", "mesh.up_axis=y", "app.steps=1"], ["mesh.up_axis=z"]),
    "file_mesh_at_1e-300": (["mesh=file", "mesh.path={tiny}"], ["mesh.normalize=true"]),
    "file_with_unreferenced_vertex": (["mesh=file", "mesh.path={unreferenced}", "app.steps=1"], ["mesh.repair=true"]),
    "file_with_flipped_triangle": (["mesh=file", "mesh.path={flipped}", "app.steps=1"], ["mesh.orient=fix"]),
    "file_with_bowtie_vertex": (["mesh=file", "mesh.path={bowtie}", "app.steps=1"], ["mesh.repair=true"]),
    "file_with_duplicate_triangle": (["mesh=file", "mesh.path={duplicate}", "app.steps=1"], ["mesh.repair=true"]),
    "file_with_zero_area_triangle": (["mesh=file", "mesh.path={degenerate}", "app.steps=1"], ["mesh.repair=true"]),
    "repair_of_tetrahedra": (["mesh=file", "mesh.path={tets}", "app=spectrum", "mesh.repair=true"],
                             ["mesh.repair=false"]),
    "mixed_area_refusing_tetrahedra": (["mesh=file", "mesh.path={tets}", "app=spectrum", "operator=mixed_area",
                                        "operator.tetrahedra=error"], ["operator=barycentric", "operator=circumcentric"]),
    "intrinsic_delaunay_on_tetrahedra": (["mesh=file", "mesh.path={tets}", "app=spectrum",
                                          "operator=intrinsic_delaunay"], ["operator=whitney", "operator=circumcentric"]),
    "surface_app_on_tetrahedra": (["mesh=file", "mesh.path={tets}", "app=smoothing"], ["app=spectrum", "mesh=icosphere"]),
    "spectrum_degree_above_the_dimension": (["mesh.subdiv=1", "app=spectrum", "app.degree=3"], ["app.degree=2"]),
    "spectrum_count_above_the_size": (["mesh.subdiv=1", "app=spectrum", "app.count=50"], ["app.count=10"]),
    "spectrum_analytic_shape_not_found": (["mesh.subdiv=1", "app=spectrum", "app.analytic=box"],
                                          ["app.analytic=auto"]),
    "spectrum_degenerate_star": (["mesh=file", "mesh.path={tets}", "app=spectrum", "app.degree=2"],
                                 ["operator=whitney"]),
    # issue 25 item 4: a negative mass ⋆_k gave negative eigenvalues (−17.0 at mesh.cells=10) silently
    "spectrum_indefinite_mass": (["app=spectrum", "mesh=box", "mesh.jitter=0.2", "operator=circumcentric",
                                  "app.degree=1"], ["operator=whitney"]),
    "spectrum_indefinite_mass_of_functions": (["mesh=bunny", "app=spectrum", "operator=circumcentric"],
                                              ["operator=mixed_area"]),
    # issue 34 item 7: a negative stiffness ⋆1 inside Δ2 gave an indefinite operator, status ok
    "spectrum_negative_stiffness_star": (["app=spectrum", "mesh=grid", "mesh.nx=8", "mesh.ny=8", "mesh.noise=0.3",
                                          "app.degree=2", "figures=false"], ["operator=whitney"]),
    "spectrum_galerkin_with_cg": (["mesh.subdiv=2", "mesh.noise=0", "app=spectrum", "app.degree=1",
                                   "operator=whitney", "solver=cg"], ["solver=direct"]),
    "tetrahedralize_unknown_surface": (["mesh=tetrahedralize", "mesh.surface=nowhere", "app=spectrum"],
                                       ["mesh.surface=icosphere"]),
    "hodge_zero_star1_on_tetrahedra": (["app=hodge", "mesh=box", "mesh.cells=3", "app.input=random", "operator=circumcentric"],
                                       ["operator=whitney"]),
    "hodge_singular_analytic_field": (["app=hodge", "mesh=box", "mesh.cells=3", "operator=whitney", "app.analytic=mixed"],
                                      ["app.analytic=frame", "app.input=random", "app.analytic=gradient"]),
    "hodge_frame_has_no_vector": (["app=hodge", "mesh.subdiv=1", "app.vector=[1.0,0.0,0.0]"],
                                  ["app.analytic=gradient"]),
    "export_unknown_colormap": (["mesh.subdiv=1", "app=smoothing", "app.steps=1", "export=ply", "export.colormap=no_such_map"],
                                ["export.colormap=viridis"]),
    # an export the app's declared fields cannot feed: refused with the config, before the mesh
    "export_obj_without_uv": (["mesh.subdiv=1", "app=spectrum", "export=obj"], ["export=vtu"]),
    "export_ply_missing_field": (["mesh.subdiv=1", "app=smoothing", "app.steps=1", "export=ply",
                                  "export.field=nothing"], ["export.field=auto"]),
    "export_ply_auto_without_a_scalar": (["mesh.subdiv=1", "app=spectrum", "export=ply"],
                                         ["export.field=eigenforms:0"]),
    "export_ply_column_of_a_scalar": (["mesh.subdiv=1", "app=smoothing", "app.steps=1", "export=ply",
                                       "export.field=displacement:1"], ["export.field=displacement"]),
    "result_vertices_field_missing": (["mesh=result", "mesh.path={result}", "mesh.vertices=nowhere", "app=spectrum"],
                                      ["mesh.vertices=mesh"]),
    "hodge_degree_two_on_a_surface": (["app=hodge", "mesh.subdiv=2", "mesh.noise=0", "app.degree=2"],
                                      ["app.degree=1"]),
    # a model's saddle-point system (Darcy's mixed form) is indefinite: Cholesky cannot take it
    "model_system_with_an_spd_solver": (["app=darcy", "solver=cholmod", "figures=false"], ["solver=direct"]),
    "model_plot_arrows_not_a_vector_field": (["app=darcy", "app.plots.flow.arrows=pressure", "figures=false"],
                                             ["app.plots.flow.arrows=velocity"]),
}

#: backticked overrides in the sources that no CLI run can reach, and why
UNREACHABLE = {
    "app.stability_check=false": "the explicit check's last resort when neither the eigen-solve nor its Gershgorin "
                                 "bound gives an estimate (a finite Jacobian always has a Gershgorin bound); "
                                 "tests/apps/test_model_stability.py runs the override on runs it would refuse",
    "mesh.max_volume=": "the tetrahedron-count refusal's fix makes millions of tetrahedra (too slow for a hint case): "
                        "tests/runner/mesh/test_volumes.py runs it under a lowered mesh.max_tetrahedra",
    "mesh.max_tetrahedra=": "see mesh.max_volume=; tests/runner/mesh/test_volumes.py runs this fix",
    "app.weights=uniform": "zero diagonal of the cot rows: needs cot weights that cancel exactly; the same "
                           "message's app.weights=mean_value is positive by construction (tested in methods)",
    "app.weights=mean_value": "see app.weights=uniform",
    "mesh.hole_pieces=all": "a log line's hint (the cut dropped pieces), not an error's: "
                            "tests/runner/mesh/test_mesh_cut.py runs it and counts the pieces kept",
    "mesh.clean=false": "a log line's hint (mesh.clean dropped pieces): tests/runner/mesh/test_mesh_cut.py runs it",
    "mesh.largest_component=false": "a log line's hint of the step the user asked for; it is the default",
    "app.record_vertices=true": "a log line's hint (export=xdmf wrote one step of a smoothing run): "
                                "tests/runner/results/test_export_and_chaining.py runs it and reads every step back",
    "mesh.field=''": "a chained field with NaN: tests/runner/results/test_export_and_chaining.py runs this fix",
    "app.initial=random": "see mesh.field=''",
    "hydra.searchpath=": "a hint of the command line (no config directory has app=<name>), before any config: "
                         "tests/runner/test_model_day_one.py runs it through the real decrun command",
}


def run(overrides):
    result = run_experiment(compose_config(overrides)).result
    return result


def hinted(message: str) -> list[str]:
    return OVERRIDE.findall(message)


@pytest.mark.parametrize("name", sorted(CASES))
def test_each_hint_is_an_override_that_fixes_the_run(name, tmp_path):
    failing, expected = CASES[name]
    paths = files(tmp_path)
    failing = [re.sub(r"\{(\w+)\}$", lambda m: paths[m.group(1)], item) for item in failing]
    with pytest.raises(DecrunError) as info:
        run(failing)
    suggested = hinted(str(info.value))
    for prefix in expected:
        assert any(s.startswith(prefix) for s in suggested), f"{prefix!r} not hinted in: {info.value}"
    # "`a=1` with `b=2`" is one fix of two overrides, applied together
    together = re.findall(r"`([^`\s]+=[^`\s]+)` with `([^`\s]+=[^`\s]+)`", str(info.value))
    fixes = [list(pair) for pair in together]
    fixes += [[s] for s in suggested if not any(s in pair for pair in together)]
    for fix in fixes:
        if fix == ["solver=pardiso"] and importlib.util.find_spec("pypardiso") is None:
            continue  # the optional extra is not installed here
        keys = {override.split("=", 1)[0] for override in fix}
        # a new group choice (`mesh=icosphere`) drops the old choice's options (mesh.path=...)
        fixed = [item for item in failing
                 if not any(item.split("=", 1)[0] == key or item.startswith(key + ".") for key in keys)] + fix
        result = run(fixed)
        assert result.metrics["status"] == "ok", (fix, result.metrics)


def test_every_hint_in_the_sources_has_a_case():
    tested = {prefix for _, expected in CASES.values() for prefix in expected}
    missing = []
    for path in SOURCES.rglob("*.py"):
        for override in hinted(path.read_text()):
            template = override.split("{", 1)[0]  # an f-string override: its fixed prefix
            if not any(template.startswith(t) or t.startswith(template) for t in tested | set(UNREACHABLE)):
                missing.append(f"{path.relative_to(SOURCES.parent)}: `{override}`")
    assert not missing, "hints without a case in tests/runner/test_hints.py:\n" + "\n".join(missing)


def test_python_hints_stay_for_python_callers_and_become_cli_overrides_in_the_runner(tmp_path):
    from decrun.core.complex import SimplicialComplex
    from decrun.errors import UnreferencedVertexError

    with pytest.raises(UnreferencedVertexError, match="unreferenced='drop'"):
        SimplicialComplex(np.array(SQUARE + [[5, 5, 5]], float), np.array(FAN))
    with pytest.raises(DecrunError) as info:
        run(["mesh=file", f"mesh.path={files(tmp_path)['unreferenced']}"])
    assert "unreferenced='drop'" not in str(info.value) and "`mesh.repair=true`" in str(info.value)


def test_largest_component_keeps_the_largest_piece_and_reports_what_it_dropped(tmp_path):
    """issue 27.4: the 4-triangle fan (5 vertices) is dropped, and the metrics say so."""
    path = files(tmp_path)["two_pieces"]
    metrics = run(["mesh=file", f"mesh.path={path}", "app=parametrization", "mesh.largest_component=true"]).metrics
    from decrun.core.primitives import grid_triangles

    V, F = grid_triangles(5)
    assert metrics["status"] == "ok" and metrics["n_vertices"] == len(V) and metrics["n_faces"] == len(F)
    assert metrics["largest_component_components"] == 2
    assert metrics["largest_component_dropped_vertices"] == 5 and metrics["largest_component_dropped_faces"] == 4
