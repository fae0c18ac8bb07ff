"""A stability flag that sees chaos: a shadow run and its finite-time Lyapunov exponent.

The energy bound of :class:`~decrun.methods.fluid.simulation.VorticityFluid` only sees runs
that blow up. A step that amplifies round-off without bound-breaking (a grid-scale instability
that saturates) leaves the energy bounded while the result depends on round-off.
The shadow is a second state started at w0 + ε‖w0‖ δ (δ a smooth random vorticity of unit
⋆0-norm, ε = ``perturbation``) and stepped with the same forces. After every step the
separation d = ‖w_shadow − w‖_⋆0 is measured and the shadow is pulled back to the relative
distance ε (w_shadow = w + (w_shadow − w) ε ‖w‖ / d; ψ and u are linear in w, so they are
rescaled the same way) — the Benettin renormalisation, so the estimate does not saturate.
Summing g_k = ln(d_after / d_before) gives L_n = Σ_{k ≤ n} g_k, the log of the separation a
never-renormalised shadow would have after n steps (L_0 = 0).

Growth rate: the least-squares slope of L_n against n over a trailing window — the
last ``window_steps`` steps, never the first ``transient_steps`` (see :func:`fitted_growth`) —
per step: ``perturbation_growth_per_step``; per second: ``perturbation_growth_per_s``. The
slope of a sustained exponent is that exponent; a single jump of L by J (the random δ aligning
with the growing direction in the first step; a backtracked point of a symmetric start state
such as a rigid rotation on an icosphere falling exactly on a dual-cell border, where the
interpolation is discontinuous: +16 in step 1 at ε = 1e-10, +ln 10 per decade of ε) moves the
slope by at most 1.5 J / window and not at all when it lies in the transient, so the verdict of
a laminar run no longer depends on how many steps it ran (the former run mean 16 / n flagged
30 steps and not 100). The run mean L_n / n (``perturbation_mean_growth_per_step``) and the
largest single step (``perturbation_largest_step_growth``) are reported beside it.

Threshold (``max_growth_per_step``, default 0.1): a physical instability grows at a rate
set by the flow (the Fig. 7.15 wake sheds at ≈ 8 Hz), the same at every dt; a numerical one
by a factor per step. A fitted growth above 0.1 per step (×1.105 per step; 13 /s at
dt = 0.0075, 40 /s at dt = 0.0025) is reported as unstable.
"""

from __future__ import annotations

import copy
from collections import deque

import numpy as np

from decrun.methods.fluid.initial import random_vorticity

__all__ = ["Shadow", "fitted_growth", "TRANSIENT_STEPS"]

#: steps at the start of a run that the fit never uses (the perturbation's alignment)
TRANSIENT_STEPS = 5


def fitted_growth(log_separation: np.ndarray, steps: np.ndarray) -> float:
    """Least-squares slope (1 / step) of the line L ≈ a + s·n through the points
    (``steps`` (k,), ``log_separation`` (k,)), k ≥ 2: s = Σ (n − n̄)(L − L̄) / Σ (n − n̄)²."""
    n = np.asarray(steps, dtype=np.float64)
    L = np.asarray(log_separation, dtype=np.float64)
    if n.size < 2:
        raise ValueError(f"a growth rate needs at least 2 steps, got {n.size}")
    n = n - n.mean()
    return float(n @ (L - L.mean()) / (n @ n))


class Shadow:
    """Shadow of a :class:`VorticityFluid` ``fluid`` (not yet stepped) with a relative
    perturbation ``perturbation`` (smooth random, ``seed``); the growth rate is fitted over the
    last ``window_steps`` ≥ 2 steps after the first ``transient_steps`` (see the module
    docstring)."""

    def __init__(self, fluid, perturbation: float = 1e-10, seed: int = 1, max_growth_per_step: float = 0.1,
                 window_steps: int = 100, transient_steps: int = TRANSIENT_STEPS):
        if not perturbation > 0:
            raise ValueError(f"shadow perturbation must be > 0, got {perturbation}")
        if window_steps < 2:
            raise ValueError(f"shadow window_steps must be >= 2 (a line through two steps), got {window_steps}")
        if transient_steps < 0:
            raise ValueError(f"shadow transient_steps must be >= 0, got {transient_steps}")
        self.fluid, self.epsilon, self.max_growth_per_step = fluid, float(perturbation), float(max_growth_per_step)
        self.window_steps, self.transient_steps = int(window_steps), int(transient_steps)
        delta = fluid._remove_mean(random_vorticity(fluid.dec, seed=seed, amplitude=1.0))
        delta /= self._norm(delta)
        self.twin = copy.copy(fluid)  # shares the mesh, operators and factorizations; own state
        self.twin.vorticity = fluid.vorticity + self._distance() * delta
        self.twin.psi = fluid._recover(self.twin.vorticity)
        self.twin.flux = fluid.d0 @ self.twin.psi + fluid.harmonic
        self.separation = self._distance()
        self.log_growth = 0.0  # L_n
        self.largest_step_growth = -np.inf
        self.steps = 0
        #: (n, L_n) of the last window_steps + 1 steps after the transient (memory stays flat),
        #: and of the first ones, for runs too short to have a window
        self._window: deque = deque([(0, 0.0)] if self.transient_steps == 0 else [], maxlen=self.window_steps + 1)
        self._start: list = [(0, 0.0)]

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
        self.largest_step_growth = max(self.largest_step_growth, growth)
        self.steps += 1
        point = (self.steps, self.log_growth)
        if self.steps >= self.transient_steps:  # (n = 0 is in the window from the start when there is no transient)
            self._window.append(point)
        if self.steps <= self.transient_steps:
            self._start.append(point)
        return growth

    def state_dict(self) -> dict:
        """The shadow's state (its twin's :meth:`~VorticityFluid.state_dict`, the separation,
        L_n, the fit's points) for a checkpoint."""
        return {"twin": self.twin.state_dict(), "separation": float(self.separation),
                "log_growth": float(self.log_growth), "largest_step_growth": float(self.largest_step_growth),
                "steps": int(self.steps), "window": np.array(self._window, dtype=np.float64).reshape(-1, 2),
                "start": np.array(self._start, dtype=np.float64).reshape(-1, 2)}

    def load_state(self, state: dict) -> None:
        """Restore a :meth:`state_dict`."""
        self.twin.load_state(state["twin"])
        self.separation, self.log_growth = float(state["separation"]), float(state["log_growth"])
        self.largest_step_growth, self.steps = float(state["largest_step_growth"]), int(state["steps"])
        points = [(int(n), float(value)) for n, value in np.asarray(state["window"]).reshape(-1, 2)]
        self._window = deque(points, maxlen=self.window_steps + 1)
        self._start = [(int(n), float(value)) for n, value in np.asarray(state["start"]).reshape(-1, 2)]

    def fit_points(self) -> np.ndarray:
        """(k, 2) the (n, L_n) the growth rate is fitted to: n from max(transient_steps,
        steps − window_steps) to steps; a run too short for two such points uses all of its
        steps from n = 0."""
        points = self._window if len(self._window) >= 2 else self._start
        return np.array(points, dtype=np.float64).reshape(-1, 2)

    def metrics(self) -> dict:
        """``perturbation_growth_per_step`` (the fitted slope, see :func:`fitted_growth`),
        ``perturbation_growth_per_s`` (the same / dt), ``perturbation_window_steps`` (steps
        the fit spans), ``perturbation_mean_growth_per_step`` (L_n / n over the whole run),
        ``perturbation_largest_step_growth`` and ``perturbation_stable`` (fitted growth per
        step ≤ ``max_growth_per_step``); {} before the first step."""
        if not self.steps:
            return {}
        points = self.fit_points()
        per_step = fitted_growth(points[:, 1], points[:, 0])
        return {"perturbation_growth_per_s": per_step / self.fluid.dt, "perturbation_growth_per_step": per_step,
                "perturbation_window_steps": int(points[-1, 0] - points[0, 0]),
                "perturbation_mean_growth_per_step": self.log_growth / self.steps,
                "perturbation_largest_step_growth": float(self.largest_step_growth),
                "perturbation_stable": bool(per_step <= self.max_growth_per_step)}
