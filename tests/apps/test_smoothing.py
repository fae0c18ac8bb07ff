"""Mean curvature flow smoothing (thesis §1.3, decrun.apps.smoothing): the mathematics."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from decrun.apps.base import Context, Figure
from decrun.apps.smoothing import Smoothing as Config
from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.errors import ConfigError
from decrun.methods.mean_curvature_flow import enclosed_volume, surface_area
from meshes_for_tests import mesh as make_mesh


def setup(star="circumcentric", **mesh_kw):
    kw = dict(source="icosphere", noise=0.3, seed=0) | mesh_kw
    if kw["source"] == "icosphere":
        kw.setdefault("subdiv", 2)
    mesh = make_mesh(**kw)
    K = SimplicialComplex(mesh.vertices, mesh.faces)
    K.meta = mesh.meta
    return K, DEC(K, star=star)


def smooth(K, dec, solver="direct", **cfg):
    """Run app=smoothing with the in-memory context; the recorded series end up in r.series."""
    app = Config(**cfg)
    app.check(K, dec)
    ctx = Context(app, K, dec, new_solver=solver)
    r = app.run(ctx)
    r.series.update({name: values for name, values in ctx.series.items() if name != "step"})
    return r


def test_velocity_is_minus_the_area_gradient():
    """The flow decreases the area at rate Σ (S v)ᵀ ⋆0⁻¹ (S v) (the area gradient is S v,
    the cot formula), i.e. v' = -⋆0⁻¹ S v = Δ_M v with the right sign."""
    K, dec = setup()
    v = K.vertices
    S, M = dec.laplacian_symmetric(0), dec.star_diagonal(0)
    rate = np.sum((S @ v) ** 2 / M[:, None])
    dt = 1e-7
    r = smooth(K, dec, scheme="explicit", dt=dt, steps=1, rescale="none")
    assert r.series["area"][1] - r.series["area"][0] == pytest.approx(-dt * rate, rel=1e-4)


def test_area_gradient_is_half_the_cot_stiffness():
    """Independent of the app: finite differences of the area equal S v (∂A/∂v_i =
    ½ Σ_j (cot α_ij + cot β_ij)(v_i - v_j)); A is 2-homogeneous, so E(v0) = vᵀ S v = 2 A."""
    K, dec = setup()
    v, faces = K.vertices, K.oriented_simplices()
    S = dec.laplacian_symmetric(0)
    direction = np.random.default_rng(3).standard_normal(v.shape)
    eps = 1e-6
    fd = (surface_area(v + eps * direction, faces) - surface_area(v - eps * direction, faces)) / (2 * eps)
    assert fd == pytest.approx(np.sum((S @ v) * direction), rel=1e-6)
    assert np.einsum("ij,ij->", v, S @ v) == pytest.approx(2 * surface_area(v, faces), rel=1e-12)


@pytest.mark.parametrize("star", ["circumcentric", "mixed_area", "barycentric"])
def test_critical_dt_is_two_over_the_largest_eigenvalue(star):
    K, dec = setup(star=star, subdiv=1)
    S, M = dec.laplacian_symmetric(0).toarray(), dec.star_diagonal(0)
    lam_max = sla.eigh(S, np.diag(M), eigvals_only=True)[-1]
    r = smooth(K, dec, steps=0)
    assert r.metrics["dt_critical_explicit"] == pytest.approx(2 / lam_max, rel=1e-8)


def predicted_divergence_step(dec, vertices, dt, steps, blowup_factor=10.0):
    """The first step n ≤ ``steps`` at which explicit Euler (no rescaling) pushes the roughness
    R_n above ``blowup_factor`` × R_0, predicted from the dense eigen-decomposition
    S φ_i = λ_i ⋆0 φ_i (⋆0-orthonormal) instead of by stepping: with a_i = φ_iᵀ ⋆0 (v_0 − c),
    v_n − c = Σ φ_i (1 − dt λ_i)ⁿ a_i, so R_n = Σ λ_i g_i²ⁿ |a_i|² / Σ g_i²ⁿ |a_i|², g_i = 1 − dt λ_i.
    −1 when it stays below."""
    S, M = dec.laplacian_symmetric(0).toarray(), dec.star_diagonal(0)
    lam, phi = sla.eigh(S, np.diag(M))
    centred = vertices - (M @ vertices) / M.sum()
    weight = np.sum((phi.T @ (M[:, None] * centred)) ** 2, axis=1)  # |a_i|²
    n = np.arange(steps + 1)[:, None]
    growth = np.abs(1 - dt * lam)[None, :] ** (2 * n) * weight[None, :]
    roughness = (growth @ lam) / growth.sum(axis=1)
    above = np.flatnonzero(roughness > blowup_factor * roughness[0])
    return int(above[0]) if above.size else -1


@pytest.mark.parametrize("mesh", [dict(source="icosphere", subdiv=2), dict(source="torus", noise=0.2)],
                         ids=["icosphere", "torus"])
def test_explicit_euler_diverges_at_the_predicted_step_just_above_the_limit(mesh):
    """Below dt_crit = 2/λ_max every |g_i| < 1: stable for all 150 steps; 3 % above it the
    λ_max mode grows by |1 − dt λ_max| per step and the blow-up is detected at exactly the
    step the spectral prediction gives — on two meshes."""
    K, dec = setup(**mesh)
    dt_crit = smooth(K, dec, steps=0).metrics["dt_critical_explicit"]
    for factor in (0.97, 1.03):
        r = smooth(K, dec, scheme="explicit", dt=factor * dt_crit, steps=150, rescale="none")
        expected = predicted_divergence_step(dec, K.vertices, factor * dt_crit, 150)
        assert (expected == -1) is (factor < 1)
        assert r.metrics.get("diverged_at_step", -1) == expected  # absent when no step blew up
        # 150 unrescaled steps thin the torus' tube into a ring: no blow-up, but degenerate
        assert r.metrics["stable"] is (expected == -1 and mesh.get("source") != "torus")
        assert r.metrics.get("unstable_reason", "").startswith(
            "diverged" if expected != -1 else "degenerate" if mesh.get("source") == "torus" else "")
        assert r.metrics["steps_done"] == (150 if expected == -1 else expected)


def test_implicit_step_solves_the_thesis_equation():
    """(Id - dt Δ) v_{n+1} = v_n with Δ = -L (§1.3), solved densely, equals the app's step."""
    K, dec = setup(subdiv=1)
    dt = 0.05
    L = dec.laplacian(0).toarray()
    expected = np.linalg.solve(np.eye(len(L)) + dt * L, K.vertices)
    for solver in ("direct", "cg"):
        r = smooth(K, dec, solver=solver, scheme="implicit", dt=dt, steps=1, rescale="none")
        np.testing.assert_allclose(r.fields["vertices_final"], expected, rtol=1e-8, atol=1e-10)


def test_implicit_area_decreases_monotonically_without_rescaling():
    K, dec = setup()
    r = smooth(K, dec, scheme="implicit", dt=0.05, steps=20, rescale="none")
    assert np.all(np.diff(r.series["area"]) < 0)
    assert np.all(np.diff(r.series["roughness"]) <= 1e-12)


@pytest.mark.parametrize("rescale, kept", [("volume", "volume"), ("area", "area")])
def test_rescaling_keeps_volume_or_area_and_the_centroid(rescale, kept):
    K, dec = setup()
    r = smooth(K, dec, scheme="implicit", dt=0.1, steps=10, rescale=rescale)
    np.testing.assert_allclose(r.series[kept], r.series[kept][0], rtol=1e-12)
    M = dec.star_diagonal(0)
    np.testing.assert_allclose(M @ r.fields["vertices_final"], M @ K.vertices, atol=1e-12)
    faces = r.fields["faces"]
    assert enclosed_volume(K.vertices, faces) > 0  # oriented outwards


def test_smoothing_moves_the_noisy_sphere_towards_the_clean_one():
    K, dec = setup(subdiv=3)
    r = smooth(K, dec, scheme="implicit", dt=0.005, steps=10, rescale="volume")
    m = r.metrics
    assert m["distance_to_clean_rms"] < 0.35 * m["distance_to_clean_rms_initial"]
    radius = np.linalg.norm(r.fields["vertices_final"] - r.fields["vertices_final"].mean(0), axis=1)
    assert radius.std() / radius.mean() < 0.01  # round again


def test_a_clean_sphere_stays_a_sphere():
    K, dec = setup(noise=0.0, subdiv=3)
    r = smooth(K, dec, scheme="implicit", dt=0.01, steps=20, rescale="volume")
    v = r.fields["vertices_final"]
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=2e-3)
    assert "distance_to_clean_rms" not in r.metrics


def test_open_mesh_refuses_volume_rescaling_but_smooths_with_area():
    K, dec = setup(source="sphere_cap", noise=0.2)
    with pytest.raises(ConfigError, match="app.rescale=volume"):
        smooth(K, dec, rescale="volume")
    r = smooth(K, dec, scheme="implicit", dt=1e-4, steps=5, rescale="area")
    assert r.metrics["stable"] and "volume_drift_rel" not in r.metrics  # does not apply to open meshes


@pytest.mark.parametrize("kw, key", [(dict(dt=-0.1), "app.dt"), (dict(dt=0.0), "app.dt"), (dict(steps=-1), "app.steps"),
                                     (dict(scheme="rk4"), "app.scheme"), (dict(rescale="mass"), "app.rescale"),
                                     (dict(blowup_factor=0.5), "app.blowup_factor")])
def test_config_values_are_checked(kw, key):
    with pytest.raises(ConfigError, match=key):
        Config(**kw)


def test_result_has_figures_series_and_fields():
    K, dec = setup(subdiv=1)
    r = smooth(K, dec, steps=3)
    assert set(r.figures) == {"smoothing", "smoothing_series"}
    assert all(isinstance(f, Figure) for f in r.figures.values())
    assert all(len(s) == 4 for s in r.series.values())
    assert r.fields["vertices_final"].shape == K.vertices.shape
    assert r.series["distortion"][0] == pytest.approx(1.0, rel=1e-12)  # E(v0) = 2 A(v0)


def test_figures_render_for_planar_and_coloured_meshes(tmp_path):
    from decrun.runner.plots import common as plots

    K, dec = setup(source="planar", max_area=0.02, noise=0.1)
    r = smooth(K, dec, scheme="implicit", dt=1e-3, steps=2, rescale="area")
    for path in plots.draw_figures(r.figures, tmp_path, K):
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    fig = plots.new_figure()
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    K3, _ = setup(subdiv=1)
    mappable = plots.plot_surface(ax3, K3.vertices, K3.oriented_simplices(), values=K3.vertices[:, 2])
    assert mappable is not None and mappable.norm.vmin == pytest.approx(K3.vertices[:, 2][K3.oriented_simplices()].mean(1).min())
    ax2 = fig.add_subplot(1, 2, 2)
    assert plots.plot_surface(ax2, K.vertices, K.oriented_simplices()) is None
    plots.save_figure(fig, tmp_path / "both.png")
    assert (tmp_path / "both.png").stat().st_size > 1000


@pytest.mark.parametrize("blowup_factor", [10.0, 1e300])
def test_step_counters_agree_whether_the_roughness_or_the_coordinates_blow_up(blowup_factor):
    """steps_done counts the recorded steps, the diverging one included: it equals
    diverged_at_step also when the coordinates overflow (NaN recorded for that step)."""
    K, dec = setup()
    r = smooth(K, dec, scheme="explicit", dt_factor=50.0, steps=400, rescale="none", blowup_factor=blowup_factor)
    m = r.metrics
    assert not m["stable"] and m["steps_done"] == m["diverged_at_step"] >= 1
    assert len(r.series["area"]) == m["steps_done"] + 1  # step 0 and every attempted step
    assert "distance_to_clean_rms" not in m and "distance_to_clean_rms_initial" in m


def test_rescale_auto_keeps_the_volume_of_closed_and_the_area_of_open_surfaces():
    closed, closed_dec = setup()
    r = smooth(closed, closed_dec, scheme="implicit", dt=0.01, steps=5)
    assert r.metrics["rescale"] == "volume" and r.metrics["volume_drift_rel"] < 1e-12
    open_, open_dec = setup(source="sphere_cap", subdiv=3)
    r = smooth(open_, open_dec, scheme="implicit", dt=0.001, steps=5)
    assert r.metrics["rescale"] == "area" and r.metrics["area_ratio"] == pytest.approx(1.0, abs=1e-12)


def _cli_metrics(decrun_cli, run, *overrides):
    import json

    proc = decrun_cli(*overrides, f"hydra.run.dir={run}")
    assert proc.returncode == 0, proc.stderr
    return json.loads((run / "metrics.json").read_text())


@pytest.mark.parametrize("overrides", [["mesh=torus", "mesh.noise=0.2", "app.rescale=area"],
                                       ["mesh=grid", "mesh.noise=0.3"]], ids=["torus", "grid"])
def test_normal_deviation_measures_the_denoising_that_the_distance_hides(overrides, decrun_cli, tmp_path):
    """The RMS distance to the clean mesh rises (torus 1.0 % → 5.5 %: the tube thins; grid:
    the border pulls in) while the picture is clean: the face-normal angle to the clean mesh
    falls to a fifth (21° → 4.3° torus, 30° → 2.5° grid), which is what smoothing removes."""
    m = _cli_metrics(decrun_cli, tmp_path / "run", *overrides, "figures=false")
    assert m["stable"] is True
    assert m["distance_to_clean_rms"] > m["distance_to_clean_rms_initial"]
    assert m["normal_deviation_to_clean_deg_initial"] > 15
    assert m["normal_deviation_to_clean_deg"] < 0.25 * m["normal_deviation_to_clean_deg_initial"]


def test_the_readme_smoothing_example_improves_both_metrics(decrun_cli, tmp_path):
    """README: ``decrun mesh=torus mesh.noise=0.2 app.dt_factor=0.3 app.steps=3`` brings the
    torus closer to the clean one by both measures (1.01 % → 0.86 %, 21° → 10.6°)."""
    m = _cli_metrics(decrun_cli, tmp_path / "run", "mesh=torus", "mesh.noise=0.2", "app.dt_factor=0.3",
                     "app.steps=3", "figures=false")
    assert m["distance_to_clean_rms"] < m["distance_to_clean_rms_initial"]
    assert m["normal_deviation_to_clean_deg"] < 0.7 * m["normal_deviation_to_clean_deg_initial"]


def test_a_collapsed_bone_is_not_stable_and_its_input_stays_visible(decrun_cli, tmp_path):
    """bone at app.dt=0.05 (366 × dt_crit): no step blows up, but the volume-rescaled result is
    a needle 1.5e4 × the bone's extent (area ratio 6543): stable false with the reason, and the
    before/after figure gives the input its own box instead of a dot beside the needle."""
    from decrun.runner.plots.common import before_after
    from decrun.runner.results import read_result

    run = tmp_path / "run"
    m = _cli_metrics(decrun_cli, run, "mesh=sample", "mesh.sample=bone", "app.dt=0.05")
    assert m["stable"] is False and "diverged_at_step" not in m  # no step blew up
    assert m["unstable_reason"].startswith("degenerate: isoperimetric quotient")
    assert (run / "smoothing.png").is_file()
    fields = read_result(run / "result.h5").fields
    before, after = fields["vertices_initial"], fields["vertices_final"]
    fig = before_after(before, after, fields["faces"], share_axes=True)
    extent = float((before.max(axis=0) - before.min(axis=0)).max())
    low, high = fig.axes[0].get_xlim()
    assert high - low <= 1.5 * extent  # the input fills its panel
    assert "own scale" in fig.axes[1].get_title()
    # a stable default run keeps the shared box (a shrunk result looks shrunk)
    shared = before_after(before, before * 0.5, fields["faces"], share_axes=True)
    assert shared.axes[0].get_xlim() == shared.axes[1].get_xlim()


def test_the_critical_dt_off_hint_names_a_step_computed_from_the_mesh(decrun_cli, tmp_path):
    """app.critical_dt=false without app.dt: the hint's app.dt is Gershgorin's bound on this
    mesh (no eigen-solve), below the explicit critical step, so explicit Euler is stable."""
    import re

    failing = decrun_cli("mesh.subdiv=1", "app.critical_dt=false", "app.scheme=explicit", "app.steps=20")
    assert failing.returncode != 0
    hinted = re.search(r"`(app\.dt=[0-9.e-]+)`", failing.stderr).group(1)
    m = _cli_metrics(decrun_cli, tmp_path / "run", "mesh.subdiv=1", "app.scheme=explicit", "app.steps=20", hinted,
                     "figures=false")
    assert m["stable"] is True and 0.3 < m["dt_over_critical"] <= 1.0  # measured 0.67


def _picture_change(run) -> float:
    """Mean |Δ grey| (0–1) between the input (left) and result (right) panels of the run's
    ``smoothing.png`` as written, below the titles: what a user sees change."""
    import matplotlib.image

    grey = matplotlib.image.imread(run / "smoothing.png")[..., :3].mean(axis=2)
    height, width = grey.shape
    below_titles, half = int(0.12 * height), width // 2
    return float(np.mean(np.abs(grey[below_titles:, :half] - grey[below_titles:, half:2 * half])))


@pytest.mark.parametrize("mesh", ["bunny", "cow"])
def test_the_default_run_visibly_smooths_the_bunny_and_the_cow(mesh, decrun_cli, tmp_path):
    """`decrun mesh=bunny` / `mesh=cow` (issue 20 item 5): implicit Euler's default step is 0.75 ×
    the resolution step 2h̄²/π² (app.dt_unit=auto), not 0.75 × 2/λ_max, which the scans' worst
    triangles make 370 × (bunny) / 55 × (cow) smaller. Measured: face normals turn by 12.1° /
    11.9° (0.19° / 1.4° at app.dt_unit=critical), and the panels of smoothing.png differ by
    0.024 / 0.0063 grey levels on average (0.0009 / 0.0006: the same picture twice)."""
    default = _cli_metrics(decrun_cli, tmp_path / "default", f"mesh={mesh}")
    assert default["stable"] is True and default["dt_unit"] == "resolution"
    assert default["dt"] == pytest.approx(0.75 * default["dt_resolution"], rel=1e-12)
    assert default["dt_over_critical"] > 30
    critical = _cli_metrics(decrun_cli, tmp_path / "critical", f"mesh={mesh}", "app.dt_unit=critical")
    assert critical["dt_over_critical"] == pytest.approx(0.75, rel=1e-9)
    assert default["normal_change_deg"] > 8 > 2 > critical["normal_change_deg"]
    assert _picture_change(tmp_path / "default") > 5 * _picture_change(tmp_path / "critical")


def test_an_indefinite_implicit_matrix_names_the_operator_that_fixes_it(decrun_cli, tmp_path):
    """circumcentric ⋆0 ≤ 0 on 47 bunny vertices: the default implicit run diverges (step 2),
    and the reason names the override; that override runs stable."""
    import re

    m = _cli_metrics(decrun_cli, tmp_path / "circumcentric", "mesh=bunny", "operator=circumcentric", "figures=false")
    assert m["stable"] is False and m["diverged_at_step"] >= 1
    assert "⋆0 ≤ 0 on 47 vertices" in m["unstable_reason"]
    hinted = re.search(r"`(operator=\w+)`", m["unstable_reason"]).group(1)
    fixed = _cli_metrics(decrun_cli, tmp_path / "fixed", "mesh=bunny", hinted, "figures=false")
    assert fixed["stable"] is True


def test_the_time_step_is_decided_once_by_the_method_and_refused_in_check_before_any_work(monkeypatch):
    """choose_time_step: dt given is kept; the resolution unit is factor × 2h̄²/π²; the critical
    unit factor × 2/λ_max of S φ = λ ⋆0 φ; without the eigen-solve the critical unit has no step
    and offers Gershgorin's bound, which is ≤ 2/λ_max. The app refuses that in ``check`` (no
    factorization has happened) and runs with the very dt the check decided."""
    from decrun.methods import mean_curvature_flow as mcf

    K, dec = setup()
    S, M = dec.laplacian_symmetric(0), dec.star_diagonal(0)
    critical = mcf.explicit_critical_dt(S, M)
    assert mcf.choose_time_step(dec, "explicit", dt=1e-4).dt == 1e-4
    step = mcf.choose_time_step(dec, "implicit", factor=0.5)
    assert step.unit == "resolution" and step.dt == pytest.approx(0.5 * 2 * K.mean_edge_length ** 2 / np.pi ** 2)
    step = mcf.choose_time_step(dec, "explicit", factor=0.5)
    assert step.unit == "critical" and step.dt == pytest.approx(0.5 * critical, rel=1e-9)
    none = mcf.choose_time_step(dec, "explicit", critical=False)
    assert none.dt is None and np.isnan(none.critical) and 0 < none.safe <= critical

    def no_factorization(*args, **kwargs):
        raise AssertionError("the flow was built before the check refused")

    monkeypatch.setattr("decrun.apps.smoothing.MeanCurvatureFlow", no_factorization)
    app = Config(scheme="explicit", critical_dt=False, steps=1)
    with pytest.raises(ConfigError, match=rf"^app.critical_dt=false .* `app.dt={none.safe:.3g}` "):
        app.check(K, dec)
    monkeypatch.undo()
    fixed = Config(scheme="explicit", dt=float(f"{none.safe:.3g}"), critical_dt=False, steps=2)
    fixed.check(K, dec)
    result = fixed.run(Context(fixed, K, dec, new_solver="direct"))
    assert result.metrics["dt"] == float(f"{none.safe:.3g}") and result.metrics["stable"]
