"""The Halfar dome (conf/app/halfar.yaml) under implicit integrators with the exact Jacobian of
its flux Γ H̄^{n+2} |∇H|^{n−1} ∇H (the derivative rules of norm and sharp,
methods/model/vector_derivatives.py): implicit Euler by Newton and SciPy's BDF with ``jac`` from
the derivative pass, against Halfar's exact thickness at t = 200 a on the 4 km grid."""

from __future__ import annotations

import numpy as np
import pytest
from test_halfar import grid_dec, run_halfar

from decrun.methods.model import FieldSpec, ModelSpec, compile_model
from decrun.methods.model.adaptive_jacobian import exact_jacobian


@pytest.mark.parametrize("integrator", ["implicit_euler", "bdf"])
def test_the_dome_under_an_implicit_integrator_matches_halfars_answer(integrator):
    """RMS over the ice 12.18 m (implicit Euler, dt = 1 a) and 12.03 m (BDF) against the exact
    answer, beside the lagged scheme's 11.99 m (the 4 km grid's spatial error dominates); the
    volume Σ⋆0 H is kept (the flux form is conservative and Newton converges) and H stays ≥ 0
    up to Newton's tolerance."""
    metrics, measured = run_halfar(f"app.integrator={integrator}")
    assert metrics["steps_done"] == 200 and metrics["stable"]
    assert metrics["rms_error_m"] == pytest.approx(measured["rms"], rel=1e-9)
    assert abs(measured["rms"] - 11.99) < 0.25 and measured["interior_rms"] < 4.0
    assert measured["volume"] == pytest.approx(measured["volume0"], rel=1e-8)
    assert metrics["min_thickness_m"] > -1e-6


def test_bdf_takes_the_exact_jacobian_of_the_dome():
    """The Jacobian handed to BDF (``exact_jacobian``) equals central differences of the model's
    strong right side F(H) to 1e-6 relative, at a dome with a front (|∇H| = 0 off the ice)."""
    dec = grid_dec(13, 11, 3.0, 2.0)
    spec = ModelSpec(fields={"H": FieldSpec(0, "max(0, 0.8 - x**2 - y**2)**0.4 + 0.1*x*y")},
                     constants={"n": 3.0, "Gamma": 0.7},
                     equations=["grad2 = norm(sharp(d(H)))**2",
                                "D = Gamma*average(cell_average(H)**(n + 2)*grad2**((n - 1)/2))",
                                "dt(H) = -codifferential(D*d(H))"])
    model = compile_model(spec, dec, None)
    jacobian = exact_jacobian(model)
    assert jacobian is not None
    H = model.initial_values["H"]

    def F(H):
        return model.derivative(model.environment({"H": H}, 0.0))["H"]
    w = np.random.default_rng(0).standard_normal(H.size)
    eps = 1e-7
    numeric = (F(H + eps * w) - F(H - eps * w)) / (2 * eps)
    assert np.abs(jacobian(0.0, H) @ w - numeric).max() <= 1e-6 * np.abs(numeric).max()
