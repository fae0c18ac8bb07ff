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
"""

from __future__ import annotations

import numpy as np

from decrun.core.geometry import corner_angles, embed3, triangle_areas
from decrun.methods.mean_curvature_flow import enclosed_volume, surface_area

__all__ = ["normal_deviation_deg", "aligned_rms_distance", "isoperimetric_quotient", "degeneration"]

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
