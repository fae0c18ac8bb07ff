"""The shipped declarative models (conf/app/{heat,poisson,wave,heat_geodesics,mcf}.yaml, issue 39
§5) against exact answers and references, every integrator against the semi-discrete solution,
and the model app through the real ``decrun`` command (sweeps, overrides, a user's own model on
``hydra.searchpath``, export, checkpoints, one-line refusals).

In-process runs compose the config as the command does (``compose_config`` + ``run_experiment``;
recorded series in ``result.series``); CLI runs are child processes (``cli_processes``).
MODELS.md (the brief) has the exact answers: Δ Y_l = −l(l+1) Y_l on the unit sphere."""

from __future__ import annotations

import json
import math
import re
import signal
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import expm_multiply, spsolve

from decrun.errors import DecrunError
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import prepare, run_experiment
from decrun.runner.results import read_result
from decrun.runner.results.checkpoint import CHECKPOINT

from cli_processes import decrun, result_contents, start

FAST = ["figures=false", "progress=false"]


def run(*overrides: str):
    """The finished in-process run (:class:`decrun.runner.job.run.Run`) of ``overrides``."""
    return run_experiment(compose_config([*overrides, "figures=false"]))


def orders(errors) -> np.ndarray:
    """Measured orders between successive refinements that halve h."""
    errors = np.asarray(errors, dtype=float)
    return np.log2(errors[:-1] / errors[1:])


def stiffness(dec) -> sp.csr_matrix:
    """d0ᵀ ⋆1 d0: the (PSD) cotan stiffness of the run's operators."""
    return (dec.d(0).T @ sp.diags(dec.star_diagonal(1)) @ dec.d(0)).tocsr()


def one_line(text: str) -> str:
    """The one error line of a refused CLI run (nothing else on stderr)."""
    lines = [line for line in text.strip().splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in text, text
    return lines[0]


# ---------------------------------------------------------------------------------------------- heat
HARMONICS = {1: "z", 2: "x*y", 3: "z*(5*z**2-3)"}


@pytest.mark.parametrize("l", sorted(HARMONICS))
def test_heat_decays_a_spherical_harmonic_as_exp_minus_l_l1_kt_at_second_order(l):
    """Crank–Nicolson at small dt (its time error ~1e-7 here): the L2 error against
    e^{−l(l+1)kt} Y_l is O(h²). Measured (subdiv 2, 3, 4): l=1 4.47e-4, 1.03e-4, 2.44e-5 (orders
    2.12, 2.08); l=2 1.42e-2, 3.54e-3, 8.83e-4 (2.00, 2.00); l=3 6.62e-2, 1.65e-2, 4.11e-3 (2.01,
    2.00). ∫u stays 0 (Y_l has zero mean) to round-off."""
    Y, lam = HARMONICS[l], l * (l + 1)
    exact = f"exp(-{lam}*k*t)*({Y})"
    errors = []
    for subdiv in (2, 3, 4):
        metrics = run("app=heat", f"mesh.subdiv={subdiv}", f"app.fields.u.initial='{Y}'", "app.dt=0.0005",
                      f"+app.metrics.l2_error_rel='norm(u - {exact}) / norm({exact})'").result.metrics
        assert metrics["stable"] is True and metrics["steps_done"] == 200
        assert abs(metrics["mass"]) < 1e-12
        errors.append(metrics["l2_error_rel"])
    assert errors[0] > errors[1] > errors[2] and errors[2] < 5e-3
    assert min(orders(errors)) >= 1.8, (errors, orders(errors))


#: (integrator, order, two step sizes) for the fixed-step schemes; error against the
#: semi-discrete solution exp(−t ⋆0⁻¹ S) u0 on the same mesh
FIXED_STEP = [("explicit_euler", 1, 0.001), ("implicit_euler", 1, 0.001), ("imex", 1, 0.001),
              ("crank_nicolson", 2, 0.005), ("rk4", 4, 0.005)]
ADAPTIVE = ["bdf", "radau", "rk45"]


@pytest.fixture(scope="module")
def semi_discrete():
    """u(0.1) of dt(u) = Δu from u0 = x*y + 1 on the subdiv-3 sphere (no time error), the
    continuous answer there, and a function giving (relative error, ∫u drift) of a run."""
    base = ["app=heat", "mesh.subdiv=3", "app.fields.u.initial='x*y + 1'"]
    done = run(*base)
    dec, V = done.dec, done.mesh.vertices
    u0 = V[:, 0] * V[:, 1] + 1
    reference = expm_multiply(-0.1 * sp.diags(1 / dec.star_diagonal(0)) @ stiffness(dec), u0)
    continuous = np.exp(-0.6) * V[:, 0] * V[:, 1] + 1

    def measure(*overrides):
        result = run(*base, *overrides).result
        u, mass = result.fields["u"], result.series["mass"]
        assert result.metrics["t_final"] == pytest.approx(0.1, abs=1e-15)
        return np.linalg.norm(u - reference) / np.linalg.norm(reference), np.abs(mass - mass[0]).max() / abs(mass[0])

    return measure, reference, continuous


@pytest.mark.parametrize("scheme, order, dt", FIXED_STEP)
def test_every_fixed_step_integrator_converges_at_its_order_and_conserves_mass(semi_discrete, scheme, order, dt):
    """Measured errors at (dt, dt/2): explicit Euler 2.51e-4, 1.25e-4; implicit Euler and IMEX
    2.50e-4, 1.25e-4; Crank–Nicolson (dt 0.005) 6.23e-6, 1.56e-6; RK4 5.97e-10, 3.65e-11."""
    measure, reference, continuous = semi_discrete
    (e1, drift1), (e2, drift2) = (measure(f"app.integrator={scheme}", f"app.dt={step}") for step in (dt, dt / 2))
    assert order - 0.15 <= math.log2(e1 / e2) <= order + 0.3, (e1, e2)
    assert e2 < 2e-4
    assert max(drift1, drift2) < 1e-12  # ∫u = Σ ⋆0 u: 1ᵀ S = 0, every scheme keeps it
    # the same answer as the exact solution, up to the mesh's own O(h²) error
    assert np.linalg.norm(reference - continuous) / np.linalg.norm(continuous) < 2e-3


@pytest.mark.parametrize("scheme", ADAPTIVE)
def test_every_adaptive_integrator_meets_its_tolerance_and_conserves_mass(semi_discrete, scheme):
    """solve_ivp at rtol 1e-6 (measured: bdf 1.3e-5, radau 6.5e-12, rk45 3.2e-12) and 1e-9 (bdf
    1.7e-8; rk45 1.7e-11: the reference's own round-off)."""
    measure = semi_discrete[0]
    error, drift = measure(f"app.integrator={scheme}", "app.dt=0.01")
    tight, _ = measure(f"app.integrator={scheme}", "app.dt=0.01", "app.rtol=1e-9", "app.atol=1e-12")
    assert error < 1e-4 and tight < 1e-7 and (tight < error / 100 or tight < 1e-10), (error, tight)
    assert drift < 1e-12


def test_an_adaptive_integrator_runs_past_a_step_whose_span_rounds_below_dt():
    """(t + dt) − t < dt in floating point at some steps: the first step handed to solve_ivp
    (the last accepted one, ≤ dt) must not exceed that span (it raised SciPy's "first_step
    exceeds bounds" after ~15 steps of 0.001)."""
    metrics = run("app=heat", "mesh.subdiv=1", "app.integrator=rk45", "app.dt=0.001", "app.t_end=0.05").result.metrics
    assert metrics["stable"] is True and metrics["steps_done"] == 50


DIRICHLET_CASES = [("crank_nicolson", 2, 0.0005, "circumcentric"), ("rk4", 4, 0.0002, "circumcentric"),
                   ("rk45", None, 0.005, "circumcentric"), ("crank_nicolson", 2, 0.0005, "whitney"),
                   ("rk4", 4, 0.0001, "whitney"), ("bdf", None, 0.005, "whitney")]


@pytest.mark.parametrize("scheme, order, dt, operator", DIRICHLET_CASES)
def test_dirichlet_values_hold_from_t0_so_every_scheme_keeps_its_order(scheme, order, dt, operator):
    """Heat on the square with border values g = 0.5 + x and an initial value that disagrees
    with them on the border, against the semi-discrete solution of the interior rows
    M_II u_I' = −S_II u_I − S_IB g_B (u = g on the border for t ≥ 0).

    Two bugs: the first step saw the initial value's border (step 0 recorded it) — an O(dt)
    error that made Crank–Nicolson and RK4 first order (CN 1.1e-3 → 5.5e-4, now 5.5e-6 →
    1.4e-6) and put rk45 2.3e-2 off; and with Whitney's Galerkin ⋆0 the explicit and adaptive
    schemes took F_I of F = M⁻¹(−S u), whose border rows M⁻¹ spreads inward: 4.2e-2 off where
    Crank–Nicolson was 5e-6 (now RK4 9e-13, bdf 3e-6)."""
    from scipy.linalg import expm

    errors = []
    for step in (dt, dt / 2) if order else (dt,):
        done = run("app=heat", "mesh=grid", "mesh.nx=9", "mesh.ny=9", f"operator={operator}",
                   "app.fields.u.initial='1 + x*y + sin(3*x)'", "+app.fields.u.dirichlet='0.5 + x'",
                   f"app.integrator={scheme}", f"app.dt={step}", "app.t_end=0.05")
        x, y = done.mesh.vertices[:, 0], done.mesh.vertices[:, 1]
        border = np.isclose(x, x.min()) | np.isclose(x, x.max()) | np.isclose(y, y.min()) | np.isclose(y, y.max())
        inner, g = ~border, 0.5 + x
        dec = done.dec
        S, M = (dec.d(0).T @ dec.star(1) @ dec.d(0)).toarray(), dec.star(0).toarray()
        M_II = M[np.ix_(inner, inner)]
        A = np.zeros((inner.sum() + 1,) * 2)  # the constant forcing as an extra unknown
        A[:-1, :-1] = -np.linalg.solve(M_II, S[np.ix_(inner, inner)])
        A[:-1, -1] = -np.linalg.solve(M_II, S[np.ix_(inner, border)] @ g[border])
        exact = g.copy()
        exact[inner] = (expm(0.05 * A) @ np.append((1 + x * y + np.sin(3 * x))[inner], 1.0))[:-1]
        u, series = done.result.fields["u"], done.result.series["u"]
        assert np.array_equal(u[border], g[border]) and np.array_equal(series[0][border], g[border])
        errors.append(np.linalg.norm(u - exact) / np.linalg.norm(exact))
    if order is None:
        assert errors[0] < 1e-5, errors
    else:
        assert math.log2(errors[0] / errors[1]) > order - 0.2 and errors[1] < 2e-6, errors


# ---------------------------------------------------------------------- explicit stability limit
def test_an_explicit_dt_beyond_2_over_lambda_max_is_refused_before_stepping_and_its_hint_runs(tmp_path):
    done = run("app=heat")  # λ_max of ⋆0⁻¹ S on the default mesh (subdiv 3 sphere)
    dec = done.dec
    from scipy.sparse.linalg import eigsh

    lam = eigsh(stiffness(dec), k=1, M=sp.diags(dec.star_diagonal(0)), which="LM", return_eigenvectors=False)[0]
    refused = decrun("app=heat", "app.integrator=explicit_euler", "app.dt=0.01", *FAST,
                     f"hydra.run.dir={tmp_path / 'refused'}", cwd=tmp_path)
    line = one_line(refused.stderr)
    assert refused.returncode == 1 and line.startswith("error: app.dt=0.01 exceeds the stability limit")
    assert f"{2 / lam:.3g}" in line  # 2/λ_max ≈ 0.0065
    assert not (tmp_path / "refused" / "result.h5").exists()
    hint = re.search(r"`(app\.dt=\S+)`", line).group(1)
    safe = float(hint.split("=")[1])
    assert safe < 2 / lam and abs(0.1 / safe - round(0.1 / safe)) < 1e-9
    ok = decrun("app=heat", "app.integrator=explicit_euler", hint, *FAST, f"hydra.run.dir={tmp_path / 'ok'}",
                cwd=tmp_path)
    assert ok.returncode == 0, ok.stderr
    metrics = json.loads((tmp_path / "ok" / "metrics.json").read_text())
    assert metrics["stable"] is True and metrics["steps_done"] == round(0.1 / safe)
    assert metrics["dt_stability_limit"] == pytest.approx(2 / lam, rel=1e-6)
    # RK4's interval is 2.785: refused in prepare, before any step
    with pytest.raises(DecrunError, match=r"^app.dt=0.02 exceeds the stability limit .* for dt\(u\)"):
        prepare(compose_config(["app=heat", "app.integrator=rk4", "app.dt=0.02"]))


# ---------------------------------------------------------------------------------------- poisson
def test_poisson_on_the_square_converges_at_second_order():
    """The shipped manufactured solution: measured 5.01e-3, 1.14e-3, 2.75e-4 (orders 2.13, 2.05)."""
    errors = [run("app=poisson", f"mesh.nx={n}", f"mesh.ny={n}").result.metrics["l2_error_rel"] for n in (9, 17, 33)]
    assert errors[2] < 5e-4 and min(orders(errors)) >= 1.8, errors


DISK_U = "exp(x)*sin(2*y)"  # Δu = −3 eˣ sin 2y


def disk(n: int, max_area: float) -> list[str]:
    """mesh=planar with a regular n-gon of radius 1 (no holes)."""
    outer = ",".join(f"[{math.cos(2 * math.pi * i / n):.17g},{math.sin(2 * math.pi * i / n):.17g}]" for i in range(n))
    return ["mesh=planar", f"mesh.outer=[{outer}]", "mesh.holes=[]", f"mesh.max_area={max_area}"]


def test_poisson_on_a_disk_with_manufactured_dirichlet_values_converges_at_second_order():
    """64-, 128-, 256-gons, max_area /4 each (282, 1060, 4020 vertices): measured 1.62e-3,
    4.55e-4, 1.12e-4 (orders 1.83, 2.02; max |error| 7.6e-3, 2.4e-3, 5.8e-4). Triangle's meshes
    are deterministic: the coarse order is what this mesh gives, not noise."""
    model = ["app=poisson", f"app.fields.u.dirichlet='{DISK_U}'",
             f"app.equations=['solve(laplacian(u) = -3*{DISK_U})']",
             f"app.metrics={{l2_error_rel: 'norm(u - {DISK_U})/norm({DISK_U})', max_abs_error: 'max(abs(u - {DISK_U}))'}}"]
    errors = []
    for n, area in ((64, 0.01), (128, 0.0025), (256, 0.000625)):
        metrics = run(*model, *disk(n, area)).result.metrics
        assert metrics["stable"] is True and "u_kernel_pieces" not in metrics  # the border fixes the constant
        errors.append(metrics["l2_error_rel"])
    assert errors[2] < 2e-4 and min(orders(errors)) >= 1.8, errors


SPHERE_POISSON = ["app=poisson", "mesh=icosphere_clean", "app.fields.u.dirichlet=null"]


def test_poisson_on_the_closed_sphere_fixes_the_mean_and_meets_xy_at_second_order():
    """Δu = −6xy: u = xy (zero mean). Measured 2.33e-2, 5.78e-3, 1.44e-3 (orders 2.01, 2.00)."""
    errors = []
    for subdiv in (2, 3, 4):
        metrics = run(*SPHERE_POISSON, f"mesh.subdiv={subdiv}", "app.equations=['solve(laplacian(u) = -6*x*y)']",
                      "app.metrics={l2_error_rel: 'norm(u - x*y)/norm(x*y)', max_abs_error: 'integral(u)'}"
                      ).result.metrics
        assert metrics["u_kernel_pieces"] == 1 and metrics["u_rhs_mean_removed"] < 1e-14
        assert abs(metrics["max_abs_error"]) < 1e-12  # here: ∫u, the fixed mean
        errors.append(metrics["l2_error_rel"])
    assert min(orders(errors)) >= 1.8, errors


def absolute_integral_on_sphere(c: float) -> float:
    """∫_{S²} |c − 6xy| dA on the unit sphere, exactly up to quadrature round-off: with
    6xy = A sin 2φ, A = 3 sin²θ, the ring integral ∫_0^{2π} |c − A sin 2φ| dφ is
    4cα + 4√(A² − c²) (α = arcsin(c/A)) for A > c and 2πc otherwise."""
    from scipy.integrate import quad

    def ring(theta):
        amplitude = 3 * math.sin(theta) ** 2
        if amplitude <= c:
            return 2 * math.pi * c * math.sin(theta)
        return (4 * c * math.asin(c / amplitude) + 4 * math.sqrt(amplitude**2 - c**2)) * math.sin(theta)

    return quad(ring, 0, math.pi, epsabs=1e-13, epsrel=1e-13, limit=200)[0]


def test_a_small_real_mean_on_the_closed_sphere_is_removed_and_logged_exactly(tmp_path):
    """Δu = −6xy + 0.02 through the real command: the compatible part −6xy has the exact answer
    u = xy (zero mean), the mean 0.02 has none and is subtracted. The metric and the log line
    say the subtracted mean (0.02 to round-off: the icosphere is symmetric under x → −x) and its
    relative part 0.02·4π / ∫|f| (0.015706; measured 0.015759, 0.015714 at subdiv 3, 4: the mesh's O(h²)).
    Errors to xy: 5.78e-3, 1.44e-3 (subdiv 3, 4) — second order, as with a zero-mean side."""
    c, errors = 0.02, []
    relative = c * 4 * math.pi / absolute_integral_on_sphere(c)
    for subdiv in (3, 4):
        out = tmp_path / f"s{subdiv}"
        proc = decrun(*SPHERE_POISSON, f"mesh.subdiv={subdiv}", f"app.equations=['solve(laplacian(u) = -6*x*y + {c})']",
                      "app.metrics.l2_error_rel='norm(u - x*y)/norm(x*y)'", "app.metrics.max_abs_error='integral(u)'",
                      *FAST, f"hydra.run.dir={out}", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
        metrics = json.loads((out / "metrics.json").read_text())
        assert metrics["u_rhs_mean"] == pytest.approx(c, rel=1e-10)
        assert metrics["u_rhs_mean_removed"] == pytest.approx(relative, rel=5e-3)  # the mesh's O(h²)
        assert "the right side's mean 0.02 " in proc.stdout + proc.stderr
        assert abs(metrics["max_abs_error"]) < 1e-12  # ∫u: the fixed mean
        errors.append(metrics["l2_error_rel"])
    assert errors[1] < 2e-3 and min(orders(errors)) >= 1.8, errors


def test_a_right_side_with_nonzero_mean_on_a_closed_surface_is_refused_with_one_line(tmp_path):
    proc = decrun(*SPHERE_POISSON, "app.equations=['solve(laplacian(u) = z + 1)']", *FAST,
                  f"hydra.run.dir={tmp_path / 'r'}", cwd=tmp_path)
    line = one_line(proc.stderr)
    assert proc.returncode == 1 and line.startswith("error: app.equations[0]: ") and "singular" in line
    assert "subtract its mean" in line and not (tmp_path / "r" / "result.h5").exists()


# ------------------------------------------------------------------------------------------- wave
def l2_frequency(series) -> float:
    """ω of the recorded ``projection`` ≈ a cos(ωt) + b (least squares)."""
    from scipy.optimize import curve_fit

    (a, omega, b), _ = curve_fit(lambda t, a, w, b: a * np.cos(w * t) + b, series["time"], series["projection"],
                                 p0=[1.0, math.sqrt(6), 0.0])
    assert abs(a - 1) < 1e-3 and abs(b) < 1e-3
    return omega


def test_wave_keeps_its_modified_energy_and_rings_at_sqrt6_to_second_order():
    """Störmer–Verlet over 10 periods (5130 steps): the modified energy drifts 1.4e-15
    (subdiv 3) — the plain one 3.7e-5; ω − √6: −6.95e-3 (subdiv 3), −1.73e-3 (subdiv 4),
    ratio 4.02 (Verlet's own shift, ω²dt²/24 ≈ 6e-6, is far below)."""
    errors = []
    for subdiv in (3, 4):
        done = run("app=wave", f"mesh.subdiv={subdiv}")
        series, metrics = done.result.series, done.result.metrics
        assert metrics["steps_done"] == 5130 and metrics["stable"] is True
        assert series["time"][-1] == pytest.approx(25.65) and len(series["time"]) == 514
        energy = series["energy_modified"]
        assert np.abs(energy - energy[0]).max() <= 1e-10 * energy[0]
        errors.append(abs(l2_frequency(series) - math.sqrt(6)))
    assert errors[1] < 2e-3 and errors[0] / errors[1] > 3.5, errors


# -------------------------------------------------------------------------------------------- mcf
@pytest.mark.parametrize("operator", ["circumcentric", "whitney"])
def test_mcf_is_the_implicit_smoothing_step_to_round_off(operator):
    """Measured: 1.7e-15 (circumcentric), 1.5e-15 (Whitney's Galerkin ⋆0), relative max."""
    common = [f"operator={operator}", "app.dt=0.003", "app.steps=1"]
    model = run("app=mcf", *common).result.fields
    smoothing = run("app=smoothing", "app.scheme=implicit", "app.rescale=none", *common).result.fields
    moved = np.stack([model["vx"], model["vy"], model["vz"]], axis=1)
    final = smoothing["vertices_final"]
    assert np.abs(moved - final).max() <= 1e-12 * np.abs(final).max()
    assert np.abs(final - smoothing["vertices_initial"]).max() > 1e-3  # the step moved the noisy sphere


# -------------------------------------------------------------------------------- heat geodesics
def test_heat_geodesics_on_the_sphere_is_within_one_percent_at_20k_faces_and_improves():
    """Mean relative error to arccos(p·s): 1.15 % at 5120 faces, 0.86 % at 20480."""
    coarse, fine = (run("+experiment=heat_geodesics_sphere", f"mesh.subdiv={s}").result.metrics for s in (4, 5))
    assert fine["n_faces"] == 20480 and fine["mean_relative_error"] <= 0.01
    assert fine["mean_relative_error"] < coarse["mean_relative_error"]


def test_heat_geodesics_on_the_bunny_equals_potpourri3d_once_its_shift_is_accounted_for():
    """potpourri3d (geometry-central's HeatMethodDistanceSolver, use_robust=False): cotan L,
    barycentric lumped mass (decrun's operator=barycentric), t = t_coef · mean edge length², a
    vertex source's right side its indicator, and (L + 1e-6 I) φ = ∇·X in step 3, then φ(s) = 0.
    The model's own right side (a definition added to the shipped equations) solved with that
    shift equals potpourri3d to 3e-14 relative; decrun's unshifted distance differs by 2.3e-4
    (relative L2; 2.8e-4 relative max)."""
    pp3d = pytest.importorskip("potpourri3d")
    source = 100
    equations = ["solve(u - m*h**2*laplacian(u) = delta)", "X = -sharp(d(u)) / norm(sharp(d(u)))",
                 "rhs = -codifferential(flat(X))", "solve(laplacian(phi) = rhs)",
                 "distance = phi - integral(delta*phi) / integral(delta)"]
    done = run("app=heat_geodesics", "mesh=bunny", "operator=barycentric", f"app.constants.source={source}",
               f"app.equations={json.dumps(equations)}")
    fields, dec = done.result.fields, done.dec
    V, F = done.mesh.vertices, done.mesh.simplices
    reference = pp3d.MeshHeatMethodDistanceSolver(V, F, t_coef=1.0, use_robust=False).compute_distance(source)
    S = stiffness(dec)
    b = -dec.star_diagonal(0) * fields["rhs"]  # Δφ = rhs is −⋆0⁻¹ S φ = rhs
    assert np.abs(S @ fields["phi"] - b).max() < 1e-9 * np.abs(b).max()  # the model solved it
    shifted = spsolve((S + 1e-6 * sp.identity(S.shape[0])).tocsc(), b)
    shifted -= shifted[source]
    assert np.linalg.norm(shifted - reference) <= 1e-12 * np.linalg.norm(reference)
    difference = np.linalg.norm(fields["distance"] - reference) / np.linalg.norm(reference)
    assert 1e-5 < difference < 1e-3  # the shift alone (MODELS.md: ~3e-4)
    assert fields["distance"][source] == 0 and done.result.metrics["phi_kernel_pieces"] == 1


# ------------------------------------------------------------------------------ the real command
def test_decrun_app_heat_as_written_writes_its_fields_series_and_figures(tmp_path):
    proc = decrun("app=heat", "progress=false", "export=vtu", "hydra.run.dir=run", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "run"
    recorded = read_result(out / "result.h5")
    assert recorded.complete and set(recorded.fields) == {"u"} and recorded.fields["u"].shape == (642,)
    assert {"time", "u", "mass", "dirichlet_energy"} <= set(recorded.series)
    assert recorded.series["u"].shape == (11, 642)  # record_every 10 over 100 steps, and step 0
    assert "dt(u) = k * laplacian(u)" in str(recorded.provenance["model_equations_resolved"])
    metrics = json.loads((out / "metrics.json").read_text())
    assert abs(metrics["mass"]) < 1e-12 and metrics["dirichlet_energy"] > 0
    for name in ("u.png", "u_snapshots.png", "u_animation.gif", "metrics.png"):
        assert (out / name).is_file(), name
    import meshio

    mesh = meshio.read(out / "result.vtu")
    assert np.array_equal(mesh.point_data["u"], recorded.fields["u"])


def test_heat_on_the_torus_with_whitney_and_k_2(tmp_path):
    proc = decrun("app=heat", "app.constants.k=2", "mesh=torus", "operator=whitney", *FAST, "hydra.run.dir=run",
                  cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    recorded = read_result(tmp_path / "run" / "result.h5")
    energy, mass = recorded.series["dirichlet_energy"], recorded.series["mass"]
    assert np.all(np.diff(energy) < 0)  # diffusion
    assert np.abs(mass - mass[0]).max() < 1e-12  # ∫u = 1ᵀ M u with Whitney's Galerkin ⋆0
    assert recorded.metrics["integrator"] == "crank_nicolson" and recorded.metrics["steps_done"] == 100


def test_a_sweep_of_the_heat_model_has_its_declared_metrics_as_columns(tmp_path):
    proc = decrun("-m", "app=heat", "app.constants.k=0.5,1,2", "mesh.subdiv=3,4", *FAST, "hydra.sweep.dir=s",
                  cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    table = pd.read_csv(tmp_path / "s" / "metrics.csv")
    assert len(table) == 6 and (table["status"] == "ok").all()
    assert {"app.constants.k", "mesh.subdiv", "mass", "dirichlet_energy"} <= set(table.columns)
    # ⟨du, du⟩ of e^{−6kt} xy at t = 0.1: 6 e^{−1.2k} ∫(xy)² = 6 e^{−1.2k} 4π/15
    exact = 6 * np.exp(-1.2 * table["app.constants.k"]) * 4 * np.pi / 15
    assert np.all(np.abs(table["dirichlet_energy"] / exact - 1) < 0.01)
    assert np.all(np.abs(table["mass"]) < 1e-12)


def test_an_initial_value_override_and_a_users_own_model_on_the_searchpath(tmp_path):
    proc = decrun("app=heat", 'app.fields.u.initial="z*(5*z**2-3)"', "+app.metrics.decay='inner(u, z)'", *FAST,
                  "hydra.run.dir=initial", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    recorded = read_result(tmp_path / "initial" / "result.h5")
    V = recorded.mesh["vertices"]
    np.testing.assert_allclose(recorded.series["u"][0], V[:, 2] * (5 * V[:, 2] ** 2 - 3), rtol=0, atol=1e-15)
    assert abs(recorded.metrics["decay"]) < 1e-12  # l = 3 stays orthogonal to z (l = 1)
    # a model that is only YAML, in the user's own config directory
    conf = tmp_path / "my_conf" / "app"
    conf.mkdir(parents=True)
    (conf / "mymodel.yaml").write_text(
        "_target_: decrun.apps.model.Model\n"
        "model: decay\n"
        "fields:\n  c: {form: 0, initial: z}\n"
        "constants: {D: 0.5, r: 1.0}\n"
        "equations:\n  - 'dt(c) = D*laplacian(c) - r*c'\n"
        "integrator: crank_nicolson\ndt: 0.0005\nt_end: 0.2\nrecord_every: 100\n"
        "metrics:\n  l2_error_rel: 'norm(c - exp(-(2*D + r)*t)*z) / norm(exp(-(2*D + r)*t)*z)'\n")
    proc = decrun(f"hydra.searchpath=[file://{tmp_path / 'my_conf'}]", "app=mymodel", "mesh=icosphere_clean", *FAST,
                  "hydra.run.dir=mine", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    recorded = read_result(tmp_path / "mine" / "result.h5")
    assert set(recorded.fields) == {"c"} and recorded.metrics["l2_error_rel"] < 5e-4
    assert recorded.metrics["steps_done"] == 400 and len(recorded.series["c"]) == 5




def kill_after_checkpoint(args, checkpoint: Path, cwd) -> None:
    """Start ``decrun *args`` and SIGKILL it once ``checkpoint`` exists."""
    proc = start(*args, cwd=cwd)
    deadline = time.monotonic() + 120
    while not checkpoint.exists():
        assert proc.poll() is None, f"ended before its first checkpoint: {proc.communicate()}"
        assert time.monotonic() < deadline
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=30)


def test_a_killed_model_run_continues_from_its_checkpoint_bit_for_bit(tmp_path):
    """The wave (subdiv 4, 20 periods: 10260 steps) killed with SIGKILL after checkpoint.h5
    appeared and rerun with the same command: fields and series equal to an uninterrupted
    run's, bitwise. (A fixed-step integrator's state is empty, so the checkpoint holds no
    `integrator` group: resuming raised KeyError: 'integrator'.)"""
    args = ["app=wave", "mesh.subdiv=4", "app.t_end=51.3", "app.record_every=100", "checkpoint.steps=100", *FAST]
    reference = decrun(*args, "hydra.run.dir=reference", cwd=tmp_path)
    assert reference.returncode == 0, reference.stderr
    run_dir = tmp_path / "killed"
    kill_after_checkpoint([*args, f"hydra.run.dir={run_dir}"], run_dir / CHECKPOINT, tmp_path)
    assert not (run_dir / "result.h5").exists()
    again = decrun(*args, f"hydra.run.dir={run_dir}", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert "checkpoint: continuing from step" in (run_dir / "decrun.log").read_text()
    resumed = json.loads((run_dir / "metrics.json").read_text())
    assert 0 < resumed["resumed_from_step"] < 10260 and resumed["steps_done"] == 10260
    first, second = result_contents(tmp_path / "reference" / "result.h5"), result_contents(run_dir / "result.h5")
    assert first.keys() == second.keys() and second["complete"]
    for key in first:
        assert np.array_equal(first[key], second[key]), key
    assert not (run_dir / CHECKPOINT).exists()


# -------------------------------------------------------------------------------------- bad input
BAD = [
    (['app.equations=["dt(u) = k * lapalcian(u)"]'], "app.equations[0]: unknown operator 'lapalcian'",
     "did you mean 'laplacian'"),
    (['app.equations=["dt(u) = k * d(u)"]'], "app.equations[0]: k * d(u) is a primal 1-form but dt(u) is a "
     "primal 0-form", ""),
    (["app.fields.u.initial=null"], "app.fields.u.initial: missing initial value", "app.fields.u.initial=0"),
    (["app=poisson", 'app.equations=["solve(laplacian(x) = 1)"]'], "app.equations[0]: the solve has no unknown",
     "app.fields"),
    (["app.constants.k=nan"], "app.constants.k: must be a finite number, got nan", ""),
    (["app.integrator=foo"], "app.integrator: must be one of explicit_euler", "got 'foo'"),
    (["app.fields.u.form=7"], "app.fields.u.form: form must be 0 | 1 | 2 | 3", ""),
    # the integrator's own checks, when the model loads (they were raised at the app's set-up)
    (["app.integrator=symplectic"], "app.equations[0]: integrator=symplectic needs pairs", "app.integrator=rk4"),
    # Crank–Nicolson takes u**3 by Newton (issue 47); a term without an exact Jacobian is refused
    (['app.equations=["dt(u) = k*laplacian(u) - u*integral(u)"]'], "app.equations[0]: integral(u): a number "
     "computed from u couples all its values", "app.integrator=rk4"),
]


@pytest.mark.parametrize("overrides, starts, contains", BAD)
def test_bad_input_is_one_line_naming_the_key_before_any_work(overrides, starts, contains):
    with pytest.raises(DecrunError) as refused:
        prepare(compose_config(["app=heat", *overrides]))  # prepare: before the app's run
    message = str(refused.value)
    assert "\n" not in message and message.startswith(starts) and contains in message, message


def test_bad_input_through_the_command_and_the_t_end_hint_runs(tmp_path):
    for overrides, starts, _ in (BAD[4],):
        proc = decrun("app=heat", *overrides, *FAST, "hydra.run.dir=bad", cwd=tmp_path)
        assert proc.returncode == 1 and one_line(proc.stderr) == f"error: {proc.stderr.strip()[7:]}"
        assert starts in proc.stderr and not (tmp_path / "bad" / "result.h5").exists()
    proc = decrun("app=heat", "app.dt=0.003", *FAST, "hydra.run.dir=bad", cwd=tmp_path)
    line = one_line(proc.stderr)
    assert line.startswith("error: app.t_end=0.1 is not a whole number of steps of app.dt=0.003")
    hint = re.search(r"`(app\.dt=\S+)`", line).group(1)
    proc = decrun("app=heat", hint, *FAST, "hydra.run.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    metrics = json.loads((tmp_path / "fixed" / "metrics.json").read_text())
    assert metrics["steps_done"] == 34 and metrics["t_final"] == pytest.approx(0.1, rel=1e-12)


def test_the_t_end_refusals_other_hint_runs():
    """The second hint, `app.steps=N app.t_end=null`, runs as printed (every model's YAML lists
    `steps` through conf/app/_model.yaml, so no `+` is needed)."""
    with pytest.raises(DecrunError) as refused:
        prepare(compose_config(["app=heat", "app.dt=0.003"]))
    hint = re.search(r"\(or `([^`]+)`\)", str(refused.value)).group(1)
    assert hint == "app.steps=33 app.t_end=null"
    metrics = run("app=heat", "app.dt=0.003", *hint.split()).result.metrics
    assert metrics["steps_done"] == 33 and metrics["t_final"] == pytest.approx(0.099)


@pytest.mark.slow
def test_a_killed_sweep_of_an_adaptive_model_resumes_bit_for_bit(tmp_path):
    """rk45 keeps its last accepted step size in the checkpoint: a sweep job killed after its
    checkpoint, resumed with hydra.sweeper.resume=true, repeats the uninterrupted job's steps."""
    args = ["app=heat", "app.integrator=rk45", "mesh.subdiv=4", "app.dt=0.002", "app.t_end=1", "checkpoint.steps=20",
            *FAST]
    reference = decrun(*args, "hydra.run.dir=reference", cwd=tmp_path)
    assert reference.returncode == 0, reference.stderr
    sweep = tmp_path / "sweep"
    multirun = ["-m", *args, f"hydra.sweep.dir={sweep}"]
    kill_after_checkpoint(multirun, sweep / "0" / CHECKPOINT, tmp_path)
    proc = decrun(*multirun, "hydra.sweeper.resume=true", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    resumed = json.loads((sweep / "0" / "metrics.json").read_text())
    assert 0 < resumed["resumed_from_step"] < 500 and resumed["steps_done"] == 500
    first, second = result_contents(tmp_path / "reference" / "result.h5"), result_contents(sweep / "0" / "result.h5")
    assert first.keys() == second.keys() and second["complete"]
    for key in first:
        assert np.array_equal(first[key], second[key]), key
