"""Darcy flow in mixed form with Whitney forms (conf/app/darcy.yaml) and what the model language
gained for it: systems of linear equations in several unknowns (``solve(l1 = r1, l2 = r2)``, one
block matrix factorized once), ``border(q)`` (natural border values in a weak form), forms
relative to the mesh dimension (``n``, ``n-1``), ``{flux: [...]}`` initial values and
``flux_field(u)`` (the Whitney / Raviart–Thomas field of a flux).

The mathematics: u = −K∇p, div u = f with u a primal (n−1)-form and p a top form; the block system
[[⋆_{n−1}, −K d_{n−1}ᵀ ⋆_n], [d_{n−1}, 0]] [u; p] = [−K B pb; f] (⋆_{n−1} the Whitney mass matrix).
Exact answers checked here: the lowest-order mixed elements reproduce a linear pressure (constant
velocity) exactly; d u = f per top simplex to round-off; Stokes' theorem for ``border``; the orders
of the pressure and flux errors over three refinements on the square and on the tetrahedral box.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import scipy.sparse as sp

from decrun.errors import DecrunError
from decrun.methods.model.kinds import form_kind
from decrun.methods.model.language import ModelError, parse_equation
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import prepare, run_experiment
from decrun.runner.results import read_result

from cli_processes import decrun

FAST = ["figures=false", "progress=false"]
SQUARE = ["mesh=grid", "mesh.nx=9", "mesh.ny=9"]
BOX = ["mesh=box", "mesh.cells=2"]
PLANAR = ["mesh=planar", "mesh.holes=[]", "mesh.max_area=0.01"]

#: a linear pressure p = 1 + 2x − y + z/2 (K = 2.5): u = −K∇p is constant and f = 0
LINEAR = ["app.constants.K=2.5", 'app.fields.pb.initial="1 + 2*x - y + 0.5*z"',
          'app.fields.p_exact.initial="1 + 2*x - y + 0.5*z"', "app.fields.f.initial=0",
          'app.fields.u_exact.initial={flux: ["-2*K", "K", "-0.5*K"]}']


def run(*overrides: str):
    """The finished in-process run of ``app=darcy`` with ``overrides``."""
    return run_experiment(compose_config(["app=darcy", *overrides, *FAST]))


def orders(errors) -> np.ndarray:
    errors = np.asarray(errors, dtype=float)
    return np.log2(errors[:-1] / errors[1:])


def one_line(text: str) -> str:
    lines = [line for line in text.strip().splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in text, text
    return lines[0]


def system_of(done):
    """The compiled block system (``SystemSolve``) of a finished darcy run."""
    model = done.experiment.app.compiled(done.dec)
    (system,) = [item for what, item in model.order if what == "system"]
    return system


# ---------------------------------------------------------------------------------------------- language
def test_a_solve_of_several_equations_parses_as_one_system_and_keeps_the_commas_of_calls():
    equation = parse_equation("solve(u - inner(a, b)*codifferential(p) = -border(q), d(u) = f)", "app.equations[0]")
    assert equation.kind == "system" and len(equation.pairs) == 2
    assert equation.pairs[0][0].right.left.function == "inner"  # inner(a, b): its comma is not a split
    assert parse_equation("solve(laplacian(u) = f)", "k").kind == "solve"


def test_forms_relative_to_the_mesh_dimension():
    assert form_kind("n-1", "k", 2).degree == 1 and form_kind("n-1", "k", 3).degree == 2
    assert form_kind("n", "k", 3).degree == 3 and form_kind("dualn", "k", 2) == form_kind("dual2", "k", 2)
    with pytest.raises(ModelError, match="form of degree n-3 does not exist on a mesh of dimension 2"):
        form_kind("n-3", "app.fields.u.form", 2)


# ---------------------------------------------------------------------------------------------- exactness
@pytest.mark.parametrize("mesh", [SQUARE, BOX], ids=["square", "box"])
def test_the_block_matrix_is_the_mixed_whitney_saddle_point(mesh):
    """[[⋆_{n−1}, −K d_{n−1}ᵀ ⋆_n], [d_{n−1}, 0]] with Whitney's ⋆ (not symmetric: its second row is
    d u = f as written), and its right side [−K B pb; f] with (B pb)_σ = o_σ·(mean of pb on σ)."""
    done = run(*mesh, "app.constants.K=2.5")
    dec, K = done.dec, done.dec.K
    n = K.dim
    M, d, top = dec.star(n - 1), dec.d(n - 1), dec.star(n)
    assert abs(M - M.T).max() < 1e-14 and (M - sp.diags(M.diagonal())).count_nonzero() > 0  # Galerkin ⋆
    expected = sp.bmat([[M, -2.5 * d.T @ top], [d, None]]).tocsr()
    item = system_of(done)
    assert item.unknowns == ("u", "p")
    difference = abs(item.system.A_full - expected).max()
    assert difference <= 1e-12 * abs(expected).max()
    # the right side: −K B pb with B the outward incidence times the vertex mean on border facets
    outward = d.T @ np.ones(K.num_simplices(n))
    border = np.flatnonzero(outward)
    assert set(np.abs(outward[border])) == {1.0} and len(border) == len(K.border_faces()[0])
    pb = done.experiment.app.compiled(dec).base["pb"]
    mean = pb[K.simplices(n - 1)].mean(axis=1)
    env = {**done.experiment.app.compiled(dec).base}
    rhs = np.concatenate([row(env) for row in item.rows])
    assert np.allclose(rhs[: len(outward)], -2.5 * outward * mean, atol=1e-13)
    assert np.allclose(rhs[len(outward):], env["f"], atol=1e-13)


@pytest.mark.parametrize("mesh", [SQUARE, BOX, PLANAR], ids=["square", "box", "planar"])
def test_a_linear_pressure_is_reproduced_exactly(mesh):
    """u = −K∇p constant lies in the lowest-order Whitney space and p's cell averages in the top
    forms, and the border term is exact for a linear pb: the discrete solution is the exact one
    to round-off (on the Kuhn box, the square and an unstructured Delaunay square alike)."""
    done = run(*mesh, *LINEAR)
    metrics = done.result.metrics
    assert metrics["pressure_l2_error_rel"] < 1e-11 and metrics["flux_l2_error_rel"] < 1e-11, metrics
    velocity = done.result.fields["velocity"]
    expected = -2.5 * np.array([2.0, -1.0, 0.5])[: velocity.shape[1]]
    if done.dec.K.dim == 2 and velocity.shape[1] == 3:
        expected[2] = 0.0  # in the plane z = 0 the normal component carries no flux
    assert np.abs(velocity - expected).max() < 1e-10 * np.abs(expected).max()


@pytest.mark.parametrize("mesh", [SQUARE, BOX], ids=["square", "box"])
def test_the_divergence_holds_per_top_simplex_to_round_off(mesh):
    done = run(*mesh)
    fields = done.result.fields
    d = done.dec.d(done.dec.K.dim - 1)
    f = done.experiment.app.compiled(done.dec).base["f"]
    u = getattr(fields["u"], "values", fields["u"])  # a 1-form on triangles comes with its edge list
    assert np.abs(d @ u - f).max() < 1e-12 * np.abs(f).max()
    assert done.result.metrics["divergence_residual"] < 1e-12 * np.abs(f).max()


def test_border_is_the_boundary_term_of_stokes_theorem():
    """⟨border(1), v⟩ = Σ_σ (d v)_σ for any (n−1)-form v (∫_∂Ω tr v = ∫_Ω d v), on triangles and
    tetrahedra, with the Galerkin ⋆ and with a diagonal one."""
    metric = ['+app.metrics.stokes_defect="inner(border(1 + 0*x), v) - integral(d(v))"',
              '+app.metrics.stokes_size="integral(abs(d(v)))"', "+app.fields.v.form=n-1",
              "+app.fields.v.initial={flux: [random, random, random]}"]
    for mesh in (SQUARE, BOX, [*PLANAR, "operator=circumcentric"]):
        metrics = run(*mesh, *metric).result.metrics
        assert abs(metrics["stokes_defect"]) < 1e-12 * metrics["stokes_size"], (mesh, metrics)


@pytest.mark.parametrize("mesh", [SQUARE, BOX, PLANAR], ids=["square", "box", "planar"])
def test_flux_initial_values_and_flux_field_agree_with_a_vector_field(mesh):
    """{flux: X} samples the fluxes of X; d of them is ∫ div X per top simplex (Stokes); and
    flux_field gives X back exactly when X is constant."""
    extra = ["+app.fields.c.form=n-1", "+app.fields.c.initial={flux: [0.3, -1.2, 0.7]}",
             "+app.fields.g.form=n-1", '+app.fields.g.initial={flux: ["x*y", "y - 2*x", "0"]}',
             '+app.fields.div_g.form=n', '+app.fields.div_g.initial="y + 1"',
             'app.equations=["solve(u - K*codifferential(p) = -K*border(pb), d(u) = f)", "velocity = flux_field(c)", '
             '"pressure = star(p)"]',
             '+app.metrics.stokes="max(abs(d(g) - div_g))"']
    done = run(*mesh, *extra)
    velocity = done.result.fields["velocity"]
    expected = np.array([0.3, -1.2, 0.7])[: velocity.shape[1]]
    if done.dec.K.dim == 2 and velocity.shape[1] == 3:
        expected[2] = 0.0
    assert np.abs(velocity - expected).max() < 1e-13
    # div (xy, y − 2x, 0) = y + 1: quadratic fluxes, linear divergence, both sampled exactly
    assert done.result.metrics["stokes"] < 1e-13


@pytest.mark.parametrize("star", ["mixed_area", "whitney"])
def test_a_system_is_any_linear_equations_in_as_many_unknowns(star):
    """Not Darcy-specific: two 0-forms, a = Δb with b = x y given by the second equation — rows
    matched to the unknowns by kind, the Laplacian's ⋆0⁻¹ turned into the weak row ⋆0 a − S b = 0
    (with Whitney's Galerkin ⋆0 too) — equal to the language's laplacian(x*y); and an algebraic
    pair a + b = 3x, a − b = x solved exactly."""
    from decrun.core.dec import DEC
    from decrun.core.solvers import solver_factory
    from decrun.methods.model import FieldSpec, ModelSpec, compile_model

    from meshes_for_tests import complex_of

    dec = DEC(complex_of("icosphere", subdiv=2), star=star)
    spec = ModelSpec(fields={"a": FieldSpec(0), "b": FieldSpec(0), "c": FieldSpec(0), "e": FieldSpec(0)},
                     equations=["solve(b = x*y, a - laplacian(b) = 0)", "solve(c + e = 3*x, c - e = x)",
                                "reference = laplacian(x*y)"])
    model = compile_model(spec, dec, solver_factory("direct"))
    env = model.environment({}, 0.0)
    assert np.abs(env["a"] - env["reference"]).max() < 1e-10 * np.abs(env["reference"]).max()
    assert np.abs(env["b"] - env["x"] * env["y"]).max() < 1e-14
    assert np.abs(env["c"] - 2 * env["x"]).max() < 1e-14 and np.abs(env["e"] - env["x"]).max() < 1e-14
    assert "system a : primal 0-form, b : primal 0-form" in "\n".join(model.resolved())


def test_the_block_system_is_factorized_once():
    done = run(*SQUARE)
    model = done.experiment.app.compiled(done.dec)
    item = system_of(done)
    solver = item.system.solver
    assert solver is not None

    def refuse(*_):
        raise AssertionError("factorized again")

    solver.factorize = refuse
    first = model.environment({}, 0.0)
    second = model.environment({}, 0.0)
    assert item.system.solver is solver and np.array_equal(first["p"], second["p"])


def test_a_block_system_that_is_not_solved_is_refused_not_returned():
    """A singular block matrix is refused when it is factorized; a solver whose answer does not
    solve the system (here one that returns zeros) is refused by the backward-error check."""
    from decrun.core.solvers import solver_factory
    from decrun.methods.model.solve import BlockSystem

    singular = BlockSystem(sp.csr_matrix(np.array([[1.0, 1.0], [1.0, 1.0]])), solver_factory("direct"),
                           where="app.equations[0]", unknowns=("a", "b"))
    with pytest.raises(ModelError, match=r"^app.equations\[0\]: the block system of a, b could not be factorized"):
        singular.solve(np.array([1.0, 2.0]))

    class Zeros:
        name, needs_spd = "zeros", False

        def factorize(self, matrix):
            self.size = matrix.shape[0]

        def solve(self, b):
            return np.zeros(self.size)

    wrong = BlockSystem(sp.csr_matrix(np.array([[0.0, 1.0], [1.0, 0.0]])), Zeros, where="app.equations[0]",
                        unknowns=("a", "b"))
    with pytest.raises(ModelError, match="is not one"):
        wrong.solve(np.array([1.0, 2.0]))


# ---------------------------------------------------------------------------------------------- convergence
@pytest.mark.parametrize("meshes", [[["mesh=grid", f"mesh.nx={n}", f"mesh.ny={n}"] for n in (9, 17, 33)],
                                    [["mesh=box", f"mesh.cells={c}"] for c in (2, 4, 8)]], ids=["square", "box"])
def test_pressure_and_flux_errors_fall_at_least_as_h_over_three_refinements(meshes):
    """Each refinement halves h. Required: O(h). Measured (docs/models.md): on the square both
    errors fall as h² (1.96–2.00: superconvergence of the cell averages and of the fluxes of the
    uniform mesh), on the Kuhn box the pressure 1.46 → 1.82 and the flux 1.54 → 1.64."""
    pressure, flux = [], []
    for mesh in meshes:
        metrics = run(*mesh).result.metrics
        pressure.append(metrics["pressure_l2_error_rel"])
        flux.append(metrics["flux_l2_error_rel"])
    assert np.all(orders(pressure) > 1.0) and np.all(orders(flux) > 1.0), (pressure, flux)
    floor = 1.9 if meshes[0][0] == "mesh=grid" else 1.4
    assert np.all(orders(pressure) > floor) and np.all(orders(flux) > floor), (orders(pressure), orders(flux))


def docs_table() -> dict[str, list[float]]:
    """The convergence table of docs/models.md's Darcy section, as the page shows it: its cells are
    the placeholders ``{{ numbers.model_darcy.<mesh>_<column> }}`` filled from docs/numbers.json.
    Mesh config → [h, pressure error, relative, order, flux error, relative, order] (orders NaN on
    the first row)."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    numbers = json.loads((root / "docs" / "numbers.json").read_text(encoding="utf-8"))
    text = (root / "docs" / "models.md").read_text(encoding="utf-8")
    section = text[text.index("## Darcy flow (mixed Whitney forms)"):]
    section = section[: section.index("\n## ", 10)]
    rows = [line for line in section.splitlines() if line.startswith(("| square, ", "| box, "))]
    names = [f"darcy/{domain}_{level}" for domain in ("square", "box") for level in (1, 2, 3)]
    assert len(rows) == len(names), rows
    table = {}
    for name, row in zip(names, rows, strict=True):
        cells = [cell.strip() for cell in row.strip("|").split("|")]
        values = []
        for cell in cells[3:10]:
            if cell == "–":
                values.append(float("nan"))
                continue
            key = re.fullmatch(r"\{\{ numbers\.(model_darcy\.[\w]+) \}\}", cell).group(1)
            assert key.startswith(f"model_darcy.{name.split('/')[1]}_"), (name, key)  # the row's own mesh
            values.append(float(numbers[key]["value"]))
        table[name] = values
    return table


@pytest.mark.parametrize("mesh", ["darcy/square_1", "darcy/square_2", "darcy/square_3", "darcy/box_1",
                                  "darcy/box_2", pytest.param("darcy/box_3", marks=pytest.mark.slow)])
def test_the_documented_convergence_table_is_what_the_runs_give(mesh):
    """Each row of docs/models.md's table (the sweep +experiment=darcy_convergence) against a run;
    and its orders: at least O(h), as required (measured: about h² on the square)."""
    done = run(f"mesh={mesh}")
    h, pressure, pressure_rel, pressure_order, flux, flux_rel, flux_order = docs_table()[mesh]
    metrics = done.result.metrics
    assert done.dec.K.mean_edge_length == pytest.approx(h, abs=6e-5)
    for documented, name in ((pressure, "pressure_l2_error"), (pressure_rel, "pressure_l2_error_rel"),
                             (flux, "flux_l2_error"), (flux_rel, "flux_l2_error_rel")):
        assert metrics[name] == pytest.approx(documented, rel=1e-3), name
    if not np.isnan(pressure_order):
        assert pressure_order > 1.5 and flux_order > 1.5


# ---------------------------------------------------------------------------------------------- the command
def test_darcy_on_the_tetrahedral_box_through_the_command(tmp_path):
    proc = decrun("app=darcy", "mesh=box", "mesh.cells=3", "progress=false", "hydra.run.dir=run", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["status"] == "ok"  # the numbers of docs/models.md's table (box, 3 cells)
    assert metrics["pressure_l2_error_rel"] == pytest.approx(0.06494, rel=1e-3)
    assert metrics["flux_l2_error_rel"] == pytest.approx(0.1807, rel=1e-3)
    assert metrics["divergence_residual"] < 1e-12
    result = read_result(tmp_path / "run" / "result.h5")
    assert result.fields["u"].shape == (378,) and result.fields["p"].shape == (162,)  # faces, tetrahedra of 3³ cells
    assert result.fields["velocity"].shape == (162, 3) and (tmp_path / "run" / "flow.png").stat().st_size > 10_000


@pytest.mark.slow
def test_the_convergence_experiment_sweeps_both_domains(tmp_path):
    proc = decrun("-m", "+experiment=darcy_convergence", "hydra.sweep.dir=s", cwd=tmp_path, timeout=900)
    assert proc.returncode == 0, proc.stderr
    table = (tmp_path / "s" / "metrics.csv").read_text()
    rows = [line for line in table.splitlines()[1:] if line]
    assert len(rows) == 6 and all(",ok," in row for row in rows)


# ---------------------------------------------------------------------------------------------- refusals
def test_a_solver_that_needs_spd_is_refused_in_one_line_and_its_hint_runs(tmp_path):
    proc = decrun("app=darcy", "solver=cholmod", *FAST, "hydra.run.dir=bad", cwd=tmp_path)
    line = one_line(proc.stderr)
    assert proc.returncode == 1 and not (tmp_path / "bad" / "result.h5").exists()
    assert line.startswith("error: app.equations[0]: solver=cholmod needs a symmetric positive definite matrix, but "
                           "the block system of u, p is")
    hint = re.search(r"`(solver=\w+)`", line).group(1)
    assert run(hint).result.metrics["divergence_residual"] < 1e-12


BAD = [
    # the second equation's left side is a dual 0-form (star(d(u))) where p is a primal top form
    (['app.equations=["solve(u - K*codifferential(p) = -K*border(pb), star(d(u)) = star(f))"]'],
     "app.equations[0]: the system's equations (u - K * codifferential(p) : primal 1-form, star(d(u)) : dual "
     "0-form) do not match its unknowns (u : primal 1-form, p : primal 2-form)", "one more left side should be a "
     "primal 2-form"),
    (['app.equations=["solve(u - K*codifferential(p) = -K*border(pb), d(u) = f + p)"]'],
     "app.equations[0]: the right side f + p reads the unknown p; move the terms of the unknowns to the left side", ""),
    (['app.equations=["solve(u - K*codifferential(p) = -K*border(pb), d(u) = f, d(u) = 2*f)"]'],
     "app.equations[0]: the system has 3 equations but its left sides read 2 undetermined field(s)", "app.fields"),
    (['app.equations=["solve(u - K*codifferential(p) = -K*border(pb), d(u) = f*u)"]'], "app.equations[0]: f * u "
     "multiplies a primal 2-form and a primal 1-form", ""),
    # every border flux given (PyDEC's example pins one pressure instead): p only up to a constant
    (['+app.fields.u.dirichlet={flux: ["-K*(pi*cos(pi*x)*sin(pi*y) + z)", "-K*pi*sin(pi*x)*cos(pi*y)", "-K*x"]}',
      'app.equations=["solve(u - K*codifferential(p) = 0, d(u) = f)", "velocity = flux_field(u)", "pressure = star(p)"]'],
     "app.equations[0]: the block system of u, p is singular: p is determined only up to a constant",
     "drop app.fields.u.dirichlet"),
    (["app.plots.flow.arrows=pressure"], "app.plots.flow.arrows: 'pressure' is a dual 0-form, but a plot's arrows "
     "is a vector field", "`app.plots.flow.arrows=velocity`"),
]


@pytest.mark.parametrize("overrides, starts, contains", BAD, ids=["degrees", "rhs", "count", "kinds", "kernel", "plots"])
def test_bad_systems_are_one_line_naming_the_key_before_any_work(overrides, starts, contains):
    with pytest.raises(DecrunError) as refused:
        prepare(compose_config(["app=darcy", *overrides]))
    message = str(refused.value)
    assert "\n" not in message and message.startswith(starts) and contains in message, message


def test_the_hints_of_the_refusals_run():
    """The fixes the messages name: the plot's vector field, and the equation of the top form
    (d(u) = f, the shipped system)."""
    with pytest.raises(DecrunError) as refused:
        prepare(compose_config(["app=darcy", "app.plots.flow.arrows=pressure"]))
    hint = re.search(r"`([^`]+)`", str(refused.value)).group(1)
    assert run(hint).result.metrics["status"] == "ok"
    fixed = 'app.equations=["solve(u - K*codifferential(p) = -K*border(pb), d(u) = f)", "pressure = star(p)", ' \
            '"velocity = flux_field(u)"]'
    assert run(fixed).result.metrics["divergence_residual"] < 1e-12
