"""The fluid scheme's choices have one home (decrun/methods/fluid/options.py): FluidOptions
makes each a member of its set and refuses the two unstable pairs, with the same words for
the app (``app.*`` keys, the CLI override that fixes it) and for Python callers of
VorticityFluid (its keyword names); ``walls: auto`` resolves by the viscosity there."""

from __future__ import annotations

import numpy as np
import pytest

from decrun.complex import SimplicialComplex
from decrun.core.solvers.direct import DirectSolver
from decrun.dec import DEC
from decrun.errors import ConfigError
from decrun.methods.fluid.options import Backtracking, Circulation, FluidOptions, Velocity, Walls
from decrun.methods.fluid.simulation import VorticityFluid

from meshes_for_tests import jittered_lattice


def test_choices_become_members_and_the_unstable_pairs_are_refused_with_the_callers_words():
    options = FluidOptions(velocity="wshd07", circulation="trapezoid", walls="no_slip", integrator="per_triangle")
    assert options.velocity is Velocity.wshd07 and options.integrator is Backtracking.per_triangle
    assert not options.swept and options.resolved_walls(0.0) is Walls.no_slip
    with pytest.raises(ConfigError, match=r"^walls=slip needs a swept circulation \(circulation=trapezoid takes"):
        FluidOptions(velocity="wshd07", circulation="trapezoid", walls="slip")
    with pytest.raises(ConfigError, match=r"^app.circulation=trapezoid with app.velocity=least_squares is "
                                          r"unstable; use app.velocity=wshd07"):
        FluidOptions(circulation="trapezoid", key="app")
    with pytest.raises(ConfigError, match=r"^integrator: must be one of midpoint \| euler \| per_triangle, got 'rk4'"):
        FluidOptions(integrator="rk4")
    # auto: slip at ν = 0 with a swept rule, no-slip otherwise
    assert FluidOptions().resolved_walls(0.0) is Walls.slip and FluidOptions().resolved_walls(0.01) is Walls.no_slip
    assert FluidOptions(circulation=Circulation.swept).swept


def test_the_app_refuses_a_slip_wall_with_a_trapezoid_rule_and_the_override_runs():
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    base = ["app=fluid", "mesh.subdiv=1", "mesh.noise=0", "app.steps=2", "app.animation=false", "figures=false",
            "app.velocity=wshd07", "app.circulation=trapezoid"]
    with pytest.raises(ConfigError) as info:
        run_experiment(compose_config([*base, "app.walls=slip"]))
    assert str(info.value) == ("app.walls=slip needs a swept circulation (app.circulation=trapezoid takes the wall "
                               "velocity at the border points); use app.walls=no_slip")
    result = run_experiment(compose_config([*base, "app.walls=no_slip"])).result
    assert result.metrics["status"] == "ok" and result.metrics["steps_done"] == 2


def test_the_method_takes_options_or_keywords_and_the_same_step_either_way():
    dec = DEC(SimplicialComplex(*jittered_lattice()))
    w0 = np.random.default_rng(0).standard_normal(dec.K.num_simplices(0))
    common = dict(dt=0.5, viscosity=0.0, inflow_velocity=(1.0, 0.5), initial_vorticity=w0)
    by_keyword = VorticityFluid(dec, DirectSolver, kernels="numpy", velocity="wshd07",
                                circulation="corrected_trapezoid", **common)
    by_options = VorticityFluid(dec, DirectSolver, options=FluidOptions(
        kernels="numpy", velocity=Velocity.wshd07, circulation=Circulation.corrected_trapezoid), **common)
    assert by_keyword.options == by_options.options and by_keyword.walls is Walls.no_slip
    by_keyword.step()
    by_options.step()
    np.testing.assert_array_equal(by_keyword.vorticity, by_options.vorticity)
    with pytest.raises(TypeError, match=r"give options= or the choices \['walls'\] by keyword, not both"):
        VorticityFluid(dec, DirectSolver, options=FluidOptions(), walls="slip", **common)
