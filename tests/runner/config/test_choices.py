"""Options whose values are a closed set are ``Enum`` fields (:class:`decrun.core.choices.Choice`):
a value outside the set stops ``decrun`` before anything runs with one line naming the key,
every choice and an override that fixes it — the choice closest in spelling to the wrong value
(``difflib``, as for a mistyped key), else the first — and that override runs; Python callers get the
same check; a member is the plain string it names."""

from __future__ import annotations

import pytest

from decrun.core.choices import Choice
from decrun.core.solvers import make_solver
from decrun.errors import ConfigError
from decrun.runner.job.config import Direction, OptimizeConfig
from decrun.runner.mesh.base import Refine

FAST = ["app.steps=1", "figures=false", "progress=false"]

CASES = [  # (overrides, the wrong one, the error line, the fix it names: the closest value, else the first)
    ([], "mesh.refine=magic", "mesh.refine: must be one of none | loop | midpoint | isotropic, got 'magic'",
     "mesh.refine=none"),
    ([], "mesh.hole_cut=round", "mesh.hole_cut: must be one of split | whole_triangles, got 'round'",
     "mesh.hole_cut=split"),
    ([], "mesh.orient=Fix", "mesh.orient: must be one of check | fix, got 'Fix'", "did you mean mesh.orient=fix?"),
    (["solver=cg"], "solver.preconditioner=ilu", "solver.preconditioner: must be one of jacobi | none, got 'ilu'",
     "solver.preconditioner=jacobi"),
    (["solver=amg"], "solver.accel=minres", "solver.accel: must be one of cg | gmres | bicgstab | none, got 'minres'",
     "did you mean solver.accel=gmres?"),
    (["solver=amg"], "solver.method=classic",
     "solver.method: must be one of smoothed_aggregation | ruge_stuben, got 'classic'",
     "solver.method=smoothed_aggregation"),
    ([], "optimize.direction=up", "optimize.direction: must be one of minimize | maximize, got 'up'",
     "optimize.direction=minimize"),
    (["solver=iterative"], "solver.method=lsqr", "solver.method: must be one of auto | cg | minres | gmres | bicgstab, "
     "got 'lsqr'", "solver.method=auto"),
    (["solver=iterative"], "solver.preconditioner=ssor",
     "solver.preconditioner: must be one of auto | jacobi | ilu | none, got 'ssor'", "solver.preconditioner=auto"),
    (["operator=mixed_area"], "operator.tetrahedra=circumcentric",
     "operator.tetrahedra: must be one of barycentric | error, got 'circumcentric'",
     "did you mean operator.tetrahedra=barycentric?"),
    (["app=fluid"], "app.walls=noslip", "app.walls: must be one of auto | slip | no_slip, got 'noslip'",
     "did you mean app.walls=no_slip?"),
    (["app=fluid"], "app.walls=free", "app.walls: must be one of auto | slip | no_slip, got 'free'", "app.walls=auto"),
]


def _hint(fix: str) -> str:
    """The parenthesis of the error line: a did-you-mean as it stands, a plain override as ``e.g.``."""
    return fix if fix.startswith("did you mean ") else f"e.g. {fix}"


def _override(fix: str) -> str:
    return fix.removeprefix("did you mean ").removesuffix("?")


@pytest.mark.parametrize("base, wrong, line, fix", CASES, ids=[case[1] for case in CASES])
def test_a_value_outside_the_choices_is_one_line_naming_them_and_the_fix_runs(decrun_cli, base, wrong, line, fix):
    if "solver=amg" in base:
        pytest.importorskip("pyamg")
    bad = decrun_cli(*base, wrong, *FAST)
    assert bad.returncode == 1
    assert bad.stderr.strip().splitlines() == [f"error: {line} ({_hint(fix)})"]
    good = decrun_cli(*base, _override(fix), *FAST)
    assert good.returncode == 0, good.stderr[-2000:]


#: the apps' closed sets: (the app's overrides, the wrong one, its choices, the fix it names)
APP_CASES = [
    (["app.steps=1"], "app.scheme=backward", "implicit | explicit", "app.scheme=implicit"),
    (["app.steps=1"], "app.dt_unit=edge", "auto | critical | resolution", "app.dt_unit=auto"),
    (["app.steps=1"], "app.rescale=length", "auto | volume | area | none", "app.rescale=auto"),
    (["app=parametrization", "mesh=sphere_cap"], "app.border=square", "circle | circle_arclength | conformal | free",
     "app.border=circle"),
    (["app=parametrization", "mesh=sphere_cap"], "app.weights=cot", "dec | uniform | mean_value", "app.weights=dec"),
    (["app=parametrization", "mesh=sphere_cap"], "app.reflex_rows=none", "harmonic | cauchy_riemann",
     "app.reflex_rows=harmonic"),
    (["app=parametrization", "mesh=sphere_cap"], "app.holes=patch", "auto | fill | conformal", "app.holes=auto"),
    (["app=fluid", "app.steps=1"], "app.initial=spin", "zero | rotation | vortex_pair | random | mesh_field",
     "app.initial=zero"),
    (["app=fluid", "app.steps=1"], "app.velocity=pic", "least_squares | wshd07", "app.velocity=least_squares"),
    (["app=fluid", "app.steps=1"], "app.circulation=simpson",
     "swept_bounded | swept_clamped | swept | corrected_trapezoid | trapezoid", "app.circulation=swept_bounded"),
    (["app=hodge", "app.harmonic_dimension=false"], "app.input=file", "analytic | random | result",
     "app.input=analytic"),
    (["app=hodge", "app.harmonic_dimension=false"], "app.analytic=curl",
     "gradient | rotated_gradient | rotation | toroidal | mixed | frame", "app.analytic=gradient"),
    (["app=spectrum", "app.count=3"], "app.analytic=cube", "auto | none | sphere | ball | box | flat_torus",
     "app.analytic=auto"),
    (["app=vector_field", "mesh.subdiv=2"], "app.stroke_magnitude=auto", "fixed | precomputed",
     "app.stroke_magnitude=fixed"),
]


@pytest.mark.parametrize("base, wrong, choices, fix", APP_CASES, ids=[case[1] for case in APP_CASES])
def test_an_apps_closed_option_names_its_choices_and_the_fix_runs(base, wrong, choices, fix):
    """The same line as the CLI cases above (the CLI prints it after ``error:``), composed and
    run in this process: the wrong value stops before any work, the named fix runs."""
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    key, value = wrong.split("=")
    with pytest.raises(ConfigError) as info:
        run_experiment(compose_config([*base, wrong, "figures=false"]))
    assert str(info.value) == f"{key}: must be one of {choices}, got '{value}' (e.g. {fix})"
    result = run_experiment(compose_config([*base, fix, "figures=false"])).result
    assert result.metrics["status"] == "ok"


def test_python_callers_get_the_same_check_and_members_are_their_strings():
    with pytest.raises(ConfigError, match=r"^solver.preconditioner: must be one of jacobi \| none, got 'ilu'"):
        make_solver("cg", preconditioner="ilu")
    solver = make_solver("cg", preconditioner="none")
    assert solver.preconditioner is type(solver.preconditioner).none and solver.preconditioner == "none"
    with pytest.raises(ConfigError, match="optimize.direction: must be one of minimize | maximize"):
        OptimizeConfig(metric="dt", direction="up")
    assert OptimizeConfig(direction="maximize").direction is Direction.maximize
    assert f"mesh.refine={Refine.loop}" == "mesh.refine=loop" and str(Refine.isotropic) == "isotropic"
    assert Refine.names() == ["none", "loop", "midpoint", "isotropic"]
    assert all(issubclass(kind, Choice) for kind in (Refine, Direction))
    from decrun.apps.parametrization import Parametrization
    from decrun.apps.smoothing import Smoothing
    from decrun.methods.parametrization import Border

    with pytest.raises(ConfigError, match=r"^app.scheme: must be one of implicit \| explicit, got 'backward'"):
        Smoothing(scheme="backward")
    assert Parametrization(border="circle").border is Border.circle and Border.circle == "circle"


#: the other closed sets a value is checked against (not Choice fields): (overrides, the wrong one,
#: the start of the error line, the override it suggests)
OTHER_CASES = [
    (["app=smoothing", "export=ply"], "export.colormap=viridsi", "export.colormap: unknown colormap 'viridsi'",
     "export.colormap=viridis"),
    (["mesh.post=[clean,normalise]"], None, "mesh.post: unknown step 'normalise'", "mesh.post=[clean,normalize]"),
]


@pytest.mark.parametrize("base, wrong, start, fix", OTHER_CASES, ids=[case[-1] for case in OTHER_CASES])
def test_other_closed_sets_suggest_the_closest_value_and_it_runs(decrun_cli, base, wrong, start, fix):
    """The colormaps of an export and the post steps of a mesh name the value closest in
    spelling as the override that fixes the run, and that override runs."""
    bad = decrun_cli(*base, *([wrong] if wrong else []), *FAST)
    assert bad.returncode == 1
    (line,) = bad.stderr.strip().splitlines()
    assert line.startswith(f"error: {start}") and line.endswith(f"did you mean `{fix}`?"
                                                                if "colormap" in fix else f"did you mean {fix}?"), line
    good = decrun_cli(*[b for b in base if not b.startswith(fix.split("=")[0] + "=")], fix, *FAST)
    assert good.returncode == 0, good.stderr[-2000:]


def test_python_callers_get_the_closest_value_too():
    """The kernels switch, a plugin name and a sample mesh name suggest the closest value; the
    suggestion is accepted; a value close to none names the first (or lists them all)."""
    from decrun.core.choices import closest
    from decrun.core.jit.switch import check_mode
    from decrun.runner.mesh.sources.files import Sample

    with pytest.raises(ConfigError) as info:
        check_mode("numbaa")
    assert str(info.value) == "app.kernels: must be one of auto | numba | numpy, got 'numbaa' (did you mean app.kernels=numba?)"
    assert check_mode("numba") == "numba"
    with pytest.raises(ConfigError, match=r"^solver=directt: unknown Solver; choose one of solver=amg \| .*; "
                                          r"did you mean solver=direct\?$"):
        make_solver("directt")
    assert make_solver("direct").name == "direct"
    with pytest.raises(ConfigError, match=r"^solver=gauss: unknown Solver; choose one of solver=amg \| [^;]*$"):
        make_solver("gauss")
    with pytest.raises(ConfigError, match=r"^mesh.sample: must be one of airplane \| .*, got 'bunyn' "
                                          r"\(did you mean mesh.sample=bunny\?\)$"):
        Sample(sample="bunyn")
    assert Sample(sample="bunny").sample == "bunny"
    assert closest("NO_SLIP", ["auto", "slip", "no_slip"]) == "no_slip" and closest("free", ["auto", "slip"]) is None
