"""Options whose values are a closed set are ``Enum`` fields (:class:`decrun.core.choices.Choice`):
a value outside the set stops ``decrun`` before anything runs with one line naming the key,
every choice and an override that fixes it, and that override runs; Python callers get the
same check; a member is the plain string it names."""

from __future__ import annotations

import pytest

from decrun.core.choices import Choice
from decrun.core.solvers import make_solver
from decrun.errors import ConfigError
from decrun.runner.config import Direction, OptimizeConfig
from decrun.runner.mesh.base import Refine

FAST = ["app.steps=1", "figures=false", "progress=false"]

CASES = [  # (overrides, the wrong one, the error line, the fix it names)
    ([], "mesh.refine=magic", "mesh.refine: must be one of none | loop | midpoint | isotropic, got 'magic'",
     "mesh.refine=none"),
    ([], "mesh.hole_cut=round", "mesh.hole_cut: must be one of split | whole_triangles, got 'round'",
     "mesh.hole_cut=split"),
    ([], "mesh.orient=Fix", "mesh.orient: must be one of check | fix, got 'Fix'", "mesh.orient=check"),
    (["solver=cg"], "solver.preconditioner=ilu", "solver.preconditioner: must be one of jacobi | none, got 'ilu'",
     "solver.preconditioner=jacobi"),
    (["solver=amg"], "solver.accel=minres", "solver.accel: must be one of cg | gmres | bicgstab | none, got 'minres'",
     "solver.accel=cg"),
    (["solver=amg"], "solver.method=classic",
     "solver.method: must be one of smoothed_aggregation | ruge_stuben, got 'classic'",
     "solver.method=smoothed_aggregation"),
    ([], "optimize.direction=up", "optimize.direction: must be one of minimize | maximize, got 'up'",
     "optimize.direction=minimize"),
]


@pytest.mark.parametrize("base, wrong, line, fix", CASES, ids=[case[1] for case in CASES])
def test_a_value_outside_the_choices_is_one_line_naming_them_and_the_fix_runs(decrun_cli, base, wrong, line, fix):
    if "solver=amg" in base:
        pytest.importorskip("pyamg")
    bad = decrun_cli(*base, wrong, *FAST)
    assert bad.returncode == 1
    assert bad.stderr.strip().splitlines() == [f"error: {line} (e.g. {fix})"]
    good = decrun_cli(*base, fix, *FAST)
    assert good.returncode == 0, good.stderr[-2000:]


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
