"""A compiled model and its integrator as a :class:`decrun.methods.stepping.Stepper`.

The state is the evolved fields at step n (time t_n = n·dt, computed from n so that no
round-off accumulates in t), plus the integrator's own state (the adaptive step size); a
checkpoint holds both, so a resumed run repeats the uninterrupted one bit for bit. Recorded at
every record: ``time``, each evolved field (its values) and each declared metric (a number).
"""

from __future__ import annotations

import numpy as np

from decrun.methods.model.integrators import _enforce

__all__ = ["ModelStepper"]


class ModelStepper:
    """Steps ``model`` (a :class:`~decrun.methods.model.system.CompiledModel`) with
    ``integrator`` from ``t0`` by ``dt``."""

    record_divergent_step = False

    def __init__(self, model, integrator, dt: float, t0: float = 0.0, watch=None):
        self.model, self.integrator, self.dt, self.t0 = model, integrator, float(dt), float(t0)
        #: a :class:`~decrun.methods.model.growth.GrowthWatch`: declared bounds and runaway growth (None: none)
        self.watch = watch
        # fixed (Dirichlet) values hold from t = 0: the first step must not see the initial value's border
        self.state = _enforce(model, {name: np.array(model.initial_values[name], dtype=np.float64)
                                      for name in model.evolved})
        self.n = 0
        self._env = None

    @property
    def t(self) -> float:
        return self.t0 + self.n * self.dt

    def environment(self) -> dict:
        """Every value of the model at the current state (computed once per state)."""
        if self._env is None:
            self._env = self.model.environment(self.state, self.t, complete=True)
        return self._env

    def values(self) -> dict:
        out = {"time": self.t, **{name: self.state[name] for name in self.model.evolved}}
        with np.errstate(all="ignore"):  # a non-finite definition or metric is reported at the end, by name
            out.update(self.model.metric_values(self.environment()))
        return out

    def step(self, n: int) -> str:
        try:
            state = self.integrator.step(self.state, self.t)
        except FloatingPointError as error:
            return str(error)
        self.state = {name: np.asarray(value, dtype=np.float64) for name, value in state.items()}
        self.n = n
        self._env = None
        return self.watch.check(self.state, n) if self.watch is not None else ""

    def state_dict(self) -> dict:
        state = {"fields": dict(self.state), "n": self.n}
        integrator = self.integrator.state_dict()
        if integrator:  # an empty group leaves nothing in checkpoint.h5: the state read back has no key for it
            state["integrator"] = integrator
        return state

    def load_state(self, state: dict) -> None:
        self.state = {name: np.array(state["fields"][name], dtype=np.float64) for name in self.model.evolved}
        self.n = int(state["n"])
        self.integrator.load_state(state.get("integrator", {}))  # an empty state leaves no group in the file
        self._env = None
