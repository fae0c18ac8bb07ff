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
    enclosed_volume,
    gershgorin_safe_dt,
    resolution_dt,
    smallest_positive_eigenvalue,
    surface_area,
)
from decrun.methods.smoothing_metrics import degeneration, normal_deviation_deg
from decrun.methods.stepping import run_steps


class DtUnit(Choice):
    """``app.dt_unit``: what app.dt_factor multiplies when app.dt is null — ``critical`` 2/λ_max
    (explicit Euler's stability limit), ``resolution`` 2h̄²/π² (:func:`resolution_dt`), ``auto``
    critical for explicit and resolution for implicit Euler."""

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

    def check(self, K, dec) -> None:
        if self.dt is None and self.resolved_dt_unit == "critical" and not self.critical_dt:
            # a step computed from this mesh: Gershgorin's bound, ≤ the critical step, no eigen-solve
            safe = gershgorin_safe_dt(dec.laplacian_symmetric(0), dec.star_diagonal_or_none(0))
            value = f"`app.dt={safe:.3g}` (Gershgorin's bound, ≤ the explicit critical step of this mesh) or " \
                if np.isfinite(safe) else ""
            raise ConfigError(f"app.critical_dt=false leaves no critical step for app.dt_factor: give the step "
                              f"itself, {value}use `app.critical_dt=true`")
        closed = not bool(K.border_vertices().any())
        if self.rescale == "volume" and not (closed and K.embedding_dim == 3):
            raise ConfigError("app.rescale=volume needs a closed surface in 3-D; this mesh has a border "
                              "or is planar: use `app.rescale=auto` (area on open surfaces)")

    def _divergence_reason(self, step: int, flow: MeanCurvatureFlow) -> str:
        """``diverged at step N``, with the cause and the override that avoids it when ⋆0 ≤ 0
        makes the implicit matrix M + dt S indefinite (the circumcentric ⋆0 on scans)."""
        reason = f"diverged at step {step}"
        nonpositive = int(np.sum(flow.M <= 0)) if flow.M is not None else 0
        if nonpositive and self.scheme == "implicit":
            reason += (f" (⋆0 ≤ 0 on {nonpositive} vertices: M + dt S is indefinite; "
                       "`operator=mixed_area` has a positive ⋆0)")
        return reason

    def outputs(self) -> dict[str, Output]:
        """The input and smoothed positions and the displacement per vertex; the (oriented) faces."""
        return {"vertices_initial": Output("0", None), "vertices_final": Output("0", None),
                "faces": Output("connectivity", 3), "displacement": Output("0")}

    def run(self, ctx: Context) -> Result:
        """Smooth the mesh; see the module docstring.

        Metrics: ``area_ratio`` (final/initial area), ``volume_drift_rel`` (|V_end − V_0|/|V_0|,
        closed surfaces only), ``stable`` (false when a step blew up or the result is degenerate,
        :func:`decrun.methods.smoothing_metrics.degeneration`), ``unstable_reason`` (only when
        not stable), ``diverged_at_step`` (only when a step blew up), ``steps_done``
        (steps computed and recorded, the diverging one included, so it equals
        ``diverged_at_step`` when unstable), ``rescale`` (the resolved choice),
        ``roughness_ratio`` (R_end / R_0), ``distortion_final`` (ρ, 1 for the input),
        ``dt_critical_explicit`` and ``dt_over_critical``, ``dt_resolution`` (2h̄²/π²,
        :func:`resolution_dt`) and ``dt_unit`` (the resolved unit, only when app.dt is null),
        ``normal_change_deg`` (area-weighted face-normal angle between input and result, 3-D
        only, when stable: how much the shading changed, no clean mesh needed),
        ``distance_to_clean_rms`` and
        ``distance_to_clean_rms_initial`` (RMS vertex distance to the noise-free mesh / its
        bounding-box diagonal, only with noise; the final one only when stable; it adds the
        flow's shrinkage and drift to the noise), ``normal_deviation_to_clean_deg`` (+
        ``_initial``; area-weighted face-normal angle to the clean mesh, 3-D only, final only
        when stable: what denoising removes, blind to translation and scale),
        ``negative_star1_fraction``,
        ``setup_seconds``, ``solve_seconds``.
        Series (recorded per step, the initial state as step 0): ``area``, ``volume``,
        ``roughness``, ``distortion``.
        Fields: ``vertices_initial``, ``vertices_final`` (n0, d), ``faces`` (n2, 3),
        ``displacement`` (n0,).
        """
        K, dec = ctx.complex, ctx.dec
        faces = K.oriented_simplices()
        vertices = np.array(K.vertices, dtype=np.float64)
        has_volume = not bool(K.border_vertices().any()) and vertices.shape[1] == 3
        rescale = str(self.rescale) if self.rescale != Rescale.auto else ("volume" if has_volume else "area")

        t0 = time.perf_counter()
        dt_crit = float("nan")
        if self.critical_dt:  # 2/λ_max of S φ = λ ⋆0 φ (one eigen-solve per DEC, kept by it)
            with ctx.task("critical time step 2/λ_max (eigen-solve)"):
                dt_crit = dec.require(("mcf_critical_dt",),
                                      lambda: MeanCurvatureFlow(dec, "explicit", 1.0).critical_dt())
        dt = self.dt
        dt_resolution = resolution_dt(K.mean_edge_length)
        if dt is None and self.resolved_dt_unit == "resolution":
            dt = self.dt_factor * dt_resolution
        elif dt is None:
            if not (np.isfinite(dt_crit) and dt_crit > 0):
                raise ConfigError(
                    f"app.dt_factor: the explicit critical step 2/λ_max does not exist for operator="
                    f"{dec.star_variant.name} on this mesh (⋆0 is not positive on "
                    f"{int(np.sum(dec.star_diagonal_or_none(0) <= 0)) if dec.star_is_diagonal(0) else 0} vertices); "
                    "use `operator=mixed_area` (positive ⋆0, so app.dt_factor scales its critical step); with "
                    "a negative ⋆0 a given app.dt may diverge (the implicit matrix is indefinite)")
            dt = self.dt_factor * dt_crit
        with ctx.task(f"factorizing ({self.scheme} Euler)"):
            flow = MeanCurvatureFlow(dec, str(self.scheme), dt, ctx.new_solver() if self.scheme == "implicit" else None)
        setup_seconds = time.perf_counter() - t0
        centroid = flow.centroid(vertices)

        stepper = SmoothingStepper(flow, vertices, faces, centroid, rescale, has_volume, self.blowup_factor)
        first = stepper.first
        report = run_steps(stepper, int(self.steps), progress=ctx.progress, record=ctx.record,
                           checkpoint=ctx.checkpoint, desc=f"smoothing ({self.scheme})", check_finite=False)
        v, last_finite, series = stepper.v, stepper.last_finite, stepper.series
        diverged_at = report.diverged_at_step  # None: no step blew up
        solve_seconds = report.seconds
        stable = diverged_at is None
        # a flow that did not blow up may still have collapsed the surface (a needle, a sheet)
        degenerate = degeneration(vertices, v, faces, has_volume) if stable else ""
        stable = stable and not degenerate
        last = {name: values[-1] for name, values in series.items()}

        edges = K.simplices(1)
        weights = -np.asarray(flow.S[edges[:, 0], edges[:, 1]]).ravel()  # cot weights on the mesh edges
        metrics = {
            "dt": dt,
            "rescale": rescale,
            "stable": stable,
            **({"diverged_at_step": diverged_at} if diverged_at is not None else {}),
            **({"unstable_reason": self._divergence_reason(diverged_at, flow) if diverged_at is not None else
                f"degenerate: {degenerate}"} if not stable else {}),
            "steps_done": len(series["area"]) - 1,
            "area_ratio": last["area"] / first["area"],
            "roughness_ratio": last["roughness"] / first["roughness"],
            "distortion_final": last["distortion"],
            "dt_critical_explicit": dt_crit,
            "dt_resolution": dt_resolution,
            **({"dt_unit": self.resolved_dt_unit} if self.dt is None else {}),
            "negative_star1_fraction": float(np.mean(weights < 0)),
        }
        if np.isfinite(dt_crit) and dt_crit > 0:
            metrics["dt_over_critical"] = dt / dt_crit
        if flow.M is not None:
            metrics["nonpositive_star0_vertices"] = int(np.sum(flow.M <= 0))
        if stable and vertices.shape[1] == 3:
            metrics["normal_change_deg"] = normal_deviation_deg(v, vertices, faces)
        if has_volume:
            metrics["volume_drift_rel"] = abs(last["volume"] - first["volume"]) / abs(first["volume"])
        clean = ctx.meta.get("clean_vertices")
        if clean is not None and np.shape(clean) == vertices.shape:
            clean = np.asarray(clean)
            diagonal = float(np.linalg.norm(clean.max(axis=0) - clean.min(axis=0)))

            def rms(x):
                return float(np.sqrt(np.mean(np.sum((x - clean) ** 2, axis=1))) / diagonal)

            if stable:  # a diverged or degenerate run has no meaningful distance: absent
                metrics["distance_to_clean_rms"] = rms(v)
            metrics["distance_to_clean_rms_initial"] = rms(vertices)
            if vertices.shape[1] == 3:  # planar meshes have one normal: absent
                if stable:
                    metrics["normal_deviation_to_clean_deg"] = normal_deviation_deg(v, clean, faces)
                metrics["normal_deviation_to_clean_deg_initial"] = normal_deviation_deg(vertices, clean, faces)
        metrics["setup_seconds"] = setup_seconds
        metrics["solve_seconds"] = solve_seconds
        metrics["step_seconds_max"] = report.step_seconds_max
        if report.resumed_from_step is not None:
            metrics["resumed_from_step"] = report.resumed_from_step

        series = {name: np.array(values) for name, values in series.items()}
        fields = {"vertices_initial": vertices, "vertices_final": v, "faces": faces,
                  "displacement": np.linalg.norm(v - vertices, axis=1)}
        label = f"{self.scheme} Euler, dt={dt:.3g}, rescale={rescale}"
        state = f"{metrics['steps_done']} steps" + (
            "" if stable else f" (diverged at step {diverged_at})" if diverged_at is not None else " (degenerate)")
        shown = ["area", "volume", "roughness"] if has_volume else ["area", "roughness"]
        figures = {
            "smoothing": Figure("decrun.runner.plots.common.before_after", dict(
                vertices_before=vertices, vertices_after=last_finite, faces=faces, share_axes=True,
                titles=("input", f"after {state}"), suptitle=f"mean curvature flow (§1.3): {label}")),
            "smoothing_series": Figure("decrun.runner.plots.common.plot_series", dict(
                series={name: series[name] for name in shown}, title=label,
                floors={"roughness": (smallest_positive_eigenvalue(flow.S, flow.mass) / first["roughness"],
                                      "roughness bound λ1/R0 (R ≥ λ1 > 0 of L: no smoothing takes it to 0)")})),
        }
        return Result(fields=fields, metrics=metrics, figures=figures)


class SmoothingStepper:
    """The mean curvature flow as a :class:`decrun.methods.stepping.Stepper`: one step is
    ``flow.step`` then the rescale about ``centroid`` (``volume``: by ∛(V_0/V), ``area``: by
    √(A_0/A), ``none``), then the measures ``area``, ``volume``, ``roughness``, ``distortion``
    (NaN when the coordinates are not finite). It blows up when the coordinates are not
    finite, the volume cannot be rescaled (V ≤ 0), the area is not finite or the roughness
    exceeds ``blowup_factor`` × R_0; the diverging step is recorded (its measures NaN when
    the coordinates are). State: ``v`` (n0, d), ``last_finite`` (n0, d) and the measures so
    far (``series``, for the figures and the final ratios: four floats per step)."""

    record_divergent_step = True
    #: the measures so far grow by one a step (and hold NaN volumes on open surfaces)
    state_variable = ("series",)

    def __init__(self, flow, vertices, faces, centroid, rescale: str, has_volume: bool, blowup_factor: float):
        self.flow, self.faces, self.centroid = flow, faces, centroid
        self.rescale, self.has_volume, self.blowup_factor = rescale, has_volume, float(blowup_factor)
        self.first = self.measure(vertices)
        self.now = dict(self.first)
        self.series = {name: [value] for name, value in self.first.items()}
        self.v = vertices.copy()
        self.last_finite = self.v

    def measure(self, v) -> dict:
        faces = self.faces
        return {"area": surface_area(v, faces),
                "volume": enclosed_volume(v, faces) if self.has_volume else float("nan"),
                "roughness": self.flow.roughness(v, self.centroid), "distortion": self.flow.distortion(v, faces)}

    def values(self) -> dict:
        return self.now

    def step(self, n: int) -> str:
        v = self.flow.step(self.v)
        first, centroid = self.first, self.centroid
        reason = "" if np.all(np.isfinite(v)) else "non-finite coordinates"
        if not reason and self.rescale == "volume":
            volume = enclosed_volume(v, self.faces)
            if not volume > 0:  # flattened or turned inside out: cannot be rescaled
                reason = f"enclosed volume {volume:.3g} ≤ 0 cannot be rescaled"
            else:
                v = centroid + np.cbrt(first["volume"] / volume) * (v - centroid)
        elif not reason and self.rescale == "area":
            area = surface_area(v, self.faces)
            if area > 0:
                v = centroid + np.sqrt(first["area"] / area) * (v - centroid)
        finite = bool(np.all(np.isfinite(v)))
        self.now = self.measure(v) if finite else {name: float("nan") for name in first}
        for name, value in self.now.items():
            self.series[name].append(value)
        self.v = v
        if finite:
            self.last_finite = v
        if not reason and not np.isfinite(self.now["area"]):
            reason = "non-finite area"
        if not reason and not self.now["roughness"] <= self.blowup_factor * first["roughness"]:
            reason = f"roughness {self.now['roughness']:.3g} > app.blowup_factor × R_0"
        return reason

    def state_dict(self) -> dict:
        return {"v": self.v, "last_finite": self.last_finite,
                "now": {name: float(value) for name, value in self.now.items()},
                "series": {name: np.asarray(values, dtype=np.float64) for name, values in self.series.items()}}

    def load_state(self, state: dict) -> None:
        self.v = np.array(state["v"], dtype=np.float64)
        self.last_finite = np.array(state["last_finite"], dtype=np.float64)
        self.now = {name: float(state["now"][name]) for name in self.first}
        self.series = {name: [float(x) for x in state["series"][name]] for name in self.first}
