"""The model app's refusal of an explicit time step beyond the fastest oscillation of the model at t = 0
(:func:`decrun.methods.model.wave_limit.oscillatory_stability_limit`): a wave or advection model — rotating
shallow water's gravity waves — has no diffusion block for the diffusion limit to bound."""

from __future__ import annotations

from decrun.errors import ConfigError
from decrun.methods.model.stability import fitted_dt
from decrun.methods.model.wave_limit import oscillatory_stability_limit

__all__ = ["check_wave_limit"]


def check_wave_limit(model, scheme: str, dt: float, t_end: float | None) -> float:
    """The limit dt_max (s, inf when there is none); a ``dt`` above it is one :class:`ConfigError` line giving
    ``app.dt`` that works (a whole number of steps to ``t_end``, each at most 0.95 dt_max)."""
    limit, modulus = oscillatory_stability_limit(model, scheme, model.initial_values)
    if dt > limit:
        safe = fitted_dt(0.95 * limit, t_end)
        raise ConfigError(f"app.dt={dt:g} exceeds the stability limit {limit:.4g} of integrator={scheme} for the "
                          f"fastest linear mode at t = 0 (2√2/|λ|max, |λ|max = {modulus:.4g} s⁻¹ of the Jacobian: "
                          f"waves, e.g. shallow water's gravity waves √(g h) on the shortest edges); use `app.dt={safe}`")
    return limit
