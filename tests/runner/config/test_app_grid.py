"""Every app × every solver × the boundary adaptations: a run, or a ConfigError naming the
override that fixes it, before any work (no mesh loaded, no solve)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import yaml

from decrun.errors import ConfigError
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment, validate

CONF_APP = Path(__file__).resolve().parents[3] / "conf" / "app"


def is_model(path: Path) -> bool:
    """A declarative model's config (``defaults: [_model, …]``, or the Model class itself)."""
    node = yaml.safe_load(path.read_text()) or {}
    return "_model" in (node.get("defaults") or []) or node.get("_target_") == "decrun.apps.model.Model"


#: the model app's representatives in the grid (its other shipped models: tests/apps/test_model_app.py)
MODELS = ["heat", "poisson", "heat_geodesics"]
#: every app config of conf/app/ that is not a model (so a new app is in the grid), then the models
APPS = sorted(path.stem for path in CONF_APP.glob("*.yaml") if not path.stem.startswith("_") and not is_model(path)) \
    + MODELS
SOLVERS = ["auto", "cholmod", "direct", "cg", "amg", "iterative", "pardiso"]
APP_MESH = {"parametrization": ["mesh=sphere_cap", "mesh.subdiv=2"], "hodge": ["mesh.subdiv=2", "mesh.noise=0.05"],
            "smoothing": ["mesh.subdiv=2"], "vector_field": ["mesh.subdiv=2"],
            "fluid": ["mesh.subdiv=2", "mesh.noise=0.0", "app.steps=5", "app.animation=false"],
            "heat": ["mesh.subdiv=2", "app.t_end=0.01"], "poisson": ["mesh.nx=9", "mesh.ny=9"],
            "heat_geodesics": ["mesh.subdiv=2"], "spectrum": ["mesh.subdiv=2"]}
EXTRA = {"amg": "pyamg", "pardiso": "pypardiso"}


def test_the_grid_holds_every_app_config_and_its_mesh():
    """The grid's app list comes from conf/app/: the non-model apps all there (spectrum among
    them), the model representatives real model configs, each with its small mesh."""
    configs = {path.stem: path for path in CONF_APP.glob("*.yaml") if not path.stem.startswith("_")}
    assert {"smoothing", "parametrization", "hodge", "vector_field", "fluid", "spectrum"} <= set(APPS)
    assert all(is_model(configs[name]) for name in MODELS)
    assert set(APPS) == {name for name, path in configs.items() if not is_model(path)} | set(MODELS)
    assert set(APP_MESH) == set(APPS)


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("app", APPS)
def test_every_app_runs_with_every_solver_or_refuses_before_work(app, solver, monkeypatch):
    if solver in EXTRA and importlib.util.find_spec(EXTRA[solver]) is None:
        pytest.skip(f"{EXTRA[solver]} is not installed (extra decrun[{solver}])")
    cfg = compose_config([f"app={app}", f"solver={solver}", "figures=false", *APP_MESH[app]])
    try:
        validate(cfg)
        if app == "hodge" and solver in ("cholmod", "cg", "amg"):  # the ⋆1 check needs the operators: still before a solve
            run_experiment(cfg)
    except ConfigError as exc:
        # the default conformal border (unsymmetric) and hodge's default Galerkin ⋆1 (a saddle point)
        assert app in ("parametrization", "hodge") and solver in ("cholmod", "cg", "amg")
        assert f"solver={solver}" in str(exc) and "use `solver=iterative`" in str(exc)
        # the hints work: the suggested overrides run
        fix = "app.border=circle" if app == "parametrization" else "operator.lumped=true"
        for hint in (["solver=iterative"], ["solver=direct"], [f"solver={solver}", fix]):
            result = run_experiment(compose_config([f"app={app}", "figures=false", *APP_MESH[app], *hint])).result
            assert result.metrics["status"] == "ok"
        return
    result = run_experiment(cfg).result
    assert result.metrics["status"] == "ok"


@pytest.mark.parametrize("solver", ["auto", "cholmod", "cg", "amg", "iterative"])
def test_spd_solvers_give_the_direct_answer(solver):
    """The systems handed to auto/cholmod/cg/amg are the SPD ones (and iterative's Krylov
    method fits each): same result as SuperLU."""
    if importlib.util.find_spec(EXTRA.get(solver, "scipy")) is None:
        pytest.skip(f"{EXTRA[solver]} is not installed")
    for app, extra, metric in (("parametrization", ["app.border=circle"], "angle_distortion_mean_deg"),
                               ("hodge", ["operator=mixed_area"], "energy_fraction_harmonic"), ("smoothing", [], "distance_to_clean_rms"),
                               ("vector_field", [], "smoothness_energy")):
        values = []
        for name in ("direct", solver):
            result = run_experiment(compose_config([f"app={app}", f"solver={name}", "figures=false",
                                                    *APP_MESH[app], *extra])).result
            values.append(result.metrics[metric])
        assert values[1] == pytest.approx(values[0], rel=1e-6, abs=1e-9), app


def test_hodge_with_indefinite_star1_refuses_cg_and_names_whitney():
    """A planar grid of right triangles: circumcentric ⋆1 = 0 on the diagonals, so the Poisson
    systems are singular-indefinite for cg; operator=whitney (SPD) is the override that works."""
    overrides = ["app=hodge", "mesh=grid", "mesh.nx=8", "mesh.ny=8", "figures=false"]
    with pytest.raises(ConfigError, match="use `operator=whitney` with `operator.lumped=true`"):
        run_experiment(compose_config([*overrides, "operator=circumcentric", "solver=cg"]))
    result = run_experiment(compose_config([*overrides, "operator=whitney", "operator.lumped=true", "solver=cg"])).result
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


@pytest.mark.parametrize("app", APPS)
def test_spd_solvers_through_the_cli_on_every_app(app, decrun_cli, tmp_path):
    """The real command: a sweep over the default (auto), cholmod and direct on each app; the
    same metrics to round-off (parametrization with a circle border, whose systems are SPD)."""
    import pandas as pd

    # SPD systems: a circle border; hodge with diagonal stars (its default whitney is a saddle point)
    extra = {"parametrization": ["app.border=circle"], "hodge": ["operator=mixed_area"]}.get(app, [])
    proc = decrun_cli("-m", f"app={app}", "solver=auto,cholmod,direct", "figures=false", *APP_MESH[app], *extra)
    assert proc.returncode == 0, proc.stderr[-2000:]
    (sweep,) = (tmp_path / "outputs" / "sweeps").iterdir()
    table = pd.read_csv(sweep / "metrics.csv").set_index("solver")
    assert list(table["status"]) == ["ok"] * 3
    # timings, and the bookkeeping of the sweep (the job number, which earlier job a job repeats)
    numeric = table.select_dtypes("number").drop(columns=[c for c in table.columns
                                                          if "second" in c or c in ("job", "same_as")],
                                                  errors="ignore")
    for name in ("auto", "cholmod"):
        np.testing.assert_allclose(numeric.loc[name], numeric.loc["direct"], rtol=1e-6, atol=1e-9, err_msg=name)


def test_cholmod_on_an_unsymmetric_app_is_refused_by_the_cli_with_the_override(decrun_cli):
    proc = decrun_cli("app=parametrization", "solver=cholmod", "figures=false", *APP_MESH["parametrization"])
    assert proc.returncode != 0 and "`solver=direct`" in proc.stderr and "Traceback" not in proc.stderr
    fixed = decrun_cli("app=parametrization", "solver=direct", "figures=false", *APP_MESH["parametrization"])
    assert fixed.returncode == 0, fixed.stderr[-2000:]
