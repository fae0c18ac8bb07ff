"""``app=spectrum`` through its Context (core meshes): metrics against the analytic spectra,
kernel dimension = Betti_k, refusals before any work."""

from __future__ import annotations

import numpy as np
import pytest

from decrun.apps.base import Context
from decrun.apps.spectrum import Spectrum
from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.primitives import kuhn_cube
from decrun.core.solvers import make_solver
from decrun.errors import ConfigError, TopologyError

from meshes_for_tests import icosphere, pieces_mesh


def run(K, star="circumcentric", **options):
    app = Spectrum(**options)
    dec = DEC(K, star=star)
    app.check_dimension(K)
    app.check_operators(dec)
    app.check(K, dec)
    return app.run(Context(app, K, dec))


def test_sphere_functions_match_l_l_plus_one():
    result = run(SimplicialComplex(*icosphere(3)), count=9)
    m = result.metrics
    assert m["analytic_domain"] == "sphere(1)"
    assert m["eigenvalue_relative_error_max"] < 0.02 and m["eigenvalue_zero_abs_max"] < 1e-12
    assert m["kernel_dimension"] == m["betti_0"] == 1 and m["kernel_dimension_matches_betti"]
    assert m["orthonormality_error_max"] < 1e-9 and m["residual_relative_max"] < 1e-8
    np.testing.assert_allclose(result.fields["eigenvalues_analytic"], [0, 2, 2, 2, 6, 6, 6, 6, 6])
    assert result.fields["eigenforms"].shape == (642, 9)
    assert len(result.figures["eigenforms"].data["values"]) == 4


def test_cube_two_forms_with_galerkin_stars():
    result = run(SimplicialComplex(*kuhn_cube(4)), star="whitney", degree=2, count=6)
    m = result.metrics
    assert m["analytic_domain"] == "box(1, 1, 1)" and m["eigenvalue_relative_error_max"] < 0.1
    assert m["kernel_dimension"] == m["betti_2"] == 0
    assert "eigenvalue_imaginary_max" not in m  # SPD stars: the metric does not apply


def test_cavity_gives_one_harmonic_two_form():
    cavity = kuhn_cube(5, keep_cell=lambda c: np.abs(c - 0.5).max(axis=1) > 0.15)
    m = run(SimplicialComplex(*cavity), star="whitney", degree=2, count=4).metrics
    assert m["betti_2"] == 1 and m["kernel_dimension"] == 1 and m["kernel_dimension_matches_betti"]
    assert "analytic_domain" not in m  # no known spectrum for a cube with a cavity


def test_refusals_name_the_fix():
    K = SimplicialComplex(*icosphere(1))
    with pytest.raises(ConfigError, match="app.degree=2"):
        run(K, degree=3)
    with pytest.raises(ConfigError, match="app.count="):
        run(K, count=100)
    with pytest.raises(TopologyError, match="app.analytic=auto"):
        run(K, analytic="box")
    with pytest.raises(ConfigError, match="app.shift"):
        Spectrum(shift=1.0)
    app, dec = Spectrum(degree=1), DEC(SimplicialComplex(*kuhn_cube(2)), star="whitney")
    with pytest.raises(ConfigError, match="`solver=direct`"):
        app.check_solver(make_solver("cg"), dec)


def test_only_zero_form_operators_of_intrinsic_delaunay():
    from decrun.core.stars.intrinsic_delaunay import IntrinsicDelaunay

    K = SimplicialComplex(*icosphere(2))
    run(K, star=IntrinsicDelaunay(), count=4)
    with pytest.raises(ConfigError, match="operator=mixed_area"):
        Spectrum(degree=1).check_operators(DEC(K, star=IntrinsicDelaunay()))


def test_an_unconverged_eigen_solve_makes_no_betti_claim(monkeypatch):
    """Issue 25 item 4: at 6 cells of a jittered box the eigen-solve's residual was 0.046 and
    yet ``kernel_dimension_matches_betti: true``. Every pair is checked now: a solve whose
    pairs do not solve the pencil keeps its numbers but says ``eigen_converged: false``, with
    ``eigen_residual_max``, and makes no kernel/Betti claim."""
    import scipy.sparse.linalg as spla

    K = SimplicialComplex(*icosphere(3))
    good = run(K, count=6).metrics
    assert good["eigen_converged"] and good["eigen_residual_max"] < 1e-12
    assert good["kernel_dimension_matches_betti"]
    real = spla.eigsh

    def stopped_short(*args, **kwargs):
        values, vectors = real(*args, **kwargs)
        return values, vectors + 1e-3 * np.random.default_rng(0).standard_normal(vectors.shape)

    monkeypatch.setattr(spla, "eigsh", stopped_short)
    bad = run(K, count=6).metrics
    assert bad["eigen_converged"] is False and bad["eigen_residual_max"] > 1e-6
    assert "kernel_dimension_matches_betti" not in bad


def test_negative_stiffness_star_is_refused_and_the_override_runs(decrun_cli, tmp_path):
    """Issue 34 item 7 through the command: Δ2 of a noisy grid with the cot ⋆1 (negative on
    13 of 161 edges) is refused before any work, in one line naming `operator=whitney`; that
    override runs and its eigenvalues are positive."""
    import json

    common = ("app=spectrum", "mesh=grid", "mesh.nx=8", "mesh.ny=8", "mesh.noise=0.3", "app.degree=2", "figures=false")
    refused = decrun_cli(*common, "hydra.run.dir=refused")
    assert refused.returncode == 1 and not (tmp_path / "refused" / "result.h5").exists()
    line = [x for x in (refused.stdout + refused.stderr).splitlines() if "indefinite" in x]
    assert len(line) == 1 and "⋆_1 of operator=mixed_area is negative on 13 of 161" in line[0]
    assert line[0].endswith("use `operator=whitney` (Galerkin stars, SPD on every mesh)")
    fixed = decrun_cli(*common, "operator=whitney", "hydra.run.dir=fixed")
    assert fixed.returncode == 0, fixed.stderr
    metrics = json.loads((tmp_path / "fixed" / "metrics.json").read_text())
    assert metrics["eigen_converged"] and metrics["eigenvalue_min"] > 0 and metrics["kernel_dimension"] == 0


def test_several_pieces_kernel_matches_betti_0():
    """Issue 34 item 8: 22 pieces, 22 zero eigenvalues (one per piece), then the big square's
    π² — kernel_dimension = betti_0 = 22 (17 before, with 9.86 among "the lowest")."""
    m = run(SimplicialComplex(*pieces_mesh()), star="mixed_area", count=25, analytic="none").metrics
    assert m["betti_0"] == 22 and m["kernel_dimension"] == 22 and m["kernel_dimension_matches_betti"]
    assert m["eigen_converged"] and m["eigenvalue_max"] == pytest.approx(2 * np.pi**2, rel=0.01)  # π², π², 2π²
