"""decrun.methods.fluid.metrics: a metric that does not apply is absent, never false."""

import pytest

from decrun.methods.fluid.metrics import fluid_metrics

REST = {"step": 0, "stable": True, "kinetic_energy": 0.0, "enstrophy": 0.0, "total_circulation": 0.0}


def test_a_bounded_run_at_rest_on_an_open_domain_has_no_ratios_no_drift_no_divergence_step():
    last = dict(REST, step=10, kinetic_energy=0.5, enstrophy=0.2, total_circulation=1e-3)
    metrics = fluid_metrics(REST, last, max_divergence=1e-15, seconds=2.0, step_seconds_max=0.3,
                            obtuse_triangles=0, closed=False)
    assert metrics["stable"] is True and metrics["steps_done"] == 10 and metrics["steps_per_second"] == 5.0
    for absent in ("energy_ratio", "enstrophy_ratio", "circulation_drift", "diverged_at_step", "unstable_reason",
                   "perturbation_stable"):
        assert absent not in metrics


def test_a_diverged_run_on_a_closed_surface_says_where_and_why():
    first = dict(REST, kinetic_energy=2.0, enstrophy=4.0)
    last = dict(first, step=7, stable=False, diverged_at_step=7, total_circulation=-2e-3)
    metrics = fluid_metrics(first, last, max_divergence=0.0, seconds=1.0, step_seconds_max=0.2, obtuse_triangles=3,
                            closed=True, reason="step 7 produced non-finite values",
                            chaos={"perturbation_stable": True})
    assert metrics["stable"] is False and metrics["diverged_at_step"] == 7
    assert metrics["unstable_reason"] == "step 7 produced non-finite values"
    assert metrics["energy_ratio"] == 1.0 and metrics["enstrophy_ratio"] == 1.0
    assert metrics["circulation_drift"] == 2e-3


def test_a_chaotic_shadow_makes_a_bounded_run_unstable():
    last = dict(REST, step=3, kinetic_energy=1.0)
    metrics = fluid_metrics(REST, last, max_divergence=0.0, seconds=1.0, step_seconds_max=0.1, obtuse_triangles=0,
                            closed=True, chaos={"perturbation_stable": False, "perturbation_growth_per_step": 0.5})
    assert metrics["stable"] is False and "diverged_at_step" not in metrics
    assert metrics["perturbation_growth_per_step"] == 0.5
    # stable: false always says why (here the shadow, not the energy bound)
    assert metrics["unstable_reason"].startswith("chaotic: the shadow's perturbation grew at 0.5 per step")
    assert "app.shadow_max_growth_per_step=0.1" in metrics["unstable_reason"]


def test_ratios_of_a_round_off_start_are_left_out():
    """A start at rest up to round-off (enstrophy 1e-30) has no meaningful ratios: the ones
    named round-off are absent, the others stay."""
    first = dict(REST, kinetic_energy=2.0, enstrophy=1e-30)
    last = dict(first, step=5, kinetic_energy=1.0, enstrophy=0.78e-30)
    kept = fluid_metrics(first, last, max_divergence=0.0, seconds=1.0, step_seconds_max=0.1, obtuse_triangles=0,
                         closed=True)
    assert kept["enstrophy_ratio"] == pytest.approx(0.78) and kept["energy_ratio"] == 0.5
    dropped = fluid_metrics(first, last, max_divergence=0.0, seconds=1.0, step_seconds_max=0.1, obtuse_triangles=0,
                            closed=True, round_off=("enstrophy",))
    assert "enstrophy_ratio" not in dropped and dropped["energy_ratio"] == 0.5
