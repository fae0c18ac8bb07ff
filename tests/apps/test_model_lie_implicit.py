"""A 1-form advected by its own velocity, dt(w) = ν Δw − L_w w, through the real ``decrun``
command (issue 47, items 2–3): lie of a 1-form has its derivative rule in both arguments
(methods/model/vector_derivatives.py), so implicit Euler (Newton with the exact Jacobian) and
bdf (its sparsity pattern) run the model instead of refusing it, and give rk4's answer —
implicit Euler at order 1 in dt, bdf to its tolerance."""

from __future__ import annotations

import json

import numpy as np

from cli_processes import decrun

#: on the unit sphere (subdiv 2, closed: no border), w the line integrals of an ambient field
#: that is not a Killing field (so L_w w ≠ 0); the metrics: ⟨w, w⟩ and ⟨w, d(xy)⟩
MODEL = ["app=heat", "mesh=icosphere_clean", "mesh.subdiv=2", "~app.require", "app.fields.u.form=1",
         "app.fields.u.initial=[-y + x*z, x, 0]", "app.equations=['dt(u) = 0.05*laplacian(u) - lie(u, u)']",
         "~app.metrics", "+app.metrics.energy='inner(u, u)'", "+app.metrics.circulation='inner(u, d(x*y))'",
         "app.t_end=0.2", "app.stability_check=false", "figures=false", "progress=false"]


def _metrics(tmp_path, integrator: str, dt: float, *extra: str) -> dict:
    directory = f"{integrator}_{dt}"
    done = decrun(*MODEL, f"app.integrator={integrator}", f"app.dt={dt}", *extra, f"hydra.run.dir={directory}",
                  cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    return json.loads((tmp_path / directory / "metrics.json").read_text())


def test_self_advection_of_a_1_form_runs_under_implicit_euler_and_bdf(tmp_path):
    """Refused before ("lie has no derivative in argument 1"); now implicit Euler's error
    against rk4 (dt = 0.005; its own error is O(dt⁴)) halves with dt in both metrics, and bdf
    at rtol 1e-8 agrees with rk4 to 1e-6."""
    reference = _metrics(tmp_path, "rk4", 0.005)
    errors = np.array([[abs(_metrics(tmp_path, "implicit_euler", dt)[name] - reference[name])
                        for name in ("energy", "circulation")] for dt in (0.02, 0.01)])
    assert errors.min() > 0
    orders = np.log2(errors[0] / errors[1])
    assert np.all(np.abs(orders - 1) < 0.25), (errors, orders)
    bdf = _metrics(tmp_path, "bdf", 0.05, "app.rtol=1e-8", "app.atol=1e-10")
    assert abs(bdf["energy"] - reference["energy"]) <= 1e-6 * abs(reference["energy"])
    assert abs(bdf["circulation"] - reference["circulation"]) <= 1e-6 * abs(reference["energy"])
    assert abs(reference["circulation"]) > 1e-3  # the advection moved w: the metric sees L_w w
