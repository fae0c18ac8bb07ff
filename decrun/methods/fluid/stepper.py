"""The vorticity fluid as a :class:`decrun.methods.stepping.Stepper` (``app=fluid``'s time loop):
the stirring forces of the fluid's time, the fluid and its shadow stepped together, the largest
divergence so far, and what a checkpoint keeps."""

from __future__ import annotations

import numpy as np

__all__ = ["FluidStepper", "SCALARS"]

#: the scalar diagnostics recorded every ``record_every`` steps
SCALARS = ("time", "kinetic_energy", "enstrophy", "total_circulation", "max_abs_divergence", "vorticity_min",
           "vorticity_max")


class FluidStepper:
    """:class:`decrun.methods.fluid.simulation.VorticityFluid` (and its shadow) as a
    :class:`decrun.methods.stepping.Stepper`: a step applies the stirs active at the fluid's
    time, steps the fluid and the shadow with the same force and keeps the largest
    divergence so far; it blows up when the step produced non-finite values (the fluid then
    keeps its last finite state, which is not recorded again) or the energy bound broke.
    Recorded: ``vorticity`` (n0), ``flux`` (n1) and the scalars of :data:`SCALARS`."""

    record_divergent_step = False
    #: the last step's diagnostics (a step adds keys to the initial ones) and the shadow's
    #: growth fit points (one more a step, up to its window)
    state_variable = ("last", "shadow.window", "shadow.start")

    def __init__(self, fluid, forces, shadow=None):
        """fluid : a VorticityFluid; forces : [(stroke, force flux (n1,))], a stroke's force acting
        while ``stroke.start <= time < stroke.stop``; shadow : a Shadow of the fluid, or None."""
        self.fluid, self.forces, self.shadow = fluid, forces, shadow
        self.last = fluid.diagnostics()
        self.max_divergence = float(self.last["max_abs_divergence"])

    def values(self) -> dict:
        """What is recorded: the vorticity (n0), the flux (n1) and the scalars of :data:`SCALARS`."""
        return dict(vorticity=self.fluid.vorticity, flux=self.fluid.flux, **{k: self.last[k] for k in SCALARS})

    def step(self, n: int) -> str:
        """Step ``n``: the active forces summed, fluid and shadow stepped; why it blew up, or ""."""
        fluid = self.fluid
        active = [force for stir, force in self.forces if stir.start <= fluid.time < stir.stop]
        force = np.sum(active, axis=0) if active else None
        self.last = fluid.step(force)
        if self.shadow is not None:
            self.shadow.step(force)
        self.max_divergence = max(self.max_divergence, self.last["max_abs_divergence"])
        if "diverged_at_step" in self.last:
            return f"step {n} produced non-finite values (or its solve failed); the state is that of step {n - 1}"
        if not self.last["stable"]:
            return f"the kinetic energy {self.last['kinetic_energy']:.3g} broke the blow-up bound at step {n}"
        return ""

    def state_dict(self) -> dict:
        """What a checkpoint keeps: the fluid's (and shadow's) state, the largest divergence, the diagnostics."""
        state = {"fluid": self.fluid.state_dict(), "max_divergence": self.max_divergence,
                 "last": {key: value for key, value in self.last.items()}}
        if self.shadow is not None:
            state["shadow"] = self.shadow.state_dict()
        return state

    def load_state(self, state: dict) -> None:
        """Resume from :meth:`state_dict`'s output."""
        self.fluid.load_state(state["fluid"])
        if self.shadow is not None:
            self.shadow.load_state(state["shadow"])
        self.max_divergence = float(state["max_divergence"])
        self.last = dict(state["last"])
