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
  triangle grid, or its first border crossing), walking only where that fails;
* :func:`circulation_sums` — the trapezoid circulation of :meth:`VorticityFluid.circulation`.

Compiled with ``cache=True``: the machine code is written next to this file (``__pycache__``,
or numba's user cache dir when that is read-only) on the first call, so later processes — every
job of a sweep — load it instead of compiling. Importing this module imports numba; the rest of
decrun imports it only when a fluid runs with ``kernels="numba"``.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["velocity_points", "backtrack_points", "circulation_sums", "INTEGRATOR_CODE"]

INTEGRATOR_CODE = {"euler": 0, "midpoint": 1, "per_triangle": 2}

# The helpers take the tables as separate arrays: reading an array out of a tuple inside the
# loops costs a reference count each time (measured: 10× slower walks). Numba-level inlining
# (inline="always") was ~20 % faster but doubled the cold compile time.
_kernel = numba.njit(cache=True, error_model="numpy")  # x / 0 gives inf or nan, as in numpy
_helper = _kernel


# ---------------------------------------------------------------- interpolation (interpolation.py)

@_helper
def _nearest_vertex(triangles, vertices, t, x0, x1, x2):
    """The corner of triangle t nearest to x (first of equals, as numpy's argmin)."""
    best, best_distance = triangles[t, 0], np.inf
    for c in range(3):
        v = triangles[t, c]
        d0, d1, d2 = vertices[v, 0] - x0, vertices[v, 1] - x1, vertices[v, 2] - x2
        distance = d0 * d0 + d1 * d1 + d2 * d2
        if distance < best_distance or c == 0:
            best, best_distance = v, distance
    return best


@_helper
def _weights(vertices, frames, table, scale, v, x0, x1, x2, w, h):
    """WSHD07 weights (into w, K) of the corners of cell v at x; h is scratch (K + 1)."""
    r0, r1, r2 = x0 - vertices[v, 0], x1 - vertices[v, 1], x2 - vertices[v, 2]
    f1 = r0 * frames[v, 0, 0] + r1 * frames[v, 0, 1] + r2 * frames[v, 0, 2]
    f2 = r0 * frames[v, 1, 0] + r1 * frames[v, 1, 1] + r2 * frames[v, 1, 2]
    lowest = scale[v]
    for j in range(h.shape[0]):
        value = table[v, 0, j] - table[v, 1, j] * f1 - table[v, 2, j] * f2
        h[j] = lowest if value < lowest else value
    total = 0.0
    for k in range(w.shape[0]):
        c = table[v, 3, k + 1] / (h[k] * h[k + 1])
        w[k] = c
        total += c
    for k in range(w.shape[0]):
        w[k] /= total


@_helper
def _combine(ids, vertex_normal, planar, point_velocity, f, v, t, face_normal, w, out):
    """Σ_k w_k u_k of field f over the corners of cell v (into out, 3), projected into the
    plane of triangle t along the vertex normal (curved meshes)."""
    for d in range(3):
        total = 0.0
        for k in range(w.shape[0]):
            total += w[k] * point_velocity[ids[v, k], d, f]
        out[d] = total
    if not planar:
        n0, n1, n2 = vertex_normal[v, 0], vertex_normal[v, 1], vertex_normal[v, 2]
        m0, m1, m2 = face_normal[t, 0], face_normal[t, 1], face_normal[t, 2]
        ratio = (out[0] * m0 + out[1] * m1 + out[2] * m2) / (n0 * m0 + n1 * m1 + n2 * m2)
        out[0] -= n0 * ratio
        out[1] -= n1 * ratio
        out[2] -= n2 * ratio


@_helper
def _velocity(triangles, vertices, frames, table, scale, ids, vertex_normal, planar, point_velocity, f, t, x,
              face_normal, w, h, out):
    """Interpolated velocity (into out, 3) of field f of point_velocity (n_points, 3, F) at x in t."""
    v = _nearest_vertex(triangles, vertices, t, x[0], x[1], x[2])
    _weights(vertices, frames, table, scale, v, x[0], x[1], x[2], w, h)
    _combine(ids, vertex_normal, planar, point_velocity, f, v, t, face_normal, w, out)


@_kernel
def velocity_points(field, triangle, x, point_velocity, face_normal):
    """(P, 3, F) interpolated velocities at x (P, 3) in ``triangle`` (P,) of the F fields
    ``point_velocity`` (n_points, 3, F); ``field`` is :meth:`CellInterpolator.kernel_tables`."""
    triangles, vertices, frames, table, scale, ids, vertex_normal, planar = field
    P, F, K = x.shape[0], point_velocity.shape[2], ids.shape[1]
    result = np.empty((P, 3, F))
    w, h, out = np.empty(K), np.empty(K + 1), np.empty(3)
    for p in range(P):
        t = triangle[p]
        x0, x1, x2 = x[p, 0], x[p, 1], x[p, 2]
        v = _nearest_vertex(triangles, vertices, t, x0, x1, x2)
        _weights(vertices, frames, table, scale, v, x0, x1, x2, w, h)
        for f in range(F):
            _combine(ids, vertex_normal, planar, point_velocity, f, v, t, face_normal, w, out)
            result[p, 0, f], result[p, 1, f], result[p, 2, f] = out[0], out[1], out[2]
    return result


# ---------------------------------------------------------------- the walk (backtrack.py)
@_helper
def _unfold(vertices, top, normal, d, t, slot, nb):
    """Rotate d (3, in place) about the edge opposite ``slot`` of t into the plane of nb."""
    a, b = top[t, (slot + 1) % 3], top[t, (slot + 2) % 3]
    e0, e1, e2 = vertices[b, 0] - vertices[a, 0], vertices[b, 1] - vertices[a, 1], vertices[b, 2] - vertices[a, 2]
    length = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    e0, e1, e2 = e0 / length, e1 / length, e2 / length
    o0 = normal[t, 1] * e2 - normal[t, 2] * e1
    o1 = normal[t, 2] * e0 - normal[t, 0] * e2
    o2 = normal[t, 0] * e1 - normal[t, 1] * e0
    n0 = normal[nb, 1] * e2 - normal[nb, 2] * e1
    n1 = normal[nb, 2] * e0 - normal[nb, 0] * e2
    n2 = normal[nb, 0] * e1 - normal[nb, 1] * e0
    along = d[0] * e0 + d[1] * e1 + d[2] * e2
    across = d[0] * o0 + d[1] * o1 + d[2] * o2
    d[0], d[1], d[2] = along * e0 + across * n0, along * e1 + across * n1, along * e2 + across * n2


@_helper
def _barycentric(gradient, centroid, t, x, lam):
    r0, r1, r2 = x[0] - centroid[t, 0], x[1] - centroid[t, 1], x[2] - centroid[t, 2]
    for c in range(3):
        lam[c] = 1.0 / 3.0 + (gradient[t, c, 0] * r0 + gradient[t, c, 1] * r1 + gradient[t, c, 2] * r2)


@_helper
def _round(vertices, top, gradient, centroid, corner_x, neighbor, neighbor_slot, edge, normal, planar, state, x, d,
           lam, rate):
    """One walking round of one point (TriangleWalker._advance): move inside the triangle
    state[0] until the remaining time state[3] is used or an edge is reached; cross it (entry
    slot state[1]) or stop at the wall (state[2] = border edge). Returns True when done."""
    t, entry = int(state[0]), int(state[1])
    remaining = state[3]
    _barycentric(gradient, centroid, t, x, lam)
    for c in range(3):
        if lam[c] < 0.0:
            lam[c] = 0.0
        rate[c] = gradient[t, c, 0] * d[0] + gradient[t, c, 1] * d[1] + gradient[t, c, 2] * d[2]
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
        x[k] = lam[0] * corner_x[t, 0, k] + lam[1] * corner_x[t, 1, k] + lam[2] * corner_x[t, 2, k]
    state[3] = remaining - s
    nb = neighbor[t, slot]
    if nb < 0:
        state[2] = edge[t, slot]
        state[3] = 0.0
        return True
    if not planar:
        _unfold(vertices, top, normal, d, t, slot, nb)
    state[1] = neighbor_slot[t, slot]
    state[0] = nb
    return False


@_helper
def _locate(affine, bucket_triangles, bucket_start, grid, grid_shape, y0, y1):
    """The first triangle of the grid bucket holding (y0, y1) that contains it (barycentric
    coordinates ≥ −1e-12, as numpy's _jump tests them), or -1."""
    cx = min(max(int(np.floor((y0 - grid[0]) / grid[2])), 0), grid_shape[0] - 1)
    cy = min(max(int(np.floor((y1 - grid[1]) / grid[2])), 0), grid_shape[1] - 1)
    cell = cy * grid_shape[0] + cx
    for j in range(bucket_start[cell], bucket_start[cell + 1]):
        c = bucket_triangles[j]
        if (affine[c, 0] * y0 + affine[c, 1] * y1 + affine[c, 2] >= -1e-12
                and affine[c, 3] * y0 + affine[c, 4] * y1 + affine[c, 5] >= -1e-12
                and affine[c, 6] * y0 + affine[c, 7] * y1 + affine[c, 8] >= -1e-12):
            return c
    return -1


@_helper
def _first_crossing(border_real, border_members, border_start, border_grid, border_shape, p0, p1, q0, q1):
    """First border edge crossed outwards by the segment p → q (TriangleWalker._first_crossing):
    (segment parameter in [0, 1] or inf, row of the border table or -1)."""
    size = border_grid[2]
    x_low = min(max(int(np.floor((min(p0, q0) - border_grid[0]) / size)), 0), border_shape[0] - 1)
    y_low = min(max(int(np.floor((min(p1, q1) - border_grid[1]) / size)), 0), border_shape[1] - 1)
    x_high = min(max(int(np.floor((max(p0, q0) - border_grid[0]) / size)), 0), border_shape[0] - 1)
    y_high = min(max(int(np.floor((max(p1, q1) - border_grid[1]) / size)), 0), border_shape[1] - 1)
    d0, d1 = q0 - p0, q1 - p1
    best_s, best = np.inf, -1
    for cy in range(y_low, y_high + 1):
        for cx in range(x_low, x_high + 1):
            cell = cy * border_shape[0] + cx
            for j in range(border_start[cell], border_start[cell + 1]):
                k = border_members[j]
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
def _jump(top, corner_x, clearance, affine, bucket_triangles, bucket_start, grid, grid_shape, border_real, border_int,
          border_members, border_start, border_grid, border_shape, x, t, d, time, state):
    """Planar meshes (TriangleWalker._jump): a straight path that cannot reach the border, or
    reaches no border edge, ends at x + time·d (located in the triangle grid); one that leaves
    through a border edge stops on it. Returns True when done (state[0] triangle, state[2] wall)."""
    bound = -np.inf
    for c in range(3):
        g0, g1, g2 = corner_x[t, c, 0] - x[0], corner_x[t, c, 1] - x[1], corner_x[t, c, 2] - x[2]
        bound = max(bound, clearance[top[t, c]] - np.sqrt(g0 * g0 + g1 * g1 + g2 * g2))
    safe = time * time * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) < bound * abs(bound)
    if not safe and border_real.shape[0] > 0:
        q0, q1 = x[0] + time * d[0], x[1] + time * d[1]
        s, k = _first_crossing(border_real, border_members, border_start, border_grid, border_shape, x[0], x[1],
                               q0, q1)
        if k >= 0:
            for i in range(3):
                x[i] = x[i] + (s * time) * d[i]
            state[0], state[2] = border_int[k, 1], border_int[k, 0]
            return True
    y0, y1, y2 = x[0] + time * d[0], x[1] + time * d[1], x[2] + time * d[2]
    c = _locate(affine, bucket_triangles, bucket_start, grid, grid_shape, y0, y1)
    if c < 0:
        return False
    x[0], x[1], x[2] = y0, y1, y2
    state[0] = c
    return True


@_helper
def _walk(vertices, top, gradient, centroid, corner_x, neighbor, neighbor_slot, edge, normal, planar, clearance,
          affine, bucket_triangles, bucket_start, grid, grid_shape, border_real, border_int, border_members,
          border_start, border_grid, border_shape, x, t, d, time, max_rounds, state, lam, rate):
    """Move one point (x, d in place) from triangle t for ``time``: TriangleWalker.walk (the
    jump on planar meshes, else rounds across triangles). Returns (triangle, wall edge or -1,
    rounds, unfinished)."""
    state[0], state[1], state[2], state[3] = t, -1, -1, time
    if not time > 0:
        return t, -1, 0, False
    if clearance.shape[0] > 0 and _jump(top, corner_x, clearance, affine, bucket_triangles, bucket_start, grid, grid_shape,
                        border_real, border_int, border_members, border_start, border_grid, border_shape,
                        x, t, d, time, state):
        return int(state[0]), int(state[2]), 0, False
    rounds, done = 0, False
    while not done and rounds < max_rounds:
        rounds += 1
        done = _round(vertices, top, gradient, centroid, corner_x, neighbor, neighbor_slot, edge, normal, planar,
                      state, x, d, lam, rate)
    return int(state[0]), int(state[2]), rounds, not done


@_kernel
def backtrack_points(walk, jump, field, point_velocity, face_normal, start, triangle, start_velocity, count, dt,
                     integrator, max_rounds):
    """Backtrack every point along −u for ``dt`` (TriangleWalker.backtrack), point by point.

    walk, jump : :meth:`TriangleWalker.kernel_tables`; field : :meth:`CellInterpolator.kernel_tables`
    point_velocity : (n_points, 3, F) dual-point velocities, field 1 is the full u (mesh units / s)
    start (P, 3), triangle (P,), start_velocity (P, 3) the velocity at the start points
    count : (P,) substeps per point (each of length dt / count); integrator : INTEGRATOR_CODE
    Returns position (P, 3), triangle (P,), wall edge (P,) (-1: none), rounds (S, 2) the most
    rounds any point walked in substep s (column 0: the midpoint half step, 1: the full step),
    unfinished (S,) points still walking after ``max_rounds`` in substep s.

    per_triangle (Fig. 7.9, TriangleWalker._walk_per_triangle): every round takes a fresh
    velocity in the triangle entered, unless it leaves at once through the entry edge.
    """
    vertices, top, gradient, centroid, corner_x, neighbor, neighbor_slot, edge, normal, planar = walk
    clearance, affine, bucket_triangles, bucket_start, grid, grid_shape = jump[:6]
    border_real, border_int, border_members, border_start, border_grid, border_shape = jump[6:]
    triangles, field_vertices, frames, table, scale, ids, vertex_normal, field_planar = field
    P = start.shape[0]
    steps = 1
    for p in range(P):
        steps = max(steps, count[p])
    position = start.copy()
    tri = triangle.copy()
    wall = np.full(P, -1, dtype=np.int64)
    rounds = np.zeros((steps, 2), dtype=np.int64)
    unfinished = np.zeros(steps, dtype=np.int64)
    K = ids.shape[1]
    w, h = np.empty(K), np.empty(K + 1)
    state, lam, rate = np.empty(4), np.empty(3), np.empty(3)
    d, d1, x = np.empty(3), np.empty(3), np.empty(3)
    for p in range(P):
        t = tri[p]
        x[0], x[1], x[2] = position[p, 0], position[p, 1], position[p, 2]
        tau = dt / count[p]
        hit = -1
        for substep in range(count[p]):
            r, left = 0, False
            if integrator == 2:
                state[0], state[1], state[2], state[3] = t, -1, -1, tau
                d[0], d[1], d[2] = 0.0, 0.0, 0.0
                done = not tau > 0
                while not done and r < max_rounds:
                    r += 1
                    came = int(state[1])
                    t = int(state[0])
                    _velocity(triangles, field_vertices, frames, table, scale, ids, vertex_normal, field_planar,
                              point_velocity, 1, t, x, face_normal, w, h, d1)
                    for k in range(3):
                        d1[k] = -d1[k]
                    back = False
                    if came >= 0:  # a fresh velocity leaving at once through the entry edge: keep the unfolded one
                        _barycentric(gradient, centroid, t, x, lam)
                        lam_came = lam[came] if lam[came] > 0.0 else 0.0
                        rate_came = gradient[t, came, 0] * d1[0] + gradient[t, came, 1] * d1[1] \
                            + gradient[t, came, 2] * d1[2]
                        back = rate_came < 0 and lam_came <= 1e-12
                    if not back:
                        d[0], d[1], d[2] = d1[0], d1[1], d1[2]
                    done = _round(vertices, top, gradient, centroid, corner_x, neighbor, neighbor_slot, edge, normal,
                                  planar, state, x, d, lam, rate)
                t, hit, left = int(state[0]), int(state[2]), not done
            else:
                if substep == 0:
                    for k in range(3):
                        d[k] = -start_velocity[p, k]
                else:
                    _velocity(triangles, field_vertices, frames, table, scale, ids, vertex_normal, field_planar,
                              point_velocity, 1, t, x, face_normal, w, h, d)
                    for k in range(3):
                        d[k] = -d[k]
                if integrator == 1:
                    # x + τ d2 = x_m + τ (d2 − d1 / 2): continue from the midpoint (d1 unfolded there)
                    t, hit, r, left = _walk(vertices, top, gradient, centroid, corner_x, neighbor, neighbor_slot, edge,
                                            normal, planar, clearance, affine, bucket_triangles, bucket_start, grid, grid_shape, border_real, border_int, border_members,
                                            border_start, border_grid, border_shape, x, t, d, 0.5 * tau, max_rounds, state,
                                            lam, rate)
                    rounds[substep, 0] = max(rounds[substep, 0], r)
                    d1[0], d1[1], d1[2] = d[0], d[1], d[2]
                    _velocity(triangles, field_vertices, frames, table, scale, ids, vertex_normal, field_planar,
                              point_velocity, 1, t, x, face_normal, w, h, d)
                    for k in range(3):
                        d[k] = 0.0 if hit >= 0 else -d[k] - 0.5 * d1[k]
                t, hit2, r, left = _walk(vertices, top, gradient, centroid, corner_x, neighbor, neighbor_slot, edge,
                                         normal, planar, clearance, affine, bucket_triangles, bucket_start, grid, grid_shape, border_real, border_int, border_members,
                                         border_start, border_grid, border_shape, x, t, d, tau, max_rounds, state, lam,
                                         rate)
                if hit < 0:
                    hit = hit2
            rounds[substep, 1] = max(rounds[substep, 1], r)
            if left:
                unfinished[substep] += 1
            if hit >= 0:
                break
        position[p, 0], position[p, 1], position[p, 2] = x[0], x[1], x[2]
        tri[p], wall[p] = t, hit
    return position, tri, wall, rounds, unfinished


# ---------------------------------------------------------------- circulation (simulation.py)
@_kernel
def circulation_sums(position, fixed_points, velocity, fixed_velocity, edge_a, edge_b, indptr, indices, data):
    """(n0, F) Γ = D g around every cell: g_e = <u(p_a) + u(p_b), p_b − p_a> / 2 along each
    dual edge a → b (trapezoid rule), D the signed cell–edge incidence (CSR indptr, indices,
    data). Points below m = len(position) are the backtracked ones (position, velocity
    (m, 3, F)), the others fixed (fixed_points, fixed_velocity)."""
    m, F = position.shape[0], velocity.shape[2]
    E = edge_a.shape[0]
    g = np.empty((E, F))
    for e in range(E):
        a, b = edge_a[e], edge_b[e]
        for f in range(F):
            total = 0.0
            for k in range(3):
                pa = position[a, k] if a < m else fixed_points[a - m, k]
                pb = position[b, k] if b < m else fixed_points[b - m, k]
                ua = velocity[a, k, f] if a < m else fixed_velocity[a - m, k, f]
                ub = velocity[b, k, f] if b < m else fixed_velocity[b - m, k, f]
                total += (ua + ub) * (pb - pa)
            g[e, f] = 0.5 * total
    n = indptr.shape[0] - 1
    gamma = np.zeros((n, F))
    for i in range(n):
        for j in range(indptr[i], indptr[i + 1]):
            for f in range(F):
                gamma[i, f] += data[j] * g[indices[j], f]
    return gamma
