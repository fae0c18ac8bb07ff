"""What ``stable`` means for a model run beyond "every value is finite".

After every step :class:`GrowthWatch` checks the evolved fields:

- a field with declared bounds (``app.fields.<u>.bounds: [lo, hi]``) must stay in [lo, hi]
  (to round-off: :data:`BOUND_SLACK` of the interval's size);
- without bounds, no evolved field may exceed :data:`GROWTH_FACTOR` × the run's scale, the
  largest of max|u(0)| over the evolved fields and of T·max|dt(u)(0)| (T the run's duration:
  what the initial rate would reach). A model that starts from 0 with no rate at t = 0 takes
  the rate of its initial state at t = T/4, T/2, 3T/4, T (a forcing that starts at 0); one
  with none of these takes its scale from the first step that moves it.

A field that leaves either is a diverged run: the step loop stops there with ``stable: false``,
``diverged_at_step`` and the reason (:func:`decrun.methods.stepping.run_steps`), keeping what it
recorded. The check costs one max|u| per field and step.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GrowthWatch", "GROWTH_FACTOR", "BOUND_SLACK"]

#: how far (× the run's initial scale) an evolved field without declared bounds may grow
GROWTH_FACTOR = 1e6
#: a declared bound is kept to this fraction of hi − lo (round-off of an exact invariant)
BOUND_SLACK = 1e-9


class GrowthWatch:
    """The per-step check of the module docstring for ``model`` (a compiled model), its
    declared ``bounds`` (field → (lo, hi)) and the run's ``duration`` (s of model time)."""

    def __init__(self, model, bounds: dict[str, tuple[float, float]], duration: float, key: str = "app"):
        self.bounds = {name: (float(lo), float(hi)) for name, (lo, hi) in bounds.items()}
        self.key = key
        self.names = [name for name in model.evolved if name not in self.bounds]
        self.scale = 0.0
        if self.names:
            state = {name: np.asarray(model.initial_values[name], dtype=np.float64) for name in model.evolved}
            initial = max(float(np.max(np.abs(state[name]), initial=0.0)) for name in self.names)
            rates = []
            for t in np.linspace(0.0, duration, 5):  # a time-dependent forcing may vanish at t = 0
                with np.errstate(all="ignore"):
                    rate = model.derivative(model.environment(state, float(t)), self.names)
                rates += [float(np.max(np.abs(np.asarray(rate[name], dtype=np.float64)), initial=0.0))
                          for name in self.names]
                if initial > 0 or any(value > 0 for value in rates):
                    break
            finite = [value for value in rates if np.isfinite(value)]
            self.scale = max([initial, duration * max(finite, default=0.0)])

    def check(self, state: dict[str, np.ndarray], n: int) -> str:
        """``""`` or why the state after step ``n`` has diverged."""
        for name, (lo, hi) in self.bounds.items():
            values = state[name]
            slack = BOUND_SLACK * (hi - lo)
            low, high = float(np.min(values)), float(np.max(values))
            if low < lo - slack or high > hi + slack:
                worst = low if lo - low > high - hi else high
                return (f"{name} left its declared bounds {self.key}.fields.{name}.bounds=[{lo:g}, {hi:g}] at step {n} "
                        f"({name} = {worst:.3g})")
        if not self.names:
            return ""
        largest = max(float(np.max(np.abs(state[name]), initial=0.0)) for name in self.names)
        if self.scale == 0.0:
            self.scale = largest  # nothing moved it before: its first value sets the scale
            return ""
        if largest > GROWTH_FACTOR * self.scale:
            name = max(self.names, key=lambda name: float(np.max(np.abs(state[name]), initial=0.0)))
            return (f"{name} grew to max|{name}| = {largest:.3g} at step {n}, more than {GROWTH_FACTOR:.0e} × the run's "
                    f"scale {self.scale:.3g} (max|u(0)| and t_end·max|dt(u)(0)|)")
        return ""
