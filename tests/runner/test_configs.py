"""Every config in conf/ runs: each option of each group and each experiment, through the
same composition as the ``decrun`` command (figures are built but not written)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from decrun.runner.cli import compose_config, run_experiment
from decrun.runner.sources.files import SAMPLE_MESHES, sample_mesh_dir

CONF = Path(__file__).resolve().parents[2] / "conf"


def options(group: str) -> list[str]:
    return sorted(path.stem for path in (CONF / group).glob("*.yaml") if not path.stem.startswith("_"))


def run(overrides: list[str]):
    result, _, _ = run_experiment(compose_config(overrides))
    assert result.metrics, f"{overrides}: no metrics"
    return result


# Every mesh source with the default app as it is (rescale: auto keeps the volume of closed
# surfaces, the area of open ones); mesh=file needs its path.
MESH_OVERRIDES = {"file": [f"mesh.path={sample_mesh_dir() / SAMPLE_MESHES['bunny10k_textured']}"]}


@pytest.mark.parametrize("mesh", options("mesh"))
def test_every_mesh_option_runs_with_the_default_app(mesh):
    result = run([f"mesh={mesh}", *MESH_OVERRIDES.get(mesh, [])])
    assert result.metrics["stable"] is True
    closed = "volume_drift_rel" in result.metrics
    assert result.metrics["rescale"] == ("volume" if closed else "area")


@pytest.mark.parametrize("sample", [pytest.param(s, marks=pytest.mark.slow) if s == "face" else s
                                    for s in sorted(SAMPLE_MESHES)])  # face: 82k vertices, 11 s
def test_every_sample_runs_with_the_default_app(sample):
    """The raw samples have unreferenced vertices (airplane, bone) and bowties (face):
    mesh=sample repairs and cleans them by default, and turns the Y-up ones Z-up."""
    result = run(["mesh=sample", f"mesh.sample={sample}", "app.steps=2"])
    assert result.metrics["stable"] is True


@pytest.mark.parametrize("operator", options("operator"))
def test_every_operator_option_runs(operator):
    assert run([f"operator={operator}"]).metrics["stable"] is True


@pytest.mark.parametrize("solver", options("solver"))
def test_every_solver_option_runs(solver):
    needs = {"amg": "pyamg", "pardiso": "pypardiso"}.get(solver)
    if needs and importlib.util.find_spec(needs) is None:
        pytest.skip(f"{needs} is not installed (extra decrun[{solver}])")
    assert run([f"solver={solver}"]).metrics["stable"] is True


APP_MESH = {"parametrization": ["mesh=sphere_cap"], "hodge": ["mesh.noise=0.05"]}


@pytest.mark.parametrize("app", options("app"))
def test_every_app_option_runs_with_its_defaults(app):
    run([f"app={app}", *APP_MESH.get(app, [])])


@pytest.mark.parametrize("experiment", options("experiment"))
def test_every_experiment_runs_as_a_single_run(experiment):
    result = run([f"+experiment={experiment}"])
    metrics = result.metrics
    if "poincare_hopf_holds" in metrics and metrics.get("closed"):
        # a single run of a vector field experiment on a closed surface must be a real field
        assert metrics["poincare_hopf_holds"] is True
        assert metrics["singularities"] > 0
        assert np.abs(result.fields["omega"].values).max() > 0
