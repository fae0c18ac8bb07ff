"""Small meshes for the core tests (generated, seeded, fast)."""

from __future__ import annotations

import numpy as np
import pymeshlab
import scipy.spatial
import triangle

from decrun.core.complex import SimplicialComplex
from decrun.core.primitives import grid_triangles, kuhn_cube  # noqa: F401
from decrun.runner.job.config import config_dir
from decrun.runner.job.plugins import build
from decrun.runner.mesh import MeshSource


def mesh(source: str = "icosphere", **options):
    """The mesh of source ``conf/mesh/<source>.yaml`` with its *class* defaults (no noise, no
    refinement unless asked) and ``options``."""
    from omegaconf import OmegaConf

    target = OmegaConf.load(config_dir() / "mesh" / f"{source}.yaml")["_target_"]
    return build({"_target_": target, **options}, "mesh", MeshSource).load()


def complex_of(source: str = "icosphere", **options) -> SimplicialComplex:
    """The complex of ``mesh(source, **options)`` (re-oriented)."""
    m = mesh(source, **options)
    return SimplicialComplex(m.vertices, m.simplices, orient="fix")


def icosphere(subdiv: int):
    """Unit icosphere (pymeshlab), (vertices, faces)."""
    ms = pymeshlab.MeshSet()
    ms.create_sphere(radius=1.0, subdiv=subdiv)
    mesh = ms.current_mesh()
    vertices = mesh.vertex_matrix()
    return vertices / np.linalg.norm(vertices, axis=1, keepdims=True), mesh.face_matrix().astype(np.int64)


def remeshed_torus(target: float = 0.08):
    """A torus remeshed isotropically (so no cyclic-quad diagonals with ⋆1 = 0)."""
    ms = pymeshlab.MeshSet()
    ms.create_torus(hradius=1.0, vradius=0.4, hsubdiv=48, vsubdiv=24)
    ms.meshing_isotropic_explicit_remeshing(iterations=4, targetlen=pymeshlab.PureValue(target))
    mesh = ms.current_mesh()
    return mesh.vertex_matrix(), mesh.face_matrix().astype(np.int64)


def random_planar(n_points: int = 120, seed: int = 0):
    """Delaunay triangulation of random points in the unit square: obtuse triangles included."""
    points = np.random.default_rng(seed).random((n_points, 2))
    return points, scipy.spatial.Delaunay(points).simplices.astype(np.int64)


def jittered_lattice(nx: int = 12, ny: int = 10, jitter: float = 0.04, seed: int = 0):
    """A parallelogram of equilateral triangles, interior vertices jittered (no obtuse angle):
    (vertices (n, 2), faces)."""
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    points = np.stack([i + 0.5 * j, j * np.sqrt(3) / 2], -1).reshape(-1, 2).astype(float)
    border = ((i == 0) | (j == 0) | (i == nx - 1) | (j == ny - 1)).ravel()
    points += np.random.default_rng(seed).normal(scale=jitter, size=points.shape) * ~border[:, None]
    a = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + nx], 1), np.stack([a + 1, a + nx + 1, a + nx], 1)])
    return points, faces


def random_tets(n_points: int = 80, seed: int = 0):
    """Delaunay tetrahedralization of random points in the unit cube."""
    points = np.random.default_rng(seed).random((n_points, 3))
    return points, scipy.spatial.Delaunay(points).simplices.astype(np.int64)


def planar_domain(holes: int = 0, max_area: float = 0.002, min_angle: float = 25.0):
    """The unit disk with ``holes`` small circular holes, meshed by ``triangle``."""
    def circle(center, radius, count):
        angle = np.linspace(0, 2 * np.pi, count, endpoint=False)
        return np.stack([center[0] + radius * np.cos(angle), center[1] + radius * np.sin(angle)], 1)

    loops = [circle((0.0, 0.0), 1.0, 64)]
    hole_points = []
    centers = [(0.45 * np.cos(a), 0.45 * np.sin(a)) for a in np.linspace(0, 2 * np.pi, holes, endpoint=False)]
    for c in centers:
        loops.append(circle(c, 0.15, 20))
        hole_points.append(c)
    vertices, segments, offset = [], [], 0
    for loop in loops:
        count = len(loop)
        vertices.append(loop)
        segments.append(np.stack([np.arange(count), (np.arange(count) + 1) % count], 1) + offset)
        offset += count
    domain = {"vertices": np.concatenate(vertices), "segments": np.concatenate(segments)}
    if hole_points:
        domain["holes"] = np.array(hole_points)
    result = triangle.triangulate(domain, f"pq{min_angle}a{max_area}")
    return result["vertices"], result["triangles"].astype(np.int64)


def annulus(max_area: float = 0.002):
    """The annulus 0.4 ≤ r ≤ 1 meshed by ``triangle``."""
    angle = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    outer = np.stack([np.cos(angle), np.sin(angle)], 1)
    inner = 0.4 * outer[::2]
    vertices = np.concatenate([outer, inner])
    segments = np.concatenate([
        np.stack([np.arange(64), (np.arange(64) + 1) % 64], 1),
        np.stack([np.arange(32), (np.arange(32) + 1) % 32], 1) + 64,
    ])
    result = triangle.triangulate({"vertices": vertices, "segments": segments, "holes": [[0.0, 0.0]]},
                                  f"pq25a{max_area}")
    return result["vertices"], result["triangles"].astype(np.int64)


def spiral_strip(turns: float = 1.5, segments: int = 90, rise: float = 0.0):
    """A strip between radii 1 + 0.1 t and 1.5 + 0.1 t (t = θ / (2π turns)) over ``turns`` turns,
    (vertices (2 (segments+1), 3), counter-clockwise faces (2 segments, 3)): a disk. With
    ``rise`` = 0 it is a flat map that overlaps itself after one turn — no flipped triangle,
    border turning number +1, but its border crosses itself; with ``rise`` > 0 (z = rise θ) it
    is an embedded helical ramp in 3-D whose isometric layout overlaps in the same way."""
    theta = np.linspace(0.0, 2 * np.pi * turns, segments + 1)
    t = theta / theta[-1]
    rings = [(1.0 + 0.1 * t), (1.5 + 0.1 * t)]
    vertices = np.concatenate([np.column_stack([r * np.cos(theta), r * np.sin(theta), rise * theta]) for r in rings])
    i = np.arange(segments)
    inner, outer = i, i + segments + 1
    faces = np.concatenate([np.stack([inner, outer + 1, inner + 1], 1), np.stack([inner, outer, outer + 1], 1)])
    return vertices, faces.astype(np.int64)


def flux_through_circle(K: SimplicialComplex, omega: np.ndarray, center, radius: float, samples: int = 720) -> float:
    """Outward flux ∮ u·n ds of the Whitney field u = ♯ω (eq. 6.7) of a planar 1-form through
    the circle |x − center| = radius (midpoint rule on ``samples`` arcs; each sample located in
    its triangle by barycentric coordinates computed here, independently of decrun's search)."""
    from decrun.core.forms import whitney_sharp

    angle = (np.arange(samples) + 0.5) * 2 * np.pi / samples
    normal = np.column_stack([np.cos(angle), np.sin(angle)])
    points = np.asarray(center, dtype=np.float64) + radius * normal
    corners = K.vertices[K.simplices(2)][:, :, :2]  # sorted tuples, as whitney_sharp wants
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    rel = points[:, None, :] - a[None]
    l1 = (rel[..., 0] * (c[:, 1] - a[:, 1]) - rel[..., 1] * (c[:, 0] - a[:, 0])) / det
    l2 = ((b[:, 0] - a[:, 0]) * rel[..., 1] - (b[:, 1] - a[:, 1]) * rel[..., 0]) / det
    lam = np.stack([1 - l1 - l2, l1, l2], axis=-1)  # (samples, faces, 3)
    face = np.argmax(lam.min(axis=-1), axis=1)
    assert np.all(lam[np.arange(samples), face].min(axis=1) > -1e-12), "circle leaves the mesh"
    u = whitney_sharp(K, omega, barycentric=lam[np.arange(samples), face], faces=face)[:, :2]
    return float(np.sum(np.einsum("sd,sd->s", u, normal)) * 2 * np.pi * radius / samples)


def square_lattice(n: int, jitter: float = 0.0, seed: int = 0):
    """The unit square meshed from rows of near-equilateral triangles (side ≈ 1/n, every
    other row offset by half a side, half triangles at the left and right walls), Delaunay
    triangulated; interior vertices moved by up to ``jitter`` × the side (uniform per
    coordinate). Returns (vertices (n0, 2), faces (m, 3))."""
    from scipy.spatial import Delaunay

    h = 1.0 / n
    rows = int(round(1.0 / (h * np.sqrt(3) / 2)))
    points = []
    for j in range(rows + 1):
        x = np.arange(n + 1) * h if j % 2 == 0 else np.concatenate([[0.0], (np.arange(n) + 0.5) * h, [1.0]])
        points.append(np.stack([x, np.full(x.size, j / rows)], 1))
    points = np.concatenate(points)
    border = (points[:, 0] < 1e-12) | (points[:, 0] > 1 - 1e-12) | (points[:, 1] < 1e-12) | (points[:, 1] > 1 - 1e-12)
    rng = np.random.default_rng(seed)
    points = points + rng.uniform(-jitter * h, jitter * h, points.shape) * ~border[:, None]
    faces = Delaunay(points).simplices.astype(np.int64)
    a, b, c = (points[faces[:, i]] for i in range(3))
    flip = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) < 0
    faces[flip] = faces[flip][:, [0, 2, 1]]
    return points, faces


def kuhn_cells(n: int, kept=None, removed=()):
    """kuhn_cube(n) keeping the cells whose integer corner (i, j, k) is in ``kept`` (every cell
    when None) and not in ``removed``: cells meeting only along an edge or at a vertex make
    pinched solids and borders."""
    def member(corners, cells):
        cells = np.asarray(list(cells), dtype=np.int64).reshape(-1, 3)
        return (corners[:, None, :] == cells[None]).all(axis=2).any(axis=1)

    def keep(centers):
        corners = np.floor(centers * n).astype(np.int64)
        inside = np.ones(len(corners), dtype=bool) if kept is None else member(corners, kept)
        return inside & ~member(corners, removed)
    return kuhn_cube(n, keep_cell=keep)


def pieces_mesh():
    """22 pieces in z = 0: a unit square (30 × 30 grid) and 21 squares of side 0.05 (2 triangles each)."""
    vertices, triangles, offset = [], [], 0
    for i, (n, side) in enumerate([(30, 1.0)] + [(1, 0.05)] * 21):
        V, T = grid_triangles(n)
        vertices.append(np.column_stack([V * side, np.zeros(len(V))]) + [2.0 * i, 0, 0])
        triangles.append(T + offset)
        offset += len(V)
    return np.vstack(vertices), np.vstack(triangles)
