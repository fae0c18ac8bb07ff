"""Every app × every solver × the boundary adaptations: a run, or a ConfigError naming the
override that fixes it, before any work (no mesh loaded, no solve)."""

from __future__ import annotations

import importlib.util

import pytest

from decrun.errors import ConfigError
from decrun.runner.config import compose_config
from decrun.runner.run import run_experiment, validate

APPS = ["smoothing", "parametrization", "hodge", "vector_field", "fluid"]
SOLVERS = ["direct", "cg", "amg", "pardiso"]
APP_MESH = {"parametrization": ["mesh=sphere_cap", "mesh.subdiv=2"], "hodge": ["mesh.subdiv=2", "mesh.noise=0.05"],
            "smoothing": ["mesh.subdiv=2"], "vector_field": ["mesh.subdiv=2"],
            "fluid": ["mesh.subdiv=2", "mesh.noise=0.0", "app.steps=5", "app.animation=false"]}
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
        assert app == "parametrization" and solver in ("cg", "amg")  # the default conformal border only
        assert f"solver={solver}" in str(exc) and "use `solver=direct`" in str(exc)
        # the hints work: the suggested overrides run
        for hint in (["solver=direct"], [f"solver={solver}", "app.border=circle"]):
            result, _, _ = run_experiment(compose_config([f"app={app}", "figures=false", *APP_MESH[app], *hint]))
            assert result.metrics["status"] == "ok"
        return
    result, _, _ = run_experiment(cfg)
    assert result.metrics["status"] == "ok"


@pytest.mark.parametrize("solver", ["cg", "amg"])
def test_iterative_solvers_give_the_direct_answer(solver):
    """The systems handed to cg/amg are the SPD ones: same result as the direct solver."""
    if importlib.util.find_spec(EXTRA.get(solver, "scipy")) is None:
        pytest.skip(f"{EXTRA[solver]} is not installed")
    for app, extra, metric in (("parametrization", ["app.border=circle"], "angle_distortion_mean_deg"),
                               ("hodge", [], "energy_fraction_harmonic"), ("smoothing", [], "distance_to_clean_rms"),
                               ("vector_field", [], "smoothness_energy")):
        values = []
        for name in ("direct", solver):
            result, _, _ = run_experiment(compose_config([f"app={app}", f"solver={name}", "figures=false",
                                                          *APP_MESH[app], *extra]))
            values.append(result.metrics[metric])
        assert values[1] == pytest.approx(values[0], rel=1e-6, abs=1e-9), app


def test_hodge_with_indefinite_star1_refuses_cg_and_names_whitney():
    """A planar grid of right triangles: circumcentric ⋆1 = 0 on the diagonals, so the Poisson
    systems are singular-indefinite for cg; operator=whitney (SPD) is the override that works."""
    overrides = ["app=hodge", "mesh=grid", "mesh.nx=8", "mesh.ny=8", "figures=false"]
    with pytest.raises(ConfigError, match="use `operator=whitney` with `operator.lumped=true`"):
        run_experiment(compose_config([*overrides, "operator=circumcentric", "solver=cg"]))
    result, _, _ = run_experiment(compose_config([*overrides, "operator=whitney", "operator.lumped=true", "solver=cg"]))
    assert result.metrics["harmonic_dimension"] == result.metrics["betti_1"] == 0


@pytest.mark.parametrize("app", ["smoothing", "parametrization", "hodge"])
def test_unsupported_boundary_adaptation_is_refused_before_any_solve(app, monkeypatch):
    """boundary=flux is only for app=vector_field; the error comes before any linear solve."""
    from decrun.core.solvers.direct import DirectSolver

    def no_solve(self, A):
        raise AssertionError("factorized before the boundary check")

    monkeypatch.setattr(DirectSolver, "_prepare", no_solve)
    with pytest.raises(ConfigError, match=f"boundary=flux: app={app} supports boundary=none"):
        run_experiment(compose_config([f"app={app}", "boundary=flux", "figures=false", *APP_MESH[app]]))
