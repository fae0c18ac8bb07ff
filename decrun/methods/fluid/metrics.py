"""The fluid's metrics (``app=fluid``) from its first and last diagnostics
(:meth:`decrun.methods.fluid.simulation.VorticityFluid.diagnostics`), the stepping driver's
report and the shadow's metrics. A metric that does not apply is absent, never ``false``:
``diverged_at_step`` only when the energy bound broke or a step went non-finite,
``unstable_reason`` whenever ``stable`` is false (the bound, or the shadow's growth), ``energy_ratio`` / ``enstrophy_ratio`` only when the initial value is > 0 and not round-off,
``circulation_drift`` only on closed surfaces, the ``perturbation_*`` ones only with a shadow."""

from __future__ import annotations

from typing import Any

__all__ = ["fluid_metrics"]


def fluid_metrics(first: dict, last: dict, *, max_divergence: float, seconds: float, step_seconds_max: float,
                  obtuse_triangles: int, closed: bool, reason: str = "", chaos: dict | None = None,
                  max_growth_per_step: float = 0.1, round_off: tuple[str, ...] = ()) -> dict[str, Any]:
    """Metrics of one fluid run.

    first, last : diagnostics of the initial and the last state (``step``, ``stable``,
        ``kinetic_energy``, ``enstrophy``, ``total_circulation``, and ``diverged_at_step``
        once a step went non-finite)
    max_divergence : max over the run of max |d⋆u| (the discrete divergence of the flux)
    seconds, step_seconds_max : wall time of the steps and of the slowest step (s)
    closed : the surface has no border; reason : why the run stopped ("" when it did not);
    chaos : the shadow's metrics (``perturbation_stable`` among them) or None
    max_growth_per_step : the shadow's bound on the fitted growth of ln(separation) per step
    round_off : the diagnostics (``"kinetic_energy"``, ``"enstrophy"``) whose initial value
        is round-off (a start at rest up to round-off): their ratios would be ratios of
        round-off and are left out

    ``stable`` = the energy stayed bounded and (with a shadow) the perturbation's growth was
    small; ``steps_per_second`` = steps_done / seconds.
    """
    chaos = chaos or {}
    steps_done = int(last["step"])
    bounded = bool(last["stable"]) and "diverged_at_step" not in last
    metrics: dict[str, Any] = {
        "stable": bounded and chaos.get("perturbation_stable", True),
        "steps_done": steps_done,
        "max_abs_divergence": float(max_divergence),
        "enstrophy_final": float(last["enstrophy"]),
        "kinetic_energy_final": float(last["kinetic_energy"]),
        "steps_per_second": steps_done / seconds if seconds > 0 else float("inf"),
        "obtuse_triangles": int(obtuse_triangles),
        "solve_seconds": seconds,
        "step_seconds_max": step_seconds_max,
    }
    if not bounded:
        metrics["diverged_at_step"] = int(last.get("diverged_at_step", steps_done))
        metrics["unstable_reason"] = reason
    elif not chaos.get("perturbation_stable", True):
        metrics["unstable_reason"] = (
            f"chaotic: the shadow's perturbation grew at {chaos['perturbation_growth_per_step']:.3g} per step "
            f"(slope of ln separation over the last {chaos.get('perturbation_window_steps', steps_done)} steps), "
            f"above app.shadow_max_growth_per_step={max_growth_per_step:g}")
    metrics.update(chaos)
    if first["kinetic_energy"] > 0 and "kinetic_energy" not in round_off:
        metrics["energy_ratio"] = float(last["kinetic_energy"] / first["kinetic_energy"])
    if first["enstrophy"] > 0 and "enstrophy" not in round_off:
        metrics["enstrophy_ratio"] = float(last["enstrophy"] / first["enstrophy"])
    if closed:
        metrics["circulation_drift"] = abs(float(last["total_circulation"]))
    return metrics
