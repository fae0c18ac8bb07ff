"""The shallow-water test cases as experiments (conf/experiment/williamson_tc5.yaml, williamson_tc6.yaml,
galewsky.yaml) and what the language gained for them: ``arctan2``, ``latitude_integral`` (Galewsky's
balanced depth), a stored spherical-harmonic field as an initial value (the T170 references), the refusal of
an explicit dt beyond the fastest wave at t = 0 and of a mesh that is not a sphere centred at the origin."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.errors import ConfigError
from decrun.methods import williamson as W
from decrun.methods.model.initial import PointExpression
from decrun.methods.model.kinds import NUMBER, primal
from decrun.methods.model.language import ModelError
from decrun.methods.model.operators import OPERATORS, Mismatch

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

from shallow_water_reference import reference_depth  # noqa: E402


def _decrun(*args, cwd, timeout=300):
    """The real `decrun` command (``python -m decrun``) with this checkout first on the path."""
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}
    env.update(PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-m", "decrun", *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)


def _compiled(overrides):
    """The compiled model of ``decrun <overrides>`` (its initial values sampled, nothing stepped)."""
    from decrun.core.solvers import solver_factory
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import prepare

    run = prepare(compose_config([*overrides, "figures=false", "progress=false"]))
    return run.experiment.app.compiled(run.dec, solver_factory("auto")), run.dec


def _sphere_points(n=500, radius=W.EARTH_RADIUS, seed=0):
    p = np.random.default_rng(seed).standard_normal((n, 3))
    return radius * p / np.linalg.norm(p, axis=1, keepdims=True)


# ------------------------------------------------------------------ arctan2
def test_arctan2_is_numpys_and_its_derivative_rule_is_exact():
    """arctan2(y, x) value by value, its derivative rule (x/r², −y/r²) equal to central differences to 1e-8."""
    operator = OPERATORS["arctan2"]
    rng = np.random.default_rng(1)
    y, x = rng.standard_normal(50), rng.standard_normal(50)
    assert np.array_equal(operator.evaluate(None, [primal(0)] * 2, y, x), np.arctan2(y, x))
    step = 1e-6
    for i, (dy, dx) in enumerate(((step, 0.0), (0.0, step))):
        numeric = (np.arctan2(y + dy, x + dx) - np.arctan2(y - dy, x - dx)) / (2 * step)
        assert np.allclose(operator.derivative(None, None, [y, x], i), numeric, rtol=1e-8, atol=1e-8)
    assert operator.kind([NUMBER, primal(0)], 2) == primal(0)
    with pytest.raises(Mismatch, match="arctan2 takes forms of one kind"):
        operator.kind([primal(0), primal(1)], 2)


# ------------------------------------------------------------------ latitude_integral
def _octahedron() -> DEC:
    """The DEC of a unit octahedron: PointExpression compiles on a mesh's operators (values at any points)."""
    vertices = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    faces = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return DEC(SimplicialComplex(vertices, faces))


def test_latitude_integral_of_cos_is_sin_latitude():
    """∫_{−π/2}^{θ} cos θ' dθ' = sin θ + 1, whose sphere mean is 1: latitude_integral(cos θ) = sin θ = z/|x|
    (to the quadrature's 1e-12), at points of any radius."""
    points = _sphere_points(radius=3.0)
    expression = PointExpression("latitude_integral(sqrt(x**2 + y**2)/sqrt(x**2 + y**2 + z**2))", "test", {}, _octahedron())
    value = expression.at(points, np.random.default_rng(0))
    assert np.abs(value - points[:, 2] / 3.0).max() < 1e-12


def test_latitude_integral_gives_galewskys_balanced_depth():
    """The jet's balance g h = g h̄ − ∫ a u (f + u tan θ / a) dθ' of conf/experiment/galewsky.yaml equals
    decrun.methods.williamson.galewsky's (its own Simpson + spline, h0 from a trapezoid mean: a constant 1.1e-6 m
    apart) to 2e-6 m = 2e-10 relative, and the
    sphere mean of the latitude integral is 0 (∫ L cos θ dθ / 2 by 4000-point Gauss–Legendre)."""
    model, dec = _compiled(["+experiment=galewsky", "mesh.subdiv=3", "app.constants.perturbation=0"])
    points = dec.K.vertices
    assert np.abs(model.initial_values["depth"] - W.galewsky(perturbed=False).depth(points)).max() < 2e-6
    model, dec = _compiled(["+experiment=galewsky", "mesh.subdiv=3"])
    assert np.abs(model.initial_values["depth"] - W.galewsky().depth(points)).max() < 2e-6
    # the removed mean: latitude_integral(sin θ) = −cos θ + ⟨cos θ⟩ = π/4 − cos θ
    nodes, weights = np.polynomial.legendre.leggauss(4000)
    lat = 0.5 * np.pi * nodes
    meridian = np.column_stack([np.cos(lat), 0.0 * lat, np.sin(lat)])
    value = PointExpression("latitude_integral(z/sqrt(x**2 + y**2 + z**2))", "test", {}, _octahedron()).at(meridian, None)
    assert np.abs(value - (np.pi / 4 - np.cos(lat))).max() < 1e-9  # the spline near the poles: 9.5e-11
    assert abs(0.5 * 0.5 * np.pi * weights @ (value * np.cos(lat))) < 1e-10


@pytest.mark.parametrize("text, message", [
    ("latitude_integral(x)", "a function of the latitude alone"),
    ("latitude_integral(random)", "may not use random"),
    ("latitude_integral(1/(z - z))", "not finite on the meridian"),
])
def test_latitude_integral_refuses_what_is_not_a_function_of_the_latitude(text, message):
    with pytest.raises(ModelError, match=message) as refused:
        PointExpression(text, "app.fields.h.initial", {}, _octahedron()).at(_sphere_points(), np.random.default_rng(0))
    assert "app.fields.h.initial" in str(refused.value) and "\n" not in str(refused.value)


def test_latitude_integral_in_an_equation_is_refused_in_one_line(tmp_path):
    """Through the real CLI: the typing rule names the operator and where it belongs."""
    result = _decrun("app=shallow_water", "mesh.subdiv=2", "figures=false",
                     "app.equations=[\"dt(depth) = latitude_integral(depth)\", \"dt(u) = -d(depth)\"]", cwd=tmp_path)
    assert result.returncode != 0
    lines = [line for line in result.stderr.splitlines() if "latitude_integral" in line]
    assert len(lines) == 1 and "initial value" in lines[0], result.stderr[-2000:]


# ------------------------------------------------------------------ the test cases' initial states
def test_tc5_and_tc6_initial_states_are_williamsons():
    """The YAML formulas (arctan2 for the cone's λ − λc, R = 4 multiplied out) against
    decrun.methods.williamson's: depth and mountain to 1e-9 m, the circulation to 1e-9 relative."""
    for experiment, case in (("williamson_tc5", W.williamson_tc5()), ("williamson_tc6", W.williamson_tc6())):
        model, dec = _compiled([f"+experiment={experiment}", "mesh.subdiv=3"])
        points = dec.K.vertices
        assert np.abs(model.initial_values["depth"] - case.depth(points)).max() < 1e-9 * case.depth(points).max()
        assert np.abs(model.initial_values["b"] - case.topography(points)).max() < 1e-9
        from decrun.core.trisk import TRiSK

        circulation = W.circulation(TRiSK(dec), case.velocity, W.EARTH_RADIUS)
        assert np.abs(model.initial_values["u"] - circulation).max() < 1e-9 * np.abs(circulation).max()
    assert model.initial_values["b"].max() == 0.0  # TC6 is flat
    tc5, _ = _compiled(["+experiment=williamson_tc5", "mesh.subdiv=3"])
    assert 1500.0 < tc5.initial_values["b"].max() <= 2000.0


# ------------------------------------------------------------------ the stored spectral references
def test_a_spherical_harmonic_field_is_the_reference_loaders():
    """TC5's depth_reference (stored T170 surface at the vertices minus the model's cone) and TC6's equal
    benchmarks/shallow_water_reference.py's reference_depth (an independent evaluator) to 1e-9 relative."""
    for experiment, case, day in (("williamson_tc5", "tc5", 15), ("williamson_tc6", "tc6", 10)):
        model, dec = _compiled([f"+experiment={experiment}", "mesh.subdiv=3"])
        env = model.environment(model.initial_values, 0.0)
        expected = reference_depth(case, day, dec.K.vertices)
        assert np.abs(np.asarray(env["depth_reference"]) - expected).max() < 1e-9 * np.abs(expected).max()


def test_a_stored_field_whose_sha256_differs_is_refused_with_its_command(tmp_path):
    from decrun.methods.spherical_harmonics import MANIFEST_NAME, load_coefficients

    data = ROOT / "benchmarks" / "data"
    shutil.copy(data / MANIFEST_NAME, tmp_path / MANIFEST_NAME)
    copy = tmp_path / "sw_tc6_T170_rk4_day10.npz"
    copy.write_bytes((data / copy.name).read_bytes() + b"\0")
    with pytest.raises(ConfigError, match="regenerate it: python benchmarks/shallow_water_spectral.py --case tc6"):
        load_coefficients(str(copy), "h_lm", "app.fields.depth_reference.initial")
    alm, lmax = load_coefficients(str(data / copy.name), "h_lm", "here")
    assert lmax == 170 and alm.shape == (171 * 172 // 2,)
    with pytest.raises(ConfigError, match="no array 'nothing'"):
        load_coefficients(str(data / copy.name), "nothing", "here")


# ------------------------------------------------------------------ bad input, before any work
def test_a_dt_over_the_wave_limit_is_refused_with_a_dt_that_runs(tmp_path):
    """Through the real CLI at subdiv 3: app.dt=20000 is refused in one line naming app.dt and the limit;
    the dt it offers runs (stable, mass kept)."""
    common = ("app=shallow_water", "mesh.subdiv=3", "figures=false", "app.t_end=80000")
    refused = _decrun(*common, "app.dt=20000", cwd=tmp_path)
    assert refused.returncode != 0
    lines = [line for line in refused.stderr.splitlines() if "app.dt=20000 exceeds the stability limit" in line]
    assert len(lines) == 1, refused.stderr[-2000:]
    offered = lines[0].split("use `")[1].split("`")[0]
    assert not list(tmp_path.rglob("result.h5"))
    ran = _decrun(*common, offered, cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr[-2000:]
    metrics = json.loads(next(tmp_path.rglob("metrics.json")).read_text())
    assert metrics["stable"] and abs(metrics["mass_drift"]) <= 1e-12
    assert float(offered.split("=")[1]) <= metrics["dt_stability_limit"]


def test_the_wave_limit_is_two_root_two_over_the_jacobians_largest_eigenvalue():
    """At subdiv 2 (642 unknowns) the dense spectrum of the exact Jacobian at t = 0: ARPACK's |λ|max is its
    largest modulus to 1e-3 (the top of the spectrum is a cluster of gravity waves of nearly one modulus; ARPACK
    at tol 1e-6 may land on a neighbour 1.2e-4 below), the spectrum is that of waves (|Re λ| ≤ 1e-2 |λ|max; measured 1.7e-3),
    and the limit 2√2/|λ|max."""
    from decrun.methods.model.problem import ModelProblem
    from decrun.methods.model.wave_limit import oscillatory_stability_limit

    model, _ = _compiled(["app=shallow_water", "mesh.subdiv=2"])
    problem = ModelProblem(model)
    J = problem.jacobian(problem.free_values(model.initial_values), 0.0).toarray()
    spectrum = np.linalg.eigvals(J)
    largest = np.abs(spectrum).max()
    limit, modulus = oscillatory_stability_limit(model, "rk4", model.initial_values)
    assert modulus == pytest.approx(largest, rel=1e-3)
    assert limit == pytest.approx(2 * np.sqrt(2) / modulus, rel=1e-12)
    assert np.abs(spectrum.real).max() <= 1e-2 * largest


@pytest.mark.parametrize("mesh", [["mesh=torus"], ["mesh=icosphere", "mesh.radius=6.37122e6"]])
def test_a_mesh_that_is_not_a_sphere_centred_at_the_origin_is_refused_in_one_line(mesh, tmp_path):
    result = _decrun("app=shallow_water", *mesh, "figures=false", cwd=tmp_path)
    assert result.returncode != 0
    lines = [line for line in result.stderr.splitlines() if "not a sphere centred at the origin" in line]
    assert len(lines) == 1 and "mesh=icosphere_earth" in lines[0], result.stderr[-2000:]
    assert not list(tmp_path.rglob("result.h5"))


# ------------------------------------------------------------------ the experiments end to end
@pytest.mark.parametrize("experiment", ["williamson_tc5", "williamson_tc6", "galewsky"])
def test_each_experiment_runs_through_the_cli_and_keeps_mass(experiment, tmp_path):
    """Cut to 3 steps at subdiv 3: stable, mass kept to 1e-12, the error metrics present, the maps drawn."""
    result = _decrun(f"+experiment={experiment}", "mesh.subdiv=3", "app.t_end=null", "app.steps=3",
                     "app.animation=false", cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    metrics = json.loads(next(tmp_path.rglob("metrics.json")).read_text())
    assert metrics["stable"] and metrics["steps_done"] == 3 and abs(metrics["mass_drift"]) <= 1e-12
    assert all(np.isfinite(metrics[k]) for k in ("l1_h", "l2_h", "linf_h"))
    for figure in ("depth_map.png", "vorticity_map.png", "depth_error.png"):
        assert next(tmp_path.rglob(figure)).stat().st_size > 10_000
