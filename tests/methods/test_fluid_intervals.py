"""``intervals="per_point"``: each backtracked point walks only the swept intervals its own CFL
number needs, its positions at the others interpolated (decrun/methods/fluid/simulation.py)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from decrun.complex import SimplicialComplex  # noqa: E402
from decrun.core.channel_mesh import channel_mesh  # noqa: E402
from decrun.core.solvers.direct import DirectSolver  # noqa: E402
from decrun.dec import DEC  # noqa: E402
from decrun.errors import ConfigError  # noqa: E402
from decrun.methods.fluid.initial import random_vorticity  # noqa: E402
from decrun.methods.fluid.interpolation import dot3  # noqa: E402
from decrun.methods.fluid.simulation import VorticityFluid  # noqa: E402

from meshes_for_tests import square_lattice  # noqa: E402


@lru_cache(maxsize=None)
def channel(target: int = 1400, obstacle: bool = True):
    mesh = channel_mesh(target_faces=target, obstacles=None if obstacle else [])
    return mesh, DEC(SimplicialComplex(mesh.vertices, mesh.faces))


def interval_need(sim: VorticityFluid) -> np.ndarray:
    """(m,) ceil(CFL_p / swept_cfl) at the start velocities: the intervals each point needs."""
    both = sim._point_velocities()
    start = sim._circumcenter_velocity(np.ascontiguousarray(both[..., 1:2]))
    return np.maximum(1, np.ceil(np.sqrt(dot3(start, start)) * sim.dt / sim.walker.size / sim.swept_cfl))


def test_a_uniform_flow_moves_every_point_by_minus_v_dt_whatever_its_interval_count():
    """In the uniform channel flow (no obstacle) every point lands at x − v dt whatever its
    interval count (the mesh's edge lengths vary, so the counts do) and the swept change is zero."""
    _, dec = channel(1400, obstacle=False)
    v = np.array([10.0, 3.0, 0.0])
    for intervals in ("uniform", "per_point"):
        sim = VorticityFluid(dec, DirectSolver, dt=0.012, viscosity=0.0, inflow_velocity=v[:2], intervals=intervals)
        need = interval_need(sim)
        assert need.max() >= 2 and need.min() < need.max()  # the counts differ: per_point is exercised
        result, velocity = sim.backtrack()
        start = sim.cells.points[: sim.cells.n_circumcenters]
        expected = start - v * sim.dt
        inside = (expected[:, 0] > 1e-9) & (expected[:, 1] > 1e-9) & (expected[:, 1] < 1 - 1e-9)
        assert inside.sum() > 0.9 * inside.size
        np.testing.assert_allclose(result.position[inside], expected[inside], atol=1e-12)
        assert np.all(result.wall_edge[inside] == -1) and np.all(result.wall_edge[~inside] >= 0)
        assert np.abs(sim._swept_change).max() < 1e-9


def test_per_point_intervals_stay_close_to_finer_uniform_intervals_in_the_channel():
    """The Fig. 7.15 channel (1455 faces, inflow 10, ν = 0.02, dt = 0.005), 10 steps, against the
    uniform rule at swept_cfl = 0.25 (4× finer intervals) as the reference: per_point (each point
    at most swept_cfl = 1 edge length per interval) is within 8 % (⋆0-weighted) and within 3× the
    uniform rule's deviation (measured 4.9 % and 2.1 %: the uniform rule moves most points far
    less than an edge length per interval, since the obstacle's points set k)."""
    mesh, dec = channel(1400)
    common = dict(dt=0.005, viscosity=0.02, inflow_velocity=[10.0, 0.0], obstacle_loops=mesh.obstacle_loops)
    reference = VorticityFluid(dec, DirectSolver, swept_cfl=0.25, **common)
    uniform = VorticityFluid(dec, DirectSolver, intervals="uniform", **common)
    per_point = VorticityFluid(dec, DirectSolver, intervals="per_point", **common)
    need = interval_need(per_point)
    assert need.max() > 2 * need.mean()  # the obstacle's points need several times the mean
    for _ in range(10):
        reference.step()
        a, b = uniform.step(), per_point.step()
    assert a["stable"] and b["stable"]
    star, w = reference.star0, reference.vorticity

    def deviation(sim):
        return float(np.sqrt(star @ (sim.vorticity - w) ** 2 / (star @ w**2)))

    assert 0 < deviation(per_point) < min(0.08, 3 * deviation(uniform)), (deviation(per_point), deviation(uniform))


def test_per_point_keeps_energy_and_enstrophy_at_zero_viscosity_between_slip_walls():
    """Unforced at ν = 0 in the walled unit square with a smooth random vorticity, at a dt where the
    interval counts differ between points: energy and enstrophy never rise above round-off and
    Σ ⋆0 w stays constant (the swept change enters the two cells of a side with opposite signs)."""
    dec = DEC(SimplicialComplex(*square_lattice(24)))
    w0 = random_vorticity(dec, seed=4, amplitude=5.0)
    sim = VorticityFluid(dec, DirectSolver, dt=0.08, viscosity=0.0, initial_vorticity=w0, intervals="per_point")
    assert sim.walls == "slip"
    need = interval_need(sim)
    assert need.max() >= 2 and need.min() == 1
    energy, enstrophy = [sim.kinetic_energy()], [sim.diagnostics()["enstrophy"]]
    for _ in range(25):
        d = sim.step()
        energy.append(d["kinetic_energy"])
        enstrophy.append(d["enstrophy"])
    energy, enstrophy = np.array(energy), np.array(enstrophy)
    assert np.all(np.diff(energy) <= 1e-12 * energy[:-1]) and np.all(np.diff(enstrophy) <= 1e-12 * enstrophy[:-1])
    assert abs(sim.star0 @ sim.vorticity - sim.star0 @ w0) <= 1e-12 * (sim.star0 @ np.abs(w0))
    assert energy[-1] > 0.8 * energy[0]  # bounded, not damped away


@pytest.mark.parametrize("options", [{}, dict(walls="slip", viscosity=0.0)])
def test_per_point_numba_run_equals_the_numpy_run_bitwise(options):
    """The compiled walk on each count's slice of points and the numpy walk on the same points:
    every diagnostic, the vorticity and ψ bit for bit (the interpolation between walked
    boundaries is shared numpy)."""
    mesh, dec = channel(1400)
    common = dict(dt=0.005, viscosity=0.02, inflow_velocity=[10.0, 0.0], obstacle_loops=mesh.obstacle_loops,
                  intervals="per_point")
    common.update(options)
    reference = VorticityFluid(dec, DirectSolver, kernels="numpy", **common)
    sim = VorticityFluid(dec, DirectSolver, kernels="numba", **common)
    assert sim.compiled_walk and not reference.compiled_walk
    for _ in range(8):
        expected, got = reference.step(), sim.step()
        assert got == expected
    assert got["clamped_points"] > 0
    np.testing.assert_array_equal(sim.vorticity, reference.vorticity)
    np.testing.assert_array_equal(sim.psi, reference.psi)


def test_an_unknown_interval_rule_names_the_option():
    _, dec = channel(1400)
    with pytest.raises(ConfigError, match=r"^intervals: must be one of uniform \| per_point, got 'adaptive'"):
        VorticityFluid(dec, DirectSolver, dt=0.005, viscosity=0.0, intervals="adaptive")


def test_app_intervals_through_the_cli_refused_then_fixed_and_per_point_runs(decrun_cli, tmp_path):
    """``app.intervals``: a bad value stops with one line naming the key and the override; the
    override (uniform) and ``app.intervals=per_point`` both run the channel stably."""
    from decrun.runner.results import read_result

    common = ("app=fluid", "mesh=channel", "mesh.target_faces=600", "app.inflow=[10.0, 0.0]", "app.initial=zero",
              "app.viscosity=0.02", "app.steps=10", "app.animation=false", "figures=false")
    proc = decrun_cli(*common, "app.intervals=adaptive", "hydra.run.dir=bad")
    assert proc.returncode != 0 and "Traceback" not in proc.stderr
    message = proc.stderr.strip().splitlines()[-1]
    assert "app.intervals" in message and "app.intervals=uniform" in message, message
    for intervals in ("uniform", "per_point"):
        proc = decrun_cli(*common, f"app.intervals={intervals}", f"hydra.run.dir={intervals}")
        assert proc.returncode == 0, proc.stderr[-2000:]
        metrics = read_result(tmp_path / intervals / "result.h5").metrics
        assert metrics["stable"], metrics
