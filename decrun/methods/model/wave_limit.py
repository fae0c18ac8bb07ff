"""The oscillatory stability limit of an explicit integrator: the time step above which the fastest
linear mode of a model at its initial state — for rotating shallow water the gravity waves, |λ| ≈ √(g h_max)
|k|_max — leaves the integrator's stability region along the imaginary axis.

The diffusion limit (:func:`decrun.methods.model.integrators.explicit_stability_limit`) needs a symmetric
negative semi-definite linear block; a wave or advection model has none. Here the exact Jacobian
J = ∂f/∂y of the model's right side at the initial state (:class:`~decrun.methods.model.problem.ModelProblem`,
M⁻¹ J with a diagonal mass M) gives its eigenvalue of largest modulus λ* (ARPACK, ``which="LM"``), and

    dt_max = β / |λ*|,  β = 2√2 for classical RK4 (its stability region's half-length on the imaginary axis;
    explicit Euler contains no imaginary interval: β = 0),

a necessary bound of the linearized problem at t = 0. For TRiSK's shallow water on the icosphere the measured
largest stable RK4 steps of Williamson's TC2 (the hand-written twin's bisection, 2 days) are
1.04, 1.04 and 1.02 × this bound at subdiv 4, 5, 6 (tests/methods/model/test_wave_limit.py): the refusal sits just below them.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["IMAGINARY_INTERVAL", "oscillatory_stability_limit"]

#: the half-length of the imaginary-axis interval inside each explicit scheme's stability region
IMAGINARY_INTERVAL = {"rk4": 2.0 * np.sqrt(2.0)}


def oscillatory_stability_limit(model, scheme: str, state: dict) -> tuple[float, float]:
    """(dt_max = β/|λ*| (s), |λ*|) for the explicit ``scheme`` on ``model`` linearized at ``state`` (the
    initial values by field name); (inf, 0) when the scheme has no interval here or J vanishes; explicit
    Euler with an oscillatory J (|Im λ*| > |Re λ*|) gets dt_max = 0 (it is unstable at any step)."""
    from scipy.sparse.linalg import ArpackNoConvergence, eigs

    from decrun.methods.model.language import ModelError
    from decrun.methods.model.problem import ModelProblem

    if scheme not in IMAGINARY_INTERVAL:
        return float("inf"), 0.0
    problem = ModelProblem(model)
    y = problem.free_values({name: np.asarray(state[name], dtype=np.float64) for name in model.evolution.names})
    try:
        J = problem.jacobian(y, 0.0)
    except ModelError:  # no exact sparse Jacobian (a Galerkin ⋆⁻¹): stability.explicit_limit judges it
        return float("inf"), 0.0
    if problem.mass is not None:
        diagonal = problem.mass.diagonal()
        if (problem.mass - sp.diags(diagonal)).count_nonzero() or not np.all(diagonal > 0):
            return float("inf"), 0.0  # a Galerkin mass: no cheap M⁻¹ J
        J = sp.diags(1.0 / diagonal) @ J
    if J.count_nonzero() == 0:
        return float("inf"), 0.0
    try:
        values = eigs(J.tocsr(), k=min(6, J.shape[0] - 2), which="LM", return_eigenvectors=False, tol=1e-8,
                      maxiter=20 * J.shape[0], v0=np.ones(J.shape[0]))
    except ArpackNoConvergence as stuck:
        if not len(stuck.eigenvalues):
            return float("inf"), 0.0
        values = stuck.eigenvalues
    value = values[np.argmax(np.abs(values))]  # the top of the spectrum is a cluster of waves: six of it
    modulus = float(abs(value))
    beta = IMAGINARY_INTERVAL[scheme]
    if beta == 0.0:
        return (0.0 if abs(value.imag) > abs(value.real) else float("inf")), modulus
    return beta / modulus, modulus
