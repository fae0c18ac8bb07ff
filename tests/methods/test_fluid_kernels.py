"""The numba kernels of the fluid (decrun/methods/fluid/compiled.py) against their numpy twins.

Both paths do the same arithmetic in the same order (the numpy twins sum 3-vectors with
``dot3`` and cell weights in order, not with einsum's SIMD order or numpy's pairwise sums), so
the results are bitwise equal: the backtracking (all integrators, CFL substeps, planar jumps and
forced walks, wall clamping, walks through vertices — where the tie between two exit edges is
decided alike), the WSHD07 interpolation and the circulation, on a sphere, a channel with an
obstacle, a jittered lattice with borders and a random Delaunay mesh with obtuse triangles, at
points exactly on vertices, edges and cell corners, and whole multi-step runs.
"""

from __future__ import annotations

import subprocess
import sys
from functools import lru_cache

import numpy as np
import pytest

from decrun.complex import SimplicialComplex
from decrun.core.channel_mesh import channel_mesh
from decrun.core.solvers.direct import DirectSolver
from decrun.dec import DEC
from decrun.methods.fluid.initial import random_vorticity
from decrun.methods.fluid.simulation import VorticityFluid

from meshes_for_tests import icosphere, jittered_lattice, random_planar


@lru_cache(maxsize=None)
def case(name: str):
    """(DEC, VorticityFluid options) of the test meshes, each with a lively flow."""
    if name == "sphere":
        dec = DEC(SimplicialComplex(*icosphere(3)))
        return dec, dict(dt=0.5, viscosity=1e-3, initial_vorticity=random_vorticity(dec, 2, amplitude=5))
    if name == "channel":
        mesh = channel_mesh(target_faces=1400)
        dec = DEC(SimplicialComplex(mesh.vertices, mesh.faces))
        return dec, dict(dt=0.01, viscosity=0.02, inflow_velocity=(10.0, 0.0), obstacle_loops=mesh.obstacle_loops,
                         initial_vorticity=random_vorticity(dec, 1, amplitude=50))
    if name == "lattice":
        dec = DEC(SimplicialComplex(*jittered_lattice()))
        return dec, dict(dt=1.5, viscosity=0.0, inflow_velocity=(1.0, 0.5),
                         initial_vorticity=random_vorticity(dec, 3, amplitude=3))
    if name == "obtuse":  # random Delaunay: obtuse triangles, non-convex flattened cells
        dec = DEC(SimplicialComplex(*random_planar(150, seed=3)))
        return dec, dict(dt=0.02, viscosity=0.0, inflow_velocity=(1.0, 0.0),
                         initial_vorticity=random_vorticity(dec, 4, amplitude=3))
    raise KeyError(name)


#: the thesis' scheme (WSHD07 interpolation); the default (least squares, swept_bounded) is tested too
COMPILED_SCHEME = dict(velocity="wshd07", circulation="corrected_trapezoid")


def pair(name: str, **options):
    dec, base = case(name)
    return [VorticityFluid(dec, DirectSolver, kernels=k, **{**base, **COMPILED_SCHEME, **options})
            for k in ("numpy", "numba")]


def assert_same_points(reference, result):
    """Bitwise the same end points, triangles, walls and counts."""
    np.testing.assert_array_equal(result.position, reference.position)
    np.testing.assert_array_equal(result.triangle, reference.triangle)
    np.testing.assert_array_equal(result.wall_edge, reference.wall_edge)
    assert (result.rounds, result.unfinished, result.substeps) == \
        (reference.rounds, reference.unfinished, reference.substeps)


def special_points(sim, rng):
    """(triangles, points): random interior points, the triangles' corners (vertices), edge
    midpoints and points on edges, the circumcenters (cell corners)."""
    x, top = sim.walker.x, sim.walker.top
    m = top.shape[0]
    t = rng.integers(0, m, 400)
    lam = rng.dirichlet(np.ones(3), size=t.size)
    inside = np.einsum("pc,pcd->pd", lam, x[top[t]])
    corner = x[top[t, rng.integers(0, 3, t.size)]]
    s = rng.random(t.size)[:, None]
    on_edge = s * x[top[t, 0]] + (1 - s) * x[top[t, 1]]
    middle = 0.5 * (x[top[t, 1]] + x[top[t, 2]])
    circumcenter = sim.cells.points[t]
    return np.tile(t, 5), np.concatenate([inside, corner, on_edge, middle, circumcenter])


@pytest.mark.parametrize("name", ["sphere", "channel", "lattice", "obtuse"])
def test_interpolation_kernel_equals_numpy(name):
    reference, sim = pair(name)
    t, x = special_points(sim, np.random.default_rng(0))
    both = sim._point_velocities()
    expected = reference.interpolator.velocity(t, x, both, reference.face_normal)
    got = sim.interpolator.velocity_compiled(t, x, both, sim.face_normal)
    assert got.shape == expected.shape == (t.size, 3, 2)
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("name", ["sphere", "channel", "lattice", "obtuse"])
def test_least_squares_interpolation_kernel_equals_numpy(name):
    reference, sim = pair(name, velocity="least_squares", circulation="swept_bounded")
    t, x = special_points(sim, np.random.default_rng(0))
    both = sim._point_velocities()
    expected = reference.reconstruction.velocity(t, x, both)
    got = sim.reconstruction.velocity_compiled(t, x, both)
    assert got.shape == expected.shape == (t.size, 3, 2)
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("name", ["sphere", "channel", "obtuse"])
def test_swept_change_kernel_equals_numpy(name):
    reference, sim = pair(name, velocity="least_squares", circulation="swept")
    result, _ = reference.backtrack()
    m = reference.cells.n_circumcenters
    before = reference.cells.points
    after = before.copy()
    after[:m] = result.position
    rng = np.random.default_rng(1)
    value, new_value = rng.normal(size=before.shape[0]), rng.normal(size=before.shape[0])
    expected = reference._swept.change(before, after, value, new_value)
    got = sim._swept.change(before, after, value, new_value, compiled=True)
    assert np.abs(expected).max() > 0
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("name", ["sphere", "channel", "lattice", "obtuse"])
@pytest.mark.parametrize("integrator, max_cfl", [("midpoint", 1.0), ("midpoint", None), ("euler", 0.5),
                                                  ("per_triangle", None)])
def test_backtracking_kernel_equals_numpy(name, integrator, max_cfl):
    reference, sim = pair(name, integrator=integrator, max_cfl=max_cfl)
    expected, v_expected = reference.backtrack()
    result, v = sim.backtrack()
    assert_same_points(expected, result)
    np.testing.assert_array_equal(v, v_expected)
    if name != "sphere":
        assert (result.wall_edge >= 0).sum() > 0  # walls were met and clamped
    if max_cfl is not None and name != "obtuse":
        assert result.substeps > 1


@pytest.mark.parametrize("name", ["channel", "lattice", "obtuse"])
@pytest.mark.parametrize("max_cfl", [1.0, 0.3, None])
def test_the_specialised_planar_least_squares_walk_equals_numpy(name, max_cfl):
    """The default scheme's walk on planar meshes (midpoint, least-squares P1 velocity) runs a
    specialised block (compiled._backtrack_block_planar_p1): the same bits as the numpy twin with
    CFL substeps (max_cfl 0.3: several per point, the later ones from a fresh velocity), walls met
    and clamped."""
    reference, sim = pair(name, velocity="least_squares", circulation="swept_bounded", max_cfl=max_cfl)
    walk, jump = sim.walker.kernel_tables()
    field = sim._kernel_field.kernel_tables()
    assert walk[4] and field[3] and field[4] == 1 and jump[0].shape[0] > 0  # the specialised block's case
    both = sim._point_velocities()
    m = sim.cells.n_circumcenters
    start = sim._circumcenter_velocity(np.ascontiguousarray(both[..., 1:2]))
    expected = reference.walker.backtrack(sim.cells.points[:m], np.arange(m), sim.dt, lambda tri, p: (
        reference.reconstruction.velocity(tri, p, np.ascontiguousarray(both[..., 1:2]))[:, :, 0]),
        start_velocity=start, max_cfl=max_cfl)
    result = sim.walker.backtrack_compiled(sim.cells.points[:m], np.arange(m), sim.dt, sim._kernel_field, both,
                                           start_velocity=start, max_cfl=max_cfl)
    assert_same_points(expected, result)
    np.testing.assert_array_equal(result.velocity, reference.reconstruction.velocity(result.triangle,
                                                                                      result.position, both))
    assert (result.wall_edge >= 0).sum() > 0  # clamped at walls
    if max_cfl == 0.3:
        assert result.substeps > 1


def test_the_specialised_walk_from_vertices_and_edges_equals_numpy():
    """The specialised planar least-squares walk from points exactly on vertices, on edges and at
    circumcenters, aimed exactly at vertices and long enough to cross many triangles and reach
    the walls: the bits of the numpy twin."""
    reference, sim = pair("channel", velocity="least_squares", circulation="swept_bounded")
    rng = np.random.default_rng(7)
    t, x = special_points(sim, rng)
    walker = sim.walker
    target = walker.x[walker.top[t][np.arange(t.size), rng.integers(0, 3, t.size)]]
    direction = target - x
    direction[np.linalg.norm(direction, axis=1) < 1e-12] = (1.0, 0.25, 0.0)
    both = sim._point_velocities()
    full = np.ascontiguousarray(both[..., 1:2])
    for time in (0.01, 0.2):
        args = dict(integrator="midpoint", start_velocity=-direction / 0.05, max_cfl=None)
        expected = reference.walker.backtrack(x, t, time, lambda tri, p: reference.reconstruction.velocity(
            tri, p, full)[:, :, 0], **args)
        result = walker.backtrack_compiled(x, t, time, sim._kernel_field, both, **args)
        assert_same_points(expected, result)
    moved = np.linalg.norm(result.position - x, axis=1) / walker.size[t]
    assert (moved > 5).sum() > 100  # paths beyond the two rings the specialised block locates in
    assert (result.wall_edge >= 0).sum() > 0

@pytest.mark.parametrize("walls", ["no_slip", "slip"])
def test_swept_intervals_kernel_equals_numpy(walls):
    """The default scheme's step c in several intervals (compiled: between intervals the end
    velocity of field 1 only, all fields at the last and at points clamped on the way)."""
    reference, sim = pair("channel", velocity="least_squares", circulation="swept_bounded", walls=walls, dt=0.05)
    expected, v_expected = reference.backtrack()
    result, v = sim.backtrack()
    assert_same_points(expected, result)
    np.testing.assert_array_equal(v, v_expected)
    assert result.substeps >= 3 and (result.wall_edge >= 0).sum() > 0  # several intervals; walls met


@pytest.mark.parametrize("walls", ["no_slip", "slip"])
def test_the_default_walks_its_intervals_point_by_point_with_the_same_bits(walls):
    """On a planar mesh the default scheme walks every point through all its swept intervals in
    one kernel call (compiled.sweep_points) and adds the swept change of all intervals side by
    side (compiled.swept_change_path); one kernel call per interval over all points
    (compiled.backtrack_points and swept_change_add, the path of curved meshes) gives the same end
    points, counts, end velocities and swept change, bit for bit, over steps that clamp points at
    walls."""
    dec, base = case("channel")
    options = {**base, "velocity": "least_squares", "circulation": "swept_bounded", "walls": walls, "dt": 0.05}
    at_once, by_interval = (VorticityFluid(dec, DirectSolver, kernels="numba", **options) for _ in range(2))
    by_interval._sweeps_at_once = lambda *args: False
    assert at_once._sweeps_at_once(*at_once.walker.kernel_tables(), at_once._kernel_field.kernel_tables(), "midpoint")
    for _ in range(3):
        expected, v_expected = by_interval.backtrack()
        result, v = at_once.backtrack()
        assert_same_points(expected, result)
        np.testing.assert_array_equal(v, v_expected)
        np.testing.assert_array_equal(at_once._swept_change, by_interval._swept_change)
        assert result.substeps >= 3 and (result.wall_edge >= 0).sum() > 0  # several intervals; walls met
        assert by_interval.step() == at_once.step()  # every diagnostic, bitwise
    np.testing.assert_array_equal(at_once.vorticity, by_interval.vorticity)


@pytest.mark.parametrize("name", ["channel", "lattice"])
def test_walking_kernel_equals_numpy_without_the_planar_jump(name):
    """Planar meshes jump; with the jump switched off both walk triangle by triangle."""
    reference, sim = pair(name, max_cfl=None, integrator="euler")
    reference.walker._locator = sim.walker._locator = None
    expected, _ = reference.backtrack()
    result, _ = sim.backtrack()
    assert expected.rounds > 3
    assert_same_points(expected, result)


def test_walks_through_vertices_and_from_edges_equal_numpy():
    """Degenerate-near starts: points exactly on vertices and edges, directions aimed exactly
    at a vertex (the walk leaves through a corner), long enough to cross many triangles."""
    reference, sim = pair("sphere")
    rng = np.random.default_rng(5)
    t, x = special_points(sim, rng)
    walker = sim.walker
    top = walker.top[t]
    target = walker.x[top[np.arange(t.size), rng.integers(0, 3, t.size)]]
    direction = walker.to_plane(target - x, t)
    direction[np.linalg.norm(direction, axis=1) < 1e-12] = walker.to_plane(rng.normal(size=(1, 3)), t[:1])
    both = sim._point_velocities()
    for integrator in ("euler", "midpoint"):
        args = dict(integrator=integrator, start_velocity=-direction, max_cfl=None)
        expected = reference.walker.backtrack(x, t, 3.0, lambda tri, p: reference.interpolator.velocity(
            tri, p, np.ascontiguousarray(both[..., 1:2]), reference.face_normal)[:, :, 0], **args)
        result = walker.backtrack_compiled(x, t, 3.0, sim.interpolator, both, **args)
        assert expected.rounds > 5
        assert_same_points(expected, result)


@pytest.mark.parametrize("name", ["sphere", "channel", "obtuse"])
def test_circulation_kernel_equals_numpy(name):
    reference, sim = pair(name)
    result, velocity = reference.backtrack()
    clamped = result.wall_edge >= 0
    expected, border = reference.circulation(result.position, velocity, clamped)
    got, got_border = sim.circulation(result.position, velocity, clamped)
    np.testing.assert_array_equal(got_border, border)
    np.testing.assert_array_equal(got, expected)
    # some cells only (the swept rules' border cells): their Γ with the same bits, 0 elsewhere
    cells = border | (np.arange(border.size) % 3 == 0)
    every = reference.trapezoid_circulation(result.position, velocity)
    np.testing.assert_array_equal(np.where(border, every[:, 1], every[:, 0]), expected)
    for fluid in (reference, sim):
        some = fluid.trapezoid_circulation(result.position, velocity, cells=cells)
        np.testing.assert_array_equal(some[cells], every[cells])
        assert not some[~cells].any()


@pytest.mark.parametrize("name, steps, scheme", [
    ("sphere", 20, {}), ("channel", 20, {}), ("lattice", 10, {}),
    ("channel", 10, dict(circulation="swept")),  # the compiled walk in the swept intervals
    ("channel", 10, dict(velocity="least_squares", circulation="swept")),  # the least-squares walk
    ("sphere", 10, dict(velocity="least_squares", circulation="swept_bounded")),  # the default scheme
    ("channel", 10, dict(velocity="least_squares", circulation="swept_bounded")),
    # slip walls: points clamped in an early swept interval keep that interval's end velocities
    ("channel", 10, dict(velocity="least_squares", circulation="swept_bounded", walls="slip")),
])
def test_a_whole_run_with_numba_kernels_equals_the_numpy_run(name, steps, scheme):
    reference, sim = pair(name, dt=case(name)[1]["dt"] / 2, **scheme)
    assert sim.compiled_walk and not reference.compiled_walk
    for _ in range(steps):
        expected, got = reference.step(), sim.step()
        assert got == expected  # every diagnostic, bitwise
    assert got["stable"] and got["clamped_points"] > 0 or name == "sphere"
    np.testing.assert_array_equal(sim.vorticity, reference.vorticity)
    np.testing.assert_array_equal(sim.psi, reference.psi)


def test_unknown_kernels_are_refused():
    from decrun.errors import ConfigError

    dec, options = case("lattice")
    with pytest.raises(ConfigError, match=r"^kernels: must be one of auto \| numba \| numpy, got 'fortran'"):
        VorticityFluid(dec, DirectSolver, kernels="fortran", **options)


def test_numba_is_imported_only_when_a_fluid_runs():
    """Composing configs and importing the fluid's modules stays numba-free (decrun --help fast)."""
    code = ("import sys, decrun.apps.fluid, decrun.methods.fluid.simulation, decrun.runner.command.task; "
            "print('numba' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@pytest.mark.parametrize("name, scheme", [
    ("sphere", dict(velocity="least_squares", circulation="swept_bounded")),  # the default scheme
    ("channel", dict(velocity="least_squares", circulation="swept_bounded")),  # swept intervals, walls, inflow
    ("channel", {}),  # the thesis' scheme: one plain walk
])
def test_parallel_kernels_give_the_same_bits_on_one_thread_and_on_all(name, scheme):
    """The kernels split their points, sides and cells into one block per thread (``prange``);
    every item is computed as in the serial loop, so the run does not depend on the thread count
    (one thread against numba's all, the machine's cores: 2 on CI)."""
    import numba

    dec, base = case(name)
    sims = [VorticityFluid(dec, DirectSolver, kernels="numba", **{**base, **COMPILED_SCHEME, **scheme})
            for _ in range(2)]
    before = numba.get_num_threads()
    try:
        for _ in range(6):
            got = []
            for sim, threads in zip(sims, (1, numba.config.NUMBA_NUM_THREADS), strict=True):
                numba.set_num_threads(threads)
                got.append(sim.step())
            assert got[0] == got[1]  # every diagnostic, bitwise
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(sims[0].vorticity, sims[1].vorticity)
    assert got[0]["stable"]
    assert got[0]["backtrack_rounds"] > 0 if name == "sphere" else got[0]["clamped_points"] > 0  # walked; walls met


def test_a_step_runs_one_blas_thread_and_restores_the_setting():
    """numpy's BLAS threads its inner products of mesh vectors, and its spinning threads took the
    cores from the parallel kernels (decrun.core.threads): inside a step every BLAS runs one
    thread; after it the process's own setting is back."""
    from threadpoolctl import threadpool_info, threadpool_limits

    dec, base = case("sphere")
    sim = VorticityFluid(dec, DirectSolver, kernels="numba", **base)
    inside = []
    kinetic_energy = sim.kinetic_energy

    def spy():
        inside.append([lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"])
        return kinetic_energy()

    sim.kinetic_energy = spy
    with threadpool_limits(limits=2, user_api="blas"):
        sim.step()
        after = [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]
    assert inside and all(threads == [1] * len(threads) for threads in inside) and inside[0]
    assert after == [2] * len(after)

