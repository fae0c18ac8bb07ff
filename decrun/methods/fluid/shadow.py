"""A stability flag that sees chaos: a shadow run and its finite-time Lyapunov exponent.

The energy bound of :class:`~decrun.methods.fluid.simulation.VorticityFluid` only sees runs
that blow up. A step that amplifies round-off without bound-breaking (a grid-scale instability
that saturates) leaves the energy bounded while the result depends on round-off (issue 18).
The shadow is a second state started at w0 + ε‖w0‖ δ (δ a smooth random vorticity of unit
⋆0-norm, ε = ``perturbation``) and stepped with the same forces. After every step the
separation d = ‖w_shadow − w‖_⋆0 is measured and the shadow is pulled back to the relative
distance ε (w_shadow = w + (w_shadow − w) ε ‖w‖ / d; ψ and u are linear in w, so they are
rescaled the same way) — the Benettin renormalisation, so the estimate does not saturate.
The mean of ln(d_after / d_before) per second is the largest finite-time Lyapunov exponent
of the discrete map: ``perturbation_growth_per_s``; per step: ``perturbation_growth_per_step``.

Threshold (``max_growth_per_step``, default 0.1): a physical instability grows at a rate
set by the flow (the Fig. 7.15 wake sheds at ≈ 8 Hz), the same at every dt; a numerical one
by a factor per step. A mean growth above 0.1 per step (×1.105 per step; 13 /s at
dt = 0.0075, 40 /s at dt = 0.0025) is reported as unstable.
"""

from __future__ import annotations

import copy

import numpy as np

from decrun.methods.fluid.initial import random_vorticity

__all__ = ["Shadow"]


class Shadow:
    """Shadow of a :class:`VorticityFluid` ``fluid`` (not yet stepped) with a relative
    perturbation ``perturbation`` (smooth random, ``seed``)."""

    def __init__(self, fluid, perturbation: float = 1e-10, seed: int = 1, max_growth_per_step: float = 0.1):
        if not perturbation > 0:
            raise ValueError(f"shadow perturbation must be > 0, got {perturbation}")
        self.fluid, self.epsilon, self.max_growth_per_step = fluid, float(perturbation), float(max_growth_per_step)
        delta = fluid._remove_mean(random_vorticity(fluid.dec, seed=seed, amplitude=1.0))
        delta /= self._norm(delta)
        self.twin = copy.copy(fluid)  # shares the mesh, operators and factorizations; own state
        self.twin.vorticity = fluid.vorticity + self._distance() * delta
        self.twin.psi = fluid._recover(self.twin.vorticity)
        self.twin.flux = fluid.d0 @ self.twin.psi + fluid.harmonic
        self.separation = self._distance()
        self.log_growth = 0.0
        self.steps = 0

    def _norm(self, w: np.ndarray) -> float:
        return float(np.sqrt(self.fluid.star0 @ (w * w)))

    def _distance(self) -> float:
        """ε relative to the current state (ε absolute for a fluid at rest)."""
        return self.epsilon * max(self._norm(self.fluid.vorticity), 1.0)

    def step(self, force_flux=None) -> float | None:
        """Step the shadow (call right after the fluid stepped with the same ``force_flux``);
        return this step's ln(d_after / d_before), or None once either run diverged."""
        self.twin.step(force_flux)
        if self.fluid.diverged_at_step is not None or self.twin.diverged_at_step is not None:
            return None
        difference = self.twin.vorticity - self.fluid.vorticity
        d = self._norm(difference)
        if not d > 0:  # identical round-off: nothing to measure this step, perturb again
            difference = self.fluid._remove_mean(random_vorticity(self.fluid.dec, seed=self.steps + 2, amplitude=1.0))
            d, growth = self._norm(difference), 0.0
        else:
            growth = float(np.log(d / self.separation))
        self.separation = self._distance()
        scale = self.separation / d
        twin, fluid = self.twin, self.fluid
        twin.vorticity = fluid.vorticity + scale * difference
        twin.psi = fluid._recover(twin.vorticity)
        twin.flux = fluid.d0 @ twin.psi + fluid.harmonic
        self.log_growth += growth
        self.steps += 1
        return growth

    def metrics(self) -> dict:
        """``perturbation_growth_per_s``, ``perturbation_growth_per_step`` (means over the
        steps so far) and ``perturbation_stable`` (growth per step ≤ the threshold)."""
        if not self.steps:
            return {}
        per_step = self.log_growth / self.steps
        return {"perturbation_growth_per_s": per_step / self.fluid.dt, "perturbation_growth_per_step": per_step,
                "perturbation_stable": bool(per_step <= self.max_growth_per_step)}
