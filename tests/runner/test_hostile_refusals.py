"""Wrong answers and tracebacks under hostile models, through the real ``decrun`` command (issue 50,
items 1, 2, 3, 4, 8 and 11; issue 48, items 3 and 4): an inconsistent system solved by an iterative
solver, non-finite definitions, look-alike names, metrics named as the run's record, number
arithmetic that Python refuses, garbled requirements, the norm of an indefinite inner product and a
solve that reads its own unknown. Each is one line naming the key or the term and its fix (and
the fix runs), or a run that says what went non-finite — never a success on a wrong answer."""

from __future__ import annotations

import importlib.util
import json
import math
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from cli_processes import decrun

SEARCH = "hydra.searchpath=[file://my_conf]"


def model(tmp_path: Path, name: str, text: str) -> None:
    """``my_conf/app/<name>.yaml`` under ``tmp_path`` holding ``text``."""
    directory = tmp_path / "my_conf" / "app"
    directory.mkdir(parents=True, exist_ok=True)
    (directory / f"{name}.yaml").write_text(text, encoding="utf-8")


def one_line(proc: subprocess.CompletedProcess, *words: str) -> str:
    """The single stderr line of a refused command (exit 1), holding every one of ``words``."""
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1 and len(lines) == 1, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr and len(lines[0]) < 500, lines[0][:500]
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


def ran(proc: subprocess.CompletedProcess, run: Path) -> dict:
    """The metrics.json of a run that succeeded (exit 0)."""
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads((run / "metrics.json").read_text())


# ------------------------------------------------------------------ item 1: inconsistent systems
SYSTEM = """defaults:
  - poisson
  - _self_
model: pair
fields:
  u: {{form: 0, dirichlet: null}}
  v: {{form: 0}}
equations:
  - "{equation}"
metrics:
  u_max: "max(abs(u))"
  v_max: "max(abs(v))"
"""

SOLVERS = ["iterative"] + (["pardiso"] if importlib.util.find_spec("pypardiso") else [])


@pytest.mark.parametrize("solver", SOLVERS)
def test_an_inconsistent_system_is_refused_whatever_the_solver(tmp_path, solver):
    # u + v = 1 and u + v = 2 have no solution: a Krylov solver or PARDISO answered max|u| ≈ 1e14,
    # whose backward error (divided by max|x|) passed, and the run ended stable: true
    model(tmp_path, "pair", SYSTEM.format(equation="solve(u + v = 1, u + v = 2)"))
    proc = decrun("app=pair", SEARCH, f"solver={solver}", "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    one_line(proc, "app.equations[0]", "block system of u, v has no solution", "of the right side")
    assert not (tmp_path / "run" / "result.h5").exists()
    # independent equations, as the line says: u = 3/2, v = -1/2 exactly
    fixed = 'app.equations=["solve(u + v = 1, u - v = 2)"]'
    metrics = ran(decrun("app=pair", SEARCH, f"solver={solver}", fixed, "hydra.run.dir=fixed", cwd=tmp_path,
                         timeout=300), tmp_path / "fixed")
    assert metrics["u_max"] == pytest.approx(1.5, abs=1e-8) and metrics["v_max"] == pytest.approx(0.5, abs=1e-8)
    assert metrics["stable"] is True


# ------------------------------------------------------------------ item 2: non-finite definitions
def test_a_definition_that_is_infinite_at_some_vertices_is_reported(tmp_path):
    model(tmp_path, "reciprocal", SYSTEM.replace("model: pair", "model: reciprocal").format(
        equation="solve(laplacian(u) = 1)").replace('  - "solve(laplacian(u) = 1)"\n',
                                                    '  - "solve(laplacian(u) = 1)"\n  - "w = 1/x"\n'
                                                    ).replace("  v: {form: 0}\n", "")
          .replace('  v_max: "max(abs(v))"\n', "").replace("u: {form: 0, dirichlet: null}", "u: {form: 0, dirichlet: 0}"))
    # a 17 × 17 grid of the square [-1/2, 1/2]²: its middle column of 17 vertices has x = 0
    proc = decrun("app=reciprocal", SEARCH, "mesh.nx=17", "mesh.ny=17", "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    metrics = ran(proc, tmp_path / "run")
    line = "app.equations[1]: the definition w = 1/x is not finite at 17 of its 289 entries"
    assert f"warning: {line}" in proc.stderr
    assert metrics["stable"] is False and metrics["unstable_reason"] == "non-finite definition w"
    assert "RuntimeWarning" not in proc.stderr
    with h5py.File(tmp_path / "run" / "result.h5") as f:  # the result is kept, as computed
        assert np.count_nonzero(~np.isfinite(f["fields/w"][()])) == 17


def test_a_definition_that_overflows_is_reported(tmp_path):
    model(tmp_path, "power", "defaults:\n  - heat\n  - _self_\nmodel: power\nfields:\n  v: {form: 0}\n"
                             'equations:\n  - "dt(u) = k * laplacian(u)"\n  - "v = (u + 2)**1e308"\n')
    proc = decrun("app=power", SEARCH, "app.t_end=0.003", "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    metrics = ran(proc, tmp_path / "run")
    assert "warning: app.equations[1]: the definition v = (u + 2)**1e308 is not finite at 642 of its 642" in proc.stderr
    assert metrics["stable"] is False and metrics["unstable_reason"] == "non-finite definition v"


# ------------------------------------------------------------------ item 3: look-alike names
def test_a_name_that_folds_onto_another_is_refused(tmp_path):
    # Python's parser reads 𝕜 as k (NFKC): the run used k = 1 where the model meant 5
    model(tmp_path, "alike", "defaults:\n  - heat\n  - _self_\nmodel: alike\nconstants: {k: 1.0, 𝕜: 5.0}\n"
                             'equations: ["dt(u) = 𝕜 * laplacian(u)"]\nt_end: 0.01\n')
    proc = decrun("app=alike", SEARCH, "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    one_line(proc, "app.constants.𝕜", "'k'", "app.constants.k", "rename")
    # renamed as the line says: the equation reads 5, and x*y (l = 2) decays as exp(-6·5·t)
    model(tmp_path, "alike", "defaults:\n  - heat\n  - _self_\nmodel: alike\nconstants: {k: 1.0, kk: 5.0}\n"
                             'equations: ["dt(u) = kk * laplacian(u)"]\nt_end: 0.01\nintegrator: crank_nicolson\n'
                             'metrics: {u_xy: "inner(u, x*y) / inner(x*y, x*y)"}\n')
    metrics = ran(decrun("app=alike", SEARCH, "hydra.run.dir=fixed", cwd=tmp_path, timeout=300), tmp_path / "fixed")
    assert metrics["u_xy"] == pytest.approx(math.exp(-30 * 0.01), rel=0.02)


# ------------------------------------------------------------------ item 4: the run's record
@pytest.mark.parametrize("name", ["result_h5", "config_hash"])
def test_a_metric_named_as_the_record_is_refused(tmp_path, name):
    # the record's own entry replaced the user's metric in metrics.json (and the sweep table)
    model(tmp_path, "recorded", f'defaults:\n  - heat\n  - _self_\nmodel: recorded\nmetrics: {{{name}: "integral(u)"}}\n')
    proc = decrun("app=recorded", SEARCH, "app.t_end=0.01", "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    one_line(proc, f"app.metrics.{name}", "decrun writes into every run's record", f"{name}_value")
    model(tmp_path, "recorded", f'defaults:\n  - heat\n  - _self_\nmodel: recorded\n'
                                f'metrics: {{{name}_value: "integral(u)"}}\n')
    metrics = ran(decrun("app=recorded", SEARCH, "app.t_end=0.01", "hydra.run.dir=fixed", cwd=tmp_path, timeout=300),
                  tmp_path / "fixed")
    assert metrics[f"{name}_value"] == pytest.approx(0.0, abs=1e-12) and isinstance(metrics["result_h5"], dict)


def test_every_name_the_runner_writes_is_reserved():
    from decrun.methods.model.language import ModelError
    from decrun.methods.model.names import FIELD_SUFFIXES, RECORD_NAMES, check_metric_names
    from decrun.methods.model.system import RESERVED_METRICS
    from decrun.runner.job.run import FIGURES_ERROR, FIGURES_INTERRUPTED, FIGURES_NOT_DRAWN
    from decrun.runner.results.checked import RESULT_RECORD
    from decrun.runner.results.provenance import SAME_AS
    from decrun.runner.results.reading import CHAINED_STATUS
    from decrun.runner.sweep.tables import HEADLINE_COLUMN

    written = {FIGURES_ERROR, FIGURES_INTERRUPTED, FIGURES_NOT_DRAWN, RESULT_RECORD, SAME_AS, CHAINED_STATUS,
               HEADLINE_COLUMN, "config_hash", "export_error", "status", "error", "warnings", "job", "result"}
    assert written <= RECORD_NAMES
    for name in sorted(RECORD_NAMES - RESERVED_METRICS) + [f"u_{suffix}" for suffix in FIELD_SUFFIXES]:
        with pytest.raises(ModelError, match=rf"^app\.metrics\.{name}: .* e\.g\. {name}_value$"):
            check_metric_names("app", {"mass": "integral(u)", name: "integral(u)"}, {"u": None})


# ------------------------------------------------------------------ item 8: numbers follow numpy
def test_number_arithmetic_gives_inf_and_keeps_the_run(tmp_path):
    # a static model runs at t = 0: integral(u)/t and 1/t were ZeroDivisionError, k/(k-1) with k = 1
    # too, and 2**1e308 an OverflowError: the run and its result were lost
    metrics_yaml = ('{e: "integral(u)/t", b: "1/t", c: "k/(k - 1)", p: "(k + 1)**1e308", z: "k**1e308", '
                    'l2_error_rel: "norm(u - (sin(pi*x)*cos(pi*y) + x**2)) / norm(sin(pi*x)*cos(pi*y) + x**2)"}')
    model(tmp_path, "numbers", f"defaults:\n  - poisson\n  - _self_\nmodel: numbers\nconstants: {{k: 1.0}}\n"
                               f"metrics: {metrics_yaml}\n")
    proc = decrun("app=numbers", SEARCH, "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    metrics = ran(proc, tmp_path / "run")
    assert "Traceback" not in proc.stderr and "RuntimeWarning" not in proc.stderr
    assert metrics["b"] == math.inf and metrics["c"] == math.inf and metrics["p"] == math.inf
    assert metrics["z"] == 1.0 and abs(metrics["e"]) == math.inf  # 1**1e308 = 1; integral(u) ≠ 0 over t = 0
    assert metrics["l2_error_rel"] < 0.01  # the other metrics and the result stand
    assert metrics["stable"] is False and metrics["unstable_reason"].startswith("non-finite metric")
    assert (tmp_path / "run" / "result.h5").is_file()


def test_a_number_that_overflows_in_an_equation_is_refused_naming_its_constants(tmp_path):
    proc = decrun("app=heat", 'app.equations=["dt(u) = (k + 1)**1e308 * laplacian(u)"]', "app.t_end=0.01",
                  "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    one_line(proc, "app.equations[0]", "(k + 1) ** 1e+308 is inf", "app.constants.k=1")
    metrics = ran(decrun("app=heat", 'app.equations=["dt(u) = (k + 1)**1e308 * laplacian(u)"]', "app.t_end=0.01",
                         "app.constants.k=0", "hydra.run.dir=fixed", cwd=tmp_path, timeout=300), tmp_path / "fixed")
    assert metrics["stable"] is True


def test_a_parts_constant_whose_rate_factor_overflows_is_one_line(tmp_path):
    # Γ = 2A(ρg)ⁿ/(n+2) with n = 100: (ρg)¹⁰⁰ ≈ 1e395 is inf in float64 (n >= 1 holds)
    args = ("app=halfar", "app.steps=1", "app.t_end=null")
    proc = decrun(*args, "app.parts.glen_law.constants.n=100", "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    one_line(proc, "app.parts.glen_law.equations[0]", "is inf", "app.constants.n=100")
    ran(decrun(*args, "app.parts.glen_law.constants.n=3", "hydra.run.dir=fixed", cwd=tmp_path, timeout=300),
        tmp_path / "fixed")


# ------------------------------------------------------------------ item 11: requirements
def test_a_requirement_that_reads_no_constant_reads_right(tmp_path):
    proc = decrun("app=heat", 'app.require=["1 > 2"]', "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    line = one_line(proc, "app.require[0]", "1 > 2", "reads no constant", "`app.require=[]`")
    assert "  " not in line and "set  " not in line
    ran(decrun("app=heat", 'app.require=["1 > 2"]', "app.require=[]", "app.t_end=0.01", "hydra.run.dir=fixed",
               cwd=tmp_path, timeout=300), tmp_path / "fixed")


def test_a_requirement_that_overflows_to_true_holds(tmp_path):
    # exp(exp(exp(10))) is inf, and inf > 0: Python's OverflowError made it nan and "ill-posed"
    ran(decrun("app=heat", 'app.require=["exp(exp(exp(k*10))) > 0"]', "app.t_end=0.01", "hydra.run.dir=run",
               cwd=tmp_path, timeout=300), tmp_path / "run")


# ------------------------------------------------------------------ issue 48, item 3: norm()
NEGATIVE = """defaults:
  - _model
  - override /mesh@_global_.mesh: planar
  - _self_
model: negative
fields:
  ones: {form: 1, initial: 1}
equations:
  - "s = star(ones)"
  - "w = star(abs(s) - s)"
metrics:
  w_norm: "norm(w)"
"""


def test_the_norm_of_an_indefinite_inner_product_is_nan_and_says_why(tmp_path):
    # w lives on the edges whose circumcentric ⋆1 is negative (obtuse border triangles): ⟨w, w⟩ < 0,
    # which √max(⟨w, w⟩, 0) made an error metric of exactly 0
    model(tmp_path, "negative", NEGATIVE)
    proc = decrun("app=negative", SEARCH, "mesh.holes=[]", "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    metrics = ran(proc, tmp_path / "run")
    assert math.isnan(metrics["w_norm"]) and metrics["stable"] is False
    warning = [line for line in proc.stderr.splitlines() if line.startswith("warning: app.metrics.w_norm")]
    assert len(warning) == 1 and "⋆1 has" in warning[0] and "negative entries" in warning[0], proc.stderr
    assert "`operator=whitney`" in warning[0]
    metrics = ran(decrun("app=negative", SEARCH, "mesh.holes=[]", "operator=whitney", "hydra.run.dir=fixed",
                         cwd=tmp_path, timeout=300), tmp_path / "fixed")
    assert metrics["w_norm"] > 0 and metrics["stable"] is True


# ------------------------------------------------------------------ issue 48, item 4: the unknown on the right
def test_a_solve_that_reads_its_unknown_on_the_right_is_refused_with_the_rewrite(tmp_path):
    proc = decrun("app=poisson", 'app.equations=["solve(laplacian(u) = u + x)"]', "app.metrics={}",
                  "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    line = one_line(proc, "app.equations[0]", "reads the unknown u", "'solve(laplacian(u) - u = x)'")
    suggested = line.split("'")[-2]
    ran(decrun("app=poisson", f'app.equations=["{suggested}"]', "app.metrics={}", "hydra.run.dir=fixed",
               cwd=tmp_path, timeout=300), tmp_path / "fixed")


# ------------------------------------------------------------------ issue 48, item 9: IMEX indefinite
ALLEN_CAHN = """defaults:
  - _model
  - override /mesh@_global_.mesh: icosphere_clean
  - _self_
model: allen_cahn
fields:
  u: {form: 0, initial: "0.1*x*y + 0.05*z"}
constants: {eps: 0.01}
equations:
  - "dt(u) = eps*laplacian(u) + u - u**3"
integrator: imex
dt: 1.25
t_end: 12.5
metrics:
  u_max: "max(abs(u))"
"""


def test_imex_with_a_step_beyond_the_growth_rate_names_dt_the_term_and_both_fixes(tmp_path):
    # (1 − dt) M + dt·eps·S is indefinite at dt = 1.25 (singular at dt = 1): "cholmod solver: the
    # solution is not finite" named neither app.dt, nor the term u, nor a fix
    model(tmp_path, "allen_cahn", ALLEN_CAHN)
    proc = decrun("app=allen_cahn", SEARCH, "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    line = one_line(proc, "app.equations[0]", "app.integrator=imex", "app.dt=1.25", "its term u",
                    "below 1", "`app.dt=0.5`", "'dt(u) = eps * laplacian(u) + explicit(u - u ** 3)'")
    for fix in ("app.dt=0.5", f"app.equations=[\"{line.split(chr(39))[-2]}\"]"):
        metrics = ran(decrun("app=allen_cahn", SEARCH, fix, "hydra.run.dir=fixed", cwd=tmp_path, timeout=300),
                      tmp_path / "fixed")
        # u → ±1 where it starts away from 0 (the stable states of u - u³); first order in dt around them
        assert metrics["stable"] is True and 0.8 < metrics["u_max"] < 1.01


# ------------------------------------------------------------------ issue 48, item 11: hints that match intent
def test_a_caret_power_suggests_the_power(tmp_path):
    proc = decrun("app=heat", 'app.equations=["dt(u) = u - u^3"]', "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    line = one_line(proc, "app.equations[0]", "u ^ 3", "wedge product ∧, not a power", "write u**3")
    assert line.endswith("write u**3")
    metrics = ran(decrun("app=heat", 'app.equations=["dt(u) = u - u**3"]', "app.t_end=0.01", "hydra.run.dir=fixed",
                         cwd=tmp_path, timeout=300), tmp_path / "fixed")
    assert metrics["stable"] is True


def test_the_integral_of_a_number_suggests_the_area_built_in(tmp_path):
    proc = decrun("app=heat", 'app.metrics={mass: "integral(1)"}', "hydra.run.dir=run", cwd=tmp_path, timeout=300)
    line = one_line(proc, "app.metrics.mass", "a 0-form or a 2-form", "`app.metrics.mass=area`", "integral(f)/area")
    assert "an 2-form" not in line
    # the unit square (mesh=grid) has area 1, and area equals Σ ⋆0 (integral(1 + 0*x))
    metrics = ran(decrun("app=poisson", "app.metrics.l2_error_rel=area", 'app.metrics.max_abs_error="integral(1 + 0*x)"',
                         "hydra.run.dir=fixed", cwd=tmp_path, timeout=300), tmp_path / "fixed")
    assert metrics["l2_error_rel"] == pytest.approx(1.0, abs=1e-12)
    assert metrics["max_abs_error"] == pytest.approx(1.0, abs=1e-12)
    on_sphere = ran(decrun("app=heat", "app.metrics.mass=area", "app.t_end=0.01", "hydra.run.dir=sphere", cwd=tmp_path,
                           timeout=300), tmp_path / "sphere")
    assert on_sphere["mass"] == pytest.approx(4 * math.pi, rel=0.01)  # the icosphere's area, below 4π by O(h²)


def test_articles_agree_with_the_degree():
    from decrun.methods.model.wording import article

    assert [article(n) for n in (0, 1, 2, 3, 8, 11, 18, 21)] == ["a", "a", "a", "a", "an", "an", "an", "a"]


# ------------------------------------------------------------------ item 8: a metric that fails keeps the run
def test_a_metric_whose_evaluation_fails_is_nan_and_named_and_the_others_stand():
    # an operator (a plugin's) that raises where it is evaluated: through the API, as the app does
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC
    from decrun.core.solvers import solver_factory
    from decrun.methods.model import FieldSpec, ModelSpec, compile_model
    from decrun.methods.model.finite import nonfinite_lines
    from decrun.methods.model.metrics import model_metrics
    from decrun.methods.model.operators import OPERATORS, pointwise, register
    from decrun.runner.job.plugins import option

    def refuses(values):
        raise ValueError("no value here\nsecond line")

    mesh = option("mesh", "grid", nx=5, ny=5).load()
    dec = DEC(SimplicialComplex(mesh.vertices, mesh.simplices, orient="fix"))
    register(pointwise("refuses", refuses, refuses, "raises"), "test")
    try:
        spec = ModelSpec(fields={"u": FieldSpec(form=0, initial="x + 2")}, equations=["v = 2*u"],
                         metrics={"broken": "integral(refuses(u))", "mass": "integral(u)"})
        model = compile_model(spec, dec, solver_factory("direct"))
        env = model.environment({}, 0.0)
        metrics = model_metrics(model, env, dt=float("nan"), integrator_name="none")
        lines = nonfinite_lines(model, env)
    finally:
        OPERATORS.pop("refuses")
    assert math.isnan(metrics["broken"]) and metrics["mass"] == pytest.approx(2.0, abs=1e-12)  # ∫(x + 2) on [-½, ½]²
    assert metrics["stable"] is False and metrics["unstable_reason"] == "non-finite metric broken"
    assert lines == ["app.metrics.broken: cannot be evaluated (ValueError: no value here); its value is nan"]
