"""``app=fluid``: vorticity fluids on surfaces and planar domains (thesis ch. 7, Elcott et al. 2007).

The solver is :class:`decrun.methods.fluid.VorticityFluid` (the velocity as a flux 1-form,
the stream function ψ as a 0-form, the vorticity as a dual 2-form per vertex; see its module
docstring for one step and the corrections of the printed formulas); this adapter sets up the
initial vorticity, the stirring force and the inflow from the options, runs the steps with a
progress bar and records, every ``record_every`` steps, the vorticity per vertex, the flux per
edge and the scalar diagnostics (``ctx.record``: memory stays flat, a killed run keeps them).

Domains: closed surfaces (``mesh=icosphere mesh.noise=0``, any closed mesh file), and planar
domains with borders — the outer border carries the uniform inflow ``inflow`` (eq. 7.10; a
slip wall along it), every other border loop is a no-slip obstacle (``mesh=channel``). The
circumcentric dual cells the interpolation needs turn inside out on obtuse triangles (§7.3):
the app reports their count (``obtuse_triangles``) and warns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, List, Optional

import numpy as np

from decrun.apps.base import App, Context, FieldOnEdges, Figure, Output, Result
from decrun.apps.surface_points import check_points_on_surface
from decrun.errors import ConfigError
from decrun.methods.fluid.metrics import fluid_metrics
from decrun.methods.fluid.options import Circulation, FluidOptions, Initial, Intervals, Kernels, Velocity, Walls
from decrun.methods.fluid.stepper import FluidStepper
from decrun.methods.stepping import run_steps

if TYPE_CHECKING:  # types of the parameters only
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC

#: a chained start whose vorticity is at most this fraction of the terms it is summed from
#: (max |d1 ω| against max Σ|ω| around a triangle) is round-off: ω was a gradient (curl-free)
ROUND_OFF = 1e-10


@dataclass
class Stir:
    """A stirring stroke: polyline ``points`` (projected to the surface) pushed with
    ``strength`` (mesh units / s²) from ``start`` to ``stop`` (seconds)."""

    points: List[List[float]] = field(default_factory=list)
    strength: float = 10.0
    start: float = 0.0
    stop: float = 0.5


@dataclass
class Fluid(App):
    """Options of ``app=fluid`` (conf/app/fluid.yaml)."""

    name = "fluid"
    one_piece = "the velocity solve's matrix is singular with one kernel per piece"
    headline_metrics = ("stable", "diverged_at_step", "max_abs_divergence", "energy_ratio", "enstrophy_ratio")
    form_degrees = (0, 1, 2)
    diagonal_stars = "the scheme divides by ⋆0 and ⋆1 entrywise (vorticity = circulation / ⋆0)"
    dt: float = 0.005  # time step (s)
    steps: int = 200
    t_end: Optional[float] = None  # if set: steps = ceil(t_end / dt)
    viscosity: float = 0.03  # ν (mesh units² / s)
    inflow: List[float] = field(default_factory=list)  # uniform velocity on the outer border ([] : none)
    initial: Initial = Initial.zero  # zero | rotation | vortex_pair | random | mesh_field (mesh=result mesh.field=...)
    initial_strength: float = 1.0  # Ω (rotation), Γ (vortex_pair), max |w| (random)
    vortex_separation_deg: float = 60.0  # vortex_pair: angular distance on the unit sphere
    vortex_radius: float = 0.15  # vortex_pair: blob radius
    seed: int = 0
    stirs: List[Stir] = field(default_factory=list)
    velocity: Velocity = Velocity.least_squares  # least_squares | wshd07 (the thesis' interpolation, §7.2.3)
    circulation: Circulation = Circulation.swept_bounded  # swept_bounded | swept_clamped | swept | corrected_trapezoid | trapezoid
    walls: Walls = Walls.auto  # auto (slip at ν = 0, else no_slip) | slip | no_slip
    intervals: Intervals = Intervals.uniform  # uniform | per_point: the swept rules' backtracking intervals
    shadow: bool = False  # also run a shadow with a 1e-10 perturbation: perturbation_growth_per_s (shadow.py)
    shadow_perturbation: float = 1e-10  # relative size of the shadow's perturbation
    shadow_max_growth_per_step: float = 0.1  # stable: false when the fitted growth per step exceeds this
    shadow_window_steps: int = 100  # the growth is the least-squares slope of ln(separation) over the last this many steps
    record_every: int = 5
    snapshots: int = 6
    animation: bool = True
    kernels: Kernels = Kernels.auto  # auto | numba (compiled loops) | numpy (their twins): decrun.core.jit

    def __post_init__(self):
        if not (self.dt > 0 and math.isfinite(self.dt)):
            raise ConfigError(f"app.dt: must be > 0, got {self.dt}")
        if self.steps < 1 and self.t_end is None:
            raise ConfigError(f"app.steps: must be >= 1, got {self.steps}")
        if self.t_end is not None and not self.t_end > 0:
            raise ConfigError(f"app.t_end: must be > 0 or null, got {self.t_end}")
        if not self.viscosity >= 0:
            raise ConfigError(f"app.viscosity: must be >= 0, got {self.viscosity}")
        self.initial = Initial.of(self.initial, "app.initial")  # also for Python callers (strings)
        scheme = self.scheme()  # each choice a member, the unstable pairs refused
        self.velocity, self.circulation, self.walls, self.kernels = (scheme.velocity, scheme.circulation,
                                                                     scheme.walls, scheme.kernels)
        self.intervals = scheme.intervals
        if not self.shadow_perturbation > 0:
            raise ConfigError(f"app.shadow_perturbation: must be > 0, got {self.shadow_perturbation}")
        if self.shadow_window_steps < 2:
            raise ConfigError(f"app.shadow_window_steps: a growth rate is fitted over at least 2 steps, got "
                              f"{self.shadow_window_steps}; use e.g. app.shadow_window_steps=100 (the default)")
        if self.record_every < 1:
            raise ConfigError(f"app.record_every: must be >= 1, got {self.record_every}")
        for i, stir in enumerate(self.stirs):
            if len(stir.points) < 2:
                raise ConfigError(f"app.stirs[{i}].points: a stroke needs at least two points")
            if not stir.stop > stir.start:
                raise ConfigError(f"app.stirs[{i}].stop: must be after start ({stir.start})")

    def scheme(self) -> FluidOptions:
        """The scheme's choices as the method takes them (validated there, messages naming ``app.*``)."""
        return FluidOptions(velocity=self.velocity, circulation=self.circulation, walls=self.walls,
                            kernels=self.kernels, intervals=self.intervals, key="app")

    @property
    def total_steps(self) -> int:
        return int(math.ceil(self.t_end / self.dt - 1e-9)) if self.t_end is not None else int(self.steps)

    def check(self, K: SimplicialComplex, dec: DEC) -> None:
        closed = K.border_faces()[0].size == 0
        if self.inflow and closed:
            raise ConfigError("app.inflow: a closed surface has no border to flow in through; use app.inflow=[]")
        if self.inflow and len(self.inflow) != K.embedding_dim:
            raise ConfigError(f"app.inflow: needs {K.embedding_dim} components (the mesh's dimension), "
                              f"got {list(self.inflow)}")
        for i, stir in enumerate(self.stirs):  # projected onto the surface, so no distance bound
            try:
                check_points_on_surface(K, stir.points, f"app.stirs[{i}].points", tolerance=float("inf"))
            except ConfigError as error:
                raise ConfigError(f"{error}; give strokes in the mesh's coordinates or drop them with app.stirs=[]") \
                    from None
        if self.initial == "mesh_field" and "field" not in getattr(K, "meta", {}):
            raise ConfigError("app.initial=mesh_field: the mesh carries no field; chain a previous run with "
                              "mesh=result mesh.path=<run>/result.h5 mesh.field=<name> (e.g. omega of app=vector_field)")
        if self.initial in ("rotation", "vortex_pair") and not closed:
            raise ConfigError(f"app.initial={self.initial} is defined on the unit sphere; use app.initial=random "
                              "or zero on domains with borders")

    def outputs(self) -> dict[str, Output]:
        """Vorticity and stream function per vertex, the flux per edge."""
        return {"vorticity": Output("0"), "psi": Output("0"), "flux": Output("1")}

    def run(self, ctx: Context) -> Result:
        """Run the fluid; see the module docstring.

        Metrics: ``stable`` (the energy stayed bounded and, with ``shadow``, the perturbation's
        fitted growth was at most ``shadow_max_growth_per_step`` per step), ``diverged_at_step``
        (when the energy bound broke), ``steps_done``; with ``shadow`` (decrun/methods/fluid/shadow.py):
        ``perturbation_growth_per_step`` — the least-squares slope of L_n = ln(separation / ε)
        (the renormalised log-growths summed up to step n) against n over the last
        ``shadow_window_steps`` steps, never the first 5 (the perturbation's alignment; a run of
        at most 5 steps fits all of them), so a single jump of L does not flag a laminar run
        and the verdict does not depend on the run length —, ``perturbation_growth_per_s``
        (the same / dt), ``perturbation_window_steps`` (the steps fitted),
        ``perturbation_mean_growth_per_step`` (L_n / n over the run, the former rate),
        ``perturbation_largest_step_growth``, ``perturbation_stable``;
        ``energy_ratio`` (final / initial kinetic energy, when the initial one is > 0),
        ``enstrophy_ratio``; for ``initial=mesh_field`` ``initial_vorticity_max_abs`` (max |w0| of
        the start, mean removed, 1/s: the number the round-off log line and the figure title
        say) and ``initial_vorticity_round_off``; ``max_abs_divergence`` (over the run), ``circulation_drift``
        (|Σ⋆0 w| at the end, closed surfaces), ``steps_per_second``, ``obtuse_triangles``.
        Series (every ``record_every`` steps): ``vorticity`` (n0), ``flux`` (n1) and the scalars
        ``time``, ``kinetic_energy``, ``enstrophy``, ``total_circulation``, ``max_abs_divergence``,
        ``vorticity_min``, ``vorticity_max``. Fields: the final ``vorticity``, ``psi``, ``flux``.
        """
        K = ctx.complex
        fluid, stepper, shadow = self._simulation(ctx)
        first = stepper.last
        # the vorticity the fluid starts from (after its mean is removed): the one number the log and title say
        start = max(abs(first["vorticity_min"]), abs(first["vorticity_max"]))
        # a chained field without curl starts the fluid from round-off: which ratios say nothing
        round_off = self._round_off_start(ctx, ctx.dec, ctx.meta["field"], start) if self.initial == "mesh_field" \
            else ()
        report = run_steps(stepper, self.total_steps, progress=ctx.progress, record=ctx.record,
                           record_every=self.record_every, checkpoint=ctx.checkpoint, desc="fluid")
        metrics = fluid_metrics(first, stepper.last, max_divergence=stepper.max_divergence, seconds=report.seconds,
                                step_seconds_max=report.step_seconds_max, obtuse_triangles=fluid.obtuse_triangles,
                                closed=K.border_faces()[0].size == 0, reason=report.reason,
                                chaos=shadow.metrics() if shadow is not None else None,
                                max_growth_per_step=self.shadow_max_growth_per_step, round_off=round_off)
        if self.initial == "mesh_field":
            metrics["initial_vorticity_round_off"] = bool(round_off)
            metrics["initial_vorticity_max_abs"] = start
        if report.resumed_from_step is not None:
            metrics["resumed_from_step"] = report.resumed_from_step
        if not fluid.closed:  # the wall condition app.walls resolved to (a closed surface has no wall)
            metrics["walls"] = str(fluid.walls)
        fields = {"vorticity": fluid.vorticity, "psi": fluid.psi, "flux": FieldOnEdges(fluid.flux)}
        return Result(fields=fields, metrics=metrics, figures=self._figures(K, start if round_off else None))

    def _simulation(self, ctx: Context):
        """(fluid, stepper, shadow): the :class:`~decrun.methods.fluid.simulation.VorticityFluid`
        from the options and the initial vorticity, the stirs' force fluxes, the shadow (None
        without ``shadow``) and the :class:`~decrun.methods.fluid.stepper.FluidStepper` of them."""
        from decrun.methods.fluid import initial as initial_vorticity
        from decrun.methods.fluid.simulation import VorticityFluid

        dec = ctx.dec
        w0 = self._initial_vorticity(dec, initial_vorticity, ctx.meta)
        fluid = VorticityFluid(dec, ctx.new_solver, dt=self.dt, viscosity=self.viscosity,
                               inflow_velocity=list(self.inflow) or None, initial_vorticity=w0,
                               options=self.scheme())
        if fluid.obtuse_triangles:
            ctx.log(f"fluid: {fluid.obtuse_triangles} obtuse triangles — their circumcentric dual cells turn inside "
                    "out (§7.3); use a mesh without obtuse triangles (e.g. mesh=channel, or mesh.noise=0 on the "
                    "icosphere)")
        forces = [(stir, initial_vorticity.stroke_force(dec, np.asarray(stir.points, dtype=np.float64), stir.strength))
                  for stir in self.stirs]
        shadow = None
        if self.shadow:
            from decrun.methods.fluid.shadow import Shadow

            shadow = Shadow(fluid, self.shadow_perturbation, seed=self.seed + 1,
                            max_growth_per_step=self.shadow_max_growth_per_step,
                            window_steps=self.shadow_window_steps)
        return fluid, FluidStepper(fluid, forces, shadow), shadow

    def _figures(self, K, round_off_start: float | None = None) -> dict:
        """By kind: vorticity snapshots (and the animation), looking towards the strokes in 3-D;
        ``round_off_start``: max |w0| of a start that is round-off, said in the title."""
        title = f"vorticity, dt={self.dt:g}, ν={self.viscosity:g}"
        if round_off_start is not None:  # the colours show round-off, not vortices: say so on the figure
            title += f" — round-off start (max |w0| = {round_off_start:.1e})"
        strokes = [np.asarray(stir.points, dtype=np.float64) for stir in self.stirs]
        towards = np.concatenate(strokes).mean(axis=0) if strokes and K.embedding_dim == 3 else None
        view = {"towards": None if towards is None or not np.linalg.norm(towards) > 0 else towards.tolist()}
        figures = {"vorticity": Figure.of_kind("snapshots", name="vorticity", count=int(self.snapshots), title=title,
                                               **view)}
        if self.animation:
            figures["vorticity_animation"] = Figure.of_kind("animation", name="vorticity", title="vorticity", **view)
        return figures

    def _round_off_start(self, ctx: Context, dec, field: dict, size: float) -> tuple[str, ...]:
        """The diagnostics whose initial value is round-off for a chained start
        (:func:`field_cancellation` ≤ :data:`ROUND_OFF`): the enstrophy, and the kinetic energy
        too without inflow (with inflow the harmonic part carries it). Logged as one line with
        ``size``, max |w0| of the fluid's start (the metric ``initial_vorticity_max_abs``, 1/s)."""
        cancellation = field_cancellation(dec, field)
        if cancellation > ROUND_OFF:
            return ()
        ctx.log(f"fluid: app.initial=mesh_field: the vorticity of mesh.field={field['name']} is round-off "
                f"(max |w0| = {size:.1e}, {cancellation:.0e} of the terms it sums: the field is curl-free); the "
                "fluid starts at rest up to round-off, so energy_ratio and enstrophy_ratio are left out "
                "(initial_vorticity_round_off: true). A field with vorticity: e.g. app=vector_field "
                "\"app.vortices=[{point: [0, 0, 1], curl: 1.0}, {point: [0, 0, -1], curl: -1.0}]\"")
        return ("enstrophy",) if self.inflow else ("enstrophy", "kinetic_energy")

    def _initial_vorticity(self, dec: DEC, initial_vorticity, meta=None) -> np.ndarray:
        if self.initial == "mesh_field":
            return vorticity_of_field(dec, (meta or {})["field"])
        if self.initial == "zero":
            return np.zeros(dec.K.num_simplices(0))
        if self.initial == "rotation":
            return initial_vorticity.solid_body_rotation(dec, angular_velocity=self.initial_strength)
        if self.initial == "vortex_pair":
            w, _ = initial_vorticity.sphere_vortex_pair(dec, np.radians(self.vortex_separation_deg),
                                                        self.initial_strength, self.vortex_radius)
            return w
        return initial_vorticity.random_vorticity(dec, seed=self.seed, amplitude=self.initial_strength)


def vorticity_of_field(dec: DEC, field: dict) -> np.ndarray:
    """(n0,) initial vorticity from a field of a previous run (``mesh=result mesh.field=...``):
    a per-vertex field is the vorticity itself; a circulation 1-form ω per edge (app=vector_field's
    ``omega``, the line integrals of its tangent field u) gives by Stokes the exact integral of
    curl u over each triangle, (d1 ω)_f, and the vorticity at a vertex is their mean over its
    triangles, w_v = Σ_{f ∋ v} (d1 ω)_f / Σ_{f ∋ v} |f| (first-order accurate)."""
    K = dec.K
    values, where, name = np.asarray(field["values"], dtype=np.float64), field["on"], field["name"]
    if where == "vertices":
        if values.shape != (K.num_simplices(0),):
            raise ConfigError(f"mesh.field={name}: a per-vertex vorticity needs one value per vertex, got {values.shape}")
        return values
    if where != "edges" or values.shape != (K.num_simplices(1),):
        raise ConfigError(f"mesh.field={name}: the fluid starts from a per-vertex vorticity or a 1-form per edge "
                          f"(a circulation, e.g. omega of app=vector_field), not a field on {where} of shape "
                          f"{values.shape}")
    if not np.array_equal(np.asarray(field["edges"]), K.simplices(1)):
        raise ConfigError(f"mesh.field={name}: the stored edge list differs from this mesh's edges")
    # ∫_f curl·N dA per triangle, N the complex's orientation (d1 = δ2ᵀ carries it for top simplices)
    curl = dec.d(1) @ values
    faces = K.simplices(2)
    n0 = K.num_simplices(0)
    area = np.bincount(faces.ravel(), weights=np.repeat(K.top_volumes, 3), minlength=n0)
    return np.bincount(faces.ravel(), weights=np.repeat(curl, 3), minlength=n0) / area


def field_cancellation(dec, field: dict) -> float:
    """How much of a chained initial field survives as vorticity, a ratio in [0, 1].

    For a circulation 1-form ω per edge the vorticity is made of the sums (d1 ω)_f of its
    three edge values around each triangle; the ratio is max_f |(d1 ω)_f| / max_f (|d1| |ω|)_f
    (0 for an exact gradient, ~1e-16 when the sums cancel to round-off, O(1) for a field with
    vortices). A per-vertex vorticity is taken as it is: 1 unless it is exactly zero (0). The
    field is checked by :func:`vorticity_of_field` (which the fluid's start went through)."""
    values = np.asarray(field["values"], dtype=np.float64)
    if field["on"] != "edges":
        return 1.0 if values.size and np.abs(values).max() > 0 else 0.0
    d1 = dec.d(1)
    terms = float((abs(d1) @ np.abs(values)).max()) if values.size else 0.0
    return float(np.abs(d1 @ values).max()) / terms if terms > 0 else 0.0
