"""Every app runs with ``solver=iterative`` through the real CLI and matches ``solver=direct``
to 1e-8: the Krylov method is chosen per matrix (CG for the SPD heat and Poisson systems,
GMRES with an incomplete LU where negative cot weights make them indefinite and for the
conformal border's unsymmetric rows and the Galerkin saddle point)."""

from __future__ import annotations

import numpy as np
import pytest

from decrun.runner.results import read_result

#: app → overrides (small meshes: each case runs twice)
CASES = {
    "smoothing": ["app=smoothing", "mesh.subdiv=3", "app.steps=5"],
    "parametrization_conformal_border": ["app=parametrization", "mesh=sphere_cap"],
    "parametrization_holes_eq_5_9": ["+experiment=fig5_5_flat_hole", "app.border=conformal"],
    "parametrization_mean_value": ["+experiment=fig5_5_flat_hole", "app.border=circle", "app.weights=mean_value"],
    "hodge_galerkin": ["app=hodge", "mesh=torus", "mesh.major_segments=16", "mesh.minor_segments=8", "mesh.noise=0.05"],
    "hodge_negative_cot_weights": ["app=hodge", "mesh=grid", "mesh.nx=8", "mesh.ny=8", "mesh.noise=0.1",
                                   "operator=circumcentric"],
    "vector_field": ["app=vector_field", "mesh.subdiv=2"],
    # a singular normal matrix (kernel: the two harmonic 1-forms): ω was 1.2e-7 off direct
    # before SingularSolve projected the kernel out (issue 25 item 3)
    "vector_field_harmonic_kernel": ["app=vector_field", "mesh=torus",
                                     "app.sources=[{vertex:0,divergence:1.0},{vertex:300,divergence:-1.0}]"],
    "fluid": ["app=fluid", "mesh=channel", "mesh.target_faces=600", "app.steps=10", "app.record_every=10"],
}
#: potentials defined up to ker of their Poisson matrix (constants): only their d-images, the
#: exact and coexact parts, are determined, and those are compared
GAUGE = {"alpha", "beta"}


def _fields(decrun_cli, tmp_path, name, solver):
    run = tmp_path / solver
    proc = decrun_cli(*CASES[name], f"solver={solver}", "figures=false", f"hydra.run.dir={run}")
    assert proc.returncode == 0, proc.stderr
    result = read_result(run / "result.h5")
    return {k: np.asarray(v, dtype=float) for k, v in result.fields.items()
            if np.asarray(v).dtype.kind in "fc" and np.asarray(v).size and k not in GAUGE}, result.metrics


@pytest.mark.parametrize("name", sorted(CASES))
def test_iterative_solver_matches_direct_through_the_cli(name, decrun_cli, tmp_path):
    direct, direct_metrics = _fields(decrun_cli, tmp_path, name, "direct")
    iterative, metrics = _fields(decrun_cli, tmp_path, name, "iterative")
    assert metrics["status"] == "ok" and direct.keys() == iterative.keys()
    for key, reference in direct.items():
        # relative to the largest field of the same shape (a harmonic part of round-off is
        # compared with ω, not with itself)
        scale = max(np.abs(v).max() for v in direct.values() if v.shape == reference.shape) or 1.0
        difference = np.abs(iterative[key] - reference).max() / scale
        assert difference <= 1e-8, f"{key}: {difference:.3g}"
