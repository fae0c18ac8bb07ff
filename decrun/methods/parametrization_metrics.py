"""Distortion and validity measures of a parametrization ``uv`` of a triangle mesh (thesis ch. 5).

Everything here is plain numpy on arrays — ``vertices (n, 3)`` (or ``(n, 2)``), consistently
oriented ``faces (m, 3)``, per-vertex texture coordinates ``uv (n, 2)`` and border loops
(vertex cycles traversed with the surface on their left, as
:meth:`decrun.core.complex.SimplicialComplex.border_loops` returns them) — so the measures can be
checked on hand-made maps without any DEC machinery.

The map of one triangle ``T`` onto its image is affine; its linear part ``J_T`` (2×2, from an
orthonormal frame of the plane of ``T`` to the uv plane) has singular values ``σ1 ≥ σ2``. A
conformal map has ``σ1 = σ2`` on every triangle; ``σ1/σ2`` is the quasi-conformal distortion
(as Boundary First Flattening reports it) and ``|corner angle on the mesh − corner angle in uv|``
the angle distortion. Conditions of Gortler's theorem (thesis Theorem 2, §5.2.1) are checked
on the result: border winding (exterior +2π, holes −2π), reflex border vertices, flips and
border self-intersections.
"""

from __future__ import annotations

import numpy as np

from decrun.core.geometry import corner_angles, embed3, triangle_areas

__all__ = [
    "corner_angles",
    "triangle_areas",
    "signed_uv_areas",
    "majority_orientation",
    "map_singular_values",
    "angle_distortion",
    "quasi_conformal_distortion",
    "area_distortion_std",
    "flipped_triangles",
    "degenerate_triangles",
    "border_self_intersections",
    "border_turning_numbers",
    "border_vertex_uv_angles",
    "is_embedding",
    "parametrization_metrics",
]


def signed_uv_areas(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Signed areas of the image triangles, uv (n, 2), faces (m, 3) -> (m,); > 0 when counter-clockwise."""
    q = np.asarray(uv, dtype=np.float64)[np.asarray(faces)]
    e1, e2 = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def _degenerate_tolerance(uv: np.ndarray) -> float:
    uv = np.asarray(uv, dtype=np.float64)
    extent = float(np.max(np.ptp(uv, axis=0))) if len(uv) else 0.0
    return 1e-14 * max(extent, np.finfo(float).tiny) ** 2


def majority_orientation(uv: np.ndarray, faces: np.ndarray) -> int:
    """+1 if most image triangles are counter-clockwise, −1 if most are clockwise.

    Ties (and the all-degenerate case) are broken by the sign of the total signed area, then +1.
    A global reflection of a map therefore changes this sign and nothing else.
    """
    signed = signed_uv_areas(uv, faces)
    tol = _degenerate_tolerance(uv)
    positive, negative = int(np.sum(signed > tol)), int(np.sum(signed < -tol))
    if positive != negative:
        return 1 if positive > negative else -1
    return -1 if signed.sum() < 0 else 1


def flipped_triangles(uv: np.ndarray, faces: np.ndarray) -> int:
    """Number of image triangles oriented against the majority orientation (degenerate ones excluded)."""
    signed = signed_uv_areas(uv, faces) * majority_orientation(uv, faces)
    return int(np.sum(signed < -_degenerate_tolerance(uv)))


def degenerate_triangles(uv: np.ndarray, faces: np.ndarray) -> int:
    """Number of image triangles with (numerically) zero area: |A| ≤ 1e-14 · extent²."""
    return int(np.sum(np.abs(signed_uv_areas(uv, faces)) <= _degenerate_tolerance(uv)))


def _local_frames(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Coordinates of each triangle's corners in an orthonormal frame of its plane: (m, 3, 2).

    Corner 0 at the origin, corner 1 on the positive first axis; the frame is right-handed with
    respect to the triangle's orientation, so an orientation-preserving map has det J > 0.
    """
    p = embed3(vertices)[np.asarray(faces)]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    length1 = np.linalg.norm(e1, axis=1)
    normal = np.cross(e1, e2)
    double_area = np.linalg.norm(normal, axis=1)
    local = np.zeros((len(p), 3, 2))
    local[:, 1, 0] = length1
    with np.errstate(invalid="ignore", divide="ignore"):
        local[:, 2, 0] = np.einsum("md,md->m", e1, e2) / length1
        local[:, 2, 1] = double_area / length1
    return local


def map_singular_values(vertices: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Singular values σ1 ≥ σ2 ≥ 0 of each triangle's affine map mesh → uv: (m, 2).

    J_T = [q1−q0, q2−q0] · [p1−p0, p2−p0]⁻¹ with p in the local orthonormal frame of T
    (:func:`_local_frames`) and q in uv. Closed form for 2×2 matrices:
    σ1,2 = ½(√((a+d)²+(c−b)²) ± √((a−d)²+(b+c)²)) for J = [[a, b], [c, d]].
    A degenerate mesh triangle gives NaN.
    """
    local = _local_frames(vertices, faces)
    q = np.asarray(uv, dtype=np.float64)[np.asarray(faces)]
    P = np.stack([local[:, 1] - local[:, 0], local[:, 2] - local[:, 0]], axis=2)  # columns = edges
    Q = np.stack([q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]], axis=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        # P = [[l1, x2], [0, y2]] is upper triangular: its inverse in closed form.
        l1, x2, y2 = P[:, 0, 0], P[:, 0, 1], P[:, 1, 1]
        P_inv = np.zeros_like(P)
        P_inv[:, 0, 0] = 1.0 / l1
        P_inv[:, 0, 1] = -x2 / (l1 * y2)
        P_inv[:, 1, 1] = 1.0 / y2
        J = Q @ P_inv
    a, b, c, d = J[:, 0, 0], J[:, 0, 1], J[:, 1, 0], J[:, 1, 1]
    conformal_part = np.hypot(a + d, c - b)
    anticonformal_part = np.hypot(a - d, b + c)
    return np.column_stack([0.5 * (conformal_part + anticonformal_part), 0.5 * np.abs(conformal_part - anticonformal_part)])


def quasi_conformal_distortion(vertices: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """σ1/σ2 per triangle, (m,); 1 for a similarity, ∞ for a triangle squashed to a segment."""
    sigma = map_singular_values(vertices, uv, faces)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(sigma[:, 1] > 0, sigma[:, 0] / np.where(sigma[:, 1] > 0, sigma[:, 1], 1.0), np.inf)


def angle_distortion(vertices: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """|corner angle on the mesh − corner angle in uv| per corner, in radians: (m, 3)."""
    return np.abs(corner_angles(vertices, faces) - corner_angles(uv, faces))


def area_distortion_std(vertices: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> float:
    """Area-weighted standard deviation of log(area ratio) after normalizing both total areas.

    ratio_T = (|A_uv(T)| / Σ|A_uv|) / (A(T) / ΣA); weights A(T)/ΣA. 0 for an area-preserving map
    (up to global scale); ∞ if an image triangle has zero area.
    """
    area = triangle_areas(vertices, faces)
    area_uv = np.abs(signed_uv_areas(uv, faces))
    if np.any(area_uv <= 0):
        return float("inf")
    weight = area / area.sum()
    log_ratio = np.log(area_uv / area_uv.sum()) - np.log(weight)
    mean = np.sum(weight * log_ratio)
    return float(np.sqrt(np.sum(weight * (log_ratio - mean) ** 2)))


def _segments_from_loops(uv: np.ndarray, loops: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    starts = np.concatenate([np.asarray(loop) for loop in loops])
    ends = np.concatenate([np.roll(np.asarray(loop), -1) for loop in loops])
    return np.stack([starts, ends], axis=1), np.asarray(uv, dtype=np.float64)


def border_self_intersections(uv: np.ndarray, loops: list[np.ndarray], chunk: int = 2048) -> int:
    """Number of pairs of border segments (over all loops) that intersect or touch in uv.

    Segments sharing a mesh vertex are skipped (they meet at that vertex by construction).
    Two segments count if they cross, or if an endpoint of one lies on the other (within
    1e-12 · extent), or if they overlap collinearly. All pairs are tested, chunked by rows,
    with a bounding-box prefilter: O(s²) for s border segments, vectorized.
    """
    if not loops:
        return 0
    segments, uv = _segments_from_loops(uv, loops)
    a, b = uv[segments[:, 0]], uv[segments[:, 1]]
    low, high = np.minimum(a, b), np.maximum(a, b)
    extent = float(np.max(np.ptp(uv, axis=0))) or 1.0
    eps = 1e-12 * extent
    total = 0
    s = len(segments)
    for start in range(0, s, chunk):
        i = np.arange(start, min(start + chunk, s))[:, None]
        j = np.arange(s)[None, :]
        candidate = j > i
        candidate &= np.all(low[i] <= high[j] + eps, axis=2) & np.all(low[j] <= high[i] + eps, axis=2)
        shares = (segments[i, 0] == segments[j, 0]) | (segments[i, 0] == segments[j, 1])
        shares |= (segments[i, 1] == segments[j, 0]) | (segments[i, 1] == segments[j, 1])
        candidate &= ~shares
        ii, jj = np.nonzero(candidate)
        ii = ii + start
        if len(ii) == 0:
            continue
        p, p2, q, q2 = a[ii], b[ii], a[jj], b[jj]

        def orient(o, u, w):
            return (u[:, 0] - o[:, 0]) * (w[:, 1] - o[:, 1]) - (u[:, 1] - o[:, 1]) * (w[:, 0] - o[:, 0])

        def on_segment(o, u, w):  # w on segment o-u, given collinear
            return np.all((np.minimum(o, u) - eps <= w) & (w <= np.maximum(o, u) + eps), axis=1)

        scale = extent * eps  # orientation values are areas
        o1, o2, o3, o4 = orient(p, p2, q), orient(p, p2, q2), orient(q, q2, p), orient(q, q2, p2)
        proper = (((o1 > scale) & (o2 < -scale)) | ((o1 < -scale) & (o2 > scale))) & (
            ((o3 > scale) & (o4 < -scale)) | ((o3 < -scale) & (o4 > scale))
        )
        touching = (
            ((np.abs(o1) <= scale) & on_segment(p, p2, q))
            | ((np.abs(o2) <= scale) & on_segment(p, p2, q2))
            | ((np.abs(o3) <= scale) & on_segment(q, q2, p))
            | ((np.abs(o4) <= scale) & on_segment(q, q2, p2))
        )
        total += int(np.sum(proper | touching))
    return total


def border_turning_numbers(uv: np.ndarray, loops: list[np.ndarray]) -> np.ndarray:
    """Turning number of each border polygon in uv, in units of 2π: (n_loops,).

    Σ over the loop's vertices of the signed turning angle atan2(e_in × e_out, e_in · e_out).
    For an embedding with counter-clockwise triangles, the exterior loop (surface on its left)
    turns +1 and every hole −1 (Gortler's conditions 2 and 3, thesis Theorem 2).
    Zero-length edges contribute 0 turning.
    """
    uv = np.asarray(uv, dtype=np.float64)
    turns = []
    for loop in loops:
        loop = np.asarray(loop)
        incoming = uv[loop] - uv[np.roll(loop, 1)]
        outgoing = uv[np.roll(loop, -1)] - uv[loop]
        cross = incoming[:, 0] * outgoing[:, 1] - incoming[:, 1] * outgoing[:, 0]
        dot = np.einsum("kd,kd->k", incoming, outgoing)
        turns.append(np.sum(np.arctan2(cross, dot)) / (2 * np.pi))
    return np.asarray(turns, dtype=np.float64)


def border_vertex_uv_angles(uv: np.ndarray, faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Sum of signed uv corner angles around every vertex, (n_vertices,), radians.

    A corner's angle counts positive when its triangle has the majority orientation and negative
    otherwise. For an embedding this is 2π at interior vertices and the interior angle of the
    border polygon (seen from the surface) at border vertices: > π exactly at reflex vertices.
    """
    signs = np.sign(signed_uv_areas(uv, faces)) * majority_orientation(uv, faces)
    angles = corner_angles(uv, faces) * signs[:, None]
    return np.bincount(np.asarray(faces).ravel(), weights=angles.ravel(), minlength=n_vertices)


def is_embedding(uv: np.ndarray, faces: np.ndarray, loops: list[np.ndarray]) -> bool:
    """True iff the map is injective: no flipped and no degenerate triangle, no two border
    segments meeting, and border turning numbers +1 (exterior, ``loops[0]``) and −1 (holes)
    measured in the majority orientation.

    For a connected genus-0 surface with borders the first three conditions already imply
    injectivity (an orientation-preserving map whose border curves are disjoint simple curves
    has degree 1 on the image); the winding check is kept as an independent guard.
    """
    if flipped_triangles(uv, faces) or degenerate_triangles(uv, faces):
        return False
    if border_self_intersections(uv, loops):
        return False
    turns = border_turning_numbers(uv, loops) * majority_orientation(uv, faces)
    expected = np.array([1.0] + [-1.0] * (len(loops) - 1))
    return bool(np.all(np.abs(turns - expected) < 1e-6))


def parametrization_metrics(
    vertices: np.ndarray, uv: np.ndarray, faces: np.ndarray, loops: list[np.ndarray]
) -> dict:
    """All scalar metrics of a parametrization, named as the app reports them.

    ``loops[0]`` must be the exterior border. Angles in degrees; ``qc_*`` are σ1/σ2; the
    means are weighted by mesh triangle area (the angle mean by the area of the corner's
    triangle). Returns a flat dict of floats, ints and bools.
    """
    faces = np.asarray(faces)
    area = triangle_areas(vertices, faces)
    weight = area / area.sum()
    angle_error = np.degrees(angle_distortion(vertices, uv, faces))
    qc = quasi_conformal_distortion(vertices, uv, faces)
    orientation = majority_orientation(uv, faces)
    turns = border_turning_numbers(uv, loops) * orientation
    reflex = 0
    if loops:
        border = np.concatenate([np.asarray(loop) for loop in loops])
        uv_angle = border_vertex_uv_angles(uv, faces, len(uv))[border]
        reflex = int(np.sum(uv_angle > np.pi + 1e-9))
    flips, degenerate = flipped_triangles(uv, faces), degenerate_triangles(uv, faces)
    intersections = border_self_intersections(uv, loops)
    winding_ok = bool(len(turns) > 0 and abs(turns[0] - 1) < 1e-6 and np.all(np.abs(turns[1:] + 1) < 1e-6))
    return {
        "angle_distortion_mean_deg": float(np.sum(weight * angle_error.mean(axis=1))),
        "angle_distortion_max_deg": float(angle_error.max()),
        "qc_distortion_mean": float(np.sum(weight * qc)),
        "qc_distortion_max": float(np.max(qc)),
        "area_distortion_std": area_distortion_std(vertices, uv, faces),
        "flipped_triangles": flips,
        "degenerate_triangles": degenerate,
        "border_self_intersections": intersections,
        "border_winding_exterior_turns": float(turns[0]) if len(turns) else 0.0,
        "border_winding_inner_turns_min": float(turns[1:].min()) if len(turns) > 1 else 0.0,
        "border_winding_inner_turns_max": float(turns[1:].max()) if len(turns) > 1 else 0.0,
        "border_winding_ok": winding_ok,
        "reflex_border_vertices_uv": reflex,
        "is_embedding": bool(flips == 0 and degenerate == 0 and intersections == 0 and winding_ok),
        "uv_orientation": int(orientation),
    }
