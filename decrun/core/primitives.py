"""Structured meshes generated with numpy: planar triangle grids and Kuhn-subdivided cubes.

Used by tests, benchmarks and the ``mesh`` config group where pymeshlab has no equivalent
(tetrahedral meshes, exactly known flat domains).
"""

from __future__ import annotations

from itertools import permutations

import numpy as np

from decrun.core.connectivity import drop_unreferenced

__all__ = ["grid_triangles", "kuhn_cube", "flat_torus"]


def grid_triangles(nx: int, ny: int | None = None, size=(1.0, 1.0), jitter: float = 0.0, seed: int = 0):
    """Triangulated rectangle [0, size_x] × [0, size_y] with nx × ny cells, each split in two.

    Parameters
    ----------
    nx, ny : cells along x and y (ny defaults to nx)
    size : (width, height)
    jitter : interior vertices move by up to ``jitter`` cell sizes (uniform, seeded),
        which breaks the right angles of the plain grid
    Returns
    -------
    vertices (n, 2) float64, triangles (2·nx·ny, 3) int64 counter-clockwise
    """
    ny = nx if ny is None else ny
    x, y = np.meshgrid(np.linspace(0, size[0], nx + 1), np.linspace(0, size[1], ny + 1), indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel()], axis=1)
    if jitter:
        rng = np.random.default_rng(seed)
        interior = (x.ravel() > 0) & (x.ravel() < size[0]) & (y.ravel() > 0) & (y.ravel() < size[1])
        step = np.array([size[0] / nx, size[1] / ny])
        vertices[interior] += jitter * step * rng.uniform(-1, 1, (interior.sum(), 2))
    index = np.arange((nx + 1) * (ny + 1)).reshape(nx + 1, ny + 1)
    a, b = index[:-1, :-1].ravel(), index[1:, :-1].ravel()
    c, d = index[1:, 1:].ravel(), index[:-1, 1:].ravel()
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return vertices, triangles.astype(np.int64)


def kuhn_cube(n: int, size: float = 1.0, keep_cell=None):
    """Tetrahedral mesh of the cube [0, size]³: n³ cells, each cut into the 6 Kuhn tetrahedra.

    The Kuhn (Freudenthal) subdivision cuts each cell along its main diagonal; the six
    tetrahedra are v, v+e_π(0), v+e_π(0)+e_π(1), v+(1,1,1) for the permutations π, and
    neighbouring cells match face to face.

    Parameters
    ----------
    n : cells per side
    keep_cell : optional callable (c, 3) cell centers -> (c,) bool; cells where it is False
        are removed (whole cells, so the result stays a manifold for box-shaped holes)

    Returns
    -------
    vertices (n0, 3) float64, tetrahedra (m, 4) int64 (positively oriented),
    unreferenced vertices removed.
    """
    axis = np.linspace(0.0, size, n + 1)
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    index = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    corner = np.stack(np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 3)
    if keep_cell is not None:
        corner = corner[np.asarray(keep_cell((corner + 0.5) * size / n), dtype=bool)]
    tets = []
    unit = np.eye(3, dtype=np.int64)
    for perm in permutations(range(3)):
        path = [corner]
        for axis_index in perm:
            path.append(path[-1] + unit[axis_index])
        tet = np.stack([index[p[:, 0], p[:, 1], p[:, 2]] for p in path], axis=1)
        tets.append(tet)
    tets = np.concatenate(tets)
    # orient positively
    p = vertices[tets]
    det = np.linalg.det(p[:, 1:] - p[:, :1])
    tets[det < 0, 0], tets[det < 0, 1] = tets[det < 0, 1], tets[det < 0, 0].copy()
    vertices, tets, _ = drop_unreferenced(vertices, tets)
    return vertices, tets


def flat_torus(nx: int, ny: int | None = None, radii=(1.0, 1.0)):
    """The flat torus with periods 2π r1 × 2π r2 as a triangle mesh in R⁴ (Clifford embedding
    (r1 cos u, r1 sin u, r2 cos v, r2 sin v), flat and isometric to the quotient of the
    plane): an nx × ny periodic grid in (u, v), each cell split in two.

    Returns
    -------
    vertices (nx·ny, 4) float64, triangles (2·nx·ny, 3) int64 (consistently oriented)
    """
    ny = nx if ny is None else ny
    u, v = np.meshgrid(2 * np.pi * np.arange(nx) / nx, 2 * np.pi * np.arange(ny) / ny, indexing="ij")
    u, v = u.ravel(), v.ravel()
    vertices = np.stack([radii[0] * np.cos(u), radii[0] * np.sin(u), radii[1] * np.cos(v), radii[1] * np.sin(v)], 1)
    index = np.arange(nx * ny).reshape(nx, ny)
    a = index.ravel()
    b = np.roll(index, -1, axis=0).ravel()
    c = np.roll(np.roll(index, -1, axis=0), -1, axis=1).ravel()
    d = np.roll(index, -1, axis=1).ravel()
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return vertices, triangles.astype(np.int64)
