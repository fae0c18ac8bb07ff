"""``app=smoothing``: mesh smoothing by mean curvature flow (thesis §1.3).

The flow and its measurements are :mod:`decrun.methods.mean_curvature_flow`; this adapter
runs the steps, rescales after every step (the thesis' note: the flow shrinks the mesh)
about the ⋆0-weighted centroid — ``rescale: volume`` keeps the enclosed volume (closed
surfaces only), ``area`` the surface area, ``none`` nothing, ``auto`` (default) volume on
closed surfaces in 3-D and area on open or planar ones — detects blow-up and records
``area``, ``volume``, ``roughness`` and ``distortion`` per step (``ctx.record``).

Blow-up: a step *diverges* when a coordinate is non-finite, the volume cannot be rescaled,
or the roughness R exceeds ``blowup_factor`` × its initial value; the run then stops and
records ``stable: false`` and ``diverged_at_step``.

Note: with the operator fixed on the input mesh, a *long* implicit run (dt·steps ≫ 1/λ₁)
drifts towards the lowest eigenvector of L and flattens even though each step is a
contraction; watch ``distortion_final``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from decrun.apps.base import App, Context, Figure, Output, Result
from decrun.core.choices import Choice
from decrun.errors import ConfigError
from decrun.methods.mean_curvature_flow import (
    MeanCurvatureFlow,
    Scheme,
    SmoothingStepper,
    choose_time_step,
    smallest_positive_eigenvalue,
)
from decrun.methods.smoothing_metrics import smoothing_metrics
from decrun.methods.stepping import run_steps


class DtUnit(Choice):
    """``app.dt_unit``: what app.dt_factor multiplies when app.dt is null — ``critical`` 2/λ_max
    (explicit Euler's stability limit), ``resolution`` 2h̄²/π²
    (:func:`decrun.methods.mean_curvature_flow.resolution_dt`), ``auto`` critical for explicit and
    resolution for implicit Euler."""

    auto = "auto"
    critical = "critical"
    resolution = "resolution"


class Rescale(Choice):
    """``app.rescale``: what is kept after every step (``auto``: volume on closed surfaces in 3-D,
    area on open or planar ones)."""

    auto = "auto"
    volume = "volume"
    area = "area"
    none = "none"


@dataclass
class Smoothing(App):
    """Options of ``app=smoothing`` (conf/app/smoothing.yaml)."""

    name = "smoothing"
    headline_metrics = ("stable", "unstable_reason", "distance_to_clean_rms", "normal_deviation_to_clean_deg",
                        "normal_change_deg", "area_ratio", "dt_over_critical")
    form_degrees = (0,)
    scheme: Scheme = Scheme.implicit  # implicit | explicit (Euler, §1.3)
    #: time step (model units squared: L has units 1/length²); null: dt_factor × the dt_unit
    dt: Optional[float] = None
    #: with dt null, the time step as a multiple of ``dt_unit`` — scale-free, so every mesh
    #: gets the same relative step (0.75: the default run)
    dt_factor: float = 0.75
    #: auto | critical | resolution (:class:`DtUnit`): explicit Euler must stay below its
    #: critical step; implicit Euler is stable at any step, and its step should follow the
    #: scale of the noise (the mean edge), not the worst triangle, which sets 2/λ_max
    dt_unit: DtUnit = DtUnit.auto
    steps: int = 10
    #: auto (volume on closed surfaces in 3-D, area on open or planar ones) | volume | area |
    #: none, applied after every step
    rescale: Rescale = Rescale.auto
    blowup_factor: float = 10.0  # a step diverges when the roughness R exceeds this × R_0
    critical_dt: bool = True  # compute the explicit stability limit 2/λ_max (one eigsh)
    #: also record the positions (n0, d) at every step (the series ``vertices``): export=xdmf
    #: then holds the flow as a time series; off by default (n0·d floats a step on disk)
    record_vertices: bool = False

    def __post_init__(self):
        self.scheme = Scheme.of(self.scheme, "app.scheme")  # also for Python callers (strings)
        self.dt_unit = DtUnit.of(self.dt_unit, "app.dt_unit")
        self.rescale = Rescale.of(self.rescale, "app.rescale")
        if self.dt is not None and not (self.dt > 0 and math.isfinite(self.dt)):
            raise ConfigError(f"app.dt: the time step must be > 0 (or null for app.dt_factor), got {self.dt}")
        if not (self.dt_factor > 0 and math.isfinite(self.dt_factor)):
            raise ConfigError(f"app.dt_factor: must be > 0, got {self.dt_factor}")
        if self.steps < 0:
            raise ConfigError(f"app.steps: must be >= 0, got {self.steps}")
        if not self.blowup_factor > 1:
            raise ConfigError(f"app.blowup_factor: must be > 1, got {self.blowup_factor}")

    @property
    def resolved_dt_unit(self) -> str:
        """``critical`` or ``resolution``: app.dt_unit with ``auto`` resolved by the scheme."""
        if self.dt_unit != DtUnit.auto:
            return str(self.dt_unit)
        return "critical" if self.scheme == "explicit" else "resolution"

    def resolved_rescale(self, has_volume: bool) -> str:
        """app.rescale with ``auto`` resolved: ``volume`` on closed surfaces in 3-D, else ``area``."""
        return str(self.rescale) if self.rescale != Rescale.auto else ("volume" if has_volume else "area")

    def check(self, K, dec) -> None:
        """Before any work: app.rescale=volume needs a closed surface in 3-D, and the time step
        (:func:`~decrun.methods.mean_curvature_flow.choose_time_step`, with the eigen-solve for
        2/λ_max) must exist; :meth:`run` steps with the one decided here."""
        closed = not bool(K.border_vertices().any())
        if self.rescale == "volume" and not (closed and K.embedding_dim == 3):
            raise ConfigError("app.rescale=volume needs a closed surface in 3-D; this mesh has a border "
                              "or is planar: use `app.rescale=auto` (area on open surfaces)")
        step = choose_time_step(dec, str(self.scheme), dt=self.dt, factor=self.dt_factor,
                                unit=self.resolved_dt_unit, critical=self.critical_dt)
        if step.dt is None and not self.critical_dt:
            # a step computed from this mesh: Gershgorin's bound, ≤ the critical step, no eigen-solve
            value = f"`app.dt={step.safe:.3g}` (Gershgorin's bound, ≤ the explicit critical step of this mesh) or " \
                if np.isfinite(step.safe) else ""
            raise ConfigError(f"app.critical_dt=false leaves no critical step for app.dt_factor: give the step "
                              f"itself, {value}use `app.critical_dt=true`")
        if step.dt is None:
            raise ConfigError(
                f"app.dt_factor: the explicit critical step 2/λ_max does not exist for operator="
                f"{dec.star_variant.name} on this mesh (⋆0 is not positive on {step.nonpositive_star0} vertices); "
                "use `operator=mixed_area` (positive ⋆0, so app.dt_factor scales its critical step); with "
                "a negative ⋆0 a given app.dt may diverge (the implicit matrix is indefinite)")
        self._time_step = (dec, step)

    def outputs(self) -> dict[str, Output]:
        """The input and smoothed positions and the displacement per vertex; the (oriented) faces."""
        return {"vertices_initial": Output("0", None), "vertices_final": Output("0", None),
                "faces": Output("connectivity", 3), "displacement": Output("0")}

    def run(self, ctx: Context) -> Result:
        """Smooth the mesh; see the module docstring.

        Metrics: :func:`decrun.methods.smoothing_metrics.smoothing_metrics` — ``area_ratio``,
        ``volume_drift_rel`` (closed surfaces), ``stable`` (false when a step blew up or the
        result is degenerate), ``unstable_reason`` and ``diverged_at_step`` (only when not
        stable), ``steps_done`` (the diverging step included), ``rescale`` (the resolved
        choice), ``roughness_ratio``, ``distortion_final``, ``dt_critical_explicit``,
        ``dt_over_critical``, ``dt_resolution``, ``dt_unit`` (only when app.dt is null),
        ``normal_change_deg``, ``distance_to_clean_rms`` (+ ``_initial``, only with noise),
        ``normal_deviation_to_clean_deg`` (+ ``_initial``), ``negative_star1_fraction``,
        ``setup_seconds``, ``solve_seconds``.
        Series (recorded per step, the initial state as step 0): ``area``, ``volume``,
        ``roughness``, ``distortion``; with ``record_vertices`` the positions ``vertices``
        (n0, d).
        Fields: ``vertices_initial``, ``vertices_final`` (n0, d), ``faces`` (n2, 3),
        ``displacement`` (n0,).
        """
        K, dec = ctx.complex, ctx.dec
        if getattr(self, "_time_step", (None,))[0] is not dec:  # run without the runner's checks
            self.check(K, dec)
        step = self._time_step[1]
        faces = K.oriented_simplices()
        vertices = np.array(K.vertices, dtype=np.float64)
        has_volume = not bool(K.border_vertices().any()) and vertices.shape[1] == 3
        rescale = self.resolved_rescale(has_volume)
        t0 = time.perf_counter()
        assert step.dt is not None  # check() refused a run without a step
        with ctx.task(f"factorizing ({self.scheme} Euler)"):
            flow = MeanCurvatureFlow(dec, str(self.scheme), step.dt,
                                     ctx.new_solver() if self.scheme == "implicit" else None)
        setup_seconds = time.perf_counter() - t0
        stepper = SmoothingStepper(flow, vertices, faces, flow.centroid(vertices), rescale, has_volume,
                                   self.blowup_factor, record_vertices=self.record_vertices)
        report = run_steps(stepper, int(self.steps), progress=ctx.progress, record=ctx.record,
                           checkpoint=ctx.checkpoint, desc=f"smoothing ({self.scheme})", check_finite=False)
        edges = K.simplices(1)
        metrics = smoothing_metrics(stepper, report, time_step=step, scheme=str(self.scheme), rescale=rescale,
                                    cot_weights=-np.asarray(flow.S[edges[:, 0], edges[:, 1]]).ravel(),
                                    clean=ctx.meta.get("clean_vertices"), setup_seconds=setup_seconds)
        fields = {"vertices_initial": vertices, "vertices_final": stepper.v, "faces": faces,
                  "displacement": np.linalg.norm(stepper.v - vertices, axis=1)}
        return Result(fields=fields, metrics=metrics, figures=self._figures(stepper, metrics, has_volume))

    def _figures(self, stepper, metrics: dict, has_volume: bool) -> dict:
        """By kind: the input beside the last finite result (shared axes), and the measures per step."""
        label = f"{self.scheme} Euler, dt={metrics['dt']:.3g}, rescale={metrics['rescale']}"
        diverged_at = metrics.get("diverged_at_step")
        state = f"{metrics['steps_done']} steps" + (
            "" if metrics["stable"] else f" (diverged at step {diverged_at})" if diverged_at is not None
            else " (degenerate)")
        shown = ["area", "volume", "roughness"] if has_volume else ["area", "roughness"]
        return {
            "smoothing": Figure.of_kind(
                "before_after", vertices_before=stepper.vertices, vertices_after=stepper.last_finite,
                faces=stepper.faces, share_axes=True, titles=("input", f"after {state}"),
                suptitle=f"mean curvature flow (§1.3): {label}"),
            "smoothing_series": Figure.of_kind(
                "series", series={name: np.array(stepper.series[name]) for name in shown}, title=label,
                floors={"roughness": (smallest_positive_eigenvalue(stepper.flow.S, stepper.flow.mass)
                                      / stepper.first["roughness"],
                                      "roughness bound λ1/R0 (R ≥ λ1 > 0 of L: no smoothing takes it to 0)")}),
        }
