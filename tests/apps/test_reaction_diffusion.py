"""Reaction–diffusion models of the model app (conf/app/gray_scott.yaml, brusselator.yaml,
cahn_hilliard.yaml): each against the same scheme written by hand in numpy, or against its
linear theory (MODELS.md, "Reaction–diffusion")."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.core.solvers import solver_factory
from decrun.methods.model.integrators import make_integrator
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import prepare, run_experiment


def prepared(overrides):
    """(app, dec, compiled model, integrator) of ``decrun <overrides>`` with the default solver
    (``auto``: CHOLMOD for these SPD systems), nothing run yet."""
    run = prepare(compose_config(list(overrides) + ["figures=false"]))
    app, dec = run.experiment.app, run.dec
    model = app.compiled(dec, solver_factory("auto"))
    integrator = make_integrator(model, str(app.integrator), app.dt, solver_factory("auto"))
    return app, dec, model, integrator


def metrics(overrides):
    return run_experiment(compose_config(list(overrides) + ["figures=false"])).result.metrics


def mass_and_stiffness(dec):
    """M = ⋆0 (diagonal) and S = d0ᵀ ⋆1 d0 (the cotan stiffness), straight from DEC."""
    m = np.asarray(dec.star(0).diagonal(), dtype=np.float64)
    S = (dec.d(0).T @ dec.star(1) @ dec.d(0)).tocsc()
    return m, S


def steps(model, integrator, count):
    state = {u: np.array(model.initial_values[u], dtype=np.float64) for u in model.evolved}
    for n in range(count):
        state = integrator.step(state, n * integrator.dt)
    return state


# ---------------------------------------------------------------------------- Gray–Scott
def test_gray_scott_equals_the_hand_written_imex_step():
    """100 IMEX Euler steps of the model equal the same scheme written with M = ⋆0 and
    S = d0ᵀ⋆1d0: every linear term implicit, the rest explicit, one factorization each."""
    app, dec, model, integrator = prepared(["app=gray_scott"])
    c = app.constants
    Du, Dv, F, k, dt = c["Du"], c["Dv"], c["F"], c["k"], app.dt
    m, S = mass_and_stiffness(dec)
    M = sp.diags(m)
    solve_u = spla.factorized((M + dt * (Du * S + F * M)).tocsc())
    solve_v = spla.factorized((M + dt * (Dv * S + (F + k) * M)).tocsc())
    u = np.array(model.initial_values["u"])
    v = np.array(model.initial_values["v"])
    for _ in range(100):
        uvv = u * v * v
        u, v = solve_u(m * u + dt * m * (F - uvv)), solve_v(m * v + dt * m * uvv)
    state = steps(model, integrator, 100)
    assert np.abs(state["u"] - u).max() <= 1e-12 * np.abs(u).max()
    assert np.abs(state["v"] - v).max() <= 1e-12 * max(np.abs(v).max(), 1e-300)
    assert np.abs(v).max() > 0.1  # the comparison is not of two zero fields


def test_gray_scott_default_grows_a_pattern_and_a_stable_pair_stays_uniform():
    """The default (spots) pair forms a pattern (v_std > 0.02); at (F, k) = (0.06, 0.075)
    (beyond the spot region) the seed dies and the uniform (u, v) = (1, 0) remains."""
    spots = metrics(["app=gray_scott", "app.steps=1500"])
    assert spots["stable"] and spots["v_std"] > 0.02 and spots["pattern"] == 1.0
    uniform = metrics(["app=gray_scott", "app.steps=1500", "app.constants.F=0.06", "app.constants.k=0.075"])
    assert uniform["stable"] and uniform["v_std"] < 1e-6 and uniform["pattern"] == 0.0
    assert abs(uniform["u_min"] - 1) < 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("experiment, F, k, formed", [
    ("gray_scott_pearson", 0.035, 0.065, True), ("gray_scott_pearson", 0.04, 0.06, True),
    ("gray_scott_pearson", 0.06, 0.075, False), ("gray_scott_sphere", 0.035, 0.065, True),
    ("gray_scott_sphere", 0.04, 0.06, True), ("gray_scott_sphere", 0.06, 0.075, False)])
def test_gray_scott_pearson_regimes_on_the_square_and_the_sphere(experiment, F, k, formed):
    result = metrics([f"+experiment={experiment}", f"app.constants.F={F}", f"app.constants.k={k}"])
    assert result["stable"] and (result["v_std"] > 0.02) == formed and result["pattern"] == float(formed)


# ---------------------------------------------------------------------------- Brusselator
def extrema_growth_rate(times, values):
    """σ of values ≈ e^{σt}(a cos ωt + b sin ωt): the local extrema of such a function are
    equally spaced (tan(ωt + φ) = σ/ω) and grow by e^{σπ/ω} from one to the next, so the slope
    of a least-squares line through (t_i, log|values(t_i)|) at the sampled extrema is σ.
    Each extremum is located by a parabola through the three samples around it."""
    t, f = np.asarray(times), np.asarray(values)
    points = []
    for i in range(1, len(f) - 1):
        if (f[i] - f[i - 1]) * (f[i + 1] - f[i]) < 0:
            a = 0.5 * (f[i + 1] - 2 * f[i] + f[i - 1])
            b = 0.5 * (f[i + 1] - f[i - 1])
            s = -b / (2 * a)
            points.append((t[i] + s * (t[1] - t[0]), abs(f[i] + b * s + a * s * s)))
    ts, amplitudes = np.array(points).T
    return np.polyfit(ts, np.log(amplitudes), 1)[0], len(ts)


@pytest.mark.parametrize("B", [1.8, 2.2])
def test_brusselator_growth_rate_matches_the_linearized_eigenvalue(B):
    """Below (B = 1.8) and above (B = 2.2) the Hopf point B = 1 + A² = 2: a homogeneous
    perturbation eps = 1e-6 of (A, B/A) decays/grows at Re λ of J = [[B−1, A²], [−B, −A²]]
    (numpy's eigenvalues), to 5 % — measured from the extrema of u − A over 30 time units
    (about 5 periods), and by the model's own metric growth_rate_measured."""
    A = 1.0
    overrides = ["app=brusselator", f"app.constants.B={B}", "app.constants.eps=1e-6"]
    app, dec, model, integrator = prepared(overrides)
    sigma = np.linalg.eigvals(np.array([[B - 1, A * A], [-B, -A * A]])).real.max()
    state = {u: np.array(model.initial_values[u]) for u in model.evolved}
    times, deviation = [0.0], [float(np.mean(state["u"])) - A]
    for n in range(app.total_steps()):
        state = integrator.step(state, n * app.dt)
        times.append((n + 1) * app.dt)
        deviation.append(float(np.mean(state["u"])) - A)
    assert np.ptp(state["u"]) < 1e-12  # homogeneous it stays (diffusion sees no gradient)
    measured, extrema = extrema_growth_rate(times, deviation)
    assert extrema >= 8
    assert measured == pytest.approx(sigma, rel=0.05)
    assert (measured > 0) == (B > 1 + A * A)
    result = metrics(overrides)
    assert result["growth_rate_linear"] == pytest.approx(sigma, rel=1e-12)
    assert result["growth_rate_measured"] == pytest.approx(sigma, rel=0.05)


# ---------------------------------------------------------------------------- explicit(·)
def test_explicit_keeps_a_linear_term_out_of_the_implicit_matrix():
    """imex on dt(u) = k Δ explicit(u) is explicit Euler on dt(u) = k Δu (to round-off), while
    imex on dt(u) = k Δu is implicit Euler; every other integrator reads explicit(u) as u."""
    base = ["app=heat", "mesh.subdiv=2", "app.dt=1e-4"]
    lagged = 'app.equations=["dt(u) = k*laplacian(explicit(u))"]'
    *_, model, imex = prepared([*base, lagged, "app.integrator=imex"])
    assert not imex.evolution.blocks  # nothing implicit
    *_, model_e, euler = prepared([*base, "app.integrator=explicit_euler"])
    *_, model_i, implicit = prepared([*base, "app.integrator=implicit_euler"])
    *_, model_r, rk4_lagged = prepared([*base, lagged, "app.integrator=rk4"])
    *_, model_r2, rk4 = prepared([*base, "app.integrator=rk4"])
    a, b = steps(model, imex, 20), steps(model_e, euler, 20)
    assert np.abs(a["u"] - b["u"]).max() <= 1e-13 * np.abs(b["u"]).max()
    assert np.abs(a["u"] - steps(model_i, implicit, 20)["u"]).max() > 1e-9  # and it is a different scheme
    assert np.abs(steps(model_r, rk4_lagged, 20)["u"] - steps(model_r2, rk4, 20)["u"]).max() == 0


# ---------------------------------------------------------------------------- Cahn–Hilliard
PLAIN_CH = 'app.equations=["dt(c) = D*laplacian(c**3 - c - g*laplacian(c))"]'


def cahn_hilliard_run(overrides, count):
    """(relative mass drift, free energies at every step, final c) of ``count`` steps;
    mass Σ⋆0 c and E = Σ⋆0 (c² − 1)²/4 + γ/2 dcᵀ⋆1 dc computed here from DEC's ⋆0, ⋆1, d0."""
    app, dec, model, integrator = prepared(["app=cahn_hilliard", *overrides])
    g = app.constants["g"]
    m, star1, d0 = np.asarray(dec.star(0).diagonal()), dec.star(1), dec.d(0)

    def energy(c):
        dc = d0 @ c
        return float(m @ ((c * c - 1) ** 2 / 4) + 0.5 * g * dc @ (star1 @ dc))

    state = {"c": np.array(model.initial_values["c"])}
    mass0, energies = float(m @ state["c"]), [energy(state["c"])]
    for n in range(count):
        state = integrator.step(state, n * app.dt)
        energies.append(energy(state["c"]))
    return abs(float(m @ state["c"]) - mass0) / abs(mass0), np.array(energies), state["c"]


def test_cahn_hilliard_conserves_mass_and_its_energy_never_increases():
    """The default (stabilized imex, dt = 1e-3): mass to 1e-12 relative over 1000 steps; the
    free energy non-increasing at every step while the mixture separates (c reaches ±1)."""
    drift, energies, c = cahn_hilliard_run([], 1000)
    assert drift < 1e-12
    assert np.all(np.diff(energies) <= 1e-14 * energies[0])
    assert energies[-1] < 0.5 * energies[0] and c.min() < -0.9 and c.max() > 0.9


@pytest.mark.parametrize("dt", [1e-2, 1e-1])
def test_cahn_hilliard_stabilized_scheme_is_energy_stable_at_large_steps(dt):
    drift, energies, _ = cahn_hilliard_run([f"app.dt={dt}"], 200)
    assert np.all(np.diff(energies) <= 1e-14 * energies[0]) and drift < 1e-10


def test_cahn_hilliard_plain_imex_split_is_not_energy_stable_beyond_a_small_step():
    """imex on the equation as written puts the anti-diffusion −DΔc into the implicit matrix
    and leaves c³ explicit: monotone at dt = 3e-3 on the default, its energy rises at 4e-3."""
    _, fine, _ = cahn_hilliard_run([PLAIN_CH, "app.dt=3e-3"], 300)
    assert np.all(np.diff(fine) <= 1e-14 * fine[0])
    _, coarse, _ = cahn_hilliard_run([PLAIN_CH, "app.dt=4e-3"], 300)
    assert np.sum(np.diff(coarse) > 0) > 10


# ---------------------------------------------------------------------------- Klausmeier
def klausmeier_theory(a, m, nu):
    """(k_max, Re λ(k_max)) of the linearization at (w*, n*): λ(k) the eigenvalues of
    [[−1 − n*² + iνk, −2m], [n*², m − k²]] (perturbations e^{ikx + λt}), on a fine k grid."""
    n = (a + np.sqrt(a * a - 4 * m * m)) / (2 * m)
    ks = np.linspace(1e-3, 2.0, 20000)
    rates = np.array([np.linalg.eigvals(np.array([[-1 - n * n + 1j * nu * k, -2 * m], [n * n, m - k * k]])).real.max()
                      for k in ks])
    return ks[rates.argmax()], rates.max()


def x_profile(vertices, values):
    """(x, mean over y of values) on a grid."""
    xs, where = np.unique(np.round(vertices[:, 0], 9), return_inverse=True)
    return xs, np.bincount(where, weights=values) / np.bincount(where)


def test_klausmeier_dispersion_relation_and_its_fastest_growing_mode():
    """A small bump of n at x = −150 on a 600 × 4 strip: each Fourier mode of n − n* grows as
    e^{Re λ(k) t} in the linear regime, so log(|n̂(k, 18)| / |n̂(k, 8)|) / 10 is the discrete
    Re λ(k) (the ratio of two times cancels each mode's projection on the growing eigenvector).
    It follows the linear theory within 2 % over wavelengths 14–55, and its maximum (a parabola
    through the 5 bins around the largest) is the theory's k_max within 10 % (measured: 0.1 %)."""
    over = ["app=klausmeier", "app.dt=0.05", "mesh.nx=601", "mesh.ny=5", "mesh.width=600", "mesh.height=4",
            "app.fields.n.initial='(a + sqrt(a**2 - 4*m**2))/(2*m) * (1 + 1e-4*exp(-(x + 150)**2))'"]
    app, dec, model, integrator = prepared(over)
    c = app.constants
    ns = (c["a"] + np.sqrt(c["a"] ** 2 - 4 * c["m"] ** 2)) / (2 * c["m"])
    state = {u: np.array(model.initial_values[u]) for u in model.evolved}
    spectra = {}
    for n in range(int(round(18 / app.dt))):
        state = integrator.step(state, n * app.dt)
        if n + 1 in (int(round(8 / app.dt)), int(round(18 / app.dt))):
            xs, profile = x_profile(dec.K.vertices, state["n"] - ns)
            spectra[n + 1] = np.abs(np.fft.rfft(profile))[1:]
    first, last = (spectra[key] for key in sorted(spectra))
    assert np.abs(profile).max() < 0.01  # still linear
    k = 2 * np.pi * np.arange(1, len(first) + 1) / (len(xs) * (xs[1] - xs[0]))
    rate = np.log(last / first) / 10.0
    k_max, rate_max = klausmeier_theory(c["a"], c["m"], c["nu"])
    n_star = ns
    theory = np.array([np.linalg.eigvals(np.array([[-1 - n_star ** 2 + 1j * c["nu"] * q, -2 * c["m"]],
                                                   [n_star ** 2, c["m"] - q * q]])).real.max() for q in k])
    band = (k > 2 * np.pi / 55) & (k < 2 * np.pi / 14)
    assert np.abs(rate[band] - theory[band]).max() < 0.02 * rate_max
    j = int(np.argmax(np.where(k < 1.0, rate, -np.inf)))
    p = np.polyfit(k[j - 2:j + 3], rate[j - 2:j + 3], 2)
    measured = -p[1] / (2 * p[0])
    assert measured == pytest.approx(k_max, rel=0.10)
    assert 2 * np.pi / k_max == pytest.approx(21.83, abs=0.01)


@pytest.mark.slow
def test_klausmeier_bands_have_the_wavelength_of_the_fastest_growing_mode():
    """+experiment=klausmeier_bands (from noise, t = 60): bands across the slope (n peaks > 3,
    at least 6 of them between the absorbing layers) whose mean spacing is within 10 % of
    2π/k_max = 21.83."""
    run = run_experiment(compose_config(["+experiment=klausmeier_bands", "figures=false"]))
    xs, profile = x_profile(run.complex.vertices, np.asarray(run.result.fields["n"]))
    inside = np.abs(xs) < 150 - 60
    peaks = [i for i in range(1, len(xs) - 1) if inside[i] and profile[i] > 3
             and profile[i] >= profile[i - 1] and profile[i] > profile[i + 1]]
    assert len(peaks) >= 6
    spacing = (xs[peaks[-1]] - xs[peaks[0]]) / (len(peaks) - 1)
    k_max, _ = klausmeier_theory(0.94, 0.45, 20.0)
    assert spacing == pytest.approx(2 * np.pi / k_max, rel=0.10)


def test_a_gray_scott_sweep_table_says_which_runs_formed_patterns(decrun_cli, tmp_path):
    """A (F, k) sweep through the real CLI: its metrics.csv has, per run, v_std and `pattern`
    (1 when v_std > 0.02, the threshold gray_scott.yaml states) — here only (0.035, 0.065) of
    the four pairs grows spots; the others decay to the uniform (u, v) = (1, 0)."""
    import pandas as pd

    done = decrun_cli("-m", "app=gray_scott", "app.steps=1500", "app.constants.F=0.035,0.06",
                      "app.constants.k=0.065,0.075", "figures=false", "hydra.sweep.dir=outputs/sweeps/fk")
    assert done.returncode == 0, done.stderr
    table = pd.read_csv(tmp_path / "outputs" / "sweeps" / "fk" / "metrics.csv")
    assert len(table) == 4 and list(table["status"]) == ["ok"] * 4
    assert ((table["v_std"] > 0.02).astype(float) == table["pattern"]).all()
    formed = table[table["pattern"] == 1.0]
    assert [(F, k) for F, k in zip(formed["app.constants.F"], formed["app.constants.k"], strict=True)] == [(0.035, 0.065)]
    assert (table[table["pattern"] == 0.0]["v_std"] < 1e-6).all()
