"""Planar channel meshes for the vorticity fluid (thesis §7.3, Fig. 7.14–7.17).

The fluid needs meshes without obtuse triangles (its circumcentric dual cells turn
inside out otherwise) and finer triangles near the obstacles. The thesis used an
adaptive distmesh (Persson & Strang 2004); here the channel [0, L] × [0, H] with
circular or polygonal holes is meshed by ``triangle`` (Shewchuk) with a quality bound
and a graded maximum area, then improved by rounds of ODT smoothing (each interior
vertex moves to the mean of the circumcenters of its triangles weighted by area × h⁻⁴ with
h the target size; Chen &
Xu 2004, Alliez et al. 2005) with constrained Delaunay re-triangulation in between.
Border vertices never move, so border loops keep their vertex ids.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import triangle as triangle_library

from decrun.core.geometry import corner_angles, obtuse_triangle_count

__all__ = ["ChannelMesh", "circle", "channel_mesh"]


def circle(center, radius: float, count: int) -> np.ndarray:
    """(count, 2) counter-clockwise points on a circle."""
    angle = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    return np.stack([center[0] + radius * np.cos(angle), center[1] + radius * np.sin(angle)], axis=1)


@dataclass
class ChannelMesh:
    """A meshed channel.

    vertices : (n, 2) float64; faces : (m, 3) int64, counter-clockwise
    loops : border loops as vertex-id arrays (outer first, then obstacle i); each runs
        along the border as the mesh orients it (outer counter-clockwise, holes clockwise)
    loop_labels : "outer" or "obstacle i" per loop
    obtuse : number of obtuse triangles; max_angle_deg : largest angle
    """

    vertices: np.ndarray
    faces: np.ndarray
    loops: list = field(default_factory=list)
    loop_labels: list = field(default_factory=list)
    obtuse: int = 0
    max_angle_deg: float = 0.0

    @property
    def obstacle_loops(self) -> list:
        """The obstacle loops (vertex-id arrays), for ``VorticityFluid(obstacle_loops=...)``."""
        return [loop for loop, label in zip(self.loops, self.loop_labels, strict=True) if label != "outer"]


def _distance_to_polygons(points: np.ndarray, polygons: list) -> np.ndarray:
    """(P,) distance from points to the nearest obstacle border (segments)."""
    best = np.full(points.shape[0], np.inf)
    for poly in polygons:  # a handful of obstacles
        a, b = poly, np.roll(poly, -1, axis=0)
        ab = b - a
        t = np.clip(np.einsum("pkd,kd->pk", points[:, None, :] - a[None], ab) / np.einsum("kd,kd->k", ab, ab), 0, 1)
        nearest = a[None] + t[..., None] * ab[None]
        best = np.minimum(best, np.linalg.norm(points[:, None, :] - nearest, axis=2).min(axis=1))
    return best


def _resample_segment(p: np.ndarray, q: np.ndarray, size) -> np.ndarray:
    """Points from p (included) towards q (excluded) spaced by the size field."""
    fine = np.linspace(0.0, 1.0, 400)
    points = p[None] + fine[:, None] * (q - p)[None]
    density = 1.0 / size(points)
    steps = np.concatenate([[0.0], np.cumsum(0.5 * (density[1:] + density[:-1]) * np.diff(fine))]) * np.linalg.norm(q - p)
    count = max(1, int(np.round(steps[-1])))
    targets = np.arange(count) * steps[-1] / count
    return p[None] + np.interp(targets, steps, fine)[:, None] * (q - p)[None]


def _triangle_geometry(vertices: np.ndarray, faces: np.ndarray):
    p = vertices[faces]
    d = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    cross = d[0][:, 0] * d[1][:, 1] - d[0][:, 1] * d[1][:, 0]
    area = 0.5 * np.abs(cross)
    sq0, sq1 = (d[0] ** 2).sum(1), (d[1] ** 2).sum(1)
    center = p[:, 0] + np.stack([d[1][:, 1] * sq0 - d[0][:, 1] * sq1, d[0][:, 0] * sq1 - d[1][:, 0] * sq0], 1) / (2 * cross)[:, None]
    return area, center, p.mean(axis=1)


def channel_mesh(length: float = 2.0, height: float = 1.0, obstacles=None, *, target_faces: int = 2800,
                 refinement: float = 3.0, gradation: float = 0.25, min_angle: float = 30.0,
                 smoothing_rounds: int = 30) -> ChannelMesh:
    """Mesh the channel [0, length] × [0, height] minus the obstacles.

    Parameters
    ----------
    obstacles : list of obstacles, each ``("circle", center, radius)`` (sampled at the
        finest size, with a ring of near-equilateral triangles around it) or a (k, 2)
        counter-clockwise polygon (its sides are sampled at the local size); default one
        circle of radius 0.1·height at (0.25·length, 0.5·height)
    target_faces : the face count aimed at (the result is within a few percent)
    refinement : edge length far away / edge length at the obstacles
    gradation : growth of the edge length with the distance from the obstacles
    min_angle : ``triangle`` quality bound (degrees)
    smoothing_rounds : ODT smoothing + re-triangulation rounds (stops early at 0 obtuse)

    Returns
    -------
    ChannelMesh (its ``obtuse`` field reports what is left)
    """
    if obstacles is None:
        obstacles = [("circle", (0.25 * length, 0.5 * height), 0.1 * height)]
    scale = np.sqrt(2.3 * length * height / target_faces)
    for _ in range(4):  # adjust the size scale to the face count (a few cheap rounds)
        mesh = _mesh_at_scale(length, height, obstacles, scale, refinement, gradation, min_angle, smoothing_rounds)
        ratio = mesh.faces.shape[0] / target_faces
        if abs(ratio - 1.0) < 0.04:
            break
        scale *= np.sqrt(ratio)
    return mesh


def _mesh_at_scale(length, height, obstacles, scale, refinement, gradation, min_angle, rounds) -> ChannelMesh:
    h_max, h_min = scale, scale / refinement
    polys = []

    def size(points):
        if not polys:
            return np.full(points.shape[0], h_max)
        return np.minimum(h_max, h_min + gradation * _distance_to_polygons(points, polys))

    # obstacles first need the size field of the exact shapes: sample them at h_min
    for obstacle in obstacles:
        if isinstance(obstacle, tuple) and obstacle and obstacle[0] == "circle":
            _, center, radius = obstacle
            polys.append(circle(np.asarray(center, float), radius, max(8, int(np.ceil(2 * np.pi * radius / h_min)))))
        else:
            corners_of = np.asarray(obstacle, dtype=np.float64)
            polys.append(corners_of)
    for index, obstacle in enumerate(obstacles):  # polygon sides sampled at the local size
        if not (isinstance(obstacle, tuple) and obstacle and obstacle[0] == "circle"):
            poly = polys[index]
            polys[index] = np.concatenate([_resample_segment(poly[i], poly[(i + 1) % len(poly)], size)
                                           for i in range(len(poly))])
    rings = []
    for obstacle, poly in zip(obstacles, polys, strict=True):  # a layer of near-equilateral triangles round circles
        if isinstance(obstacle, tuple) and obstacle and obstacle[0] == "circle":
            _, center, radius = obstacle
            n = poly.shape[0]
            half = np.pi / n
            chord = 2 * radius * np.sin(half)
            ring_radius = radius * np.cos(half) + np.sqrt(chord**2 - (radius * np.sin(half)) ** 2)
            angle = 2 * np.pi * np.arange(n) / n + half
            rings.append(np.asarray(center, float) + ring_radius * np.stack([np.cos(angle), np.sin(angle)], 1))
    corners = np.array([[0.0, 0.0], [length, 0.0], [length, height], [0.0, height]])
    outer = np.concatenate([_resample_segment(corners[i], corners[(i + 1) % 4], size) for i in range(4)])
    loops = [outer] + polys
    offsets = np.cumsum([0] + [len(loop) for loop in loops])
    segments = np.concatenate([np.stack([np.arange(n), (np.arange(n) + 1) % n], 1) + o
                               for n, o in zip([len(loop) for loop in loops], offsets[:-1], strict=True)])
    fixed = np.concatenate(loops + rings)
    holes = np.array([poly.mean(axis=0) for poly in polys]) if polys else None

    def cdt(points, flags):
        data = {"vertices": points, "segments": segments}
        if holes is not None:
            data["holes"] = holes
        return triangle_library.triangulate(data, flags)

    area_max = np.sqrt(3) / 4 * h_max**2
    result = cdt(fixed, f"pq{min_angle}Ya{area_max:.12g}")
    for _ in range(3):  # graded refinement by a per-triangle maximum area
        v, f = result["vertices"], result["triangles"]
        _, _, centroid = _triangle_geometry(v, f)
        data = {"vertices": v, "segments": segments, "triangles": f,
                "triangle_max_area": np.sqrt(3) / 4 * size(centroid) ** 2}
        if holes is not None:
            data["holes"] = holes
        result = triangle_library.triangulate(data, f"rpq{min_angle}Ya")
    vertices, faces = result["vertices"].copy(), result["triangles"].astype(np.int64)
    n_fixed = sum(loop.shape[0] for loop in loops)  # ring points may move

    def without_low_valence(vertices, faces):
        """Interior vertices of valence ≤ 4 (their mean angle is ≥ 90°) removed, re-triangulated."""
        valence = np.bincount(faces.ravel(), minlength=vertices.shape[0])
        low = valence <= 4
        low[:n_fixed] = False
        if not low.any():
            return vertices, faces
        vertices = vertices[~low]
        return vertices, cdt(vertices, "pY")["triangles"].astype(np.int64)

    def moved_inside(new, vertices):
        """The moved interior vertices that stay in the domain (the others keep their old
        place), re-triangulated (constrained Delaunay)."""
        inside = _inside_domain(new[n_fixed:], length, height, polys)
        new[n_fixed:][~inside] = vertices[n_fixed:][~inside]
        return new, cdt(new, "pY")["triangles"].astype(np.int64)

    for _ in range(rounds):  # ODT smoothing of interior vertices + constrained Delaunay
        if obtuse_triangle_count(vertices, faces) == 0:
            break
        vertices, faces = without_low_valence(vertices, faces)
        area, center, centroid = _triangle_geometry(vertices, faces)
        area = area / size(centroid) ** 4  # density-weighted (ρ ∝ h⁻⁴): keeps the grading
        weight = np.bincount(faces.ravel(), weights=np.repeat(area, 3), minlength=vertices.shape[0])
        moved = np.stack([np.bincount(faces.ravel(), weights=np.repeat(area * center[:, a], 3),
                                      minlength=vertices.shape[0]) for a in range(2)], 1) / weight[:, None]
        new = vertices.copy()
        new[n_fixed:] = moved[n_fixed:]
        vertices, faces = moved_inside(new, vertices)
    for _ in range(8 * rounds):  # Thales repair of the obtuse triangles left
        if obtuse_triangle_count(vertices, faces) == 0:
            break
        vertices, faces = without_low_valence(vertices, faces)
        vertices, faces = moved_inside(_thales_step(vertices, faces, n_fixed), vertices)
    loops_ids = [np.arange(o, o + len(loop)) for o, loop in zip(offsets[:-1], loops, strict=True)]
    loops_ids = [loop if i == 0 else loop[::-1] for i, loop in enumerate(loops_ids)]  # holes run clockwise
    angle = np.degrees(corner_angles(vertices, faces))
    return ChannelMesh(vertices, faces, loops_ids, ["outer"] + [f"obstacle {i}" for i in range(len(polys))],
                       obtuse_triangle_count(vertices, faces), float(angle.max()))


def _thales_step(vertices: np.ndarray, faces: np.ndarray, n_fixed: int, margin: float = 0.02,
                 damping: float = 0.5) -> np.ndarray:
    """Move vertices of obtuse triangles towards non-obtuse positions.

    A corner is right-angled exactly on the Thales circle over the opposite edge jk. A
    movable obtuse vertex i moves radially from the edge midpoint to (1 + margin) times
    the circle's radius; when i is a fixed border vertex, the movable ends of jk move
    towards the midpoint until the circle passes (1 + margin) inside p_i. Moves of a
    vertex are averaged over its obtuse triangles and damped.
    """
    p = vertices[faces]  # (m, 3, 2)
    a, b = np.roll(p, -1, axis=1) - p, np.roll(p, 1, axis=1) - p
    obtuse_corner = np.einsum("mkd,mkd->mk", a, b) < 0
    t, i = np.nonzero(obtuse_corner)
    vi, vj, vk = faces[t, i], faces[t, (i + 1) % 3], faces[t, (i + 2) % 3]
    pi, pj, pk = vertices[vi], vertices[vj], vertices[vk]
    mid = 0.5 * (pj + pk)
    radius = 0.5 * np.linalg.norm(pk - pj, axis=1)
    offset = pi - mid
    distance = np.linalg.norm(offset, axis=1)
    shift = np.zeros_like(vertices)
    hits = np.zeros(vertices.shape[0])
    movable_i = vi >= n_fixed
    target = mid + offset * (radius * (1 + margin) / distance)[:, None]
    for comp in range(2):
        shift[:, comp] += np.bincount(vi[movable_i], weights=(target - pi)[movable_i, comp], minlength=vertices.shape[0])
    hits += np.bincount(vi[movable_i], minlength=vertices.shape[0])
    fixed_i = ~movable_i
    shrink = (1.0 - distance / (radius * (1 + margin)))[:, None]  # fraction to pull each end inwards
    for end in (vj, vk):
        sel = fixed_i & (end >= n_fixed)
        move = (mid - vertices[end]) * shrink
        for comp in range(2):
            shift[:, comp] += np.bincount(end[sel], weights=move[sel, comp], minlength=vertices.shape[0])
        hits += np.bincount(end[sel], minlength=vertices.shape[0])
    moved = hits > 0
    new = vertices.copy()
    new[moved] += damping * shift[moved] / hits[moved, None]
    new[:n_fixed] = vertices[:n_fixed]
    return new


def _inside_domain(points, length, height, polys) -> np.ndarray:
    inside = (points[:, 0] > 0) & (points[:, 0] < length) & (points[:, 1] > 0) & (points[:, 1] < height)
    for poly in polys:  # even-odd test per obstacle polygon
        a, b = poly, np.roll(poly, -1, axis=0)
        crosses = ((a[None, :, 1] > points[:, None, 1]) != (b[None, :, 1] > points[:, None, 1]))
        x_at = a[None, :, 0] + (points[:, None, 1] - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / (
            b[None, :, 1] - a[None, :, 1] + 1e-300)
        inside &= ~(np.sum(crosses & (points[:, None, 0] < x_at), axis=1) % 2 == 1)
    return inside
