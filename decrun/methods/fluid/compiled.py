"""Numba kernels of the fluid step: the backtracking walk, the WSHD07 interpolation and the
circulation sum, one loop per point instead of thousands of numpy calls per step.

Each kernel has a numpy twin that stays the tested reference (``VorticityFluid(kernels="numpy")``,
``app.kernels=numpy``); the arithmetic is the same per point, so results agree to round-off:

* :func:`velocity_points` — :meth:`CellInterpolator.velocity` (interpolation.py): nearest
  corner of the triangle, WSHD07 weights over the flattened dual cell, weighted sum of the
  dual-point velocities, projection into the triangle's plane along the vertex normal;
* :func:`backtrack_points` — :meth:`TriangleWalker.backtrack` (backtrack.py): per point, its
  substeps (midpoint, euler or per_triangle), each a walk across triangles with the direction
  unfolded about every crossed edge and the point clamped at the first border edge it meets.
  The velocity field is fixed during a backtrack, so walking every point through all its
  substeps at once is the same computation as numpy's substep-by-substep rounds over all
  points. On planar meshes it jumps as numpy does (the straight path's end located in the
  triangle grid, or its first border crossing), walking only where that fails. It works in
  place, so the swept scheme's intervals (VorticityFluid._backtrack_sweeping) call it once each,
  starting from the previous interval's end velocities and interpolating the vorticity at the
  new end points; blocks of points run on numba's threads (``jit.threads()``), the same bits on
  any number of threads. The default scheme's walk on a planar mesh (midpoint, least-squares P1
  velocity) runs a specialised block (:func:`_backtrack_block_planar_p1`): the same arithmetic
  in the same order with the point's position and directions in registers and the common jump
  (a path that cannot reach the border and ends within two rings of its triangle) inline, where
  the general block passes them through arrays and out-of-line helpers of a hundred arguments;
* :func:`sweep_points` — the default scheme's k intervals on a planar mesh at once, each point
  through all of them in turn (its triangle rows still in cache), the same bits as k calls of
  :func:`backtrack_points`, keeping every point's position and vorticity after every interval;
* :func:`swept_change_add` — the swept-vorticity change of :meth:`SweptVorticity.change`;
  :func:`swept_change_path` that of every interval of such a path, side by side;
* :func:`circulation_sums` — the trapezoid circulation of :meth:`VorticityFluid.circulation`
  (:func:`circulation_rows`: of some cells).

Lazy kernels of :mod:`decrun.core.jit` (the one ``auto | numba | numpy`` switch, listed in
``jit.KERNELS``), compiled with ``cache=True`` on their first call: the machine code is written
next to this file (``__pycache__``, or numba's user cache dir when that is read-only), so later
processes — every job of a sweep — load it instead of compiling. Importing this module does not
import numba; the first kernel call does.
"""

from __future__ import annotations

import numpy as np

from decrun.core import jit

__all__ = ["velocity_points", "backtrack_points", "sweep_points", "circulation_sums", "circulation_rows",
           "swept_change_add", "swept_change_path", "INTEGRATOR_CODE"]

INTEGRATOR_CODE = {"euler": 0, "midpoint": 1, "per_triangle": 2}

INLINE = "never"  # numba-level inlining of every helper ("always"): loops ~15 % faster on the 12k channel
# but a 2.7× longer cold compile (38 s instead of 14 s); the specialised walk inlines its few helpers (_hot)

# Table layouts (built by TriangleWalker.kernel_tables and CellInterpolator.kernel_tables): one
# row per triangle / vertex holds everything a point there reads, so a point touches a few cache
# lines and the helpers take a few arrays.
TRI_GRADIENT, TRI_CENTROID, TRI_CORNER, TRI_NORMAL, TRI_CLEARANCE = 0, 9, 12, 21, 24  # tri_real columns
TRI_TOP, TRI_NEIGHBOR, TRI_SLOT, TRI_EDGE = 0, 3, 6, 9  # tri_int columns
CELL_VERTEX, CELL_FRAME, CELL_NORMAL, CELL_SCALE, CELL_TABLE = 0, 3, 9, 12, 13  # cell_real columns

_kernel = jit.njit(error_model="numpy")  # x / 0 gives inf or nan, as in numpy
# The helpers allocate nothing and keep no array: without the runtime's reference counts (_nrt=False)
# they do not incref/decref every array argument on each call, which made the walk 2.4× slower.
_helper = jit.njit(error_model="numpy", inline=INLINE, _nrt=False)
# The few small helpers of the specialised walk (_backtrack_block_planar_p1) are inlined at numba's
# level: they return scalars, so the point's state stays in registers between them.
_hot = jit.njit(error_model="numpy", inline="always", _nrt=False)
# The loops over points (the backtracking, most of a step, and the interpolation): ``prange`` over
# one block of points per thread (``chunks``, from ``jit.threads()``), each block a plain compiled
# loop (the _..._block kernels: as the body of a numba parfor the same loops ran up to 2× slower),
# each point computed as in the serial loop, so the bits do not depend on the number of threads.
# The circulation and swept sums run in blocks too (a region costs a few µs on OpenMP, whose threads
# spin a moment between regions; ~0.17 ms on numba's workqueue); the swept rules' circulation of their
# few border cells (circulation_rows) runs serially.
_parallel_kernel = jit.njit(error_model="numpy", parallel=True)
prange = jit.prange


# ---------------------------------------------------------------- interpolation (interpolation.py)
@_helper
def _nearest_vertex(triangles, cell_real, t, x0, x1, x2):
    """The corner of triangle t nearest to x (first of equals, as numpy's argmin)."""
    best, best_distance = triangles[t, 0], np.inf
    for c in range(3):
        v = triangles[t, c]
        d0, d1, d2 = cell_real[v, 0] - x0, cell_real[v, 1] - x1, cell_real[v, 2] - x2
        distance = d0 * d0 + d1 * d1 + d2 * d2
        if distance < best_distance or c == 0:
            best, best_distance = v, distance
    return best


@_helper
def _weights(cell_real, v, x0, x1, x2, w, h):
    """WSHD07 weights (into w, K) of the corners of cell v at x; h is scratch (K + 1)."""
    r0, r1, r2 = x0 - cell_real[v, 0], x1 - cell_real[v, 1], x2 - cell_real[v, 2]
    f1 = r0 * cell_real[v, CELL_FRAME] + r1 * cell_real[v, CELL_FRAME + 1] + r2 * cell_real[v, CELL_FRAME + 2]
    f2 = r0 * cell_real[v, CELL_FRAME + 3] + r1 * cell_real[v, CELL_FRAME + 4] + r2 * cell_real[v, CELL_FRAME + 5]
    lowest = cell_real[v, CELL_SCALE]
    n = h.shape[0]  # K + 1 columns: offset, n1, n2 of the edges (closing edge first), det of the corners
    for j in range(n):
        value = (cell_real[v, CELL_TABLE + j] - cell_real[v, CELL_TABLE + n + j] * f1
                 - cell_real[v, CELL_TABLE + 2 * n + j] * f2)
        h[j] = lowest if value < lowest else value
    total = 0.0
    for k in range(w.shape[0]):
        c = cell_real[v, CELL_TABLE + 3 * n + k + 1] / (h[k] * h[k + 1])
        w[k] = c
        total += c
    for k in range(w.shape[0]):
        w[k] /= total


@_helper
def _combine(cell_real, ids, planar, point_velocity, f, v, t, face_normal, w, out):
    """Σ_k w_k u_k of field f over the corners of cell v (into out, 3), projected into the
    plane of triangle t along the vertex normal (curved meshes)."""
    for d in range(3):
        total = 0.0
        for k in range(w.shape[0]):
            total += w[k] * point_velocity[ids[v, k], d, f]
        out[d] = total
    if not planar:
        n0, n1, n2 = cell_real[v, CELL_NORMAL], cell_real[v, CELL_NORMAL + 1], cell_real[v, CELL_NORMAL + 2]
        m0, m1, m2 = face_normal[t, 0], face_normal[t, 1], face_normal[t, 2]
        ratio = (out[0] * m0 + out[1] * m1 + out[2] * m2) / (n0 * m0 + n1 * m1 + n2 * m2)
        out[0] -= n0 * ratio
        out[1] -= n1 * ratio
        out[2] -= n2 * ratio


@_helper
def _p1(triangles, bary, planar, point_velocity, f, t, x0, x1, x2, face_normal, out):
    """Least-squares reconstruction (reconstruction.LeastSquaresVelocity.velocity): the P1
    (barycentric) interpolation of the vertex velocities of field f at x in t (into out, 3),
    projected into the plane of t. ``triangles`` (m, ≥ 3) the corners first; ``bary`` (m, ≥ 12):
    ∇λ (9), centroid (3) per triangle first (the walker's tri_int and tri_real rows)."""
    r0, r1, r2 = x0 - bary[t, 9], x1 - bary[t, 10], x2 - bary[t, 11]
    l0 = 1.0 / 3.0 + (bary[t, 0] * r0 + bary[t, 1] * r1 + bary[t, 2] * r2)
    l1 = 1.0 / 3.0 + (bary[t, 3] * r0 + bary[t, 4] * r1 + bary[t, 5] * r2)
    l2 = 1.0 / 3.0 + (bary[t, 6] * r0 + bary[t, 7] * r1 + bary[t, 8] * r2)
    c0, c1, c2 = triangles[t, 0], triangles[t, 1], triangles[t, 2]
    for d in range(3):
        out[d] = (l0 * point_velocity[c0, d, f] + l1 * point_velocity[c1, d, f]) + l2 * point_velocity[c2, d, f]
    if not planar:
        n0, n1, n2 = face_normal[t, 0], face_normal[t, 1], face_normal[t, 2]
        along = (out[0] * n0 + out[1] * n1) + out[2] * n2
        out[0] -= n0 * along
        out[1] -= n1 * along
        out[2] -= n2 * along


@_helper
def _velocity(triangles, cell_real, ids, planar, scheme, point_velocity, f, t, x, face_normal, w, h, out):
    """Interpolated velocity (into out, 3) of field f of point_velocity (n_points, 3, F) at x in t:
    scheme 0 WSHD07 over the dual cell, 1 the least-squares vertex velocities (P1)."""
    if scheme == 1:
        _p1(triangles, cell_real, planar, point_velocity, f, t, x[0], x[1], x[2], face_normal, out)
        return
    v = _nearest_vertex(triangles, cell_real, t, x[0], x[1], x[2])
    _weights(cell_real, v, x[0], x[1], x[2], w, h)
    _combine(cell_real, ids, planar, point_velocity, f, v, t, face_normal, w, out)


@_helper
def _all_fields(triangles, cell_real, ids, planar, scheme, point_velocity, t, x0, x1, x2, face_normal, w, h, out,
                result, p, first_field):
    """result[p, :, f] (3,) = the velocity of field f at x in t for the fields f = first_field..F − 1
    (the weights computed once)."""
    F = point_velocity.shape[2]
    if scheme == 1:
        for f in range(first_field, F):
            _p1(triangles, cell_real, planar, point_velocity, f, t, x0, x1, x2, face_normal, out)
            result[p, 0, f], result[p, 1, f], result[p, 2, f] = out[0], out[1], out[2]
        return
    v = _nearest_vertex(triangles, cell_real, t, x0, x1, x2)
    _weights(cell_real, v, x0, x1, x2, w, h)
    for f in range(first_field, F):
        _combine(cell_real, ids, planar, point_velocity, f, v, t, face_normal, w, out)
        result[p, 0, f], result[p, 1, f], result[p, 2, f] = out[0], out[1], out[2]


@_kernel
def _velocity_block(triangles, cell_real, ids, planar, scheme, triangle, x, point_velocity, face_normal, result,
                    first, last):
    """:func:`velocity_points` of the points first..last − 1 into ``result`` (one thread's block)."""
    K = ids.shape[1]
    w, h, out = np.empty(K), np.empty(K + 1), np.empty(3)
    for p in range(first, last):
        _all_fields(triangles, cell_real, ids, planar, scheme, point_velocity, triangle[p], x[p, 0], x[p, 1], x[p, 2],
                    face_normal, w, h, out, result, p, 0)


@_parallel_kernel
def velocity_points(field, triangle, x, point_velocity, face_normal, chunks):
    """(P, 3, F) interpolated velocities at x (P, 3) in ``triangle`` (P,) of the F fields
    ``point_velocity`` (n_points, 3, F); ``field`` is the reconstruction's ``kernel_tables()``
    (:meth:`CellInterpolator.kernel_tables`, :meth:`LeastSquaresVelocity.kernel_tables`);
    ``chunks`` blocks of points in parallel."""
    triangles, cell_real, ids, planar, scheme = field
    P, F = x.shape[0], point_velocity.shape[2]
    result = np.empty((P, 3, F))
    for c in prange(chunks):
        _velocity_block(triangles, cell_real, ids, planar, scheme, triangle, x, point_velocity, face_normal, result,
                        c * P // chunks, (c + 1) * P // chunks)
    return result


# ---------------------------------------------------------------- the walk (backtrack.py)
@_helper
def _unfold(vertices, tri_real, tri_int, d, t, slot, nb):
    """Rotate d (3, in place) about the edge opposite ``slot`` of t into the plane of nb."""
    a, b = tri_int[t, TRI_TOP + (slot + 1) % 3], tri_int[t, TRI_TOP + (slot + 2) % 3]
    e0, e1, e2 = vertices[b, 0] - vertices[a, 0], vertices[b, 1] - vertices[a, 1], vertices[b, 2] - vertices[a, 2]
    length = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    e0, e1, e2 = e0 / length, e1 / length, e2 / length
    N0, N1, N2 = tri_real[t, TRI_NORMAL], tri_real[t, TRI_NORMAL + 1], tri_real[t, TRI_NORMAL + 2]
    o0, o1, o2 = N1 * e2 - N2 * e1, N2 * e0 - N0 * e2, N0 * e1 - N1 * e0
    N0, N1, N2 = tri_real[nb, TRI_NORMAL], tri_real[nb, TRI_NORMAL + 1], tri_real[nb, TRI_NORMAL + 2]
    n0, n1, n2 = N1 * e2 - N2 * e1, N2 * e0 - N0 * e2, N0 * e1 - N1 * e0
    along = d[0] * e0 + d[1] * e1 + d[2] * e2
    across = d[0] * o0 + d[1] * o1 + d[2] * o2
    d[0], d[1], d[2] = along * e0 + across * n0, along * e1 + across * n1, along * e2 + across * n2


@_helper
def _barycentric(tri_real, t, x, lam):
    r0 = x[0] - tri_real[t, TRI_CENTROID]
    r1 = x[1] - tri_real[t, TRI_CENTROID + 1]
    r2 = x[2] - tri_real[t, TRI_CENTROID + 2]
    for c in range(3):
        lam[c] = 1.0 / 3.0 + (tri_real[t, 3 * c] * r0 + tri_real[t, 3 * c + 1] * r1 + tri_real[t, 3 * c + 2] * r2)


@_helper
def _round(vertices, tri_real, tri_int, planar, state, x, d, lam, rate):
    """One walking round of one point (TriangleWalker._advance): move inside the triangle
    state[0] until the remaining time state[3] is used or an edge is reached; cross it (entry
    slot state[1]) or stop at the wall (state[2] = border edge). Returns True when done."""
    t, entry = int(state[0]), int(state[1])
    remaining = state[3]
    _barycentric(tri_real, t, x, lam)
    for c in range(3):
        if lam[c] < 0.0:
            lam[c] = 0.0
        rate[c] = tri_real[t, 3 * c] * d[0] + tri_real[t, 3 * c + 1] * d[1] + tri_real[t, 3 * c + 2] * d[2]
    s, slot = np.inf, 0
    for c in range(3):
        exit_time = lam[c] / -rate[c] if rate[c] < 0 else np.inf
        if c == entry:
            exit_time = np.inf
        if exit_time < s:
            s, slot = exit_time, c
    if s >= remaining:
        for k in range(3):
            x[k] = x[k] + remaining * d[k]
        state[3] = 0.0
        return True
    for c in range(3):
        value = 0.0 if c == slot else lam[c] + s * rate[c]
        lam[c] = value if value > 0.0 else 0.0
    total = lam[0] + lam[1] + lam[2]
    for c in range(3):
        lam[c] /= total
    for k in range(3):
        x[k] = (lam[0] * tri_real[t, TRI_CORNER + k] + lam[1] * tri_real[t, TRI_CORNER + 3 + k]
                + lam[2] * tri_real[t, TRI_CORNER + 6 + k])
    state[3] = remaining - s
    nb = tri_int[t, TRI_NEIGHBOR + slot]
    if nb < 0:
        state[2] = tri_int[t, TRI_EDGE + slot]
        state[3] = 0.0
        return True
    if not planar:
        _unfold(vertices, tri_real, tri_int, d, t, slot, nb)
    state[1] = tri_int[t, TRI_SLOT + slot]
    state[0] = nb
    return False


@_helper
def _inside(near, c, y0, y1, margin):
    return (near[c, 0] * y0 + near[c, 1] * y1 + near[c, 2] >= margin
            and near[c, 3] * y0 + near[c, 4] * y1 + near[c, 5] >= margin
            and near[c, 6] * y0 + near[c, 7] * y1 + near[c, 8] >= margin)


@_helper
def _locate_near(near, tri_int, t, y0, y1):
    """Triangle t, its neighbours or theirs when one holds (y0, y1) with every barycentric
    coordinate ≥ 1e-7, else -1. Such a point lies in no other triangle nor within 1e-12 of one
    (for edge-length ratios below 1e5), so the grid search would give the same triangle."""
    margin = 1e-7
    if _inside(near, t, y0, y1, margin):
        return t
    for i in range(3):
        n = tri_int[t, TRI_NEIGHBOR + i]
        if n >= 0 and _inside(near, n, y0, y1, margin):
            return n
    for i in range(3):
        n = tri_int[t, TRI_NEIGHBOR + i]
        if n < 0:
            continue
        for j in range(3):
            n2 = tri_int[n, TRI_NEIGHBOR + j]
            if n2 >= 0 and n2 != t and _inside(near, n2, y0, y1, margin):
                return n2
    return -1


@_helper
def _locate(affine, buckets, grid, grid_shape, y0, y1):
    """The first triangle of the grid bucket holding (y0, y1) that contains it (barycentric
    coordinates ≥ −1e-12, as numpy's _jump tests them), or -1. ``affine`` holds the bucket
    members' rows in bucket order (slot j: triangle buckets[j + 1 + n_cells])."""
    cx = min(max(int(np.floor((y0 - grid[0]) / grid[2])), 0), grid_shape[0] - 1)
    cy = min(max(int(np.floor((y1 - grid[1]) / grid[2])), 0), grid_shape[1] - 1)
    cell = cy * grid_shape[0] + cx
    members = grid_shape[0] * grid_shape[1] + 1  # buckets: start (cells + 1), then the members
    for j in range(buckets[cell], buckets[cell + 1]):
        if (affine[j, 0] * y0 + affine[j, 1] * y1 + affine[j, 2] >= -1e-12
                and affine[j, 3] * y0 + affine[j, 4] * y1 + affine[j, 5] >= -1e-12
                and affine[j, 6] * y0 + affine[j, 7] * y1 + affine[j, 8] >= -1e-12):
            return buckets[members + j]
    return -1


@_helper
def _first_crossing(border_real, border_buckets, grid, grid_shape, p0, p1, q0, q1):
    """First border edge crossed outwards by the segment p → q (TriangleWalker._first_crossing):
    (segment parameter in [0, 1] or inf, border edge index or -1)."""
    size, nx, ny = grid[5], grid_shape[2], grid_shape[3]
    x_low = min(max(int(np.floor((min(p0, q0) - grid[3]) / size)), 0), nx - 1)
    y_low = min(max(int(np.floor((min(p1, q1) - grid[4]) / size)), 0), ny - 1)
    x_high = min(max(int(np.floor((max(p0, q0) - grid[3]) / size)), 0), nx - 1)
    y_high = min(max(int(np.floor((max(p1, q1) - grid[4]) / size)), 0), ny - 1)
    members = nx * ny + 1
    d0, d1 = q0 - p0, q1 - p1
    best_s, best = np.inf, -1
    for cy in range(y_low, y_high + 1):
        for cx in range(x_low, x_high + 1):
            cell = cy * nx + cx
            for j in range(border_buckets[cell], border_buckets[cell + 1]):
                k = border_buckets[members + j]
                a0, a1, e0, e1 = border_real[k, 0], border_real[k, 1], border_real[k, 2], border_real[k, 3]
                den = d0 * e1 - d1 * e0
                ap0, ap1 = a0 - p0, a1 - p1
                s = (ap0 * e1 - ap1 * e0) / den
                r = (ap0 * d1 - ap1 * d0) / den
                outward = d0 * border_real[k, 4] + d1 * border_real[k, 5] > 0
                if outward and s >= -1e-12 and s <= 1 + 1e-12 and r >= -1e-12 and r <= 1 + 1e-12:
                    s = min(max(s, 0.0), 1.0)
                    if s < best_s:
                        best_s, best = s, k
    return best_s, best


@_helper
def _jump(tri_real, tri_int, affine, buckets, border_real, border_buckets, grid, grid_shape, near, x, t, d, time,
          state):
    """Planar meshes (TriangleWalker._jump): a straight path that cannot reach the border, or
    reaches no border edge, ends at x + time·d (located in the triangle grid); one that leaves
    through a border edge stops on it. Returns True when done (state[0] triangle, state[2] wall)."""
    bound = -np.inf
    for c in range(3):
        g0 = tri_real[t, TRI_CORNER + 3 * c] - x[0]
        g1 = tri_real[t, TRI_CORNER + 3 * c + 1] - x[1]
        g2 = tri_real[t, TRI_CORNER + 3 * c + 2] - x[2]
        bound = max(bound, tri_real[t, TRI_CLEARANCE + c] - np.sqrt(g0 * g0 + g1 * g1 + g2 * g2))
    safe = time * time * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) < bound * abs(bound)
    if not safe and border_real.shape[0] > 0:
        q0, q1 = x[0] + time * d[0], x[1] + time * d[1]
        s, k = _first_crossing(border_real, border_buckets, grid, grid_shape, x[0], x[1], q0, q1)
        if k >= 0:
            for i in range(3):
                x[i] = x[i] + (s * time) * d[i]
            state[0], state[2] = border_real[k, 7], border_real[k, 6]
            return True
    y0, y1, y2 = x[0] + time * d[0], x[1] + time * d[1], x[2] + time * d[2]
    c = _locate_near(near, tri_int, t, y0, y1)  # most paths end within two triangles
    if c < 0:
        c = _locate(affine, buckets, grid, grid_shape, y0, y1)
    if c < 0:
        return False
    x[0], x[1], x[2] = y0, y1, y2
    state[0] = c
    return True


@_helper
def _walk(vertices, tri_real, tri_int, planar, affine, buckets, border_real, border_buckets, grid, grid_shape, near,
          x, t, d, time, max_rounds, state, lam, rate):
    """Move one point (x, d in place) from triangle t for ``time``: TriangleWalker.walk (the
    jump on planar meshes, else rounds across triangles). Returns (triangle, wall edge or -1,
    rounds, unfinished)."""
    state[0], state[1], state[2], state[3] = t, -1, -1, time
    if not time > 0:
        return t, -1, 0, False
    if affine.shape[0] > 0 and _jump(tri_real, tri_int, affine, buckets, border_real, border_buckets, grid,
                                     grid_shape, near, x, t, d, time, state):
        return int(state[0]), int(state[2]), 0, False
    rounds, done = 0, False
    while not done and rounds < max_rounds:
        rounds += 1
        done = _round(vertices, tri_real, tri_int, planar, state, x, d, lam, rate)
    return int(state[0]), int(state[2]), rounds, not done


@_helper
def _substep_count(begin, dt, size, substeps, max_cfl, cap):
    """TriangleWalker.substep_counts for one point: ``substeps``, or with ``max_cfl`` > 0 enough
    that one substep moves it at most max_cfl × ``size`` at the velocity ``begin`` (3), at most
    ``cap``; the same rounding as numpy's (a non-finite CFL number gives ``substeps``)."""
    if not max_cfl > 0:
        return substeps
    cfl = np.sqrt((begin[0] * begin[0] + begin[1] * begin[1]) + begin[2] * begin[2]) * dt / size
    ratio = np.ceil(cfl / max_cfl)
    if not (ratio > -9.2e18 and ratio < 9.2e18):  # numpy's astype(int64) of inf / nan, then the clip
        return substeps
    return min(max(int(ratio), substeps), cap)


@_kernel
def _backtrack_block(vertices, tri_real, tri_int, face_normal, planar, affine, buckets, border_real, border_buckets, grid,
                     grid_shape, near, triangles, cell_real, ids, field_planar, scheme, point_velocity, position,
                     triangle, wall, start_velocity, end_velocity, first, size, dt, substeps, max_cfl, cap, integrator,
                     max_rounds, vorticity, value, first_field, first_point, last_point, rounds, unfinished):
    """:func:`backtrack_points` for the points first_point..last_point − 1 (one thread's block,
    compiled as a plain loop: numba's parfor body ran the same loop 1.6× slower); adds into
    ``rounds`` (cap, 2) and ``unfinished`` (cap,) and returns the largest substep count (≥ 1)."""
    K = ids.shape[1]
    interpolate = value.shape[0] > 0
    w, h = np.empty(K), np.empty(K + 1)
    state, lam, rate = np.empty(4), np.empty(3), np.empty(3)
    d, d1, x = np.empty(3), np.empty(3), np.empty(3)
    steps = 1
    for p in range(first_point, last_point):
        t = triangle[p]
        x[0], x[1], x[2] = position[p, 0], position[p, 1], position[p, 2]
        if wall[p] < 0:
            for k in range(3):  # d1: the start velocity
                d1[k] = start_velocity[p, k] if first else end_velocity[p, k, 1]
            count = _substep_count(d1, dt, size[t], substeps, max_cfl, cap)
            steps = max(steps, count)
            tau = dt / count
            hit = -1
            for substep in range(count):
                r, left = 0, False
                if integrator == 2:
                    state[0], state[1], state[2], state[3] = t, -1, -1, tau
                    d[0], d[1], d[2] = 0.0, 0.0, 0.0
                    done = not tau > 0
                    while not done and r < max_rounds:
                        r += 1
                        came = int(state[1])
                        t = int(state[0])
                        _velocity(triangles, cell_real, ids, field_planar, scheme, point_velocity, 1, t, x,
                                  face_normal, w, h, d1)
                        for k in range(3):
                            d1[k] = -d1[k]
                        back = False
                        if came >= 0:  # a fresh velocity leaving at once through the entry edge: keep the unfolded one
                            _barycentric(tri_real, t, x, lam)
                            lam_came = lam[came] if lam[came] > 0.0 else 0.0
                            rate_came = (tri_real[t, 3 * came] * d1[0] + tri_real[t, 3 * came + 1] * d1[1]
                                         + tri_real[t, 3 * came + 2] * d1[2])
                            back = rate_came < 0 and lam_came <= 1e-12
                        if not back:
                            d[0], d[1], d[2] = d1[0], d1[1], d1[2]
                        done = _round(vertices, tri_real, tri_int, planar, state, x, d, lam, rate)
                    t, hit, left = int(state[0]), int(state[2]), not done
                else:
                    if substep == 0:
                        for k in range(3):
                            d[k] = -d1[k]
                    else:
                        _velocity(triangles, cell_real, ids, field_planar, scheme, point_velocity, 1, t, x,
                                  face_normal, w, h, d)
                        for k in range(3):
                            d[k] = -d[k]
                    if integrator == 1:
                        # x + τ d2 = x_m + τ (d2 − d1 / 2): continue from the midpoint (d1 unfolded there)
                        t, hit, r, left = _walk(vertices, tri_real, tri_int, planar, affine, buckets, border_real,
                                                border_buckets, grid, grid_shape, near, x, t, d, 0.5 * tau,
                                                max_rounds, state, lam, rate)
                        rounds[substep, 0] = max(rounds[substep, 0], r)
                        d1[0], d1[1], d1[2] = d[0], d[1], d[2]
                        _velocity(triangles, cell_real, ids, field_planar, scheme, point_velocity, 1, t, x,
                                  face_normal, w, h, d)
                        for k in range(3):
                            d[k] = 0.0 if hit >= 0 else -d[k] - 0.5 * d1[k]
                    t, hit2, r, left = _walk(vertices, tri_real, tri_int, planar, affine, buckets, border_real,
                                             border_buckets, grid, grid_shape, near, x, t, d, tau, max_rounds,
                                             state, lam, rate)
                    if hit < 0:
                        hit = hit2
                rounds[substep, 1] = max(rounds[substep, 1], r)
                if left:
                    unfinished[substep] += 1
                if hit >= 0:
                    break
            position[p, 0], position[p, 1], position[p, 2] = x[0], x[1], x[2]
            triangle[p], wall[p] = t, hit
            _all_fields(triangles, cell_real, ids, field_planar, scheme, point_velocity, t, x[0], x[1], x[2],
                        face_normal, w, h, d, end_velocity, p,
                        0 if hit >= 0 else first_field)  # the end point's velocities (all at a wall: it stays)
        if interpolate:
            _barycentric(tri_real, t, x, lam)
            value[p] = (lam[0] * vorticity[tri_int[t, TRI_TOP]] + lam[1] * vorticity[tri_int[t, TRI_TOP + 1]]) \
                + lam[2] * vorticity[tri_int[t, TRI_TOP + 2]]
    return steps


@_hot
def _p1_planar(triangles, bary, point_velocity, f, t, x0, x1, x2):
    """:func:`_p1` on a planar mesh (no projection), as three scalars: the same arithmetic."""
    r0, r1, r2 = x0 - bary[t, 9], x1 - bary[t, 10], x2 - bary[t, 11]
    l0 = 1.0 / 3.0 + (bary[t, 0] * r0 + bary[t, 1] * r1 + bary[t, 2] * r2)
    l1 = 1.0 / 3.0 + (bary[t, 3] * r0 + bary[t, 4] * r1 + bary[t, 5] * r2)
    l2 = 1.0 / 3.0 + (bary[t, 6] * r0 + bary[t, 7] * r1 + bary[t, 8] * r2)
    c0, c1, c2 = triangles[t, 0], triangles[t, 1], triangles[t, 2]
    return ((l0 * point_velocity[c0, 0, f] + l1 * point_velocity[c1, 0, f]) + l2 * point_velocity[c2, 0, f],
            (l0 * point_velocity[c0, 1, f] + l1 * point_velocity[c1, 1, f]) + l2 * point_velocity[c2, 1, f],
            (l0 * point_velocity[c0, 2, f] + l1 * point_velocity[c1, 2, f]) + l2 * point_velocity[c2, 2, f])


@_hot
def _jump_near(tri_real, tri_int, near, t, x0, x1, x2, d0, d1, d2, time):
    """The common case of :func:`_jump`: a straight path that cannot reach the border (the same
    bound) and ends in triangle t, its neighbours or theirs (:func:`_locate_near`): that triangle,
    else -1 (the caller then walks the point by :func:`_walk`, which decides alike)."""
    bound = -np.inf
    for c in range(3):
        g0 = tri_real[t, TRI_CORNER + 3 * c] - x0
        g1 = tri_real[t, TRI_CORNER + 3 * c + 1] - x1
        g2 = tri_real[t, TRI_CORNER + 3 * c + 2] - x2
        bound = max(bound, tri_real[t, TRI_CLEARANCE + c] - np.sqrt(g0 * g0 + g1 * g1 + g2 * g2))
    if not time * time * (d0 * d0 + d1 * d1 + d2 * d2) < bound * abs(bound):
        return -1
    return _locate_near(near, tri_int, t, x0 + time * d0, x1 + time * d1)


@_kernel
def _backtrack_block_planar_p1(vertices, tri_real, tri_int, face_normal, planar, affine, buckets, border_real,
                               border_buckets, grid, grid_shape, near, triangles, bary, point_velocity, position,
                               triangle, wall, start_velocity, end_velocity, first, size, dt, substeps, max_cfl, cap,
                               max_rounds, vorticity, value, first_field, first_point, last_point, rounds, unfinished):
    """:func:`_backtrack_block` for the midpoint integrator with the least-squares (P1) velocity on
    a planar mesh: the same arithmetic in the same order, the point's state in registers and the
    common jump inline; a point whose path may reach the border or ends beyond the two rings
    around its triangle walks by :func:`_walk`, as there."""
    interpolate = value.shape[0] > 0
    F = point_velocity.shape[2]
    state, lam, rate = np.empty(4), np.empty(3), np.empty(3)
    xa, da = np.empty(3), np.empty(3)
    steps = 1
    for p in range(first_point, last_point):
        t = triangle[p]
        x0, x1, x2 = position[p, 0], position[p, 1], position[p, 2]
        if wall[p] < 0:
            if first:
                b0, b1, b2 = start_velocity[p, 0], start_velocity[p, 1], start_velocity[p, 2]
            else:
                b0, b1, b2 = end_velocity[p, 0, 1], end_velocity[p, 1, 1], end_velocity[p, 2, 1]
            count = substeps
            if max_cfl > 0:  # _substep_count
                ratio = np.ceil(np.sqrt((b0 * b0 + b1 * b1) + b2 * b2) * dt / size[t] / max_cfl)
                if ratio > -9.2e18 and ratio < 9.2e18:
                    count = min(max(int(ratio), substeps), cap)
            steps = max(steps, count)
            tau = dt / count
            hit = -1
            for substep in range(count):
                if substep == 0:
                    e0, e1, e2 = -b0, -b1, -b2
                else:
                    v0, v1, v2 = _p1_planar(triangles, bary, point_velocity, 1, t, x0, x1, x2)
                    e0, e1, e2 = -v0, -v1, -v2
                # x + τ d2 = x_m + τ (d2 − d1 / 2): continue from the midpoint
                half = 0.5 * tau
                r, left = 0, False
                if half > 0:
                    c = _jump_near(tri_real, tri_int, near, t, x0, x1, x2, e0, e1, e2, half)
                    if c >= 0:
                        x0, x1, x2 = x0 + half * e0, x1 + half * e1, x2 + half * e2
                        t = c
                    else:
                        xa[0], xa[1], xa[2] = x0, x1, x2
                        da[0], da[1], da[2] = e0, e1, e2
                        t, hit, r, left = _walk(vertices, tri_real, tri_int, planar, affine, buckets, border_real,
                                                border_buckets, grid, grid_shape, near, xa, t, da, half, max_rounds,
                                                state, lam, rate)
                        x0, x1, x2 = xa[0], xa[1], xa[2]
                rounds[substep, 0] = max(rounds[substep, 0], r)
                b0, b1, b2 = e0, e1, e2
                v0, v1, v2 = _p1_planar(triangles, bary, point_velocity, 1, t, x0, x1, x2)
                if hit >= 0:
                    e0, e1, e2 = 0.0, 0.0, 0.0
                else:
                    e0, e1, e2 = -v0 - 0.5 * b0, -v1 - 0.5 * b1, -v2 - 0.5 * b2
                hit2, r, left = -1, 0, False
                if tau > 0:
                    c = _jump_near(tri_real, tri_int, near, t, x0, x1, x2, e0, e1, e2, tau)
                    if c >= 0:
                        x0, x1, x2 = x0 + tau * e0, x1 + tau * e1, x2 + tau * e2
                        t = c
                    else:
                        xa[0], xa[1], xa[2] = x0, x1, x2
                        da[0], da[1], da[2] = e0, e1, e2
                        t, hit2, r, left = _walk(vertices, tri_real, tri_int, planar, affine, buckets, border_real,
                                                 border_buckets, grid, grid_shape, near, xa, t, da, tau, max_rounds,
                                                 state, lam, rate)
                        x0, x1, x2 = xa[0], xa[1], xa[2]
                if hit < 0:
                    hit = hit2
                rounds[substep, 1] = max(rounds[substep, 1], r)
                if left:
                    unfinished[substep] += 1
                if hit >= 0:
                    break
            position[p, 0], position[p, 1], position[p, 2] = x0, x1, x2
            triangle[p], wall[p] = t, hit
            for f in range(0 if hit >= 0 else first_field, F):  # the end point's velocities (all at a wall)
                v0, v1, v2 = _p1_planar(triangles, bary, point_velocity, f, t, x0, x1, x2)
                end_velocity[p, 0, f], end_velocity[p, 1, f], end_velocity[p, 2, f] = v0, v1, v2
        if interpolate:
            r0 = x0 - tri_real[t, TRI_CENTROID]
            r1 = x1 - tri_real[t, TRI_CENTROID + 1]
            r2 = x2 - tri_real[t, TRI_CENTROID + 2]
            l0 = 1.0 / 3.0 + (tri_real[t, 0] * r0 + tri_real[t, 1] * r1 + tri_real[t, 2] * r2)
            l1 = 1.0 / 3.0 + (tri_real[t, 3] * r0 + tri_real[t, 4] * r1 + tri_real[t, 5] * r2)
            l2 = 1.0 / 3.0 + (tri_real[t, 6] * r0 + tri_real[t, 7] * r1 + tri_real[t, 8] * r2)
            value[p] = (l0 * vorticity[tri_int[t, TRI_TOP]] + l1 * vorticity[tri_int[t, TRI_TOP + 1]]) \
                + l2 * vorticity[tri_int[t, TRI_TOP + 2]]
    return steps


@_kernel
def _sweep_block_planar_p1(vertices, tri_real, tri_int, planar, affine, buckets, border_real, border_buckets, grid,
                           grid_shape, near, point_velocity, path, triangle, wall, start_velocity, end_velocity, size,
                           dt, substeps, max_cfl, cap, max_rounds, vorticity, values, first_point, last_point,
                           rounds, unfinished, steps):
    """:func:`sweep_points` for the points first_point..last_point − 1 (one thread's block): each
    point through all k intervals in turn, each interval the body of
    :func:`_backtrack_block_planar_p1` (with ``bary``, ``triangles`` the walker's ``tri_real``,
    ``tri_int``), its triangle rows still in cache from the interval before. The body is written
    out here as there: as one function inlined into both (numba's inline="always") the block ran
    1.25× slower."""
    k = path.shape[1] - 1
    F = point_velocity.shape[2]
    state, lam, rate = np.empty(4), np.empty(3), np.empty(3)
    xa, da = np.empty(3), np.empty(3)
    triangles, bary = tri_int, tri_real
    for p in range(first_point, last_point):
        t, hit = triangle[p], wall[p]
        x0, x1, x2 = path[p, 0, 0], path[p, 0, 1], path[p, 0, 2]
        for i in range(k):
            base = i * cap
            if hit < 0:
                if i == 0:
                    b0, b1, b2 = start_velocity[p, 0], start_velocity[p, 1], start_velocity[p, 2]
                else:
                    b0, b1, b2 = end_velocity[p, 0, 1], end_velocity[p, 1, 1], end_velocity[p, 2, 1]
                count = substeps
                if max_cfl > 0:  # _substep_count
                    ratio = np.ceil(np.sqrt((b0 * b0 + b1 * b1) + b2 * b2) * dt / size[t] / max_cfl)
                    if ratio > -9.2e18 and ratio < 9.2e18:
                        count = min(max(int(ratio), substeps), cap)
                steps[i] = max(steps[i], count)
                tau = dt / count
                for substep in range(count):
                    if substep == 0:
                        e0, e1, e2 = -b0, -b1, -b2
                    else:
                        v0, v1, v2 = _p1_planar(triangles, bary, point_velocity, 1, t, x0, x1, x2)
                        e0, e1, e2 = -v0, -v1, -v2
                    # x + τ d2 = x_m + τ (d2 − d1 / 2): continue from the midpoint
                    half = 0.5 * tau
                    r, left = 0, False
                    if half > 0:
                        c = _jump_near(tri_real, tri_int, near, t, x0, x1, x2, e0, e1, e2, half)
                        if c >= 0:
                            x0, x1, x2 = x0 + half * e0, x1 + half * e1, x2 + half * e2
                            t = c
                        else:
                            xa[0], xa[1], xa[2] = x0, x1, x2
                            da[0], da[1], da[2] = e0, e1, e2
                            t, hit, r, left = _walk(vertices, tri_real, tri_int, planar, affine, buckets,
                                                    border_real, border_buckets, grid, grid_shape, near, xa, t, da,
                                                    half, max_rounds, state, lam, rate)
                            x0, x1, x2 = xa[0], xa[1], xa[2]
                    rounds[base + substep, 0] = max(rounds[base + substep, 0], r)
                    b0, b1, b2 = e0, e1, e2
                    v0, v1, v2 = _p1_planar(triangles, bary, point_velocity, 1, t, x0, x1, x2)
                    if hit >= 0:
                        e0, e1, e2 = 0.0, 0.0, 0.0
                    else:
                        e0, e1, e2 = -v0 - 0.5 * b0, -v1 - 0.5 * b1, -v2 - 0.5 * b2
                    hit2, r, left = -1, 0, False
                    if tau > 0:
                        c = _jump_near(tri_real, tri_int, near, t, x0, x1, x2, e0, e1, e2, tau)
                        if c >= 0:
                            x0, x1, x2 = x0 + tau * e0, x1 + tau * e1, x2 + tau * e2
                            t = c
                        else:
                            xa[0], xa[1], xa[2] = x0, x1, x2
                            da[0], da[1], da[2] = e0, e1, e2
                            t, hit2, r, left = _walk(vertices, tri_real, tri_int, planar, affine, buckets,
                                                     border_real, border_buckets, grid, grid_shape, near, xa, t, da,
                                                     tau, max_rounds, state, lam, rate)
                            x0, x1, x2 = xa[0], xa[1], xa[2]
                    if hit < 0:
                        hit = hit2
                    rounds[base + substep, 1] = max(rounds[base + substep, 1], r)
                    if left:
                        unfinished[base + substep] += 1
                    if hit >= 0:
                        break
                # the end point's velocities: field F − 1 (the next interval's start), all at the
                # last interval and at a wall
                for f in range(0 if hit >= 0 or i == k - 1 else F - 1, F):
                    v0, v1, v2 = _p1_planar(triangles, bary, point_velocity, f, t, x0, x1, x2)
                    end_velocity[p, 0, f], end_velocity[p, 1, f], end_velocity[p, 2, f] = v0, v1, v2
            path[p, i + 1, 0], path[p, i + 1, 1], path[p, i + 1, 2] = x0, x1, x2
            r0 = x0 - tri_real[t, TRI_CENTROID]
            r1 = x1 - tri_real[t, TRI_CENTROID + 1]
            r2 = x2 - tri_real[t, TRI_CENTROID + 2]
            l0 = 1.0 / 3.0 + (tri_real[t, 0] * r0 + tri_real[t, 1] * r1 + tri_real[t, 2] * r2)
            l1 = 1.0 / 3.0 + (tri_real[t, 3] * r0 + tri_real[t, 4] * r1 + tri_real[t, 5] * r2)
            l2 = 1.0 / 3.0 + (tri_real[t, 6] * r0 + tri_real[t, 7] * r1 + tri_real[t, 8] * r2)
            values[p, i + 1] = (l0 * vorticity[tri_int[t, TRI_TOP]] + l1 * vorticity[tri_int[t, TRI_TOP + 1]]) \
                + l2 * vorticity[tri_int[t, TRI_TOP + 2]]
        triangle[p], wall[p] = t, hit


@_parallel_kernel
def sweep_points(walk, jump, point_velocity, path, triangle, wall, start_velocity, end_velocity, size, dt, substeps,
                 max_cfl, cap, max_rounds, vorticity, values, chunks):
    """The k intervals of the swept scheme's walk (VorticityFluid._backtrack_sweeping) at once, for
    the midpoint integrator with the least-squares (P1) velocity on a planar mesh, whose tables are
    the walker's (``LeastSquaresVelocity.kernel_tables``): the same bits as k calls of
    :func:`backtrack_points` (interval i over ``dt`` = dt_step / k, ``first`` for i = 0, the end
    velocities of field F − 1 only before the last interval, of all fields after it), each point
    walked through its k intervals in turn, blocks of points in parallel.

    path : (≥ P, k + 1, 3) path[:P, i] where the P points are after interval i − 1 (path[:P, 0] the
        start points, in ``triangle`` (P,), ``wall`` (P,) −1, both updated to the last interval's),
        the rows from P on not read nor written (each point's path in one piece of memory)
    start_velocity (P, 3) : the velocity the first interval starts with; end_velocity (P, 3, F):
        written, the end velocities of the last interval (the earlier ones, of field F − 1, are
        each the next interval's start)
    vorticity (n0,), values (≥ P, k + 1) : values[:P, i + 1] written, the P1 vorticity at path[:P, i + 1]

    Returns rounds (k, cap, 2), unfinished (k, cap) and steps (k,): :func:`backtrack_points`'
    three results of each interval."""
    vertices, tri_real, tri_int, face_normal, planar = walk
    affine, buckets, border_real, border_buckets, grid, grid_shape, near = jump
    k, P = path.shape[1] - 1, triangle.shape[0]
    chunk_rounds = np.zeros((chunks, k * cap, 2), dtype=np.int64)
    chunk_unfinished = np.zeros((chunks, k * cap), dtype=np.int64)
    chunk_steps = np.ones((chunks, k), dtype=np.int64)
    for c in prange(chunks):
        _sweep_block_planar_p1(vertices, tri_real, tri_int, planar, affine, buckets, border_real, border_buckets,
                               grid, grid_shape, near, point_velocity, path, triangle, wall, start_velocity,
                               end_velocity, size, dt, substeps, max_cfl, cap, max_rounds, vorticity, values,
                               c * P // chunks, (c + 1) * P // chunks, chunk_rounds[c], chunk_unfinished[c],
                               chunk_steps[c])
    rounds = np.zeros((k, cap, 2), dtype=np.int64)
    unfinished = np.zeros((k, cap), dtype=np.int64)
    steps = np.ones(k, dtype=np.int64)
    for c in range(chunks):
        for i in range(k):
            steps[i] = max(steps[i], chunk_steps[c, i])
            for s in range(cap):
                rounds[i, s, 0] = max(rounds[i, s, 0], chunk_rounds[c, i * cap + s, 0])
                rounds[i, s, 1] = max(rounds[i, s, 1], chunk_rounds[c, i * cap + s, 1])
                unfinished[i, s] += chunk_unfinished[c, i * cap + s]
    return rounds, unfinished, steps


@_parallel_kernel
def backtrack_points(walk, jump, field, point_velocity, position, triangle, wall, start_velocity, end_velocity, first,
                     size, dt, substeps, max_cfl, cap, integrator, max_rounds, vorticity, value, first_field, chunks):
    """Backtrack along −u for ``dt`` (TriangleWalker.backtrack), point by point and in place, in
    ``chunks`` blocks of points run in parallel (the result does not depend on ``chunks``).

    walk, jump : :meth:`TriangleWalker.kernel_tables`; field : the reconstruction's ``kernel_tables()``
    point_velocity : (n_points, 3, F) dual-point velocities, field 1 is the full u (mesh units / s)
    position (P, 3), triangle (P,), wall (P,) : where each point is, updated; a point with
    ``wall`` ≥ 0 (clamped at that border edge) does not move
    start_velocity (P, 3) : the velocity the first substep starts with when ``first``; otherwise
        field 1 of ``end_velocity`` (P, 3, F), the previous call's end velocities (the swept
        intervals), which are then overwritten with the velocities of all F fields at the new end
        points (velocity_points there)
    size (n2,) : mean edge length per triangle; substeps, max_cfl, cap : the points' substep
        counts (TriangleWalker.substep_counts; ``max_cfl`` ≤ 0: none, at most ``cap``), each
        substep of length dt / count; integrator : INTEGRATOR_CODE
    vorticity (n0,), value (P,) : when ``value`` is not empty, value[p] = the P1 interpolation
        (λ0 w0 + λ1 w1) + λ2 w2 of the vertex vorticity at every point (moved or not)
    first_field : the end velocities of the fields first_field..F − 1 only, except at points
        clamped in this call (0: all; the swept intervals before the last need field 1 only, their
        next start velocities; a clamped point moves no more, so its end velocities are final)

    Returns rounds (cap, 2) the most rounds any moving point walked in substep s (column 0: the
    midpoint half step, 1: the full step), unfinished (cap,) points still walking after
    ``max_rounds`` in substep s, and the largest substep count (1 when no point moved).

    per_triangle (Fig. 7.9, TriangleWalker._walk_per_triangle): every round takes a fresh
    velocity in the triangle entered, unless it leaves at once through the entry edge.
    """
    vertices, tri_real, tri_int, face_normal, planar = walk
    affine, buckets, border_real, border_buckets, grid, grid_shape, near = jump
    triangles, cell_real, ids, field_planar, scheme = field
    P = position.shape[0]
    chunk_rounds = np.zeros((chunks, cap, 2), dtype=np.int64)
    chunk_unfinished = np.zeros((chunks, cap), dtype=np.int64)
    chunk_steps = np.ones(chunks, dtype=np.int64)
    fast = planar and field_planar and scheme == 1 and integrator == 1 and affine.shape[0] > 0
    for c in prange(chunks):
        if fast:  # the default scheme's walk on a planar mesh (midpoint, least squares): specialised
            chunk_steps[c] = _backtrack_block_planar_p1(
                vertices, tri_real, tri_int, face_normal, planar, affine, buckets, border_real, border_buckets, grid,
                grid_shape, near, triangles, cell_real, point_velocity, position, triangle, wall, start_velocity,
                end_velocity, first, size, dt, substeps, max_cfl, cap, max_rounds, vorticity, value, first_field,
                c * P // chunks, (c + 1) * P // chunks, chunk_rounds[c], chunk_unfinished[c])
            continue
        chunk_steps[c] = _backtrack_block(vertices, tri_real, tri_int, face_normal, planar, affine, buckets,
                                          border_real, border_buckets, grid, grid_shape, near, triangles, cell_real,
                                          ids, field_planar, scheme, point_velocity, position, triangle, wall,
                                          start_velocity, end_velocity, first, size, dt, substeps, max_cfl, cap,
                                          integrator, max_rounds, vorticity, value, first_field, c * P // chunks,
                                          (c + 1) * P // chunks, chunk_rounds[c], chunk_unfinished[c])
    rounds = np.zeros((cap, 2), dtype=np.int64)
    unfinished = np.zeros(cap, dtype=np.int64)
    steps = 1
    for c in range(chunks):
        steps = max(steps, chunk_steps[c])
        for s in range(cap):
            rounds[s, 0] = max(rounds[s, 0], chunk_rounds[c, s, 0])
            rounds[s, 1] = max(rounds[s, 1], chunk_rounds[c, s, 1])
            unfinished[s] += chunk_unfinished[c, s]
    return rounds, unfinished, steps


# ---------------------------------------------------------------- circulation (simulation.py)
@_helper
def _dual_edge_integral(position, fixed_points, velocity, fixed_velocity, a, b, f):
    """<u(p_a) + u(p_b), p_b − p_a> / 2 of field f along the dual edge a → b (trapezoid rule)."""
    m = position.shape[0]
    total = 0.0
    for k in range(3):
        pa = position[a, k] if a < m else fixed_points[a - m, k]
        pb = position[b, k] if b < m else fixed_points[b - m, k]
        ua = velocity[a, k, f] if a < m else fixed_velocity[a - m, k, f]
        ub = velocity[b, k, f] if b < m else fixed_velocity[b - m, k, f]
        total += (ua + ub) * (pb - pa)
    return 0.5 * total


@_kernel
def _dual_edge_block(position, fixed_points, velocity, fixed_velocity, edge_a, edge_b, g, first, last):
    """g[e, f] for the dual edges first..last − 1 (:func:`circulation_sums`, one thread's block)."""
    for e in range(first, last):
        for f in range(velocity.shape[2]):
            g[e, f] = _dual_edge_integral(position, fixed_points, velocity, fixed_velocity, edge_a[e], edge_b[e], f)


@_kernel
def _row_block(gamma, g, indptr, indices, data, first, last):
    """gamma[i] = Σ_j data[j] g[indices[j]] for the rows first..last − 1 (CSR order)."""
    for i in range(first, last):
        for j in range(indptr[i], indptr[i + 1]):
            for f in range(g.shape[1]):
                gamma[i, f] += data[j] * g[indices[j], f]


@_parallel_kernel
def circulation_sums(position, fixed_points, velocity, fixed_velocity, edge_a, edge_b, indptr, indices, data, chunks):
    """(n0, F) Γ = D g around every cell: g_e = <u(p_a) + u(p_b), p_b − p_a> / 2 along each
    dual edge a → b (trapezoid rule), D the signed cell–edge incidence (CSR indptr, indices,
    data). Points below m = len(position) are the backtracked ones (position, velocity
    (m, 3, F)), the others fixed (fixed_points, fixed_velocity). The edges and then the cells in
    ``chunks`` blocks in parallel; each row sums in CSR order, as the numpy twin's ``D @ g``."""
    E, n, F = edge_a.shape[0], indptr.shape[0] - 1, velocity.shape[2]
    g = np.empty((E, F))
    for c in prange(chunks):
        _dual_edge_block(position, fixed_points, velocity, fixed_velocity, edge_a, edge_b, g,
                         c * E // chunks, (c + 1) * E // chunks)
    gamma = np.zeros((n, F))
    for c in prange(chunks):
        _row_block(gamma, g, indptr, indices, data, c * n // chunks, (c + 1) * n // chunks)
    return gamma


@_kernel
def circulation_rows(position, fixed_points, velocity, fixed_velocity, edge_a, edge_b, indptr, indices, data, rows):
    """:func:`circulation_sums` of the cells ``rows`` (R,) only, zero in the others (the swept
    rules' border cells, a few of them): each row's edge integrals computed where it sums them,
    in CSR order, the same bits."""
    F = velocity.shape[2]
    gamma = np.zeros((indptr.shape[0] - 1, F))
    for r in range(rows.shape[0]):
        i = rows[r]
        for j in range(indptr[i], indptr[i + 1]):
            e = indices[j]
            for f in range(F):
                gamma[i, f] += data[j] * _dual_edge_integral(position, fixed_points, velocity, fixed_velocity,
                                                             edge_a[e], edge_b[e], f)
    return gamma


# ---------------------------------------------------------------- swept vorticity (swept.py)
@_kernel
def _swept_side_totals(before, after, value_before, value_after, side_a, side_b, normal, total, first, last):
    """total[s] for the sides first..last − 1 (:func:`swept_change_add`, one thread's block)."""
    for s in range(first, last):
        a, b = side_a[s], side_b[s]
        u0, u1, u2 = before[b, 0] - before[a, 0], before[b, 1] - before[a, 1], before[b, 2] - before[a, 2]
        v0, v1, v2 = after[b, 0] - before[a, 0], after[b, 1] - before[a, 1], after[b, 2] - before[a, 2]
        q0, q1, q2 = after[a, 0] - before[a, 0], after[a, 1] - before[a, 1], after[a, 2] - before[a, 2]
        n0, n1, n2 = normal[s, 0], normal[s, 1], normal[s, 2]
        c0, c1, c2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
        first_area = 0.5 * ((c0 * n0 + c1 * n1) + c2 * n2)
        c0, c1, c2 = v1 * q2 - v2 * q1, v2 * q0 - v0 * q2, v0 * q1 - v1 * q0
        second_area = 0.5 * ((c0 * n0 + c1 * n1) + c2 * n2)
        wa0, wb0, wa1, wb1 = value_before[a], value_before[b], value_after[a], value_after[b]
        total[s] = first_area * (wa0 + wb0 + wb1) / 3.0 + second_area * (wa0 + wb1 + wa1) / 3.0


@_kernel
def _swept_path_totals(path, values, side_a, side_b, normal, total, first, last):
    """total[s, i] of interval i (path[:, i] → path[:, i + 1]) for the sides first..last − 1
    (:func:`swept_change_path`, one thread's block): :func:`_swept_side_totals`' arithmetic."""
    for s in range(first, last):
        a, b = side_a[s], side_b[s]
        n0, n1, n2 = normal[s, 0], normal[s, 1], normal[s, 2]
        for i in range(total.shape[1]):
            a0, a1, a2 = path[a, i, 0], path[a, i, 1], path[a, i, 2]
            u0, u1, u2 = path[b, i, 0] - a0, path[b, i, 1] - a1, path[b, i, 2] - a2
            v0, v1, v2 = path[b, i + 1, 0] - a0, path[b, i + 1, 1] - a1, path[b, i + 1, 2] - a2
            q0, q1, q2 = path[a, i + 1, 0] - a0, path[a, i + 1, 1] - a1, path[a, i + 1, 2] - a2
            c0, c1, c2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
            first_area = 0.5 * ((c0 * n0 + c1 * n1) + c2 * n2)
            c0, c1, c2 = v1 * q2 - v2 * q1, v2 * q0 - v0 * q2, v0 * q1 - v1 * q0
            second_area = 0.5 * ((c0 * n0 + c1 * n1) + c2 * n2)
            wa0, wb0, wa1, wb1 = values[a, i], values[b, i], values[a, i + 1], values[b, i + 1]
            total[s, i] = first_area * (wa0 + wb0 + wb1) / 3.0 + second_area * (wa0 + wb1 + wa1) / 3.0


@_kernel
def _add_rows(change, total, indptr, indices, data, first, last):
    """change[i] += −Σ_j data[j] total[indices[j]] for the rows first..last − 1 (CSR order)."""
    for i in range(first, last):
        acc = 0.0
        for j in range(indptr[i], indptr[i + 1]):
            acc += data[j] * total[indices[j]]
        change[i] += -acc


@_parallel_kernel
def swept_change_add(change, before, after, value_before, value_after, side_a, side_b, normal, indptr, indices,
                     data, chunks):
    """``change`` (n0,) += Γ(X(C)) − Γ(C) per cell, in place (SweptVorticity.change; summed over
    the intervals of VorticityFluid._backtrack_sweeping): per side a → b the signed areas of the
    triangles (p_a, p_b, p_b') and (p_a, p_b', p_a') along the side's ``normal`` (S, 3) times the
    mean vorticity at their corners, summed into the cells by the signed incidence (CSR indptr,
    indices, data), negated. Same arithmetic order as the numpy twin (``change += −(D @ total)``);
    sides and then cells in ``chunks`` blocks in parallel (the same bits on any number)."""
    S, n = side_a.shape[0], indptr.shape[0] - 1
    total = np.empty(S)
    for c in prange(chunks):
        _swept_side_totals(before, after, value_before, value_after, side_a, side_b, normal, total,
                           c * S // chunks, (c + 1) * S // chunks)
    for c in prange(chunks):
        _add_rows(change, total, indptr, indices, data, c * n // chunks, (c + 1) * n // chunks)


@_kernel
def _add_path_rows(change, total, indptr, indices, data, first, last):
    """change[i] += −Σ_j data[j] total[indices[j], l] for l = 0..k − 1 in turn, for the rows
    first..last − 1 (CSR order): each interval's sum added as :func:`_add_rows` adds it."""
    for i in range(first, last):
        for interval in range(total.shape[1]):
            acc = 0.0
            for j in range(indptr[i], indptr[i + 1]):
                acc += data[j] * total[indices[j], interval]
            change[i] += -acc


@_parallel_kernel
def swept_change_path(change, path, values, side_a, side_b, normal, indptr, indices, data, chunks):
    """``change`` (n0,) += the swept change of every interval of ``path`` (P, k + 1, 3) (every dual
    point's positions, values (P, k + 1) the vorticity there), in place: the same bits as
    :func:`swept_change_add` of path[:, i] → path[:, i + 1] for i = 0..k − 1 in turn, each side's
    and each row's data read once for all intervals (sides and then cells in ``chunks`` blocks)."""
    S, n, k = side_a.shape[0], indptr.shape[0] - 1, path.shape[1] - 1
    total = np.empty((S, k))
    for c in prange(chunks):
        _swept_path_totals(path, values, side_a, side_b, normal, total, c * S // chunks, (c + 1) * S // chunks)
    for c in prange(chunks):
        _add_path_rows(change, total, indptr, indices, data, c * n // chunks, (c + 1) * n // chunks)
