"""Every app × every solver × the boundary adaptations: a run, or a ConfigError naming the
override that fixes it, before any work (no mesh loaded, no solve)."""

from __future__ import annotations

import importlib.util

import pytest

from decrun.errors import ConfigError
from decrun.runner.cli import compose_config, run_experiment, validate

APPS = ["smoothing", "parametrization", "hodge", "vector_field"]
SOLVERS = ["direct", "cg", "amg", "pardiso"]
APP_MESH = {"parametrization": ["mesh=sphere_cap", "mesh.subdiv=2"], "hodge": ["mesh.subdiv=2", "mesh.noise=0.05"],
            "smoothing": ["mesh.subdiv=2"], "vector_field": ["mesh.subdiv=2"]}
EXTRA = {"amg": "pyamg", "pardiso": "pypardiso"}


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("app", APPS)
def test_every_app_runs_with_every_solver_or_refuses_before_work(app, solver, monkeypatch):
    if solver in EXTRA and importlib.util.find_spec(EXTRA[solver]) is None:
        pytest.skip(f"{EXTRA[solver]} is not installed (extra decrun[{solver}])")
    cfg = compose_config([f"app={app}", f"solver={solver}", "figures=false", *APP_MESH[app]])
    try:
        validate(cfg)
    except ConfigError as exc:
        assert f"solver={solver}" in str(exc) and "use `solver=direct`" in str(exc)
        # the hint works: the suggested override runs
        result, _, _ = run_experiment(compose_config([f"app={app}", "solver=direct", "figures=false", *APP_MESH[app]]))
        assert result.metrics["status"] == "ok"
        return
    result, _, _ = run_experiment(cfg)
    assert result.metrics["status"] == "ok"


@pytest.mark.parametrize("app", ["smoothing", "parametrization", "hodge"])
def test_unsupported_boundary_adaptation_is_refused_before_any_solve(app, monkeypatch):
    """boundary=flux is only for app=vector_field; the error comes before any linear solve."""
    from decrun.core.solvers.direct import DirectSolver

    def no_solve(self, A):
        raise AssertionError("factorized before the boundary check")

    monkeypatch.setattr(DirectSolver, "_prepare", no_solve)
    with pytest.raises(ConfigError, match=f"boundary=flux: app={app} supports boundary=none"):
        run_experiment(compose_config([f"app={app}", "boundary=flux", "figures=false", *APP_MESH[app]]))
