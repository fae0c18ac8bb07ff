"""``stable`` means a trustworthy answer, through the real ``decrun`` command (issue 48 items 1, 2
and 4's ARPACK part, issue 50 item 9; :mod:`decrun.methods.model.stability`,
:mod:`decrun.methods.model.growth`, :mod:`decrun.runner.job.verdict`).

Before these checks every run below exited 0 with ``stable: true`` (or an ARPACK traceback):
the 1-form diffusion on a planar mesh grew ×1e22 in 100 Crank–Nicolson steps, RK4 advection at
10× its CFL step ×1e35, and so on. Each test also runs the fix the refusal names."""

from __future__ import annotations

import json
import re
from pathlib import Path

import h5py
import numpy as np
import pytest

from cli_processes import decrun

FAST = ["figures=false", "progress=false"]
ONE_FORM = ["app=heat", "app.fields.u.form=1", "app.equations=[\"dt(u) = laplacian(u)\"]", "~app.metrics",
            "~app.require"]


def refused(proc) -> str:
    """The one ``error:`` line of a refused run (no traceback; decrun's zero-⋆ RuntimeWarning
    of ``mesh=grid`` may come before it)."""
    assert proc.returncode != 0, proc.stdout
    lines = [line for line in proc.stderr.strip().splitlines()
             if "RuntimeWarning: ⋆_" not in line and not line.startswith("  return self.require")]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in proc.stderr, proc.stderr
    return lines[0]


def overrides(line: str, index: int = 0) -> list[str]:
    """The ``index``-th backticked override of a message, split into arguments."""
    return re.findall(r"`([^`]+)`", line)[index].split()


def metrics(run_dir: Path) -> dict:
    return json.loads((run_dir / "metrics.json").read_text())


def largest(run_dir: Path, name: str = "u") -> np.ndarray:
    """max|u| at every recorded step."""
    with h5py.File(run_dir / "result.h5", "r") as f:
        return np.abs(f[f"series/{name}"][()]).max(axis=1)


# ------------------------------------------------------------------------------ 1. negative stars
def test_a_one_form_weighted_by_a_negative_star1_is_refused_and_whitney_runs(tmp_path):
    """Circumcentric ⋆1 of the holeless planar square has 19 negative entries (obtuse border
    triangles): dt(w) = Δw was ⋆1⁻¹ × (a PSD stiffness) — indefinite — and grew ×1e22 under
    Crank–Nicolson with stable: true. Refused naming ⋆1 and the count; the fix named
    (Whitney's SPD Galerkin ⋆1, explicit adaptive steps) decays."""
    case = [*ONE_FORM, "mesh=planar", "mesh.holes=[]", "app.fields.u.initial=[y,-x]", "app.steps=20",
            "app.t_end=null", "app.dt=0.01", *FAST]
    line = refused(decrun(*case, "hydra.run.dir=bad", cwd=tmp_path))
    assert "dt(u) is weighted by ⋆1" in line and "19 negative entries" in line and "indefinite" in line, line
    fix = overrides(line)
    assert fix == ["operator=whitney", "app.integrator=rk45"], line
    proc = decrun(*case, *fix, "hydra.run.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert metrics(tmp_path / "fixed")["stable"] is True
    grown = largest(tmp_path / "fixed")
    assert grown[-1] < grown[0], grown  # a diffusion decays


def test_a_noisy_sphere_one_form_flow_is_refused(tmp_path):
    """The default noisy icosphere has slivers (2 negative ⋆1 entries): it grew ×1e36 in 20 steps."""
    line = refused(decrun(*ONE_FORM, "mesh=icosphere", "app.fields.u.initial=[y,-x,0]", "app.steps=20",
                          "app.t_end=null", *FAST, cwd=tmp_path))
    assert "⋆1" in line and "2 negative entries" in line, line


def test_zero_star1_on_the_grid_is_refused_without_an_arpack_traceback(tmp_path):
    """mesh=grid: ⋆1 = 0 on the hypotenuses made the stability check's eigen-solve raise
    ArpackError. Now one line naming the zero entries; operator=whitney (already explicit) runs."""
    case = [*ONE_FORM, "mesh=grid", "app.fields.u.initial=[y,-x,0]", "app.integrator=rk4", "app.dt=1e-5",
            "app.t_end=1e-4", *FAST]
    line = refused(decrun(*case, cwd=tmp_path))
    assert "225 zero entries" in line and "⋆1" in line, line
    fix = overrides(line)
    assert fix == ["operator=whitney"], line
    proc = decrun(*case, *fix, "hydra.run.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0 and metrics(tmp_path / "fixed")["stable"] is True, proc.stderr


def test_heat_weighted_by_a_negative_circumcentric_star0_is_refused_and_mixed_area_runs(tmp_path):
    """The bunny's circumcentric ⋆0 has 47 negative dual areas: heat grew ×1e9 in 10
    Crank–Nicolson steps with stable: true. Refused naming ⋆0; the named operator=mixed_area runs."""
    case = ["app=heat", "mesh=bunny", "app.t_end=0.01", *FAST]
    line = refused(decrun(*case, "operator=circumcentric", cwd=tmp_path))
    assert "weighted by ⋆0 of operator=circumcentric" in line and "47 negative entries" in line, line
    fix = overrides(line)
    assert fix == ["operator=mixed_area"], line
    proc = decrun(*case, *fix, "hydra.run.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0 and metrics(tmp_path / "fixed")["stable"] is True, proc.stderr


# ------------------------------------------------------------------------------ zero divisors
@pytest.mark.parametrize("integrator, equation, term", [
    ("explicit_euler", "dt(u) = laplacian(u) + u/x", "u / x"),
    ("rk4", "dt(u) = laplacian(u)/x", "laplacian(u) / x")])
def test_a_zero_divisor_is_refused_naming_the_term(tmp_path, integrator, equation, term):
    """Issue 50 item 9: both gave an ArpackError traceback. x = 0 at 32 vertices of the sphere."""
    line = refused(decrun("app=heat", f"app.integrator={integrator}", f"app.equations=[\"{equation}\"]",
                          "app.dt=0.0001", *FAST, cwd=tmp_path))
    assert f"the term {term} of dt(u) is not finite at t = 0 (32 of 642 values" in line, line


def test_the_term_left_out_runs(tmp_path):
    line = refused(decrun("app=heat", "app.integrator=explicit_euler", "app.equations=[\"dt(u) = laplacian(u) + u/x\"]",
                          "app.dt=0.0001", *FAST, cwd=tmp_path))
    assert "leave it out (dt(u) = laplacian(u))" in line, line
    proc = decrun("app=heat", "app.integrator=explicit_euler", "app.equations=[\"dt(u) = laplacian(u)\"]",
                  "app.dt=0.0001", *FAST, "hydra.run.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0 and metrics(tmp_path / "fixed")["stable"] is True, proc.stderr


# ------------------------------------------------------------------------------ 2a. every explicit term
ADVECTION = ["app=heat", "app.equations=[\"dt(u) = -lie(sharp(d(z)), u)\"]", "~app.require", "app.integrator=rk4",
             "app.t_end=40", *FAST]


def test_rk4_advection_beyond_its_cfl_step_is_refused_and_the_named_step_runs(tmp_path):
    """Centred advection on the unit sphere: |λ|max ≈ 7.4, RK4 stable to ≈ 2.83/7.4 = 0.38. At
    10× that (dt = 4, check off) u grows ×1e30 — the check refuses it before running; the step it
    names runs and stays bounded (advection conserves ‖u‖)."""
    line = refused(decrun(*ADVECTION, "app.dt=4", cwd=tmp_path))
    # refused by the fastest-mode limit of the exact Jacobian (wave_limit, first for a model with no diffusion
    # block) or else by the check of every explicit term (stability.explicit_limit): both name app.dt and rk4
    assert line.startswith("error: app.dt=4 ") and "integrator=rk4" in line, line
    fix = overrides(line)
    dt = float(fix[0].split("=")[1])
    assert 0.3 < dt < 0.39, line
    proc = decrun(*ADVECTION, *fix, "hydra.run.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert metrics(tmp_path / "fixed")["stable"] is True
    grown = largest(tmp_path / "fixed")
    assert grown.max() < 2 * grown[0], grown


def test_without_the_check_the_growth_makes_the_run_unstable(tmp_path):
    """Today's wrong answer (stable: true at ×1e35) is now stable: false with the verdict on a
    line of its own, naming app.dt and a step that works."""
    proc = decrun(*ADVECTION, "app.dt=4", "app.stability_check=false", "hydra.run.dir=off",
                  cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    record = metrics(tmp_path / "off")
    assert record["stable"] is False and record["diverged_at_step"] >= 1, record
    verdict = [line for line in proc.stdout.splitlines() if line.startswith("decrun: UNSTABLE")]
    assert len(verdict) == 1 and "app.dt=" in verdict[0] and "grew to" in verdict[0], proc.stdout
    fix = overrides(verdict[0])
    proc = decrun(*ADVECTION, *fix, "hydra.run.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0 and metrics(tmp_path / "fixed")["stable"] is True, proc.stderr


def test_a_wave_as_two_first_order_fields_is_checked(tmp_path):
    """dt(u) = v, dt(v) = Δu: imaginary eigenvalues ±i√λ (|λ|max ≈ 17.5 here), no diffusion
    block on the diagonal — the old check saw nothing. RK4 at dt = 0.5 is refused; the named step runs."""
    case = ["app=wave", "app.integrator=rk4", "app.t_end=5", *FAST]
    line = refused(decrun(*case, "app.dt=0.5", cwd=tmp_path))
    assert line.startswith("error: app.dt=0.5 ") and "integrator=rk4" in line, line  # wave_limit or explicit_limit
    proc = decrun(*case, *overrides(line), "hydra.run.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0 and metrics(tmp_path / "fixed")["stable"] is True, proc.stderr


def test_the_explicit_part_of_imex_is_checked(tmp_path):
    """Allen–Cahn's explicit u − u³ at u(0) = 2x has Jacobian 1 − 3u² down to −11: forward Euler
    needs dt ≲ 2/11. dt = 1.25 is refused before running."""
    line = refused(decrun("app=heat", "app.fields.u.initial=2*x", "app.equations=[\"dt(u) = k*laplacian(u) + "
                          "explicit(u - u**3)\"]", "app.constants.k=0.01", "~app.require", "app.integrator=imex",
                          "app.dt=1.25", "app.t_end=50", *FAST, cwd=tmp_path))
    assert "integrator=imex" in line and "explicit part" in line, line
    dt = float(overrides(line)[0].split("=")[1])
    assert 0.1 < dt < 2 / 11, line


# ------------------------------------------------------------------------------ 2b. bounds and growth
ALLEN_CAHN = ["app=heat", "app.fields.u.initial=random", "+app.fields.u.bounds=[-1,1]",
              "app.equations=[\"dt(u) = k*laplacian(u) + explicit(u - u**3)\"]", "app.constants.k=0.01",
              "~app.require", "app.integrator=imex", "app.t_end=50", *FAST]


def test_allen_cahn_leaving_its_declared_bounds_is_unstable(tmp_path):
    """Allen–Cahn keeps |u| ≤ 1; at dt = 1.25 (check off) its explicit reaction overshoots to
    a period-2 oscillation of amplitude 1.15 — stable: true before. Now stable: false at the
    step it left [-1, 1], the records up to there kept, and a verdict line whose step runs."""
    proc = decrun(*ALLEN_CAHN, "app.dt=1.25", "app.stability_check=false", "app.record_every=1", "hydra.run.dir=bad",
                  cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    record = metrics(tmp_path / "bad")
    assert record["stable"] is False and "app.fields.u.bounds=[-1, 1]" in record["unstable_reason"], record
    step = record["diverged_at_step"]
    with h5py.File(tmp_path / "bad" / "result.h5", "r") as f:
        assert list(f["series/step"][()]) == list(range(step))  # what it recorded before
    verdict = [line for line in proc.stdout.splitlines() if line.startswith("decrun: UNSTABLE")]
    assert len(verdict) == 1, proc.stdout
    proc = decrun(*ALLEN_CAHN, *overrides(verdict[0]), "hydra.run.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0 and metrics(tmp_path / "fixed")["stable"] is True, proc.stderr
    assert largest(tmp_path / "fixed").max() <= 1 + 1e-9


def test_allen_cahn_blowing_up_without_bounds_is_unstable(tmp_path):
    """u(0) = 2x, dt = 1.25, check off: |u| → 1e17 in 4 steps (then inf) — more than 1e6 × the scale."""
    proc = decrun("app=heat", "app.fields.u.initial=2*x", "app.equations=[\"dt(u) = k*laplacian(u) + "
                  "explicit(u - u**3)\"]", "app.constants.k=0.01", "~app.require", "app.integrator=imex", "app.dt=1.25",
                  "app.t_end=50", "app.stability_check=false", *FAST, "hydra.run.dir=bad", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    record = metrics(tmp_path / "bad")
    assert record["stable"] is False and "grew to" in record["unstable_reason"], record


def test_a_run_forced_from_rest_is_not_mistaken_for_growth(tmp_path):
    """u(0) = 0 and a forcing sin(t)·x that is 0 at t = 0: the scale comes from the forcing later
    in the run (T·max|sin(t) x|), so the honest growth from 0 stays stable."""
    proc = decrun("app=heat", "app.fields.u.initial=0", "app.equations=[\"dt(u) = k*laplacian(u) + sin(t)*x\"]",
                  "app.t_end=10", "app.dt=0.01", *FAST, "hydra.run.dir=ok", cwd=tmp_path)
    assert proc.returncode == 0 and metrics(tmp_path / "ok")["stable"] is True, proc.stderr
    assert "UNSTABLE" not in proc.stdout


@pytest.mark.parametrize("bounds, says", [("[1,-1]", "bounds are [lo, hi], two finite numbers with lo < hi"),
                                          ("[0]", "bounds are [lo, hi]"), ("[0,inf]", "must be a finite number")])
def test_bad_bounds_are_refused_naming_the_key(tmp_path, bounds, says):
    line = refused(decrun("app=heat", f"+app.fields.u.bounds={bounds}", *FAST, cwd=tmp_path))
    assert line.startswith("error: app.fields.u.bounds") and says in line, line


def test_good_bounds_run(tmp_path):
    """Heat keeps u(0) = xy within [-1/2, 1/2] (a maximum principle on the sphere's harmonic)."""
    proc = decrun("app=heat", "+app.fields.u.bounds=[-0.5,0.5]", *FAST, "hydra.run.dir=ok", cwd=tmp_path)
    assert proc.returncode == 0 and metrics(tmp_path / "ok")["stable"] is True, proc.stderr


def test_bounds_on_a_field_nothing_evolves_are_refused(tmp_path):
    line = refused(decrun("app=heat", "+app.fields.f.form=0", "+app.fields.f.initial=x", "+app.fields.f.bounds=[0,1]",
                          "app.equations=[\"dt(u) = k*laplacian(u) + f\"]", *FAST, cwd=tmp_path))
    assert "app.fields.f.bounds: f is not evolved" in line, line


# ------------------------------------------------------------------------------ 2c. the verdict line
def test_explicit_smoothing_far_beyond_its_critical_step_says_so_on_its_own_line(tmp_path):
    """75× the critical step: before, "wrote …" with the verdict inside a 600-character
    metrics line. Now a line of its own naming app.dt and a step that runs stable."""
    proc = decrun("app=smoothing", "app.scheme=explicit", "app.dt_factor=75", "app.dt_unit=critical", *FAST,
                  "hydra.run.dir=bad", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    verdict = [line for line in proc.stdout.splitlines() if line.startswith("decrun: UNSTABLE")]
    assert len(verdict) == 1 and len(verdict[0]) < 200, proc.stdout
    fix = overrides(verdict[0])
    assert fix[0].startswith("app.dt="), verdict
    proc = decrun("app=smoothing", "app.scheme=explicit", *fix, *FAST, "hydra.run.dir=fixed", cwd=tmp_path)
    assert proc.returncode == 0 and metrics(tmp_path / "fixed")["stable"] is True, proc.stderr
    assert "UNSTABLE" not in proc.stdout


# ------------------------------------------------------------------------------ the estimate itself
class _Flaky:
    """A Jacobian J = diag(−1, −2, …, −n) whose products ARPACK asks for are NaN (its iteration
    fails), while the probed matrix is finite."""

    def __init__(self, n: int):
        self.n, self.calls = n, 0
        self.diagonal = -np.arange(1.0, n + 1)

    def matvec(self, v):
        self.calls += 1
        return self.diagonal * np.real(np.asarray(v)).ravel() * np.nan

    def dense(self):
        return np.diag(self.diagonal)


def test_a_failed_arpack_falls_back_to_gershgorins_bound():
    """No traceback: the eigen-solve's failure gives ρ ≤ max_i Σ_j |J_ij| = n from the probed matrix."""
    from decrun.methods.model.stability import DENSE_MAX, spectrum_sample

    values, how = spectrum_sample(_Flaky(DENSE_MAX + 100))
    assert how == "gershgorin" and np.max(np.abs(values)) == DENSE_MAX + 100


def test_the_diffusion_eigen_solve_returns_nan_instead_of_raising_on_an_infinite_matrix():
    import scipy.sparse as sp

    from decrun.methods.mean_curvature_flow import DENSE_EIGEN_MAX, largest_eigenvalue

    n = DENSE_EIGEN_MAX + 36
    S = sp.diags(np.r_[np.inf, np.ones(n - 1)]).tocsr()
    assert np.isnan(largest_eigenvalue(S, np.ones(n)))


def test_the_stability_functions_are_the_schemes():
    """R(z) of forward Euler 1 + z; of RK4 the degree-4 Taylor polynomial of e^z; ARK's explicit
    tableau is third order: R(z) − e^z = O(z⁴)."""
    from decrun.methods.model.stability import stability_function

    z = np.array([-0.01, 0.02j, -2.0])
    assert np.allclose(stability_function("explicit_euler")(z), 1 + z)
    assert np.allclose(stability_function("rk4")(z), 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24)
    small = np.array([1e-2, 5e-3])
    error = np.abs(stability_function("ark_imex")(small) - np.exp(small))
    assert np.log2(error[0] / error[1]) > 3.8
    assert stability_function("crank_nicolson") is None
