"""Small meshes for the core tests (generated, seeded, fast)."""

from __future__ import annotations

import numpy as np
import pymeshlab
import scipy.spatial
import triangle

from decrun.core.complex import SimplicialComplex
from decrun.core.primitives import grid_triangles, kuhn_cube  # noqa: F401
from decrun.runner.config import config_dir
from decrun.runner.meshes import MeshSource
from decrun.runner.plugins import build


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
