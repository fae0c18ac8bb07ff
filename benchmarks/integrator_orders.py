"""The measured orders of docs/models.md ("Integrators: measured orders"): every fixed-step
integrator's observed time order, and Newton's iterations and spatial order.

Time order, by self-convergence on the nonlinear logistic reaction–diffusion model
``dt(u) = 0.05*laplacian(u) + u*(1 - u)`` (the model language, compiled and stepped through
:func:`decrun.methods.model.integrators.make_integrator`, the integrators a run uses) on a 6 × 5
grid of unit spacing (circumcentric DEC, natural borders), t ∈ [0, 1], a smooth bump
u0 = 0.1 + 0.8 exp(−((x − 1.5)² + (y − 2)²)/4): with y_dt the state at t = 1,

    order_i = log₂(‖y_dt − y_dt/2‖ / ‖y_dt/2 − y_dt/4‖)  in the ⋆0 norm,  dt = 1/4 … 1/32,

two orders per integrator (``<name>_order_0`` from dt = 1/4, 1/8, 1/16; ``<name>_order_1`` from
1/8, 1/16, 1/32). SciPy's adaptive bdf, radau and rk45 have no fixed step and are not measured;
symplectic needs a pair of fields.

Newton, on −Δu + u³ = f on the unit square (``app=poisson``, ``mesh=grid``, nx = 9, 17, 33;
u = sin(πx) cos(πy) + x² with its border values, tests/apps/test_model_newton.py's problem):
``newton_<nx>_iterations``, ``newton_<nx>_error`` (max |u − u_exact|) and ``newton_<nx>_order``
(log(e_i/e_{i+1}) / log(h_i/h_{i+1}), h = 1/(nx − 1)); tests/apps/test_model_newton.py checks
that the residual norms fall quadratically.

None of it depends on the machine or its load. ``scripts/doc_numbers.py`` takes the page's
numbers from :func:`numbers`; ``python benchmarks/integrator_orders.py`` prints them.
"""

from __future__ import annotations

import math

import numpy as np

#: the fixed-step integrators measured, with their nominal order
INTEGRATORS = {"explicit_euler": 1, "implicit_euler": 1, "semi_implicit": 1, "imex": 1, "crank_nicolson": 2,
               "ssprk3": 3, "ark_imex": 3, "rk4": 4, "gauss_legendre": 4, "radau_iia": 5}
STEPS = (4, 8, 16, 32)
NEWTON_NX = (9, 17, 33)
#: −Δu + u³ = f with u = sin(πx) cos(πy) + x²
CUBIC = ("solve(-laplacian(u) + u**3 = 2*pi**2*sin(pi*x)*cos(pi*y) - 2 + (sin(pi*x)*cos(pi*y) + x**2)**3)")


def logistic_model():
    """The compiled logistic reaction–diffusion model and its ⋆0 weights."""
    from decrun import DEC, SimplicialComplex
    from decrun.core.solvers import solver_factory
    from decrun.methods.model import FieldSpec, ModelSpec, compile_model
    from decrun.runner.mesh.sources.primitives import Grid

    mesh = Grid(nx=6, ny=5, width=5.0, height=4.0).make()
    dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
    spec = ModelSpec(fields={"u": FieldSpec(0, "0.1 + 0.8*exp(-((x - 1.5)**2 + (y - 2)**2)/4)")},
                     equations=["dt(u) = 0.05*laplacian(u) + u*(1 - u)"], dt=0.25)
    return compile_model(spec, dec, solver_factory("auto")), dec.star(0).diagonal()


def final_state(model, scheme: str, steps: int) -> np.ndarray:
    """u(1) by ``scheme`` in ``steps`` steps of dt = 1/steps."""
    from decrun.core.solvers import solver_factory
    from decrun.methods.model.integrators import make_integrator

    dt = 1.0 / steps
    stepper = make_integrator(model, scheme, dt, solver_factory("auto"))
    state = {"u": model.initial_values["u"].copy()}
    for n in range(steps):
        state = stepper.step(state, n * dt)
    return np.asarray(state["u"])


def time_orders() -> dict[str, float]:
    """``<integrator>_order_0``, ``<integrator>_order_1`` (module docstring)."""
    model, weights = logistic_model()
    out = {}
    for scheme in INTEGRATORS:
        solutions = [final_state(model, scheme, steps) for steps in STEPS]
        differences = [math.sqrt(weights @ (a - b) ** 2) for a, b in zip(solutions[:-1], solutions[1:], strict=True)]
        for i in range(len(differences) - 1):
            out[f"{scheme}_order_{i}"] = math.log2(differences[i] / differences[i + 1])
    return out


def newton_numbers() -> dict[str, float]:
    """``newton_<nx>_iterations``, ``_error``, ``_order`` (module docstring)."""
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    out: dict[str, float] = {}
    previous = None
    for nx in NEWTON_NX:
        result = run_experiment(compose_config(["app=poisson", f"mesh.nx={nx}", f"mesh.ny={nx}",
                                                f"app.equations=['{CUBIC}']", "figures=false",
                                                "progress=false"])).result
        error, h = float(result.metrics["max_abs_error"]), 1.0 / (nx - 1)
        out[f"newton_{nx}_iterations"] = int(result.metrics["u_newton_iterations"])
        out[f"newton_{nx}_error"] = error
        if previous is not None:
            out[f"newton_{nx}_order"] = math.log(previous[0] / error) / math.log(previous[1] / h)
        previous = (error, h)
    return out


def numbers() -> dict[str, float]:
    """Every number of the page's table (module docstring)."""
    return {**time_orders(), **newton_numbers()}


if __name__ == "__main__":
    for name, value in numbers().items():
        print(f"{name:32s} {value:.4g}")
