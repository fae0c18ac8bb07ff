"""What smoothing did to a mesh: denoising against the clean mesh, and degeneration.

The RMS distance to the clean mesh mixes two things: the noise that smoothing removes and
the shrinkage/drift that the flow adds (an open mesh's border pulls in, a torus thins).
Two measures see only the noise:

* :func:`normal_deviation_deg` — the area-weighted mean angle between each triangle's normal
  and the clean triangle's normal (invariant to translation, rotation-free drift and scale);
* :func:`aligned_rms_distance` — the RMS vertex distance after the best similarity transform
  (rotation, uniform scale, translation; Umeyama 1991) maps the mesh onto the clean one.

:func:`degeneration` names why a finished flow is no longer a usable surface (the shape
collapsed into a needle or a sheet, or most triangles lost their angles) — a run that did not
blow up is then still not ``stable``.

:func:`smoothing_metrics` gathers the metrics of one ``app=smoothing`` run from the stepper's
measures, the stepping driver's report and the time step.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from decrun.core.geometry import corner_angles, embed3, triangle_areas
from decrun.methods.mean_curvature_flow import enclosed_volume, surface_area

__all__ = ["normal_deviation_deg", "aligned_rms_distance", "isoperimetric_quotient", "degeneration",
           "smoothing_metrics", "divergence_reason"]

#: a smoothed surface is degenerate when its isoperimetric quotient 36πV²/A³ fell below this
#: fraction of the input's (a sphere is 1; the bone's needle at dt = 0.05 is ~1e-11 of its input)
QUOTIENT_COLLAPSE = 1e-2
#: ... or (any surface) when its area over its squared bounding-box diagonal fell below this
#: fraction of the input's (a sheet rolled into a needle; scale-free, so rescaling is irrelevant)
SPREAD_COLLAPSE = 1e-2
#: ... or when more than this fraction of triangles has a corner below 1° (and the input had not)
SLIVER_FRACTION = 0.5
SLIVER_ANGLE = np.radians(1.0)


def normal_deviation_deg(vertices: np.ndarray, clean: np.ndarray, faces: np.ndarray) -> float:
    """Σ_f A_f ∠(n_f, n_f^clean) / Σ_f A_f in degrees, A_f the clean triangle areas.

    vertices, clean: (n0, 3) positions of the same triangulation ``faces`` (n2, 3).
    0 for a mesh that is the clean one up to translation and scale.
    """
    def normals(points):  # a collapsed triangle (zero normal) deviates by 90°
        x = embed3(points)
        normal = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        return np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)

    cosine = np.clip(np.sum(normals(vertices) * normals(clean), axis=1), -1.0, 1.0)
    area = triangle_areas(clean, faces)
    return float(np.degrees(np.sum(area * np.arccos(cosine)) / np.sum(area)))


def aligned_rms_distance(vertices: np.ndarray, clean: np.ndarray) -> float:
    """min over similarities T of sqrt(mean_i |T(v_i) − c_i|²) / (bounding-box diagonal of clean).

    T(v) = s R v + t with R a rotation (det +1), s > 0: Umeyama's closed form from the SVD of
    the cross-covariance of the centred point sets. vertices, clean: (n0, d).
    """
    x = vertices - vertices.mean(axis=0)
    y = clean - clean.mean(axis=0)
    U, sigma, Vt = np.linalg.svd(y.T @ x)
    sign = np.ones(len(sigma))
    sign[-1] = np.sign(np.linalg.det(U @ Vt)) or 1.0
    rotation = (U * sign) @ Vt
    variance = float(np.sum(x * x))
    scale = float(np.sum(sigma * sign)) / variance if variance > 0 else 0.0
    residual = y - scale * x @ rotation.T
    diagonal = float(np.linalg.norm(clean.max(axis=0) - clean.min(axis=0)))
    return float(np.sqrt(np.mean(np.sum(residual ** 2, axis=1))) / diagonal)


def isoperimetric_quotient(area: float, volume: float) -> float:
    """36 π V² / A³: 1 for a sphere, → 0 for a needle or a flat sheet (scale-free)."""
    return 36.0 * np.pi * volume ** 2 / area ** 3


def degeneration(vertices: np.ndarray, result: np.ndarray, faces: np.ndarray, closed: bool) -> str:
    """Why ``result`` (n0, 3) is a degenerate smoothing of ``vertices``, or "" when it is not.

    Checks, each scale-free and against the input: the isoperimetric quotient (closed
    surfaces) fell below :data:`QUOTIENT_COLLAPSE` × its input value; area / diagonal² fell
    below :data:`SPREAD_COLLAPSE` × its input value; more than :data:`SLIVER_FRACTION` of the triangles have a
    corner below 1° while the input had fewer.
    """
    reasons = []
    area0, area1 = surface_area(vertices, faces), surface_area(result, faces)
    if closed and vertices.shape[1] == 3:
        q0 = isoperimetric_quotient(area0, enclosed_volume(vertices, faces))
        q1 = isoperimetric_quotient(area1, enclosed_volume(result, faces))
        if q1 < QUOTIENT_COLLAPSE * q0:
            reasons.append(f"isoperimetric quotient 36πV²/A³ fell from {q0:.3g} to {q1:.3g} (a needle or a sheet)")

    def spread(x, area):
        diagonal = float(np.linalg.norm(x.max(axis=0) - x.min(axis=0)))
        return area / diagonal ** 2 if diagonal > 0 else 0.0

    s0, s1 = spread(vertices, area0), spread(result, area1)
    if s1 < SPREAD_COLLAPSE * s0:
        reasons.append(f"area / diagonal² fell from {s0:.3g} to {s1:.3g}")

    def slivers(x):
        return float(np.mean(corner_angles(x, faces).min(axis=1) < SLIVER_ANGLE))

    before, after = slivers(vertices), slivers(result)
    if after > SLIVER_FRACTION > before:
        reasons.append(f"{100 * after:.0f} % of the triangles have a corner below 1° (input: {100 * before:.0f} %)")
    return "; ".join(reasons)


def divergence_reason(step: int, scheme: str, star0: np.ndarray | None) -> str:
    """``diverged at step N``, with the cause and the override that avoids it when ⋆0 ≤ 0
    (``star0`` (n0,), None for a Galerkin ⋆0) makes the implicit matrix M + dt S indefinite
    (the circumcentric ⋆0 on scans)."""
    reason = f"diverged at step {step}"
    nonpositive = int(np.sum(star0 <= 0)) if star0 is not None else 0
    if nonpositive and scheme == "implicit":
        reason += (f" (⋆0 ≤ 0 on {nonpositive} vertices: M + dt S is indefinite; "
                   "`operator=mixed_area` has a positive ⋆0)")
    return reason


def smoothing_metrics(stepper, report, *, time_step, scheme: str, rescale: str, cot_weights: np.ndarray,
                      clean: np.ndarray | None = None, setup_seconds: float = 0.0) -> dict[str, Any]:
    """Metrics of one smoothing run (a metric that does not apply is absent).

    stepper : the :class:`~decrun.methods.mean_curvature_flow.SmoothingStepper` after the run
        (``first`` and ``series`` of ``area``, ``volume``, ``roughness``, ``distortion``; the
        input ``stepper.vertices`` and the result ``stepper.v``, both (n0, d))
    report : the stepping driver's report (``diverged_at_step``, ``seconds``, …)
    time_step : the :class:`~decrun.methods.mean_curvature_flow.TimeStep` the run used
    scheme, rescale : ``implicit`` | ``explicit``; the resolved rescale
    cot_weights : (n1,) −S_ij on the mesh edges (the cot weights ⋆1 / |e|·|⋆e|)
    clean : (n0, d) the noise-free vertices, or None
    setup_seconds : the set-up's wall time (s), the eigen-solve's added

    ``stable`` = no step blew up and the result is not :func:`degeneration`'s;
    ``area_ratio`` = A_end/A_0, ``roughness_ratio`` = R_end/R_0, ``volume_drift_rel`` =
    |V_end − V_0|/|V_0| (closed surfaces), ``dt_over_critical`` = dt / (2/λ_max),
    ``distance_to_clean_rms`` = sqrt(mean |v − c|²) / diag(c), ``normal_*_deg`` by
    :func:`normal_deviation_deg`.
    """
    flow, faces, has_volume = stepper.flow, stepper.faces, stepper.has_volume
    vertices, v = stepper.vertices, stepper.v
    first, series = stepper.first, stepper.series
    last = {name: values[-1] for name, values in series.items()}
    diverged_at = report.diverged_at_step  # None: no step blew up
    # a flow that did not blow up may still have collapsed the surface (a needle, a sheet)
    degenerate = degeneration(vertices, v, faces, has_volume) if diverged_at is None else ""
    stable = diverged_at is None and not degenerate
    dt, dt_crit = time_step.dt, time_step.critical
    metrics: dict[str, Any] = {"dt": dt, "rescale": rescale, "stable": stable}
    if diverged_at is not None:
        metrics["diverged_at_step"] = diverged_at
    if not stable:
        metrics["unstable_reason"] = divergence_reason(diverged_at, scheme, flow.M) if diverged_at is not None \
            else f"degenerate: {degenerate}"
    metrics.update({
        "steps_done": len(series["area"]) - 1,
        "area_ratio": last["area"] / first["area"],
        "roughness_ratio": last["roughness"] / first["roughness"],
        "distortion_final": last["distortion"],
        "dt_critical_explicit": dt_crit,
        "dt_resolution": time_step.resolution,
        **({"dt_unit": time_step.unit} if time_step.unit is not None else {}),
        "negative_star1_fraction": float(np.mean(cot_weights < 0)),
    })
    if np.isfinite(dt_crit) and dt_crit > 0:
        metrics["dt_over_critical"] = dt / dt_crit
    if flow.M is not None:
        metrics["nonpositive_star0_vertices"] = int(np.sum(flow.M <= 0))
    if stable and vertices.shape[1] == 3:
        metrics["normal_change_deg"] = normal_deviation_deg(v, vertices, faces)
    if has_volume:
        metrics["volume_drift_rel"] = abs(last["volume"] - first["volume"]) / abs(first["volume"])
    if clean is not None and np.shape(clean) == vertices.shape:
        metrics.update(_distances_to_clean(vertices, v, faces, np.asarray(clean), stable))
    metrics["setup_seconds"] = setup_seconds + time_step.seconds
    metrics["solve_seconds"] = report.seconds
    metrics["step_seconds_max"] = report.step_seconds_max
    if report.resumed_from_step is not None:
        metrics["resumed_from_step"] = report.resumed_from_step
    return metrics


def _distances_to_clean(vertices: np.ndarray, v: np.ndarray, faces: np.ndarray, clean: np.ndarray,
                        stable: bool) -> dict[str, float]:
    """RMS distance / bounding-box diagonal and normal deviation to the clean mesh, of the input
    and (when stable: a diverged or degenerate run has no meaningful distance) of the result;
    the normal deviations in 3-D only (planar meshes have one normal)."""
    diagonal = float(np.linalg.norm(clean.max(axis=0) - clean.min(axis=0)))

    def rms(x):
        return float(np.sqrt(np.mean(np.sum((x - clean) ** 2, axis=1))) / diagonal)

    metrics = {}
    if stable:
        metrics["distance_to_clean_rms"] = rms(v)
    metrics["distance_to_clean_rms_initial"] = rms(vertices)
    if vertices.shape[1] == 3:
        if stable:
            metrics["normal_deviation_to_clean_deg"] = normal_deviation_deg(v, clean, faces)
        metrics["normal_deviation_to_clean_deg_initial"] = normal_deviation_deg(vertices, clean, faces)
    return metrics
