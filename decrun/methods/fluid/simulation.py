"""The vorticity fluid of thesis ch. 7 (Elcott, Tong, Kanso, Schröder, Desbrun 2007).

State (§7.2.1, primal and dual roles swapped): the stream function ψ (n0), the flux
1-form u = d0 ψ + c through the primal edges (n1; edge a → b, a < b, flux to its right
on the oriented surface) and the vorticity w = ⋆0⁻¹ d0ᵀ ⋆1 u per vertex (n0). One step
(Fig. 7.4 / 7.6, with the printed formulas corrected as noted below):

a.–b. a continuous velocity from u (and from d0 ψ alone), by ``velocity`` (reconstruction.py):
   ``"least_squares"`` (default) per-vertex least-squares fit to the edge fluxes, linear in each
   triangle; ``"wshd07"`` (the thesis) the constant per triangle at its circumcenter,
   interpolated over the flattened dual cells with the WSHD07 weights (interpolation.py);
c. backtrack every circumcenter along −u for dt (backtrack.py); with ``circulation="swept"``
   in equal intervals of at most ``swept_cfl`` edge lengths;
d. circulation Γ around each backtracked cell. *Border cells* take the trapezoid rule
   Γ = Σ_i <u(p_i) + u(p_{i+1}), p_{i+1} − p_i> / 2 of the full u (the wall velocities enter
   there) and w = Γ / ⋆0. Which cells are border cells is the wall condition ``walls``:
   ``"no_slip"`` (the thesis) the cell of every border vertex and every cell one of whose
   backtracked corners was clamped at a wall: walls shed vorticity, a vortex sheet of strength
   |v| resolved as ~|v|/h per border cell (a viscous effect: at ν = 0 it made the fine inviscid
   channels diverge and the whole-square steady-state drift grow with refinement);
   ``"slip"`` (the Euler condition u·n = 0) only the cells the inflow reaches (outer-border
   vertices and corners clamped at the outer border, when there is an inflow): every other cell,
   at walls too, takes the swept change below, so walls make no vorticity; ``"auto"`` (default)
   is ``"slip"`` at ν = 0 with a swept rule and ``"no_slip"`` otherwise.
   The other cells, by ``circulation``:
   ``"swept_bounded"`` (default): ``"swept"``, then bounded (limiter.py): where no vorticity is
     made or enters (closed surfaces; slip walls without inflow) blended towards one implicit
     smoothing step (or rescaled) so that neither enstrophy nor energy exceeds the previous
     step's — energy and enstrophy non-increasing at ν = 0, as consistent as ``"swept"``;
     at no-slip walls without inflow the energy alone (the walls make enstrophy);
     with slip walls and inflow each cell clamped to its footprint's range (the
     ``"swept_clamped"`` clamp: a local maximum principle, where no global bound holds); at
     no-slip walls with inflow it is ``"swept"``;
   ``"swept_clamped"``: ``"swept"``, each interior cell clamped to the vorticity range of its
     backtracked footprint (the mass given back to the cells with room), then the bound of
     ``"swept_bounded"`` (more diffusive; at no-slip walls it did not stop the inviscid channel's divergence);
   ``"swept"``: w + (Γ(X(C)) − Γ(C)) / ⋆0 with the change computed by Stokes as the
     integral of the current vorticity (linear least-squares fits) over the quadrilaterals the
     cell's sides sweep (swept.py) — consistent: the steady-flow drift shrinks with h, but at
     ν = 0 not a contraction (energy and enstrophy can grow; fine channels diverged);
   ``"corrected_trapezoid"``: w + (Γ − Γ⁰) / ⋆0 with Γ the trapezoid of the d0 ψ part and Γ⁰
     the same of the unmoved cell (on a curved surface Γ⁰ differs from ⋆0 w by O(h²), which
     applied every step acts like a diffusion depending on the number of steps);
   ``"trapezoid"`` (the thesis): w = Γ / ⋆0 of the d0 ψ part.
   On closed surfaces the ⋆0-weighted mean is removed (Σ ⋆0 w = 0);
e. viscosity, implicit: (⋆0 + ν dt d0ᵀ ⋆1 d0) w_new = ⋆0 w;
f. forces: w += dt ⋆0⁻¹ d0ᵀ ⋆1 f for a force flux f;
g. recovery (eq. 7.14 × ⋆0): (d0ᵀ ⋆1 d0 + μ d0ᵀ I_B d0) ψ = ⋆0 w with one pinned vertex
   (on the outer border when there is one), then u = d0 ψ + c.

Border velocities (no-slip): the border-edge midpoints and border vertices that close
border cells, and points clamped at a wall, move with their wall: 0 on obstacles, the
uniform inflow velocity v on the outer border (so the outer border is a slip wall
along v and fluid entering through the inflow border carries v and no vorticity).
The d0 ψ part is 0 there.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.core import jit
from decrun.core.connectivity import edge_owners
from decrun.core.dec import DEC
from decrun.core.geometry import embed3, obtuse_triangle_count
from decrun.core.threads import one_blas_thread
from decrun.errors import ConfigError, SolverError
from decrun.methods.fluid.backtrack import BacktrackResult, TriangleWalker
from decrun.methods.fluid.dual_cells import build_dual_cells
from decrun.methods.fluid.harmonic import border_layout, harmonic_flux
from decrun.methods.fluid.interpolation import CellInterpolator, dot3, triangle_velocity_matrix
from decrun.methods.fluid.limiter import EnergyEnstrophyBound, conservative_clamp, footprint_range
from decrun.methods.fluid.options import (
    SWEPT,
    Backtracking,
    Circulation,
    FluidOptions,
    Intervals,
    Kernels,
    Velocity,
    Walls,
)
from decrun.methods.fluid.reconstruction import make_reconstruction
from decrun.methods.fluid.swept import SweptVorticity, rest_point_interpolation

__all__ = ["VorticityFluid"]


class VorticityFluid:
    """Vorticity fluid on a triangle mesh (planar with borders, or a closed surface).

    Parameters
    ----------
    dec : DEC on a triangle mesh without obtuse triangles (circumcentric stars)
    new_solver : callable () -> solver with ``factorize(A)`` and ``solve(b)``; one per system
    dt : time step (s)
    viscosity : ν ≥ 0 (mesh units² / s)
    inflow_velocity : uniform velocity v (2 or 3 components) imposed on the outer border
        (eq. 7.10), or None (outer border is a wall at rest)
    obstacle_loops : list of vertex-id arrays of the obstacle border loops; default every
        border loop except the longest
    initial_vorticity : (n0,) w at t = 0 (default 0)
    penalty : μ of eq. 7.14 (default 1e6 · max ⋆1)
    blowup_factor : the run is reported unstable when the kinetic energy exceeds this
        factor times the largest legitimate energy (initial, harmonic, or after a forced step)
    options : :class:`~decrun.methods.fluid.options.FluidOptions`, the scheme's choices below
        (``integrator``, ``circulation``, ``velocity``, ``walls``, ``kernels``) validated once
        there; or give those as keywords (strings or members; the defaults are FluidOptions')
    integrator, substeps, max_cfl, max_rounds : passed to the backtracking (backtrack.py):
        each point takes at least ``substeps`` substeps and enough that one substep moves it
        at most ``max_cfl`` mean edge lengths of its start triangle (None: no such bound).
        ``integrator="per_triangle", max_cfl=None`` is Fig. 7.9 with stepSize = dt / substeps
    circulation : ``"swept_bounded"`` | ``"swept_clamped"`` | ``"swept"`` | ``"corrected_trapezoid"`` |
        ``"trapezoid"``, see step d above
    swept_cfl : ``circulation="swept"`` (and the bounded / clamped variants) backtracks in intervals moving each point at most this
        many mean edge lengths (see :meth:`_backtrack_sweeping`)
    velocity : the velocity reconstruction of steps b–d, a key of
        ``reconstruction.VELOCITY_RECONSTRUCTIONS``: ``"wshd07"`` (the thesis) or
        ``"least_squares"`` (per-vertex least-squares velocity, linear in each triangle)
    walls : ``"auto"`` | ``"slip"`` | ``"no_slip"``, the wall condition of step d (``"auto"``:
        slip at ν = 0 with a swept circulation, else no_slip); the resolved one is ``self.walls``
    kernels : the switch of :mod:`decrun.core.jit`: "numba" runs the backtracking walk with the
        reconstruction's interpolation (WSHD07 or least squares) and the circulation sum as
        compiled loops (compiled.py); "numpy" runs their vectorized numpy twins, the tested
        reference; "auto" (default) is ``DECRUN_NUMBA`` / ``jit.use`` if set, else numba (at any
        size: a run steps many times). Both do the same arithmetic in the same order: the same
        step, bit for bit. ``self.kernels`` is the resolved "numba" or "numpy".
    """

    def __init__(self, dec: DEC, new_solver, *, dt: float, viscosity: float, inflow_velocity=None,
                 obstacle_loops=None, initial_vorticity=None, penalty: float | None = None,
                 blowup_factor: float = 100.0, max_rounds: int = 1000, substeps: int = 1,
                 max_cfl: float | None = 1.0, swept_cfl: float = 1.0, options: FluidOptions | None = None,
                 integrator: Backtracking | None = None, circulation: Circulation | None = None,
                 velocity: Velocity | None = None, kernels: Kernels | None = None, walls: Walls | None = None,
                 intervals: Intervals | None = None):
        if not dt > 0:
            raise ConfigError(f"fluid: the time step dt must be > 0, got {dt}")
        if not viscosity >= 0:
            raise ConfigError(f"fluid: the viscosity must be >= 0, got {viscosity}")
        self._set_options(options, dict(integrator=integrator, circulation=circulation, velocity=velocity,
                                        kernels=kernels, walls=walls, intervals=intervals), viscosity)
        self.dec, self.K = dec, dec.K
        self.dt, self.viscosity = float(dt), float(viscosity)
        self.max_rounds, self.substeps, self.max_cfl = max_rounds, substeps, max_cfl
        self.swept_cfl = float(swept_cfl)
        self.blowup_factor = blowup_factor
        self._geometry(obstacle_loops, inflow_velocity)
        self._solvers(new_solver, inflow_velocity, penalty)
        n0 = self.K.num_simplices(0)
        w0 = np.zeros(n0) if initial_vorticity is None else np.array(initial_vorticity, dtype=np.float64)
        if w0.shape != (n0,):
            raise ConfigError(f"fluid: initial_vorticity must have one value per vertex ({n0},), got {w0.shape}")
        self.vorticity = self._remove_mean(w0)
        self.psi = self._recover(self.vorticity)
        self.flux = self.d0 @ self.psi + self.harmonic
        self.time, self.steps = 0.0, 0
        self.diverged_at_step: int | None = None
        self._energy_reference = max(self.kinetic_energy(), 0.5 * self.harmonic @ (self.star1 * self.harmonic), 1e-300)
        if self.kernels == "numba":
            self._load_kernels()

    def _set_options(self, options: FluidOptions | None, choices: dict, viscosity: float) -> None:
        """The scheme's choices (:class:`~decrun.methods.fluid.options.FluidOptions`, validated
        there once: given, or made from the keyword choices) and what they resolve to here."""
        choices = {name: value for name, value in choices.items() if value is not None}
        if options is not None and choices:
            raise TypeError(f"VorticityFluid: give options= or the choices {sorted(choices)} by keyword, not both")
        self.options = options if options is not None else FluidOptions(**choices)
        self.integrator, self.circulation_rule = self.options.integrator, self.options.circulation
        #: the wall condition: "slip" (the Euler condition, u·n = 0: walls make no vorticity) or
        #: "no_slip" (the border cells' trapezoid with the wall velocity, thesis §7.2.4); "auto" is
        #: slip at ν = 0 with a swept circulation, else no_slip
        self.walls = self.options.resolved_walls(viscosity)
        self.kernels = "numba" if jit.enabled(str(self.options.kernels)) else "numpy"
        #: the compiled walk interpolates with the reconstruction's tables (compiled.py)
        self.compiled_walk = self.kernels == "numba"

    def _geometry(self, obstacle_loops, inflow_velocity) -> None:
        """The tables of the mesh the scheme reads every step: dual cells, the triangle walker, the
        velocity reconstruction, the border layout and inflow, ⋆0, ⋆1, d0, the stiffness
        d0ᵀ ⋆1 d0, the dual edges of the swept rule and the open (inflow) border."""
        dec, K = self.dec, self.K
        self.cells = build_dual_cells(dec)
        self.face_normal = self.cells.face_normal
        self.walker = TriangleWalker(dec, self.face_normal)
        self.velocity_matrix = triangle_velocity_matrix(dec, self.face_normal)
        velocity = self.options.velocity
        self.reconstruction = make_reconstruction(velocity, dec, self.cells, self.face_normal, self.walker)
        self.interpolator = getattr(self.reconstruction, "interpolator", None)
        if self.interpolator is None:
            self.interpolator = CellInterpolator(self.cells, K.simplices(2), K.vertices)
        #: what the compiled walk interpolates with (kernel_tables, velocity_compiled)
        self._kernel_field = self.interpolator if velocity == Velocity.wshd07 else self.reconstruction
        #: mesh quality the method relies on (§7.3): obtuse triangles and non-convex flattened cells
        self.obtuse_triangles = obtuse_triangle_count(K.vertices, K.simplices(2))
        self.nonconvex_cells = int((~self.interpolator.convex).sum())
        self.closed = not self.cells.border_vertex.any()
        self.obstacles, self.label = border_layout(dec, obstacle_loops)
        self.inflow = np.zeros(3) if inflow_velocity is None else embed3(
            np.atleast_2d(np.asarray(inflow_velocity, dtype=np.float64)))[0]
        self.star0 = dec.star_diagonal(0)
        self.star1 = dec.star_diagonal(1)
        self.d0 = K.incidence(1)
        self.d0T = K.boundary(1)
        self.stiffness = dec.laplacian_symmetric(0)  # d0ᵀ ⋆1 d0 (PSD)
        self._build_dual_edges()
        self._open_border()
        # velocities of the fixed border dual points: [d0 ψ part, full u]
        m = self.cells.n_circumcenters
        fixed_vertex = self.cells.point_vertex[m:]
        self._fixed_velocity = np.zeros((fixed_vertex.size, 3, 2))
        self._fixed_velocity[:, :, 1] = np.where((self.label[fixed_vertex] == 0)[:, None], self.inflow[None, :], 0.0)
        edges = K.simplices(1)
        self._edge_wall_velocity = np.where((self.label[edges[:, 0]] == 0)[:, None], self.inflow[None, :], 0.0)

    def _solvers(self, new_solver, inflow_velocity, penalty: float | None) -> None:
        """The factorized systems, each once: the harmonic flux of the inflow, the bound of
        limiter.py, the implicit viscosity (⋆0 + ν dt d0ᵀ ⋆1 d0) and the stream function's
        penalized Poisson matrix (eq. 7.14 × ⋆0, one vertex pinned)."""
        K, circulation = self.K, self.circulation_rule
        self.harmonic = harmonic_flux(self.dec, self.face_normal, self.label, inflow_velocity, new_solver)
        #: the bound of limiter.py: energy and enstrophy on closed surfaces and between slip walls,
        #: the energy alone at no-slip walls (their border cells make vorticity: an enstrophy bound
        #: there wrecked the cellular flow's steady state, drift 298 /s instead of 1.8e-3 /s on 594
        #: faces), none with inflow (energy flows in)
        self._bound = None
        if circulation in (Circulation.swept_bounded, Circulation.swept_clamped) and not np.any(self.inflow):
            self._bound = EnergyEnstrophyBound(self.star0, self.stiffness, self._recover, new_solver,
                                               alpha=float(np.mean(self.walker.size)) ** 2,
                                               enstrophy=self.closed or self.walls == Walls.slip)
        #: per step: cells the clamp changed, and the bound's branches (limiter.EnergyEnstrophyBound.apply)
        self.limited_cells, self.bound_action = 0, 0
        #: the local clamp runs for swept_clamped, and for swept_bounded where the global bound cannot
        #: (slip walls with inflow: without it the inviscid 12059-face channel diverged at step 19, with
        #: it max |w| stayed ≤ 106 over 100 steps)
        self._clamps = circulation == Circulation.swept_clamped or (
            circulation == Circulation.swept_bounded and self.walls == Walls.slip and np.any(self.inflow))
        if self.viscosity > 0:
            self._diffusion = new_solver()
            self._diffusion.factorize((sp.diags(self.star0) + self.viscosity * self.dt * self.stiffness).tocsr())
        else:
            self._diffusion = None
        border_edge = np.zeros(K.num_simplices(1))
        border_edge[self.cells.border_edges] = 1.0
        self.penalty = float(1e6 * np.abs(self.star1).max()) if penalty is None else float(penalty)
        A = (self.stiffness + self.penalty * (self.d0T @ sp.diags(border_edge) @ self.d0)).tolil()
        outer = np.flatnonzero(self.label == 0)
        self.pinned = int(outer[0]) if outer.size else 0
        A[self.pinned, :] = 0.0
        A[:, self.pinned] = 0.0
        A[self.pinned, self.pinned] = 1.0
        self._poisson = new_solver()
        self._poisson.factorize(A.tocsr())

    # ------------------------------------------------------------------ pieces
    def _load_kernels(self) -> None:
        """Load (or, once per install, compile) the numba kernels now, on empty inputs, so the
        first step — and ``steps_per_second`` — does not include it."""
        none = np.zeros((0, 3))
        if self.compiled_walk:
            self.walker.backtrack_compiled(none, np.zeros(0, dtype=np.int64), self.dt, self._kernel_field,
                                           self._point_velocities(), integrator=self.integrator,
                                           start_velocity=none)
        m = self.cells.n_circumcenters
        some = np.zeros(self.K.num_simplices(0), dtype=bool) if self.circulation_rule in SWEPT else None
        self.trapezoid_circulation(self.cells.points[:m], np.zeros((m, 3, 2)), cells=some)  # its kernel
        if self.compiled_walk:  # the swept intervals after the first interpolate their start velocities
            self._kernel_field.velocity_compiled(np.zeros(0, dtype=np.int64), none, self._point_velocities(),
                                                 self.face_normal)
        if self.circulation_rule in SWEPT and self.compiled_walk:  # (its walk is the backtrack_points above)
            from decrun.methods.fluid import compiled

            rest = np.zeros(self.cells.points.shape[0])
            points = np.ascontiguousarray(self.cells.points, dtype=np.float64)
            D = self._swept.incidence
            compiled.swept_change_add(np.zeros(self.K.num_simplices(0)), points, points, rest, rest,
                                      self._swept.side_a, self._swept.side_b, self._swept.normal, D.indptr,
                                      D.indices, D.data, jit.threads())
            walk, jump = self.walker.kernel_tables()
            if self._sweeps_at_once(walk, jump, self._kernel_field.kernel_tables(), self.integrator):
                path, values = np.repeat(points[:, None, :], 2, axis=1), np.zeros((rest.size, 2))
                compiled.sweep_points(walk, jump, self._point_velocities(), path, np.zeros(0, dtype=np.int64),
                                      np.zeros(0, dtype=np.int64), none, np.zeros((0, 3, 2)), self.walker.size,
                                      self.dt, 1, 1.0, 64, 1, np.zeros(self.K.num_simplices(0)), values, 1)
                compiled.swept_change_path(np.zeros(self.K.num_simplices(0)), path, values, self._swept.side_a,
                                           self._swept.side_b, self._swept.normal, D.indptr, D.indices, D.data,
                                           jit.threads())

    def _remove_mean(self, w: np.ndarray) -> np.ndarray:
        if not self.closed:
            return w
        return w - (self.star0 @ w) / self.star0.sum()

    def _recover(self, w: np.ndarray) -> np.ndarray:
        """Step g: ψ from (d0ᵀ⋆1 d0 + μ d0ᵀ I_B d0) ψ = ⋆0 w, ψ[pinned] = 0 (eq. 7.14 × ⋆0)."""
        rhs = self.star0 * w
        rhs[self.pinned] = 0.0
        return self._poisson.solve(rhs)

    def kinetic_energy(self) -> float:
        """½ uᵀ ⋆1 u (mesh units⁴ / s², per unit density: ½ ∫ |v|² dA)."""
        return float(0.5 * self.flux @ (self.star1 * self.flux))

    def triangle_velocities(self, flux: np.ndarray | None = None) -> np.ndarray:
        """(m, 3) constant velocity per triangle (= at its circumcenter) of a flux form (step a)."""
        flux = self.flux if flux is None else flux
        return (self.velocity_matrix @ flux).reshape(-1, 3)

    def velocity_at(self, triangle: np.ndarray, points: np.ndarray) -> np.ndarray:
        """(P, 3) interpolated full velocity at ``points`` (P, 3) inside ``triangle`` (P,) (step b)."""
        full = np.ascontiguousarray(self._point_velocities()[..., 1:2])
        return self.reconstruction.velocity(np.asarray(triangle), embed3(points), full)[:, :, 0]

    def _point_velocities(self) -> np.ndarray:
        """The reconstruction's data for [d0 ψ part, full u] (…, 3, 2)."""
        fluxes = np.stack([self.d0 @ self.psi, self.flux], axis=1)
        return self.reconstruction.fields(fluxes, self._fixed_velocity)

    def backtrack(self):
        """Step c: the circumcenters dt ago (a BacktrackResult) and the two velocity fields there
        ((m, 3, 2): [d0 ψ part, full u], wall velocities at clamped points)."""
        both = self._point_velocities()
        full = np.ascontiguousarray(both[..., 1:2])
        reconstruction = self.reconstruction

        def velocity(triangle, x):
            return reconstruction.velocity(triangle, x, full)[:, :, 0]

        m = self.cells.n_circumcenters
        start = self._circumcenter_velocity(full)
        options = dict(integrator=self.integrator, substeps=self.substeps, max_rounds=self.max_rounds,
                       max_cfl=self.max_cfl)
        if self.circulation_rule not in SWEPT:
            result = self._walk(self.cells.points[:m], np.arange(m), self.dt, velocity, both, start, options)
        else:
            result = self._backtrack_sweeping(velocity, both, start, options)
        if self.compiled_walk:
            v = result.velocity  # the kernel interpolated every field at the end points
        else:
            v = reconstruction.velocity(result.triangle, result.position, both)
        if self.walls == "no_slip":  # a point clamped at a wall moves with it; at a slip wall with the fluid
            clamped = result.wall_edge >= 0
            v[clamped, :, 0] = 0.0
            v[clamped, :, 1] = self._edge_wall_velocity[result.wall_edge[clamped]]
        return result, v

    def _circumcenter_velocity(self, full: np.ndarray) -> np.ndarray:
        """(m, 3) the full velocity u at the circumcenters, where step c starts: the least-squares
        reconstruction interpolates its vertex velocities ``full`` (n0, 3, 1) there (P1, projected
        into the triangle's plane: the product ``circumcenter_matrix @ flux`` computed in two
        steps, by the numba kernel when compiled: 0.5 ms instead of 0.9 ms on 20k faces, the same
        values to round-off); WSHD07 takes the triangle's constant velocity (``circumcenter_matrix @ flux``)."""
        m = self.cells.n_circumcenters
        reconstruction = self.reconstruction
        if reconstruction.name != "least_squares":
            return (reconstruction.circumcenter_matrix @ self.flux).reshape(m, 3)
        triangles, circumcenters = np.arange(m), self.cells.points[:m]
        if self.compiled_walk:
            return reconstruction.velocity_compiled(triangles, circumcenters, full)[:, :, 0]
        return reconstruction.velocity(triangles, circumcenters, full)[:, :, 0]

    def _walk(self, points, triangles, dt, velocity, both, start_velocity, options):
        """One backtracking walk of ``points`` (P, 3) in ``triangles`` (P,) over ``dt``: the
        compiled kernel (the reconstruction's interpolation of field 1 of ``both``) or its numpy
        twin with the reconstruction's ``velocity`` callable."""
        if self.compiled_walk:
            return self.walker.backtrack_compiled(points, triangles, dt, self._kernel_field, both,
                                                  start_velocity=start_velocity, **options)
        return self.walker.backtrack(points, triangles, dt, velocity, start_velocity=start_velocity, **options)

    def _backtrack_sweeping(self, velocity, both, start, options):
        """Step c for ``circulation="swept"``: backtrack in k equal intervals of dt / k, k the
        smallest number that moves every point at most ``swept_cfl`` of its triangle's mean edge
        length per interval (at the start velocity), and add up the swept-vorticity change of
        every cell over the intervals (each swept quad then stays within about one cell, where
        the linear vorticity is a good model). Keeps it in ``self._swept_change``."""
        m = self.cells.n_circumcenters
        cfl = np.sqrt(dot3(start, start)) * self.dt / self.walker.size  # (|u| by dot3: 10× faster than norm(axis=1))
        k = max(1, int(np.ceil(cfl.max() / self.swept_cfl))) if cfl.size else 1
        if self.options.intervals == "per_point" and k > 1:
            return self._backtrack_sweeping_per_point(velocity, both, start, options, cfl, k)
        if self.compiled_walk:
            return self._backtrack_sweeping_compiled(both, start, k, options)
        top = self.K.simplices(2)
        points = self.cells.points.copy()
        value = self._rest_vorticity @ self.vorticity
        position, triangle = points[:m].copy(), np.arange(m)
        wall = np.full(m, -1, dtype=np.int64)
        change = np.zeros(self.K.num_simplices(0))
        rounds = unfinished = substeps = 0
        for interval in range(k):  # k small: a few intervals per step
            free = np.flatnonzero(wall < 0)
            begin = start[free] if interval == 0 else None
            part = self._walk(position[free], triangle[free], self.dt / k, velocity, both, begin, options)
            rounds, unfinished = rounds + part.rounds, max(unfinished, part.unfinished)
            substeps = max(substeps, part.substeps)
            position[free], triangle[free], wall[free] = part.position, part.triangle, part.wall_edge
            moved = points.copy()
            moved[:m] = position
            lam = self.walker.barycentric(triangle, position)
            new_value = value.copy()
            new_value[:m] = dot3(lam, self.vorticity[top[triangle]])
            change += self._swept.change(points, moved, value, new_value)
            points, value = moved, new_value
        self._swept_change = change
        return BacktrackResult(position, triangle, wall, rounds, unfinished, k * substeps)

    def _backtrack_sweeping_compiled(self, both, start, k, options):
        """:meth:`_backtrack_sweeping` by the numba kernels, the same bits: per interval one
        ``compiled.backtrack_points`` (walk, end velocities — the next interval's start velocities —
        and the vorticity at the new end points, blocks of points in parallel) and one
        ``compiled.swept_change_add``, on two point buffers used in turn; in the default scheme's
        case on a planar mesh (:meth:`_sweeps_at_once`) one ``compiled.sweep_points`` (every point
        through all k intervals in turn, its path of k + 1 positions and vorticity values kept)
        and one ``compiled.swept_change_path`` (every interval's change, added in the same order)."""
        from decrun.methods.fluid import compiled

        m = self.cells.n_circumcenters
        walk, jump = self.walker.kernel_tables()
        field = self._kernel_field.kernel_tables()
        both = np.ascontiguousarray(both, dtype=np.float64)
        start = np.ascontiguousarray(start, dtype=np.float64)
        before = np.array(self.cells.points, dtype=np.float64)  # two buffers of every dual point (the
        after = before.copy()  # fixed ones stay the rest points), the backtracked ones written in turn
        value_before = self._rest_vorticity @ self.vorticity
        value_after = value_before.copy()
        triangle = np.arange(m, dtype=np.int64)
        wall = np.full(m, -1, dtype=np.int64)
        end_velocity = np.zeros((m, 3, both.shape[2]))
        change = np.zeros(self.K.num_simplices(0))
        vorticity = np.ascontiguousarray(self.vorticity, dtype=np.float64)
        size = np.ascontiguousarray(self.walker.size, dtype=np.float64)
        max_cfl = -1.0 if options["max_cfl"] is None else float(options["max_cfl"])
        substeps = int(options["substeps"])
        cap = max(64, substeps)  # TriangleWalker.backtrack's max_substeps
        swept, D = self._swept, self._swept.incidence
        chunks = jit.threads()
        rounds = unfinished = most = 0
        if self._sweeps_at_once(walk, jump, field, options["integrator"]):
            # every point's k + 1 positions (the fixed ones the rest points) and vorticity values: each
            # point walks its k intervals in turn (compiled.sweep_points), then each side adds its
            # swept change of every interval (compiled.swept_change_path), the same bits as below
            path = np.empty((before.shape[0], k + 1, 3))
            path[:m, 0] = before[:m]
            path[m:] = before[m:, None, :]
            values = np.empty((value_before.size, k + 1))
            values[:m, 0] = value_before[:m]
            values[m:] = value_before[m:, None]
            r, left, steps = compiled.sweep_points(walk, jump, both, path, triangle, wall, start, end_velocity, size,
                                                   self.dt / k, substeps, max_cfl, cap, int(options["max_rounds"]),
                                                   vorticity, values, chunks)
            rounds = sum(int(r[interval].sum()) for interval in range(k))
            compiled.swept_change_path(change, path, values, swept.side_a, swept.side_b, swept.normal, D.indptr,
                                       D.indices, D.data, chunks)
            self._swept_change = change
            return BacktrackResult(path[:m, k].copy(), triangle, wall, rounds, int(left.max(initial=0)),
                                   k * int(steps.max()), end_velocity)
        for interval in range(k):
            after[:m] = before[:m]
            r, left, steps = compiled.backtrack_points(
                walk, jump, field, both, after[:m], triangle, wall, start, end_velocity, interval == 0, size,
                self.dt / k, substeps, max_cfl, cap, compiled.INTEGRATOR_CODE[options["integrator"]],
                int(options["max_rounds"]), vorticity, value_after[:m], 0 if interval == k - 1 else both.shape[2] - 1,
                chunks)
            rounds, unfinished, most = rounds + int(r.sum()), max(unfinished, int(left.max(initial=0))), max(most, steps)
            compiled.swept_change_add(change, before, after, value_before, value_after, swept.side_a, swept.side_b,
                                      swept.normal, D.indptr, D.indices, D.data, chunks)
            before, after = after, before
            value_before, value_after = value_after, value_before
        self._swept_change = change
        return BacktrackResult(before[:m].copy(), triangle, wall, rounds, unfinished, k * most, end_velocity)

    def _sweeps_at_once(self, walk, jump, field, integrator) -> bool:
        """Whether compiled.sweep_points walks the intervals: the midpoint integrator with the
        least-squares velocity on a planar mesh with the jump tables, the velocity reading the
        walker's own rows (the case of compiled._backtrack_block_planar_p1)."""
        return (integrator == "midpoint" and walk[4] and field[3] and field[4] == 1 and jump[0].shape[0] > 0
                and field[0] is walk[2] and field[1] is walk[1])

    def _backtrack_sweeping_per_point(self, velocity, both, start, options, cfl, k):
        """Step c for ``intervals="per_point"``: K intervals of dt / K, K the smallest 2^a or 3·2^a
        ≥ ``k``; point p walks only k_p of them, the smallest divisor of K ≥ CFL_p / ``swept_cfl``
        (``cfl`` (m,) its CFL number at the start velocity), each of length dt / k_p, and its
        position and vorticity at the K boundaries in between are interpolated linearly between
        its walked ones (x = x0 + (x1 − x0) j / s at boundary j of its s = K / k_p). Every dual side
        then sweeps its quads at the K boundaries: where both ends were interpolated the quads
        split the straight quad of the coarse interval, where one end walked they follow its path.
        The walks and the swept change are the twins' kernels (numba or numpy, the same bits);
        the interpolation is shared numpy."""
        from decrun.methods.fluid import compiled

        m = self.cells.n_circumcenters
        K = min(n for n in (2 ** a * f for a in range(k.bit_length() + 1) for f in (1, 3)) if n >= k)
        divisors = np.array([d for d in range(1, K + 1) if K % d == 0])
        need = np.maximum(1.0, np.ceil(cfl / self.swept_cfl))
        count = divisors[np.minimum(np.searchsorted(divisors, need), divisors.size - 1)]  # (m,) k_p
        order = np.argsort(count, kind="stable")  # the points by count: each count's walks on one slice
        count, stride = count[order], (K // count)[order]
        rank = np.empty(m, dtype=np.int64)
        rank[order] = np.arange(m)
        relabel = np.concatenate([rank, np.arange(m, self.cells.points.shape[0])])
        sides = (relabel[self._swept.side_a], relabel[self._swept.side_b])
        top = self.K.simplices(2)
        before = np.array(self.cells.points, dtype=np.float64)
        before[:m] = before[order]
        value_before = self._rest_vorticity @ self.vorticity
        value_before[:m] = value_before[order]
        after, value_after = before.copy(), value_before.copy()  # two buffers in turn; the fixed points stay
        anchor, anchor_value = before[:m].copy(), value_before[:m].copy()  # each point's last walked boundary
        target, target_value = anchor.copy(), anchor_value.copy()  # and its next one
        triangle = order.astype(np.int64)  # circumcenter i lies in triangle i
        wall = np.full(m, -1, dtype=np.int64)
        start = np.ascontiguousarray(start[order], dtype=np.float64)
        change = np.zeros(self.K.num_simplices(0))
        rounds = unfinished = most = 0
        if self.compiled_walk:
            walk, jump = self.walker.kernel_tables()
            field = self._kernel_field.kernel_tables()
            both = np.ascontiguousarray(both, dtype=np.float64)
            end_velocity = np.zeros((m, 3, both.shape[2]))
            vorticity = np.ascontiguousarray(self.vorticity, dtype=np.float64)
            size = np.ascontiguousarray(self.walker.size, dtype=np.float64)
            max_cfl = -1.0 if options["max_cfl"] is None else float(options["max_cfl"])
            cap = max(64, int(options["substeps"]))
            code = compiled.INTEGRATOR_CODE[options["integrator"]]
        bounds = np.searchsorted(count, divisors, side="left").tolist() + [m]
        levels = [(int(c), lo, hi) for c, lo, hi in zip(divisors, bounds[:-1], bounds[1:], strict=True) if hi > lo]
        for interval in range(K):
            for c, lo, hi in levels:
                if interval % (K // c):
                    continue
                first, last = interval == 0, interval == K - K // c
                anchor[lo:hi], anchor_value[lo:hi] = target[lo:hi], target_value[lo:hi]
                if self.compiled_walk:  # in place on the slices
                    r, left, steps = compiled.backtrack_points(
                        walk, jump, field, both, target[lo:hi], triangle[lo:hi], wall[lo:hi], start[lo:hi],
                        end_velocity[lo:hi], first, size, self.dt / c, int(options["substeps"]), max_cfl, cap, code,
                        int(options["max_rounds"]), vorticity, target_value[lo:hi],
                        0 if last else both.shape[2] - 1, jit.threads())
                    rounds, unfinished = rounds + int(r.sum()), max(unfinished, int(left.max(initial=0)))
                    most = max(most, c * steps)
                else:
                    free = lo + np.flatnonzero(wall[lo:hi] < 0)
                    most = max(most, c)  # (the kernel's count when every point of the slice is clamped)
                    if free.size:
                        part = self._walk(anchor[free], triangle[free], self.dt / c, velocity, both,
                                          start[free] if first else None, options)
                        rounds, unfinished = rounds + part.rounds, max(unfinished, part.unfinished)
                        most = max(most, c * part.substeps)
                        target[free], triangle[free], wall[free] = part.position, part.triangle, part.wall_edge
                    lam = self.walker.barycentric(triangle[lo:hi], target[lo:hi])
                    target_value[lo:hi] = dot3(lam, self.vorticity[top[triangle[lo:hi]]])
            fraction = (interval % stride + 1) / stride  # (m,) j / s, 1 at a walked boundary
            walked = fraction == 1.0
            after[:m] = np.where(walked[:, None], target, anchor + (target - anchor) * fraction[:, None])
            value_after[:m] = np.where(walked, target_value, anchor_value + (target_value - anchor_value) * fraction)
            change += self._swept.change(before, after, value_before, value_after, compiled=self.compiled_walk,
                                         sides=sides)
            before, after = after, before
            value_before, value_after = value_after, value_before
        self._swept_change = change
        position, triangle_out, wall_out = np.empty((m, 3)), np.empty(m, dtype=np.int64), np.empty(m, dtype=np.int64)
        position[order], triangle_out[order], wall_out[order] = target, triangle, wall
        velocity_out = None
        if self.compiled_walk:
            velocity_out = np.empty_like(end_velocity)
            velocity_out[order] = end_velocity
        return BacktrackResult(position, triangle_out, wall_out, rounds, unfinished, most, velocity_out)

    def _build_dual_edges(self) -> None:
        """The dual cells' sides as unique dual edges (a, b), a < b, and the signed
        incidence D (n0, n_dual_edges): Γ = D g with g the trapezoid integral along a → b."""
        corners = self.cells.corners
        a, b = corners, np.roll(corners, -1, axis=1)
        keep = a != b  # padding repeats the first corner: no side
        n_points = self.cells.points.shape[0]
        first, second = np.minimum(a, b)[keep], np.maximum(a, b)[keep]
        key, inverse = np.unique(first * n_points + second, return_inverse=True)
        self._edge_a, self._edge_b = key // n_points, key % n_points
        self._fixed_points = np.ascontiguousarray(self.cells.points[self.cells.n_circumcenters:], dtype=np.float64)
        rows = np.broadcast_to(np.arange(corners.shape[0])[:, None], corners.shape)[keep]
        sign = np.where(a[keep] < b[keep], 1.0, -1.0)
        self._dual_incidence = sp.csr_matrix((sign, (rows, inverse)), shape=(corners.shape[0], key.size))
        # Γ⁰ of the unmoved cells is linear in ψ: D · (trapezoid of the circumcenter velocities) · M · d0
        m = self.cells.n_circumcenters
        half = 0.5 * (self.cells.points[self._edge_b] - self.cells.points[self._edge_a])  # (E, 3)
        rows, cols, vals = [], [], []
        for end in (self._edge_a, self._edge_b):
            moving = end < m
            for d in range(3):
                rows.append(np.flatnonzero(moving))
                cols.append(3 * end[moving] + d)
                vals.append(half[moving, d])
        trapezoid = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                  shape=(key.size, 3 * m))
        at_circumcenters = self.reconstruction.circumcenter_matrix
        self._rest_circulation = (self._dual_incidence @ trapezoid @ at_circumcenters @ self.d0).tocsr()
        self._swept = SweptVorticity(self.cells.vertex_normal, self._dual_incidence, self._edge_a, self._edge_b)
        top = self.K.simplices(2)
        at_circumcenters = self.walker.barycentric(np.arange(m), self.cells.points[:m])
        self._rest_vorticity = rest_point_interpolation(top, at_circumcenters, self.cells.point_vertex,
                                                        self.K.simplices(1)[self.cells.border_edges], self.K.num_simplices(0))

    def _open_fixed_velocity(self) -> np.ndarray | None:
        """(n_fixed, 3, 2) velocities of the fixed border points for ``walls="slip"`` with an
        inflow and the least-squares reconstruction: on the open border (:meth:`_open_border`) the
        full u is the fluid's own (P1 of the vertex velocities), so the trapezoid of an inflow cell
        measures the vorticity there and imposes only the normal flux of v (through the harmonic
        part) — imposing the whole v made a vortex sheet of the tangential velocity the obstacle
        gives the inflow (±2 shed into the 2790-face channel); elsewhere as before. None: unchanged."""
        if self._open_edge is None or self.reconstruction.name != "least_squares":
            return None
        m = self.cells.n_circumcenters
        vertex_velocity = self.reconstruction.fields(self.flux[:, None])[:, :, 0]  # (n0, 3)
        fixed = self._fixed_velocity.copy()
        border = self.cells.border_edges
        ends = self.K.simplices(1)[border]
        open_mid = self._open_edge[border]
        fixed[: border.size, :, 1][open_mid] = 0.5 * (vertex_velocity[ends[open_mid, 0]] + vertex_velocity[ends[open_mid, 1]])
        vertices = self.cells.point_vertex[m + border.size:]
        open_vertex = self._open_vertex[vertices]
        fixed[border.size:, :, 1][open_vertex] = vertex_velocity[vertices[open_vertex]]
        return fixed

    def circulation(self, position: np.ndarray, velocity: np.ndarray, clamped: np.ndarray,
                    fixed_velocity: np.ndarray | None = None):
        """Step d: Γ (n0,) around every (backtracked) dual cell, trapezoid rule
        Γ = Σ_i <u(p_i) + u(p_{i+1}), p_{i+1} − p_i> / 2, and the (n0,) bool mask of border
        cells (which use the full u; the others the d0 ψ part).

        position (m, 3), velocity (m, 3, 2) of the backtracked circumcenters; clamped (m,) bool;
        fixed_velocity (n_fixed, 3, 2) of the fixed border points (default: the wall velocities).
        """
        gamma = self.trapezoid_circulation(position, velocity, fixed_velocity)
        border_cell = self._border_cells(clamped)
        return np.where(border_cell, gamma[:, 1], gamma[:, 0]), border_cell

    def trapezoid_circulation(self, position: np.ndarray, velocity: np.ndarray,
                              fixed_velocity: np.ndarray | None = None, cells: np.ndarray | None = None) -> np.ndarray:
        """(n0, 2) the trapezoid Γ of both fields [d0 ψ part, full u] around the dual cells
        (:meth:`circulation`), of the ``cells`` (n0,) bool only when given (0 in the others: the
        swept rules take Γ of their border cells only)."""
        fixed_velocity = self._fixed_velocity if fixed_velocity is None else fixed_velocity
        m = self.cells.n_circumcenters
        a, b = self._edge_a, self._edge_b
        D = self._dual_incidence
        if self.kernels == "numba":
            from decrun.methods.fluid import compiled

            args = (np.ascontiguousarray(position, dtype=np.float64), self._fixed_points,
                    np.ascontiguousarray(velocity, dtype=np.float64), fixed_velocity, a, b, D.indptr, D.indices, D.data)
            if cells is None:
                return compiled.circulation_sums(*args, jit.threads())
            return compiled.circulation_rows(*args, np.flatnonzero(cells))
        points = np.concatenate([position, self.cells.points[m:]])
        velocities = np.concatenate([velocity, fixed_velocity])
        side = points[b] - points[a]  # (E, 3)
        g = 0.5 * dot3(np.moveaxis(velocities[a] + velocities[b], 1, 2), side[:, None, :])  # (E, 2)
        if cells is None:
            return D @ g
        rows = np.flatnonzero(cells)
        gamma = np.zeros((D.shape[0], g.shape[1]))
        gamma[rows] = D[rows] @ g
        return gamma

    def _border_cells(self, clamped: np.ndarray) -> np.ndarray:
        """(n0,) bool: the cells of border vertices and those with a corner clamped at a wall
        (``clamped`` (m,) bool): their circulation takes the full u."""
        cells = self.cells
        if not clamped.any():  # (closed surfaces: no walls)
            return cells.border_vertex.copy()
        m = cells.n_circumcenters
        touched = np.zeros(m + 1, dtype=bool)
        touched[:m] = clamped
        corners = np.where(cells.corners < m, cells.corners, m)
        return cells.border_vertex | touched[corners].any(axis=1)

    def _inflow_cells(self, wall_edge: np.ndarray) -> np.ndarray:
        """(n0,) bool: with ``walls="slip"`` and an inflow, the cells of the vertices of the open
        outer-border edges (those v crosses, :meth:`_open_border`) and the cells with a corner
        clamped at one (``wall_edge`` (m,), -1 where not clamped): fluid enters and leaves there,
        carrying v and no vorticity in, which the trapezoid rule with the border velocity v gives;
        every other cell, at walls too, takes the swept change. None without inflow."""
        n0 = self.K.num_simplices(0)
        if self._open_edge is None:
            return np.zeros(n0, dtype=bool)
        m = self.cells.n_circumcenters
        touched = np.zeros(m + 1, dtype=bool)
        touched[:m] = self._open_edge[np.where(wall_edge >= 0, wall_edge, -1)]
        corners = np.where(self.cells.corners < m, self.cells.corners, m)
        return self._open_vertex | touched[corners].any(axis=1)

    def _open_border(self) -> None:
        """With an inflow v: the *open* outer-border edges, those v crosses (|v·n| > 1e-9 |v|, n the
        edge's outward normal in its triangle's plane: the inflow and outflow sides), as an
        (n1 + 1,) mask (the last slot for "not clamped") and their vertices (n0,); the outer
        border's other edges are walls along v (the channel's top and bottom). None without inflow."""
        self._open_edge = self._open_vertex = None
        if not np.any(self.inflow):
            return
        K = self.K
        x = embed3(K.vertices)
        edges = K.simplices(1)
        border = self.cells.border_edges
        outer = border[(self.label[edges[border, 0]] == 0) & (self.label[edges[border, 1]] == 0)]
        owner, _ = edge_owners(K.facet_indices(2), edges.shape[0])
        a, b = x[edges[outer, 0]], x[edges[outer, 1]]
        tangent = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
        away = 0.5 * (a + b) - x[K.simplices(2)[owner[outer]]].mean(axis=1)
        normal = away - np.einsum("ed,ed->e", away, tangent)[:, None] * tangent
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        crossing = np.abs(normal @ self.inflow) > 1e-9 * np.linalg.norm(self.inflow)
        self._open_edge = np.zeros(edges.shape[0] + 1, dtype=bool)
        self._open_edge[outer[crossing]] = True
        self._open_vertex = np.zeros(K.num_simplices(0), dtype=bool)
        self._open_vertex[edges[outer[crossing]].ravel()] = True

    def backtracked_vorticity(self, result, velocity) -> np.ndarray:
        """Steps c–d: the vorticity (n0,) carried to the vertices, before viscosity and forces."""
        fixed = self._open_fixed_velocity() if self.walls == "slip" else None
        clamped = result.wall_edge >= 0
        if self.circulation_rule in SWEPT:  # the trapezoid Γ on the border cells only, the swept change elsewhere
            if self.walls == "slip":  # only the cells the inflow reaches keep the trapezoid (their wall moves at v)
                border_cell = self._inflow_cells(result.wall_edge)
            else:
                border_cell = self._border_cells(clamped)
            w = self.vorticity + self._swept_change / self.star0
            if border_cell.any():  # (none on closed surfaces: no Γ to compute) the full u: they are border cells
                gamma = self.trapezoid_circulation(result.position, velocity, fixed, cells=border_cell)[:, 1]
                w = np.where(border_cell, gamma / self.star0, w)
        else:
            gamma, border_cell = self.circulation(result.position, velocity, clamped, fixed)
            w = gamma / self.star0
        if self._clamps:
            lo, hi = footprint_range(self.vorticity, self.K.simplices(2), result.triangle, self.cells.corners,
                                     self.cells.n_circumcenters)
            interior = ~border_cell
            self.limited_cells = int(((w < lo) | (w > hi))[interior].sum())
            w = conservative_clamp(w, lo, hi, self.star0, interior)
        elif self.circulation_rule == "corrected_trapezoid":
            gamma0 = self._rest_circulation @ self.psi
            w = np.where(border_cell, w, self.vorticity + (gamma - gamma0) / self.star0)
        return self._remove_mean(w)

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        """Everything a later :meth:`step` reads that a step changes (the operators and
        factorizations are fixed by the mesh and options): ``vorticity`` (n0,), ``psi`` (n0,),
        ``flux`` (n1,), ``time`` (s), ``steps``, ``diverged_at_step`` (None or int), the energy
        reference of the blow-up bound and the limiter's last counters."""
        return {"vorticity": self.vorticity, "psi": self.psi, "flux": self.flux, "time": float(self.time),
                "steps": int(self.steps), "diverged_at_step": self.diverged_at_step,
                "energy_reference": float(self._energy_reference), "limited_cells": int(self.limited_cells),
                "bound_action": int(self.bound_action)}

    def load_state(self, state: dict) -> None:
        """Restore a :meth:`state_dict` (the next steps are those of the run it came from)."""
        self.vorticity = np.array(state["vorticity"], dtype=np.float64)
        self.psi = np.array(state["psi"], dtype=np.float64)
        self.flux = np.array(state["flux"], dtype=np.float64)
        self.time, self.steps = float(state["time"]), int(state["steps"])
        diverged = state.get("diverged_at_step")
        self.diverged_at_step = None if diverged is None else int(diverged)
        self._energy_reference = float(state["energy_reference"])
        self.limited_cells, self.bound_action = int(state["limited_cells"]), int(state["bound_action"])

    # ------------------------------------------------------------------ stepping
    def step(self, force_flux: np.ndarray | None = None) -> dict:
        """Advance one time step (a–g above) and return diagnostics.

        Parameters
        ----------
        force_flux : (n1,) optional force f sampled as a flux 1-form (mesh units³ / s²)

        Returns
        -------
        dict with step, time, kinetic_energy, vortical_energy, enstrophy, total_circulation,
        max_abs_divergence, relative_divergence, vorticity_min, vorticity_max,
        backtrack_rounds, backtrack_unfinished, clamped_points, finite, stable, and with
        ``circulation="swept_bounded"`` / ``"swept_clamped"`` limited_cells (interior cells the
        clamp changed; 0 without it) and bound_action (0: within both bounds, 1: blended with the smoothed field, 2: rescaled)
        (and diverged_at_step once a step produced non-finite values; later steps do nothing).
        """
        with one_blas_thread():  # the inner products beside the parallel kernels (decrun.core.threads)
            return self._step(force_flux)

    def _step(self, force_flux: np.ndarray | None) -> dict:
        extra = {}
        if self.diverged_at_step is None:
            before = self.kinetic_energy()
            try:
                with np.errstate(all="ignore"):
                    result, velocity = self.backtrack()
                    w = self.backtracked_vorticity(result, velocity)
                    psi = None
                    if self._bound is not None and np.all(np.isfinite(w)):
                        w, psi, self.bound_action = self._bound.apply(self.vorticity, self.psi, w)
                    if self._diffusion is not None:
                        w = self._diffusion.solve(self.star0 * w) if np.all(np.isfinite(w)) else w
                        psi = None
                    if force_flux is not None:
                        w = w + self.dt * (self.d0T @ (self.star1 * np.asarray(force_flux, dtype=np.float64))) / self.star0
                        w = self._remove_mean(w)
                        psi = None
                    if not np.all(np.isfinite(w)):
                        raise FloatingPointError
                    if psi is None:  # the bound's ψ is this solve's, unless viscosity or a force changed w
                        psi = self._recover(w)
                    if not np.all(np.isfinite(psi)):
                        raise FloatingPointError
            except (FloatingPointError, SolverError):
                self.diverged_at_step = self.steps + 1
            else:
                self.vorticity, self.psi = w, psi
                self.flux = self.d0 @ psi + self.harmonic
                extra = {"backtrack_rounds": result.rounds, "backtrack_unfinished": result.unfinished,
                         "backtrack_substeps": result.substeps,
                         "clamped_points": int((result.wall_edge >= 0).sum())}
                if self.circulation_rule in ("swept_bounded", "swept_clamped"):
                    extra.update(limited_cells=self.limited_cells, bound_action=self.bound_action)
                if force_flux is not None:
                    self._energy_reference = max(self._energy_reference, self.kinetic_energy(), before)
        self.steps += 1
        self.time += self.dt
        return {**self.diagnostics(), **extra}

    def diagnostics(self) -> dict:
        """Scalars describing the current state (see :meth:`step`)."""
        w, u = self.vorticity, self.flux
        energy = self.kinetic_energy()
        finite = bool(np.all(np.isfinite(w)) and np.all(np.isfinite(u))) and self.diverged_at_step is None
        divergence = self.K.incidence(2) @ u
        max_u = float(np.abs(u).max()) if u.size else 0.0
        result = {
            "step": self.steps,
            "time": self.time,
            "kinetic_energy": energy,
            "vortical_energy": float(0.5 * self.psi @ (self.stiffness @ self.psi)),
            "enstrophy": float(0.5 * self.star0 @ (w * w)),
            "total_circulation": float(self.star0 @ w),
            "max_abs_divergence": float(np.abs(divergence).max()),
            "relative_divergence": float(np.abs(divergence).max() / max_u) if max_u > 0 else 0.0,
            "vorticity_min": float(w.min()),
            "vorticity_max": float(w.max()),
            "finite": finite,
            "stable": finite and energy <= self.blowup_factor * self._energy_reference,
        }
        if self.diverged_at_step is not None:
            result["diverged_at_step"] = self.diverged_at_step
        return result
