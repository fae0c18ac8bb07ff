"""The vorticity fluid of thesis ch. 7: checks with known answers (FLUIDS.md "Checks")."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from decrun.complex import SimplicialComplex  # noqa: E402
from decrun.core.channel_mesh import channel_mesh  # noqa: E402
from decrun.core.solvers.direct import DirectSolver  # noqa: E402
from decrun.dec import DEC  # noqa: E402
from decrun.methods.fluid.dual_cells import build_dual_cells, vertex_normals  # noqa: E402
from decrun.methods.fluid.harmonic import border_layout, harmonic_flux, harmonic_flux_least_squares, uniform_flux  # noqa: E402
from decrun.methods.fluid.initial import random_vorticity, solid_body_rotation, sphere_vortex_pair, stroke_force  # noqa: E402
from decrun.methods.fluid.interpolation import CellInterpolator, triangle_velocity_matrix, wachspress_weights  # noqa: E402
from decrun.methods.fluid.simulation import VorticityFluid  # noqa: E402

from meshes_for_tests import icosphere, jittered_lattice  # noqa: E402


def new_solver():
    return DirectSolver()


@lru_cache(maxsize=None)
def sphere(subdiv: int) -> DEC:
    v, f = icosphere(subdiv)
    return DEC(SimplicialComplex(v, f))


@lru_cache(maxsize=None)
def channel(target: int = 1400, obstacle: bool = True):
    mesh = channel_mesh(target_faces=target, obstacles=None if obstacle else [])
    return mesh, DEC(SimplicialComplex(mesh.vertices, mesh.faces))


def lattice(nx: int = 12, ny: int = 10, jitter: float = 0.04, seed: int = 0) -> DEC:
    """A parallelogram of equilateral triangles, interior vertices jittered (no obtuse angle)."""
    return DEC(SimplicialComplex(*jittered_lattice(nx, ny, jitter, seed)))


def relative(a, b, weight):
    return float(np.sqrt(weight @ (a - b) ** 2 / (weight @ b**2)))


# ---------------------------------------------------------------- interpolation (§7.2.3)
def test_wachspress_weights_reproduce_linear_fields_on_random_convex_polygons():
    rng = np.random.default_rng(3)
    corners, inside = [], []
    for _ in range(50):
        hull = ConvexHull(rng.random((12, 2)))
        poly = hull.points[hull.vertices]  # counter-clockwise
        poly = np.concatenate([poly, np.repeat(poly[:1], 12 - len(poly), axis=0)])  # padded
        corners.append(poly)
        inside.append(len(hull.vertices))
    corners = np.array(corners)
    count = np.array(inside)
    valid = np.arange(12)[None, :] < count[:, None]
    lam = rng.dirichlet(np.ones(12), size=50) * valid
    lam /= lam.sum(1, keepdims=True)
    x = np.einsum("pk,pkd->pd", lam, corners)  # interior points
    w = wachspress_weights(x, corners, valid)
    assert np.all(w >= 0) and np.all(w[~valid] == 0)
    np.testing.assert_allclose(w.sum(1), 1.0, atol=1e-14)
    np.testing.assert_allclose(np.einsum("pk,pkd->pd", w, corners), x, atol=1e-13)
    A, b = np.array([[2.0, -1.0], [0.5, 3.0]]), np.array([1.0, -2.0])  # any linear field
    np.testing.assert_allclose(np.einsum("pk,pkd->pd", w, corners @ A.T + b), x @ A.T + b, atol=1e-12)
    # Lagrange property at the corners, and linear along the edges
    at_corner = wachspress_weights(corners[:, 1], corners, valid)
    np.testing.assert_allclose(at_corner[:, 1], 1.0, atol=1e-10)
    mid = 0.3 * corners[:, 0] + 0.7 * corners[:, 1]
    on_edge = wachspress_weights(mid, corners, valid)
    np.testing.assert_allclose(on_edge[:, 0], 0.3, atol=1e-10)
    np.testing.assert_allclose(on_edge[:, 1], 0.7, atol=1e-10)


def test_dual_cell_interpolation_reproduces_linear_fields_on_a_non_obtuse_planar_mesh():
    dec = lattice()
    cells = build_dual_cells(dec)
    interp = CellInterpolator(cells, dec.K.simplices(2), dec.K.vertices)
    assert interp.convex.all()
    x = np.pad(dec.K.vertices, ((0, 0), (0, 1)))
    lam = np.random.default_rng(1).dirichlet([1, 1, 1], size=dec.K.num_simplices(2))
    points = np.einsum("mc,mcd->md", lam, x[dec.K.simplices(2)])
    A = np.array([[1.5, -0.5, 0.0], [2.0, 0.25, 0.0], [0.0, 0.0, 0.0]])
    field = cells.points @ A.T + np.array([0.3, -1.0, 0.0])  # a linear field at the dual points
    u = interp.velocity(np.arange(points.shape[0]), points, field[:, :, None], cells.face_normal)[:, :, 0]
    np.testing.assert_allclose(u, points @ A.T + np.array([0.3, -1.0, 0.0]), atol=1e-12)


def test_dual_cells_tile_the_plane_and_close_border_cells():
    dec = lattice()
    cells = build_dual_cells(dec)
    p = cells.points[cells.corners]
    area = 0.5 * np.einsum("nkd,nd->n", np.cross(p, np.roll(p, -1, axis=1)), cells.vertex_normal)
    np.testing.assert_allclose(area, dec.star_diagonal(0), rtol=1e-12)  # CCW polygons of area ⋆0
    border = cells.border_vertex
    assert np.array_equal(border, dec.K.border_vertices())
    valence = np.bincount(dec.K.simplices(2).ravel())
    np.testing.assert_array_equal(cells.count, np.where(border, valence + 3, valence))


def test_vertex_normals_are_radial_on_the_sphere_and_vertical_in_the_plane():
    dec = sphere(3)
    x = dec.K.vertices
    assert np.abs(np.einsum("nd,nd->n", vertex_normals(dec), x / np.linalg.norm(x, axis=1)[:, None]) - 1).max() < 1e-3
    np.testing.assert_allclose(np.abs(vertex_normals(lattice())[:, 2]), 1.0)


def test_triangle_velocity_has_the_edge_fluxes():
    for dec in (sphere(2), lattice()):
        cells = build_dual_cells(dec)
        psi = np.random.default_rng(0).standard_normal(dec.K.num_simplices(0))
        u = dec.d(0) @ psi
        v = (triangle_velocity_matrix(dec, cells.face_normal) @ u).reshape(-1, 3)
        x = np.pad(dec.K.vertices, ((0, 0), (0, 3 - dec.K.vertices.shape[1])))
        edges = dec.K.simplices(1)[dec.K.facet_indices(2)]  # (m, 3, 2)
        t = x[edges[..., 1]] - x[edges[..., 0]]
        flux = np.einsum("md,med->me", v, np.cross(t, cells.face_normal[:, None, :]))
        np.testing.assert_allclose(flux, u[dec.K.facet_indices(2)], atol=1e-12 * np.abs(u).max())


# ---------------------------------------------------------------- harmonic part (§7.2.5)
def test_harmonic_part_is_the_uniform_inflow_without_obstacles():
    _, dec = channel(1400, obstacle=False)
    normal = build_dual_cells(dec).face_normal
    _, label = border_layout(dec)
    v = (10.0, 0.0)
    c = harmonic_flux(dec, normal, label, v, new_solver)
    exact = uniform_flux(dec, normal, v)
    assert np.abs(c - exact).max() <= 1e-12 * np.abs(exact).max()
    c_ls, report = harmonic_flux_least_squares(dec, label, np.where(label[dec.K.simplices(1)].min(1) >= 0, exact, 0),
                                               new_solver)
    assert report["relative_residual"] < 1e-10
    assert np.abs(c_ls - exact).max() <= 1e-8 * np.abs(exact).max()


def test_harmonic_part_around_an_obstacle_has_no_flux_no_circulation_and_matches_eq_7_11():
    mesh, dec = channel(1400)
    normal = build_dual_cells(dec).face_normal
    obstacles, label = border_layout(dec, mesh.obstacle_loops)
    c = harmonic_flux(dec, normal, label, (10.0, 0.0), new_solver)
    edges = dec.K.simplices(1)
    scale = np.abs(c).max()
    on_obstacle = (label[edges] > 0).all(1)
    assert np.abs(c[on_obstacle]).max() <= 1e-12 * scale  # no flux through the obstacle
    assert np.abs(dec.d(1) @ c).max() <= 1e-12 * scale  # divergence free
    vorticity = dec.d(0).T @ (dec.star_diagonal(1) * c)  # d0ᵀ ⋆1 c: circulation around dual cells
    total = np.abs(vorticity).sum()
    assert np.abs(vorticity[label < 0]).max() <= 1e-10 * total  # harmonic inside
    assert abs(vorticity[obstacles[0]].sum()) <= 1e-10 * total  # zero period around the obstacle
    border_flux = np.where((label[edges] == 0).all(1), uniform_flux(dec, normal, (10.0, 0.0)), 0.0)
    c_ls, report = harmonic_flux_least_squares(dec, label, border_flux, new_solver)
    assert report["relative_residual"] < 1e-10
    assert np.abs(c_ls - c).max() <= 1e-7 * scale


# ---------------------------------------------------------------- the step
@pytest.mark.parametrize("integrator, max_cfl, circulation", [
    ("midpoint", 1.0, "corrected_trapezoid"), ("midpoint", None, "corrected_trapezoid"),
    ("midpoint", 0.2, "corrected_trapezoid"), ("euler", None, "corrected_trapezoid"),
    ("per_triangle", None, "corrected_trapezoid"), ("midpoint", 1.0, "swept"), ("euler", None, "swept")])
def test_backtracking_in_a_uniform_flow_moves_by_minus_v_dt(integrator, max_cfl, circulation):
    _, dec = channel(1400, obstacle=False)
    v = np.array([10.0, 3.0, 0.0])
    sim = VorticityFluid(dec, new_solver, dt=0.004, viscosity=0.0, inflow_velocity=v[:2], integrator=integrator,
                         max_cfl=max_cfl, circulation=circulation,
                         velocity="least_squares" if circulation == "swept" else "wshd07")
    result, velocity = sim.backtrack()
    h = sim.walker.size
    cfl = np.linalg.norm(v) * sim.dt / h.min()
    if circulation == "swept":  # k equal intervals of at most swept_cfl edge lengths, each point-substepped
        intervals = int(np.ceil((np.linalg.norm(v) * sim.dt / h).max() / sim.swept_cfl))
        per_interval = 1 if max_cfl is None else max(1, int(np.ceil(cfl / intervals / max_cfl)))
        assert result.substeps == intervals * per_interval
    else:
        assert result.substeps == (1 if max_cfl is None else max(1, int(np.ceil(cfl / max_cfl))))
    start = sim.cells.points[: sim.cells.n_circumcenters]
    expected = start - v * sim.dt
    inside = (expected[:, 0] > 1e-9) & (expected[:, 1] > 1e-9) & (expected[:, 1] < 1 - 1e-9)
    assert inside.sum() > 0.9 * inside.size
    np.testing.assert_allclose(result.position[inside], expected[inside], atol=1e-12)
    assert np.all(result.wall_edge[inside] == -1) and np.all(result.wall_edge[~inside] >= 0)
    np.testing.assert_allclose(velocity[:, :, 1], np.broadcast_to(v, velocity[:, :, 1].shape), atol=1e-10)
    d = sim.step()  # a uniform flow stays uniform
    assert np.abs(sim.flux - sim.harmonic).max() < 1e-6 * np.abs(sim.harmonic).max()
    assert d["relative_divergence"] <= 1e-12


def test_planar_jumps_agree_with_walking_across_triangles():
    """On planar meshes straight paths jump (located in a grid, stopped at the first border
    crossing); walking triangle by triangle must give the same end points, triangles, walls."""
    mesh, dec = channel(1400)
    sim = VorticityFluid(dec, new_solver, dt=0.02, viscosity=0.0, inflow_velocity=(10.0, 0.0),
                         obstacle_loops=mesh.obstacle_loops, initial_vorticity=random_vorticity(dec, 1, amplitude=50))
    m = sim.cells.n_circumcenters
    start = sim.cells.points[:m]
    direction = -sim.triangle_velocities()
    jumped = sim.walker.walk(start, np.arange(m), direction, sim.dt)
    sim.walker._locator = None  # force the walk
    walked = sim.walker.walk(start, np.arange(m), direction, sim.dt)
    assert (walked[2] >= 0).sum() > 20 and walked[4] > 3  # many wall hits, several rounds
    np.testing.assert_array_equal(jumped[2], walked[2])
    np.testing.assert_allclose(jumped[0], walked[0], atol=1e-12)
    same = jumped[1] == walked[1]  # a point exactly on an edge may be given either triangle
    lam = sim.walker.barycentric(jumped[1][~same], jumped[0][~same])
    assert np.all(lam > -1e-9)


def test_velocity_stays_divergence_free_every_step():
    mesh, dec = channel(1400)
    sim = VorticityFluid(dec, new_solver, dt=0.005, viscosity=0.02, inflow_velocity=(10.0, 0.0),
                         obstacle_loops=mesh.obstacle_loops)
    assert sim.obtuse_triangles == 0 and sim.nonconvex_cells == 0
    for _ in range(10):
        d = sim.step()
        assert np.abs(dec.d(1) @ sim.flux).max() <= 1e-12 * np.abs(sim.flux).max()
        assert d["relative_divergence"] <= 1e-12 and d["stable"]
    dec = sphere(3)
    sim = VorticityFluid(dec, new_solver, dt=0.05, viscosity=0.0, initial_vorticity=random_vorticity(dec, 2, amplitude=5))
    for _ in range(5):
        assert sim.step()["relative_divergence"] <= 1e-12


def _one_step_drift(subdiv: int, w0_of) -> float:
    dec = sphere(subdiv)
    sim = VorticityFluid(dec, new_solver, dt=0.01, viscosity=0.0, initial_vorticity=w0_of(dec))
    w0 = sim.vorticity.copy()
    sim.step()
    return relative(sim.vorticity, w0, sim.star0)


def test_rigid_rotation_on_the_unit_sphere_stays_steady():
    """ν = 0: rigid rotation (w = 2z, ψ = z) is steady; its per-step drift shrinks with h."""
    coarse, fine = _one_step_drift(3, solid_body_rotation), _one_step_drift(5, solid_body_rotation)
    assert coarse < 2.5e-3 and fine < 0.7 * coarse
    dec = sphere(4)
    sim = VorticityFluid(dec, new_solver, dt=0.01, viscosity=0.0, initial_vorticity=solid_body_rotation(dec))
    np.testing.assert_allclose(sim.psi - sim.psi.mean(), dec.K.vertices[:, 2], atol=2e-3)  # ψ = z


def test_steady_strain_drift_shrinks_under_refinement_with_the_default_scheme():
    """Issue 18: the degree-2 state w = 6xz (sphere) and the cellular flow (square lattice) are
    steady at ν = 0. With the default (least-squares velocity, swept circulation) the drift
    halves per refinement; the thesis' WSHD07 + trapezoid rules grow instead (0.50 → 0.60 /s
    on the sphere, benchmarks/bench_fluid_drift.py has the table)."""
    from fluid_cases import drift_per_s, steady_case

    for case, (coarse, fine) in (("degree_2", (2, 3)), ("cellular_regular", (8, 16))):
        d0, d1 = (drift_per_s(*steady_case(case, level)) for level in (coarse, fine))
        assert d1 < 0.6 * d0, (case, d0, d1)
        t0, t1 = (drift_per_s(*steady_case(case, level), scheme="corrected") for level in (coarse, fine))
        assert t0 > 10 * d0  # the former default (WSHD07, corrected trapezoid) is far larger
        if case == "degree_2":
            assert t1 > t0  # and grows with refinement on the sphere (0.50 → 0.60 /s)


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_viscous_decay_of_a_spherical_harmonic(degree):
    dec = sphere(4)
    x, y, z = dec.K.vertices.T
    mode = {1: z, 2: x * z, 3: x * (x**2 - 3 * y**2)}[degree]
    nu, dt = 0.5, 0.1 / (degree * (degree + 1))  # ν dt λ_l = 0.05 ... so the factor is 1 / 1.05
    sim = VorticityFluid(dec, new_solver, dt=dt, viscosity=nu, initial_vorticity=mode)
    w0 = sim.vorticity.copy()
    for _ in range(3):
        before = sim.vorticity.copy()
        sim.step()
        factor = (sim.star0 @ (sim.vorticity * before)) / (sim.star0 @ before**2)
        expected = 1.0 / (1.0 + nu * dt * degree * (degree + 1))
        assert abs(factor - expected) < 2e-3 * expected
    assert relative(sim.vorticity / (sim.star0 @ (sim.vorticity * w0) / (sim.star0 @ w0**2)), w0, sim.star0) < 1e-2


@pytest.mark.parametrize("velocity, circulation", [("least_squares", "swept_bounded"), ("least_squares", "swept"),
                                                     ("wshd07", "trapezoid")])
def test_total_circulation_vanishes_and_enstrophy_decays_on_closed_surfaces(velocity, circulation):
    """Σ⋆0 w = 0 every step; without forces the enstrophy never increases, nor does the energy
    with viscosity or with the default (swept_bounded). At ν = 0 the unbounded swept rule's energy
    may rise (measured: ≤ 5.8e-4 per step, +4 % over 100 steps at dt = 0.05 on 1.3k faces, a rate
    ∝ dt), the thesis' plain trapezoid only loses energy (and much of it: numerical diffusion)."""
    dec = sphere(3)
    w0 = random_vorticity(dec, seed=4, amplitude=5.0)
    for nu in (0.0, 0.01):
        sim = VorticityFluid(dec, new_solver, dt=0.05, viscosity=nu, initial_vorticity=w0, velocity=velocity,
                             circulation=circulation)
        energy, enstrophy = sim.kinetic_energy(), sim.diagnostics()["enstrophy"]
        rise = 1e-3 if nu == 0 and circulation == "swept" else 1e-12
        for _ in range(15):
            d = sim.step()
            assert abs(d["total_circulation"]) <= 1e-12 * (sim.star0 @ np.abs(sim.vorticity))
            assert d["kinetic_energy"] <= energy * (1 + rise)
            assert d["enstrophy"] <= enstrophy * (1 + 1e-12)
            energy, enstrophy = d["kinetic_energy"], d["enstrophy"]
        assert enstrophy < 0.99 * 0.5 * (sim.star0 @ (w0 - (sim.star0 @ w0) / sim.star0.sum()) ** 2)  # it decays


def _energy_enstrophy_series(sim, steps):
    energy, enstrophy = [sim.kinetic_energy()], [sim.diagnostics()["enstrophy"]]
    for _ in range(steps):
        d = sim.step()
        assert d["finite"]
        energy.append(d["kinetic_energy"])
        enstrophy.append(d["enstrophy"])
    return np.array(energy), np.array(enstrophy)


def test_the_default_scheme_never_raises_energy_or_enstrophy_at_zero_viscosity():
    """Issue 25: at ν = 0 without forces the default (circulation=swept_bounded) keeps energy and
    enstrophy non-increasing to round-off every step (measured: largest relative rise 2.6e-15 over
    1000 steps on 1280 faces, benchmarks/bench_fluid_stability.py) on closed surfaces and conserves
    Σ⋆0 w; the unbounded swept rule (issue 18's default,
    still app.circulation=swept) raises the energy in nearly every step (1.1e-4 per step here)."""
    dec = sphere(3)
    w0 = random_vorticity(dec, seed=4, amplitude=5.0)
    sim = VorticityFluid(dec, new_solver, dt=0.05, viscosity=0.0, initial_vorticity=w0)
    energy, enstrophy = _energy_enstrophy_series(sim, 40)
    assert np.all(np.diff(energy) <= 1e-12 * energy[:-1]) and np.all(np.diff(enstrophy) <= 1e-12 * enstrophy[:-1])
    assert abs(sim.star0 @ sim.vorticity) <= 1e-12 * (sim.star0 @ np.abs(w0))
    assert energy[-1] > 0.95 * energy[0]  # bounded, not damped away
    old = VorticityFluid(dec, new_solver, dt=0.05, viscosity=0.0, initial_vorticity=w0, circulation="swept")
    old_energy, _ = _energy_enstrophy_series(old, 40)
    assert (np.diff(old_energy) > 1e-12 * old_energy[:-1]).sum() > 30


@pytest.mark.parametrize("case", ["rigid_rotation", "degree_2"])
def test_the_energy_enstrophy_bound_is_inactive_on_exact_steady_states(case):
    """The bound of swept_bounded acts only where the swept update would raise energy or
    enstrophy: on the exact steady states of the drift table it never acts (20 steps), so the
    default's drift is the swept rule's to the last bit (still O(h): the drift tests)."""
    from fluid_cases import steady_case

    dec, w0, _ = steady_case(case, 3)
    runs = {}
    for circulation in ("swept", "swept_bounded"):
        sim = VorticityFluid(dec, new_solver, dt=0.01, viscosity=0.0, initial_vorticity=w0, circulation=circulation)
        actions = [sim.step().get("bound_action", 0) for _ in range(20)]
        runs[circulation] = sim.vorticity
    assert actions == [0] * 20
    np.testing.assert_array_equal(runs["swept_bounded"], runs["swept"])
    assert relative(runs["swept"], w0, sim.star0) > 1e-4  # the states do move (O(h) drift): not a no-op


def test_the_bound_damps_grid_scale_growth_by_smoothing_and_large_scale_energy_along_psi():
    """limiter.EnergyEnstrophyBound on a random sphere state. A w* within both bounds comes back
    unchanged. Grid-scale noise (enstrophy up) is blended towards the smoothed field; a uniform
    growth 1.2 w (energy up too) also gets the energy fix along ψ̄. Both come back with enstrophy
    and energy at most the previous state's (to round-off), their Σ⋆0 w, and the ψ returned is the
    stream function of the w returned; the final rescale (a round-off guard) is not needed."""
    from decrun.methods.fluid.limiter import EnergyEnstrophyBound

    dec = sphere(3)
    sim = VorticityFluid(dec, new_solver, dt=0.05, viscosity=0.0, initial_vorticity=random_vorticity(dec, seed=2))
    bound = sim._bound
    assert isinstance(bound, EnergyEnstrophyBound)
    w, psi = sim.vorticity, sim.psi
    same, _, action = bound.apply(w, psi, 0.9 * w)
    assert action == 0 and np.array_equal(same, 0.9 * w)
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(w.size)
    noise -= (sim.star0 @ noise) / sim.star0.sum()
    for grown, flags in ((w + 0.3 * np.abs(w).max() * noise, 1), (1.2 * w, 2)):
        new, new_psi, action = bound.apply(w, psi, grown)
        assert action & flags and not action & 4, action
        assert bound.enstrophy(new) <= bound.enstrophy(w) and bound.energy(new_psi) <= bound.energy(psi)
        assert bound.enstrophy(new) > 0.9 * bound.enstrophy(w)  # bounded, not damped away
        np.testing.assert_allclose(new_psi, sim._recover(new), atol=1e-10 * np.abs(new_psi).max())
        assert abs(sim.star0 @ new) <= 1e-12 * (sim.star0 @ np.abs(new))


def test_the_conservative_clamp_keeps_the_mass_and_the_range():
    """limiter.conservative_clamp: active values leave [lo, hi] nowhere, Σ⋆0 w is unchanged,
    inactive values are untouched."""
    from decrun.methods.fluid.limiter import conservative_clamp

    rng = np.random.default_rng(3)
    n = 200
    star0 = rng.uniform(0.5, 2.0, n)
    lo, hi = -np.ones(n), np.ones(n)
    w = rng.uniform(-1.2, 1.5, n)
    active = rng.random(n) < 0.8
    out = conservative_clamp(w, lo, hi, star0, active)
    assert abs(star0 @ out - star0 @ w) <= 1e-12 * (star0 @ np.abs(w))
    assert np.all(out[active] >= -1 - 1e-12) and np.all(out[active] <= 1 + 1e-12)
    assert np.array_equal(out[~active], w[~active])
    assert not np.array_equal(out, w)


def test_the_curvature_corrected_trapezoid_can_raise_the_enstrophy_of_a_rigid_rotation():
    """The README's caveat: with ``circulation="corrected_trapezoid"`` (decrun's former default)
    a rigid rotation at ν = 0 gains enstrophy in some steps (the correction Γ − Γ⁰ is not a
    contraction); measured on 1.3k faces, dt = 0.01: up in 47 of 100 steps, by ≤ 9.3e-6 each."""
    dec = sphere(3)
    sim = VorticityFluid(dec, new_solver, dt=0.01, viscosity=0.0, initial_vorticity=solid_body_rotation(dec),
                         velocity="wshd07", circulation="corrected_trapezoid")
    enstrophy = [sim.diagnostics()["enstrophy"]]
    for _ in range(40):
        enstrophy.append(sim.step()["enstrophy"])
    rise = np.diff(enstrophy) / np.array(enstrophy[:-1])
    assert (rise > 0).sum() >= 5 and rise.max() < 2e-5


@pytest.mark.parametrize("degrees", [60, 90])
def test_counter_rotating_vortex_pair_on_the_sphere_drifts_at_the_analytic_rate(degrees):
    """±Γ at angular distance θ move at Γ/(4π)·cot(θ/2), +Γ at +y moving towards −z.
    5k-face sphere, blobs of radius 0.12: measured 0.949 × the analytic rate at θ = 60°,
    0.975 × at 90° with this estimator (the centroid of the positive vorticity); the centroid of
    the core (w > half its maximum) gives 0.892 ×, 0.857 × (benchmarks/bench_fluid_claims.py).
    Before issue 25, WSHD07 + corrected trapezoid: 1.053 ×, 1.121 ×."""
    dec = sphere(4)
    theta, gamma = np.radians(degrees), 4.0
    w0, _ = sphere_vortex_pair(dec, theta, gamma, radius=0.12)
    sim = VorticityFluid(dec, new_solver, dt=0.02, viscosity=0.0, initial_vorticity=w0)
    x = dec.K.vertices
    times, latitude = [], []
    for _ in range(20):
        positive = np.clip(sim.vorticity, 0, None) * sim.star0
        center = positive @ x / positive.sum()
        times.append(sim.time)
        latitude.append(np.arcsin(center[2] / np.linalg.norm(center)))
        sim.step()
    speed = np.polyfit(times, latitude, 1)[0]
    expected = gamma / (4 * np.pi) / np.tan(theta / 2)
    assert speed < 0
    assert abs(-speed / expected - 1) < 0.1


def test_an_obstacle_in_the_channel_sheds_an_antisymmetric_wake():
    mesh, dec = channel(1400)
    sim = VorticityFluid(dec, new_solver, dt=0.005, viscosity=0.02, inflow_velocity=(10.0, 0.0),
                         obstacle_loops=mesh.obstacle_loops)
    for _ in range(30):
        d = sim.step()
    assert d["stable"]
    x, y = dec.K.vertices.T
    interior = ~dec.K.border_vertices()
    wake = interior & (x > 0.65) & (x < 1.5)
    above, below = wake & (y > 0.52), wake & (y < 0.48)
    w = sim.vorticity * sim.star0
    # flow left to right: ∂u/∂y > 0 above the obstacle (ω < 0), < 0 below (ω > 0)
    assert w[above].sum() < 0 < w[below].sum()
    # a centred obstacle: an antisymmetric wake (measured 0.5 %; WSHD07 + corrected trapezoid 14 %)
    assert abs(w[above].sum() + w[below].sum()) < 0.03 * (abs(w[above].sum()) + abs(w[below].sum()))
    assert sim.vorticity[wake].min() < -10 and sim.vorticity[wake].max() > 10


def test_stroke_force_spins_the_fluid_with_the_curl_of_the_force():
    dec = lattice(16, 14, jitter=0.0)
    stroke = np.array([[3.0, 5.5], [11.0, 5.5]])  # a push along +x
    f = stroke_force(dec, stroke, strength=2.0)
    curl = (dec.d(0).T @ (dec.star_diagonal(1) * f)) / dec.star_diagonal(0)
    x, y = dec.K.vertices.T
    mid = (x > 5) & (x < 9)
    assert curl[mid & (y > 5.5) & (y < 7)].sum() > 0 > curl[mid & (y < 5.5) & (y > 4)].sum()  # curl F = −∂Fx/∂y
    dec = sphere(3)
    f = stroke_force(dec, [[1, 0, 0.2], [0, 1, 0.2], [-1, 0, 0.2]], strength=1.0)
    sim = VorticityFluid(dec, new_solver, dt=0.05, viscosity=0.01)
    d = sim.step(force_flux=f)
    assert d["kinetic_energy"] > 0 and abs(d["total_circulation"]) < 1e-12 * (sim.star0 @ np.abs(sim.vorticity))


def test_blow_up_is_reported_not_raised():
    dec = sphere(2)
    sim = VorticityFluid(dec, new_solver, dt=0.05, viscosity=0.0, initial_vorticity=solid_body_rotation(dec),
                         blowup_factor=10.0)
    assert sim.step()["stable"]
    sim.flux = 10.0 * sim.flux  # energy × 100 without a force: must be flagged
    sim.psi = 10.0 * sim.psi
    assert not sim.diagnostics()["stable"] and sim.diagnostics()["finite"]
    bad = np.zeros(dec.K.num_simplices(1))
    bad[0] = np.inf
    d = sim.step(force_flux=bad)
    assert not d["finite"] and not d["stable"] and d["diverged_at_step"] == 2
    assert sim.step()["diverged_at_step"] == 2  # later steps do nothing and say so


def test_a_force_from_rest_gives_the_flow_along_the_force():
    """From rest, one step with force flux f (ν = 0, nothing to backtrack) is
    w = dt ⋆0⁻¹ d0ᵀ ⋆1 f; for f = d0 z (the flux of rigid rotation about z) the recovered
    flux is exactly dt f: the fluid moves along the force, not against it."""
    dec = sphere(2)
    f = dec.d(0) @ dec.K.vertices[:, 2]
    sim = VorticityFluid(dec, new_solver, dt=0.05, viscosity=0.0)
    sim.step(force_flux=f)
    np.testing.assert_allclose(sim.flux, sim.dt * f, atol=1e-12 * np.abs(f).max())
    expected = sim.dt * (dec.d(0).T @ (sim.star1 * f)) / sim.star0
    np.testing.assert_allclose(sim.vorticity, expected, atol=1e-12 * np.abs(expected).max())
    assert sim.flux @ (sim.star1 * f) > 0


def test_the_mean_vorticity_is_removed_on_closed_surfaces():
    """Σ ⋆0 w = 0 on a closed surface (the Poisson problem is solvable only then): an initial
    vorticity with a non-zero mean (w = 1 + 6xz) loses its mean, and steps keep Σ ⋆0 w = 0."""
    dec = sphere(2)
    x, _, z = dec.K.vertices.T
    w0 = 1.0 + 6.0 * x * z
    sim = VorticityFluid(dec, new_solver, dt=0.02, viscosity=0.01, initial_vorticity=w0)
    scale = sim.star0 @ np.abs(w0)
    assert abs(sim.star0 @ sim.vorticity) <= 1e-12 * scale
    np.testing.assert_allclose(sim.vorticity, w0 - (sim.star0 @ w0) / sim.star0.sum(), atol=1e-12)
    for _ in range(3):
        sim.step()
        assert abs(sim.star0 @ sim.vorticity) <= 1e-12 * scale


@pytest.mark.slow
def test_the_drift_table_of_the_default_scheme_converges():
    """benchmarks/bench_fluid_drift.py's rows for the default scheme (dt = 0.001, 1/s): every
    refinement shrinks the drift of the sphere states and the jittered cellular flow (measured
    ratios 0.47–0.62 per halving of h); the regular lattice reaches the O(dt) time floor
    (8.5e-3, 1.8e-3, 1.3e-3)."""
    from fluid_cases import drift_per_s, steady_case

    for case, levels in (("rigid_rotation", (2, 3, 4, 5)), ("degree_2", (2, 3, 4, 5)),
                         ("cellular_jittered", (8, 16, 32))):
        drift = [drift_per_s(*steady_case(case, level)) for level in levels]
        assert all(fine < 0.7 * coarse for coarse, fine in zip(drift, drift[1:], strict=False)), (case, drift)
    regular = [drift_per_s(*steady_case("cellular_regular", level)) for level in (8, 16, 32)]
    assert regular[1] < 0.5 * regular[0] and regular[2] < 2e-3, regular


@pytest.mark.slow
def test_the_shadow_flags_the_chaotic_channel_of_the_former_scheme():
    """Issue 18: the 2790-face channel at dt = 0.0075 (inflow 10, ν = 0.02) with WSHD07 and the
    corrected trapezoid amplifies a 1e-10 perturbation ×3 per step (measured 1.11 per step,
    148 /s over 0.3 s) while its energy stays bounded; the default scheme grows it at a flow
    rate (10 /s, 0.076 per step), below the 0.1-per-step threshold."""
    from decrun.methods.fluid.shadow import Shadow

    mesh, dec = channel(2800)
    growth = {}
    for velocity, circulation in (("wshd07", "corrected_trapezoid"), ("least_squares", "swept")):
        sim = VorticityFluid(dec, new_solver, dt=0.0075, viscosity=0.02, inflow_velocity=(10.0, 0.0),
                             obstacle_loops=mesh.obstacle_loops, velocity=velocity, circulation=circulation)
        shadow = Shadow(sim, 1e-10)
        for _ in range(40):
            assert sim.step()["stable"]  # the energy bound does not see it
            shadow.step()
        growth[velocity] = shadow.metrics()
    assert not growth["wshd07"]["perturbation_stable"] and growth["wshd07"]["perturbation_growth_per_step"] > 0.5
    assert growth["least_squares"]["perturbation_stable"]
    assert growth["least_squares"]["perturbation_growth_per_s"] < 0.2 * growth["wshd07"]["perturbation_growth_per_s"]


def test_least_squares_velocity_reproduces_linear_fields_at_vertices_and_inside_triangles():
    """reconstruction.py: the flux of a linear field through an edge is exactly
    v(midpoint)·(x_b − x_a) × N, so the per-vertex fit is exact for any linear field — at every
    vertex, border corners (2-ring fits) included — and its P1 interpolation is exact inside."""
    from decrun.methods.fluid.reconstruction import LeastSquaresVelocity

    from meshes_for_tests import square_lattice

    v, f = square_lattice(6, jitter=0.15)
    for dec in (lattice(), DEC(SimplicialComplex(v, f))):
        cells = build_dual_cells(dec)
        x = np.pad(dec.K.vertices, ((0, 0), (0, 1)))
        A, b = np.array([[0.7, -1.2, 0.0], [0.4, 0.3, 0.0], [0.0, 0.0, 0.0]]), np.array([0.5, -2.0, 0.0])
        edges = dec.K.simplices(1)
        mid = 0.5 * (x[edges[:, 0]] + x[edges[:, 1]])
        flux = np.einsum("ed,ed->e", mid @ A.T + b, np.cross(x[edges[:, 1]] - x[edges[:, 0]], [0.0, 0.0, 1.0]))
        ls = LeastSquaresVelocity(dec, cells, cells.face_normal)
        at_vertices = ls.fields(flux[:, None])[:, :, 0]
        np.testing.assert_allclose(at_vertices, x @ A.T + b, atol=1e-11)
        lam = np.random.default_rng(2).dirichlet([1, 1, 1], size=dec.K.num_simplices(2))
        points = np.einsum("mc,mcd->md", lam, x[dec.K.simplices(2)])
        inside = ls.velocity(np.arange(points.shape[0]), points, ls.fields(flux[:, None]))[:, :, 0]
        np.testing.assert_allclose(inside, points @ A.T + b, atol=1e-11)
        m = cells.n_circumcenters
        np.testing.assert_allclose((ls.circumcenter_matrix @ flux).reshape(m, 3), cells.points[:m] @ A.T + b,
                                   atol=1e-11)


def test_swept_vorticity_of_a_constant_is_the_area_change_and_sums_to_zero():
    """swept.py: for ω ≡ 1 the change of every cell is exactly area(X(C)) − area(C) (shoelace),
    and with the border points fixed the moved cells still tile the domain: Σ change = 0."""
    dec = lattice()
    sim = VorticityFluid(dec, new_solver, dt=0.01, viscosity=0.0)
    m = sim.cells.n_circumcenters
    before = sim.cells.points
    after = before.copy()
    after[:m, :2] += np.random.default_rng(5).uniform(-0.05, 0.05, (m, 2))
    ones = np.ones(before.shape[0])
    change = sim._swept.change(before, after, ones, ones)

    def areas(p):
        q = p[sim.cells.corners]
        return 0.5 * np.cross(q, np.roll(q, -1, axis=1))[..., 2].sum(axis=1)

    np.testing.assert_allclose(change, areas(after) - areas(before), atol=1e-14)
    assert abs(change.sum()) < 1e-13


@pytest.mark.parametrize("jitter", [0.0, 0.04])
def test_swept_vorticity_of_a_linear_field_is_its_exact_integral_over_the_moved_cells(jitter):
    """swept.py: the two triangles (p_a, p_b, p_b') and (p_a, p_b', p_a') of every swept quad
    integrate a linear ω exactly, so for ω = α + β·x and any moves of the circumcenters the
    change of every cell is ∫_{X(C)} ω − ∫_C ω, each integral by Green over the polygon,
    ∫_P ω = α A + β · Σ_i (p_i + p_{i+1}) (p_i × p_{i+1}) / 6 (A the shoelace area). The moves
    are random, so no triangle's error can cancel by symmetry (issue 25.7: swapping a corner of
    the second triangle, in its area or in its mean of ω, fails this)."""
    dec = lattice(jitter=jitter)
    sim = VorticityFluid(dec, new_solver, dt=0.01, viscosity=0.0)
    m = sim.cells.n_circumcenters
    before = sim.cells.points
    after = before.copy()
    after[:m, :2] += np.random.default_rng(7).uniform(-0.06, 0.06, (m, 2))
    alpha, beta = 0.3, np.array([1.7, -2.3, 0.0])

    def omega(p):
        return alpha + p @ beta

    def integral(p):
        q = p[sim.cells.corners][..., :2]  # (n0, corners, 2); padding repeats the first corner
        r = np.roll(q, -1, axis=1)
        cross = q[..., 0] * r[..., 1] - q[..., 1] * r[..., 0]
        first_moment = ((q + r) * cross[..., None]).sum(axis=1) / 6.0
        return alpha * 0.5 * cross.sum(axis=1) + first_moment @ beta[:2]

    change = sim._swept.change(before, after, omega(before), omega(after))
    expected = integral(after) - integral(before)
    assert np.abs(expected).min() > 1e-4  # every cell's integral changes
    # exact up to the round-off of cell integrals of size ≤ 14 (1.2e-13 measured on the jittered
    # lattice, so the atol is 1e-12 × that size); a swapped corner of the second triangle errs by
    # 1.9e-3 (its mean of ω) to 7.3e-2 (its area) in some cell
    scale = np.abs(integral(before)).max()
    np.testing.assert_allclose(change, expected, rtol=0, atol=1e-12 * scale)


def _square(cells: int) -> DEC:
    from meshes_for_tests import square_lattice

    return DEC(SimplicialComplex(*square_lattice(cells)))


def test_slip_walls_make_the_cellular_steady_state_converge_up_to_the_walls():
    """Issue 25.1: ψ = sin πx sin πy is an exact steady Euler flow in the unit square with slip
    walls (w = 2π²ψ vanishes on them). With walls=slip (the default at ν = 0) the drift of one
    step over the *whole* square shrinks with h (measured 0.147, 0.050, 0.017 /s at 8, 16, 32
    cells per side); with the thesis' no-slip border cells the walls make a vortex sheet, ~|v|/h
    per border cell, and the whole-square drift grows instead (1.8e3, 2.9e3, 4.2e3 /s); inside
    (0.2, 0.8)² both are the same."""
    from fluid_cases import steady_case

    slip, no_slip = [], []
    for cells in (8, 16, 32):
        dec, w0, inner = steady_case("cellular_regular", cells)
        runs, resolved = {}, {}
        for walls in ("auto", "no_slip"):
            sim = VorticityFluid(dec, new_solver, dt=1e-3, viscosity=0.0, initial_vorticity=w0, walls=walls)
            sim.step()
            runs[walls], resolved[walls] = sim.vorticity, sim.walls
        assert resolved == {"auto": "slip", "no_slip": "no_slip"}
        star = sim.star0
        slip.append(relative(runs["auto"], w0, star) / 1e-3)
        no_slip.append(relative(runs["no_slip"], w0, star) / 1e-3)
        inside = np.flatnonzero(inner)
        assert relative(runs["auto"][inside], w0[inside], star[inside]) == pytest.approx(
            relative(runs["no_slip"][inside], w0[inside], star[inside]), rel=1e-6)
    assert all(fine < 0.5 * coarse for coarse, fine in zip(slip, slip[1:], strict=False)), slip
    assert no_slip[0] > 1e3 and all(fine > coarse for coarse, fine in zip(no_slip, no_slip[1:], strict=False)), no_slip


def test_the_default_keeps_energy_and_enstrophy_at_zero_viscosity_between_walls():
    """Issue 25.1: unforced at ν = 0 in the walled unit square (2048 faces, smooth random vorticity)
    the default (swept_bounded, slip walls) keeps energy and enstrophy non-increasing to round-off
    in every step and Σ ⋆0 w constant (benchmarks/bench_fluid_stability.py --parts square: over
    1000 steps on 2048 and 8192 faces); the thesis' no-slip walls raise the enstrophy."""
    dec = _square(32)
    w0 = random_vorticity(dec, seed=4, amplitude=5.0)
    sim = VorticityFluid(dec, new_solver, dt=0.02, viscosity=0.0, initial_vorticity=w0)
    assert sim.walls == "slip"
    energy, enstrophy = _energy_enstrophy_series(sim, 30)
    assert np.all(np.diff(energy) <= 1e-12 * energy[:-1]) and np.all(np.diff(enstrophy) <= 1e-12 * enstrophy[:-1])
    assert abs(sim.star0 @ sim.vorticity - sim.star0 @ w0) <= 1e-12 * (sim.star0 @ np.abs(w0))
    assert energy[-1] > 0.9 * energy[0] and enstrophy[-1] > 0.5 * enstrophy[0]  # bounded, not damped away
    shedding = VorticityFluid(dec, new_solver, dt=0.02, viscosity=0.0, initial_vorticity=w0, walls="no_slip")
    _, shedding_enstrophy = _energy_enstrophy_series(shedding, 30)
    assert (np.diff(shedding_enstrophy) > 1e-12 * shedding_enstrophy[:-1]).any()


def test_the_inviscid_channel_from_rest_stays_a_potential_flow_with_slip_walls():
    """Issue 25.1: the Fig. 7.15 channel at ν = 0 from rest (inflow 10). With the thesis' no-slip
    walls every obstacle cell starts at |w| ~ |v|/h (1.9e4 at 12059 faces) and the run diverged
    (12059 faces at step 9, 5399 at step 33). With slip walls (the default at ν = 0, d'Alembert:
    an inviscid flow from rest stays irrotational) the interior keeps |w| small, the locally
    clamped swept change cannot grow it, and the energy is the potential flow's."""
    _, dec = channel(1400)
    runs = {}
    for walls in ("auto", "no_slip"):
        sim = VorticityFluid(dec, new_solver, dt=0.005, viscosity=0.0, inflow_velocity=[10.0, 0.0], walls=walls)
        e0 = sim.kinetic_energy()
        for _ in range(30):
            d = sim.step()
        runs[walls] = (d, e0, sim)
    d, e0, sim = runs["auto"]
    assert sim.walls == "slip" and d["finite"] and d["stable"]
    assert abs(d["kinetic_energy"] / e0 - 1) < 1e-3
    interior = ~sim.cells.border_vertex
    shed, _, shedding = runs["no_slip"]
    assert np.abs(sim.vorticity[interior]).max() < 0.05 * np.abs(shedding.vorticity[interior]).max()
    assert d["enstrophy"] < 0.05 * shed["enstrophy"]
