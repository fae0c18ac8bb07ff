"""Backtracking of the dual vertices along −u (thesis §7.2.3, Fig. 7.9; ETK07 §4.2).

The basic move is a *walk*: all points advance at once along fixed directions for a
given time; each round moves every still-active point in a straight line inside its
current triangle until its time is used up or it reaches an edge, where it crosses into
the neighbour and its direction is unfolded into the neighbour's plane (rotation about
the shared edge). Unlike the printed pseudocode a point always advances (a step equal to
the distance to the edge moves it onto the edge), and the edge it came through is not
an exit in the next round, so no point ping-pongs on an edge.

Integrators (per substep of length τ = dt / substeps):

* ``"midpoint"`` (default): d1 = −u(x); walk τ/2 along d1 to x_m; d2 = −u(x_m); the
  end point x + τ d2 is reached by walking on from x_m along d2 − d1/2 (d1 unfolded to
  x_m's triangle) for τ — exact on planar meshes, O(h κ) off on curved ones. A point
  that reaches a wall in the half step is clamped there. Second order; a rigid rotation
  by θ = Ω τ inflates a cell's area by (1 + θ⁴/4), i.e. its vorticity by that factor.
* ``"euler"``: walk τ along −u(x). The area factor is (1 + θ²).
* ``"per_triangle"``: Fig. 7.9 with stepSize = τ: Euler, but the velocity is evaluated
  again each time a point enters a triangle (as many velocity evaluations as rounds).

At a border edge the point stops (clamped to the wall; the rest of the time step is
dropped) and the border edge is recorded: the caller gives such points the wall's
velocity. That applies to the outer (inflow / outflow) border too: a point whose past
lies upstream of the inflow border is placed on it, where the fluid arrives with the
prescribed inflow velocity and no vorticity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from decrun.core import jit
from decrun.core.dec import DEC
from decrun.core.geometry import embed3
from decrun.methods.fluid.interpolation import dot3

__all__ = ["TriangleWalker", "BacktrackResult"]


def _check_integrator(integrator: str, substeps: int) -> None:
    if integrator not in ("euler", "midpoint", "per_triangle"):
        raise ValueError(f"integrator must be 'midpoint', 'euler' or 'per_triangle', not {integrator!r}")
    if substeps < 1:
        raise ValueError(f"substeps must be >= 1, got {substeps}")


def _box_buckets(low: np.ndarray, high: np.ndarray, origin: np.ndarray, size: float, shape: np.ndarray):
    """A uniform grid of square cells (side ``size``, ``shape`` = (nx, ny) cells from ``origin``)
    listing the boxes [low_i, high_i] (b, 2) that meet each cell, vectorized: returns
    (members, start) with the boxes of cell c = iy·nx + ix in ``members[start[c]:start[c+1]]``."""
    first = np.floor((low - origin) / size).astype(np.int64)
    last = np.floor((high - origin) / size).astype(np.int64)
    span = last - first + 1
    count = span[:, 0] * span[:, 1]
    box = np.repeat(np.arange(count.size), count)
    k = np.arange(box.size) - np.repeat(np.cumsum(count) - count, count)
    cell = (first[box, 1] + k // span[box, 0]) * shape[0] + first[box, 0] + k % span[box, 0]
    order = np.argsort(cell, kind="stable")
    return box[order], np.searchsorted(cell[order], np.arange(int(np.prod(shape)) + 1))


@dataclass
class BacktrackResult:
    """Where the points were ``dt`` earlier.

    position : (P, 3); triangle : (P,) the triangle holding each position
    wall_edge : (P,) border edge id where a point was clamped, -1 otherwise
    rounds : walking rounds used; unfinished : points still walking after ``max_rounds``
    substeps : the largest number of substeps any point took
    velocity : (P, 3, F) the interpolated velocities of all fields at the end points
        (:meth:`TriangleWalker.backtrack_compiled` only; None otherwise)
    """

    position: np.ndarray
    triangle: np.ndarray
    wall_edge: np.ndarray
    rounds: int
    unfinished: int
    substeps: int = 1
    velocity: np.ndarray | None = None


class TriangleWalker:
    """Triangle adjacency and barycentric tables for walking on a triangle mesh.

    Local vertex order is that of ``dec.K.simplices(2)``; ``neighbor[t, l]`` is the
    triangle across the edge opposite local vertex l (-1 on the border), ``edge[t, l]``
    that edge's id.
    """

    def __init__(self, dec: DEC, face_normal: np.ndarray):
        K = dec.K
        self.x = embed3(K.vertices)
        self.top = K.simplices(2)
        m = self.top.shape[0]
        self.face_normal = face_normal
        self.edge = K.facet_indices(2)  # (m, 3) edge opposite local vertex l
        flat_edge = self.edge.ravel()
        order = np.argsort(flat_edge, kind="stable")
        sorted_edge = flat_edge[order]
        pair = np.flatnonzero(sorted_edge[1:] == sorted_edge[:-1])
        self.neighbor = np.full(3 * m, -1, dtype=np.int64)
        self.neighbor_slot = np.full(3 * m, -1, dtype=np.int64)
        a, b = order[pair], order[pair + 1]
        self.neighbor[a], self.neighbor[b] = b // 3, a // 3
        self.neighbor_slot[a], self.neighbor_slot[b] = b % 3, a % 3
        self.neighbor = self.neighbor.reshape(m, 3)
        self.neighbor_slot = self.neighbor_slot.reshape(m, 3)
        p = self.x[self.top]
        gradients = np.empty_like(p)
        for i in range(3):
            s, e = p[:, (i + 1) % 3], p[:, (i + 2) % 3]
            direction = e - s
            h = p[:, i] - s
            h = h - (np.einsum("md,md->m", h, direction) / np.einsum("md,md->m", direction, direction))[:, None] * direction
            gradients[:, i] = h / np.einsum("md,md->m", h, h)[:, None]
        self.gradient = gradients  # ∇λ_i, (m, 3, 3)
        self.planar = bool(np.all(np.abs(face_normal - face_normal[:1]) < 1e-12))
        self.centroid = p.mean(axis=1)
        self.corner_x = np.ascontiguousarray(p)  # (m, 3, 3) corner positions
        self.size = np.linalg.norm(p - np.roll(p, 1, axis=1), axis=2).mean(axis=1)  # mean edge length
        self._locator = None
        if self.planar:
            self._prepare_jumps(K)

    def _prepare_jumps(self, K) -> None:
        """Planar meshes: a point whose straight path cannot reach the border (its length is
        below a lower bound of the point's distance to the border) jumps to its end point,
        located in a uniform grid of triangle buckets, instead of walking (same result)."""
        x2 = self.x[:, :2]
        border, _ = K.border_faces()
        edge_length = np.linalg.norm(self.corner_x - np.roll(self.corner_x, 1, axis=1), axis=2).max(axis=1)
        if border.size:
            ends = K.simplices(1)[border]
            a, b = x2[ends[:, 0]], x2[ends[:, 1]]
            k = int(min(8, border.size))
            distance, cand = cKDTree(0.5 * (a + b)).query(x2, k=k)
            distance, cand = distance.reshape(-1, k), cand.reshape(-1, k)
            ab = b[cand] - a[cand]
            t = np.clip(np.einsum("vkd,vkd->vk", x2[:, None] - a[cand], ab) / np.einsum("vkd,vkd->vk", ab, ab), 0, 1)
            exact = np.linalg.norm(x2[:, None] - a[cand] - t[..., None] * ab, axis=2).min(axis=1)
            half = 0.5 * np.linalg.norm(b - a, axis=1).max()
            vertex_clearance = np.minimum(exact, distance[:, -1] - half)
            self.vertex_clearance = vertex_clearance
        else:
            self.vertex_clearance = np.full(self.x.shape[0], np.inf)
        # barycentric coordinates as an affine map of (x, y, 1): λ = B[t] @ (x, y, 1)
        g = self.gradient[:, :, :2]
        affine = np.concatenate([g, (1.0 / 3.0 - np.einsum("mcd,md->mc", g, self.centroid[:, :2]))[..., None]], 2)
        self._affine_rows = np.ascontiguousarray(affine.reshape(-1, 9))
        # a uniform grid of buckets: each holds the triangles whose bounding box meets the cell
        corners = self.corner_x[:, :, :2]
        low, high = corners.min(axis=1), corners.max(axis=1)
        size = 0.5 * float(np.percentile(edge_length, 10))
        origin = low.min(axis=0)
        shape = np.floor((high.max(axis=0) - origin) / size).astype(np.int64) + 1
        self._bucket_triangles, self._bucket_start = _box_buckets(low, high, origin, size, shape)
        self._grid = (origin, size, shape)
        self._locator = True
        self._border = None
        if border.size:  # border edges in a coarser grid: first crossings of straight paths
            ends = K.simplices(1)[border]
            a, b = x2[ends[:, 0]], x2[ends[:, 1]]
            owner = np.full(K.num_simplices(1), -1, dtype=np.int64)
            owner[self.edge.ravel()] = np.repeat(np.arange(self.top.shape[0]), 3)
            inner = self.centroid[owner[border], :2]
            e = b - a
            normal = np.stack([e[:, 1], -e[:, 0]], axis=1)
            normal *= np.where(np.einsum("bd,bd->b", normal, inner - a) > 0, -1.0, 1.0)[:, None]  # outward
            cell_size = float(np.linalg.norm(e, axis=1).max())
            b_origin = np.minimum(a, b).min(axis=0) - cell_size
            b_shape = np.floor((np.maximum(a, b).max(axis=0) + cell_size - b_origin) / cell_size).astype(np.int64) + 1
            members, start = _box_buckets(np.minimum(a, b), np.maximum(a, b), b_origin, cell_size, b_shape)
            self._border = dict(a=a, e=e, normal=normal, edge=border, triangle=owner[border], members=members,
                                start=start, origin=b_origin, size=cell_size, shape=b_shape)

    def _first_crossing(self, start: np.ndarray, end: np.ndarray):
        """First border edge crossed outwards by the segments start → end (Q, 2).

        Returns (s, k): the segment parameter in [0, 1] of the crossing (inf if none) and the
        index into the border-edge table (-1 if none)."""
        B = self._border
        Q = start.shape[0]
        low = np.clip(np.floor((np.minimum(start, end) - B["origin"]) / B["size"]).astype(np.int64), 0, B["shape"] - 1)
        high = np.clip(np.floor((np.maximum(start, end) - B["origin"]) / B["size"]).astype(np.int64), 0, B["shape"] - 1)
        span = high - low + 1
        count = span[:, 0] * span[:, 1]
        point = np.repeat(np.arange(Q), count)
        k = np.arange(point.size) - np.repeat(np.cumsum(count) - count, count)
        cell = (low[point, 1] + k // span[point, 0]) * B["shape"][0] + low[point, 0] + k % span[point, 0]
        begin, length = B["start"][cell], B["start"][cell + 1] - B["start"][cell]
        pair_point = np.repeat(point, length)
        offset = np.arange(pair_point.size) - np.repeat(np.cumsum(length) - length, length)
        member = B["members"][np.repeat(begin, length) + offset]
        p, d = start[pair_point], end[pair_point] - start[pair_point]
        a, e = B["a"][member], B["e"][member]
        den = d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0]
        ap = a - p
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (ap[:, 0] * e[:, 1] - ap[:, 1] * e[:, 0]) / den
            r = (ap[:, 0] * d[:, 1] - ap[:, 1] * d[:, 0]) / den
        outward = np.einsum("qd,qd->q", d, B["normal"][member]) > 0
        crossing = outward & (s >= -1e-12) & (s <= 1 + 1e-12) & (r >= -1e-12) & (r <= 1 + 1e-12)
        best_s = np.full(Q, np.inf)
        best = np.full(Q, -1, dtype=np.int64)
        if crossing.any():
            cs, cp, cm = np.clip(s[crossing], 0.0, 1.0), pair_point[crossing], member[crossing]
            order = np.lexsort((cs, cp))
            first = np.ones(order.size, dtype=bool)
            first[1:] = cp[order][1:] != cp[order][:-1]
            chosen = order[first]
            best_s[cp[chosen]] = cs[chosen]
            best[cp[chosen]] = cm[chosen]
        return best_s, best

    def _jump(self, position, tri, direction, time, active, wall) -> np.ndarray:
        # time: (len(active),) the time each active point moves
        """Planar fast path of :meth:`walk`; returns the mask (over ``active``) of points done.

        A straight path that cannot reach the border, or reaches no border edge, ends at
        its target (located in the triangle grid); one that leaves through a border edge
        stops on it (the wall)."""
        t = tri[active]
        d = np.take(direction, active, axis=0)
        start = np.take(position, active, axis=0)
        # distance to the border ≥ clearance(v) − |x − v| for each corner v (1-Lipschitz)
        corner = np.take(self.corner_x, t, axis=0)  # (P, 3, 3)
        gap = corner - start[:, None, :]
        bound = np.take(self.vertex_clearance, np.take(self.top, t, axis=0)) - np.sqrt(dot3(gap, gap))
        bound = np.maximum(np.maximum(bound[:, 0], bound[:, 1]), bound[:, 2])
        safe = time * time * dot3(d, d) < bound * np.abs(bound)
        time = time[:, None]
        done = np.zeros(active.size, dtype=bool)
        if self._border is not None and not safe.all():
            near = np.flatnonzero(~safe)
            s_cross, k = self._first_crossing(start[near, :2], start[near, :2] + time[near] * d[near, :2])
            out = np.isfinite(s_cross)
            safe[near[~out]] = True  # its straight path stays inside: same as a safe jump
            stop = near[out]
            B = self._border
            position[active[stop]] = start[stop] + (s_cross[out, None] * time[stop]) * d[stop]
            tri[active[stop]] = B["triangle"][k[out]]
            wall[active[stop]] = B["edge"][k[out]]
            done[stop] = True
        if not safe.any():
            return done
        idx = active[safe]
        target = start[safe] + time[safe] * d[safe]
        found = np.zeros(idx.size, dtype=bool)
        choice = np.full(idx.size, -1, dtype=np.int64)
        open_ = np.arange(idx.size)

        def test(candidates, which):
            affine = np.take(self._affine_rows, candidates, axis=0)  # (Q, 9)
            x, y = target[which, 0], target[which, 1]
            hit = affine[:, 0] * x + affine[:, 1] * y + affine[:, 2] >= -1e-12
            hit &= affine[:, 3] * x + affine[:, 4] * y + affine[:, 5] >= -1e-12
            hit &= affine[:, 6] * x + affine[:, 7] * y + affine[:, 8] >= -1e-12
            found[which[hit]] = True
            choice[which[hit]] = candidates[hit]
            return which[~hit]

        if open_.size:  # the triangles of the grid bucket holding the target
            origin, size, shape = self._grid
            cell_xy = np.clip(np.floor((target[open_, :2] - origin) / size).astype(np.int64), 0, shape - 1)
            cell = cell_xy[:, 1] * shape[0] + cell_xy[:, 0]
            begin = np.zeros(idx.size, dtype=np.int64)
            length = np.zeros(idx.size, dtype=np.int64)
            begin[open_] = self._bucket_start[cell]
            length[open_] = self._bucket_start[cell + 1] - begin[open_]
            slot = 0
            while open_.size:  # bucket slots, at most the largest bucket
                open_ = open_[length[open_] > slot]
                if not open_.size:
                    break
                open_ = test(self._bucket_triangles[begin[open_] + slot], open_)
                slot += 1
        position[idx[found]] = target[found]
        tri[idx[found]] = choice[found]
        done[np.flatnonzero(safe)[found]] = True
        return done

    def barycentric(self, triangle: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(P, 3) barycentric coordinates of x (P, 3) in the plane of ``triangle`` (P,)."""
        return 1.0 / 3.0 + dot3(np.take(self.gradient, triangle, axis=0),
                                (x - np.take(self.centroid, triangle, axis=0))[:, None, :])

    def unfold(self, direction: np.ndarray, triangle: np.ndarray, slot: np.ndarray, neighbor: np.ndarray) -> np.ndarray:
        """Rotate ``direction`` (P, 3) about the edge (opposite ``slot`` of ``triangle``) into the
        plane of ``neighbor``: d' = <d, ê> ê + <d, N×ê> (N'×ê)."""
        if self.planar:
            return direction
        a = self.top[triangle, (slot + 1) % 3]
        b = self.top[triangle, (slot + 2) % 3]
        e = self.x[b] - self.x[a]
        e /= np.linalg.norm(e, axis=1, keepdims=True)
        old = np.cross(self.face_normal[triangle], e)
        new = np.cross(self.face_normal[neighbor], e)
        return dot3(direction, e)[:, None] * e + dot3(direction, old)[:, None] * new

    @staticmethod
    def _exit(lam, rate, entry):
        """Time to the first edge along the barycentric rates (entry edge excluded)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            exit_time = np.where(rate < 0, lam / -rate, np.inf)
        came = entry >= 0
        exit_time[np.flatnonzero(came), entry[came]] = np.inf
        slot = np.argmin(exit_time, axis=1)
        return exit_time[np.arange(slot.size), slot], slot

    def _advance(self, position, tri, direction, remaining, entry, wall, active):
        """One walking round for the ``active`` points (arrays updated in place)."""
        t, r = tri[active], remaining[active]
        x, d = np.take(position, active, axis=0), np.take(direction, active, axis=0)
        gradient = np.take(self.gradient, t, axis=0)
        lam = 1.0 / 3.0 + dot3(gradient, (x - np.take(self.centroid, t, axis=0))[:, None, :])
        np.maximum(lam, 0.0, out=lam)
        rate = dot3(gradient, d[:, None, :])
        s, slot = self._exit(lam, rate, entry[active])
        inside = s >= r
        position[active[inside]] = x[inside] + r[inside, None] * d[inside]
        remaining[active[inside]] = 0.0
        cross = np.flatnonzero(~inside)
        if cross.size:
            idx = active[cross]
            tc, sc, lc = t[cross], s[cross], slot[cross]
            lam_new = lam[cross] + sc[:, None] * rate[cross]
            lam_new[np.arange(cross.size), lc] = 0.0
            lam_new = np.clip(lam_new, 0.0, None)
            lam_new /= lam_new.sum(axis=1, keepdims=True)
            position[idx] = np.einsum("pc,pcd->pd", lam_new, np.take(self.corner_x, tc, axis=0))
            remaining[idx] = r[cross] - sc
            nb = self.neighbor[tc, lc]
            at_wall = nb < 0
            wall[idx[at_wall]] = self.edge[tc[at_wall], lc[at_wall]]
            remaining[idx[at_wall]] = 0.0
            go = ~at_wall
            direction[idx[go]] = self.unfold(d[cross][go], tc[go], lc[go], nb[go])
            entry[idx[go]] = self.neighbor_slot[tc[go], lc[go]]
            tri[idx[go]] = nb[go]
        return inside

    def walk(self, start: np.ndarray, triangle: np.ndarray, direction: np.ndarray, time,
             max_rounds: int = 1000):
        """Move points along fixed (unfolded) directions for ``time``.

        Parameters
        ----------
        start : (P, 3) positions; triangle : (P,) their triangles
        direction : (P, 3) velocities tangent to the triangles (mesh units / s)
        time : s, a scalar or (P,) per point

        Returns
        -------
        position (P, 3), triangle (P,), wall_edge (P,) (-1 or the border edge where the point
        stopped), direction (P, 3) unfolded into the final triangle, rounds, unfinished count
        """
        position = np.array(start, dtype=np.float64)
        tri = np.array(triangle, dtype=np.int64)
        direction = np.array(direction, dtype=np.float64)
        P = position.shape[0]
        remaining = np.array(np.broadcast_to(np.asarray(time, dtype=np.float64), (P,)))
        entry = np.full(P, -1, dtype=np.int64)
        wall = np.full(P, -1, dtype=np.int64)
        active = np.flatnonzero(remaining > 0)
        if self._locator is not None and active.size:
            active = active[~self._jump(position, tri, direction, remaining[active], active, wall)]
        rounds = 0
        while active.size and rounds < max_rounds:
            rounds += 1
            self._advance(position, tri, direction, remaining, entry, wall, active)
            active = active[remaining[active] > 0]
        return position, tri, wall, direction, rounds, int(active.size)

    def to_plane(self, vectors: np.ndarray, triangle: np.ndarray) -> np.ndarray:
        """Tangential projection onto the triangles' planes, keeping the lengths."""
        n = self.face_normal[triangle]
        projected = vectors - np.einsum("pd,pd->p", vectors, n)[:, None] * n
        length = np.linalg.norm(vectors, axis=1)
        new_length = np.linalg.norm(projected, axis=1)
        return projected * np.where(new_length > 0, length / np.where(new_length > 0, new_length, 1.0), 0.0)[:, None]

    def substep_counts(self, triangle: np.ndarray, dt: float, speed_at_start, substeps: int,
                       max_cfl: float | None, max_substeps: int) -> np.ndarray:
        """(P,) substeps per point: ``substeps``, or with ``max_cfl`` enough that one substep moves
        the point at most ``max_cfl`` mean edge lengths of its start triangle (|u| dt / h / k ≤
        max_cfl, ``speed_at_start`` (P, 3) the velocity there), capped at ``max_substeps``."""
        count = np.full(np.shape(triangle)[0], substeps, dtype=np.int64)
        if max_cfl is not None:
            cfl = np.linalg.norm(speed_at_start, axis=1) * dt / self.size[triangle]
            count = np.clip(np.ceil(cfl / max_cfl).astype(np.int64), substeps, max(max_substeps, substeps))
        return count

    def kernel_tables(self) -> tuple:
        """The tables the numba kernels (compiled.py) read, as two tuples (column layouts in
        compiled.py: one row per triangle holds what a point there reads).

        walk: vertices (n0, 3), tri_real (m, 27) ∇λ, centroid, corners, face normal, corner
        clearances; tri_int (m, 12) vertices, neighbours, their slots, edges; face normals, planar.
        jump (planar meshes; empty otherwise): the barycentric affine rows of the bucket members
        in bucket order (slots, 9), buckets (cell starts, then member triangles), the border edges
        (b, 8: a, e, outward normal, edge id, triangle), their buckets, the two grids (origin x, y,
        cell size; twice), their shapes (nx, ny; twice), the affine rows per triangle (m, 9).
        """
        jumps = self._locator is not None
        cache = self.__dict__.setdefault("_kernel_tables", {})
        if jumps not in cache:
            m = self.top.shape[0]
            clearance = self.vertex_clearance[self.top] if self.planar else np.zeros((m, 3))
            tri_real = np.concatenate([self.gradient.reshape(m, 9), self.centroid, self.corner_x.reshape(m, 9),
                                       self.face_normal, clearance], axis=1)
            tri_int = np.concatenate([self.top, self.neighbor, self.neighbor_slot, self.edge], axis=1)
            walk = (np.ascontiguousarray(self.x, dtype=np.float64), np.ascontiguousarray(tri_real, dtype=np.float64),
                    np.ascontiguousarray(tri_int, dtype=np.int64),
                    np.ascontiguousarray(self.face_normal, dtype=np.float64), bool(self.planar))
            grid, shape = np.ones(6), np.ones(4, dtype=np.int64)
            affine, buckets = np.zeros((0, 9)), np.zeros(1, dtype=np.int64)
            border, border_buckets = np.zeros((0, 8)), np.zeros(2, dtype=np.int64)
            if jumps:
                origin, size, cells = self._grid
                grid[:3], shape[:2] = (origin[0], origin[1], size), cells
                affine = self._affine_rows[self._bucket_triangles]
                buckets = np.concatenate([self._bucket_start, self._bucket_triangles])
                B = self._border
                if B is not None:
                    grid[3:], shape[2:] = (B["origin"][0], B["origin"][1], B["size"]), B["shape"]
                    border = np.concatenate([B["a"], B["e"], B["normal"], B["edge"][:, None], B["triangle"][:, None]],
                                            axis=1)
                    border_buckets = np.concatenate([B["start"], B["members"]])
            near = self._affine_rows if jumps else np.zeros((0, 9))
            real, integer = (lambda a: np.ascontiguousarray(a, dtype=np.float64)), \
                (lambda a: np.ascontiguousarray(a, dtype=np.int64))
            jump = (real(affine), integer(buckets), real(border), integer(border_buckets), grid, shape, real(near))
            cache[jumps] = (walk, jump)
        return cache[jumps]

    def backtrack_compiled(self, start: np.ndarray, triangle: np.ndarray, dt: float, interpolator,
                           point_velocity: np.ndarray, integrator: str = "midpoint", substeps: int = 1,
                           max_rounds: int = 1000, start_velocity: np.ndarray | None = None,
                           max_cfl: float | None = None, max_substeps: int = 64) -> BacktrackResult:
        """:meth:`backtrack` by the numba kernel (compiled.py), point by point.

        The velocity is the interpolation by ``interpolator`` (a CellInterpolator) of field 1 of
        ``point_velocity`` (n_points, 3, F ≥ 2: [d0 ψ part, full u] at the dual points) instead of
        a callable; the other parameters and the result are those of :meth:`backtrack`, plus
        ``result.velocity``: all fields of ``point_velocity`` interpolated at the end points.
        """
        from decrun.methods.fluid import compiled

        _check_integrator(integrator, substeps)
        position = np.array(start, dtype=np.float64, order="C")
        tri = np.array(triangle, dtype=np.int64)
        point_velocity = np.ascontiguousarray(point_velocity, dtype=np.float64)
        normal = np.ascontiguousarray(self.face_normal, dtype=np.float64)
        if start_velocity is None:
            start_velocity = interpolator.velocity_compiled(tri, position, point_velocity, normal)[:, :, 1]
        start_velocity = np.ascontiguousarray(start_velocity, dtype=np.float64)
        wall = np.full(tri.size, -1, dtype=np.int64)
        velocity = np.empty((tri.size, 3, point_velocity.shape[2]))
        rounds, unfinished, most = compiled.backtrack_points(
            *self.kernel_tables(), interpolator.kernel_tables(), point_velocity, position, tri, wall, start_velocity,
            velocity, True, np.ascontiguousarray(self.size, dtype=np.float64), float(dt), int(substeps),
            -1.0 if max_cfl is None else float(max_cfl), max(max_substeps, substeps),
            compiled.INTEGRATOR_CODE[integrator], int(max_rounds), np.zeros(0), np.zeros(0), 0, jit.threads())
        return BacktrackResult(position, tri, wall, int(rounds.sum()), int(unfinished.max(initial=0)), int(most),
                               velocity)

    def backtrack(self, start: np.ndarray, triangle: np.ndarray, dt: float, velocity,
                  integrator: str = "midpoint", substeps: int = 1, max_rounds: int = 1000,
                  start_velocity: np.ndarray | None = None, max_cfl: float | None = None,
                  max_substeps: int = 64) -> BacktrackResult:
        """Follow −u for time ``dt`` from every start point.

        Parameters
        ----------
        start : (P, 3) positions; triangle : (P,) their triangles
        dt : time step (s)
        velocity : callable (triangles (Q,), positions (Q, 3)) -> (Q, 3) the interpolated
            velocity (mesh units / s) tangent to the given triangles
        integrator : "midpoint" | "euler" | "per_triangle" (see the module docstring)
        substeps : least number of substeps (of length dt / substeps)
        max_rounds : safety bound on walking rounds per walk (unfinished points are reported)
        start_velocity : (P, 3) optional velocity at the start points (saves one evaluation;
            at the circumcenters it is the triangle's velocity, which the interpolation
            reproduces there exactly)
        max_cfl : if given, each point takes enough substeps that one substep moves it at most
            ``max_cfl`` times the mean edge length of its start triangle (|u| dt / h / k ≤ max_cfl,
            the stepSize of Fig. 7.9 made per point), capped at ``max_substeps``
        """
        _check_integrator(integrator, substeps)
        position = np.array(start, dtype=np.float64)
        tri = np.array(triangle, dtype=np.int64)
        P = position.shape[0]
        wall = np.full(P, -1, dtype=np.int64)
        speed_at_start = None
        if max_cfl is not None:
            speed_at_start = start_velocity if start_velocity is not None else velocity(tri, position)
        count = self.substep_counts(tri, dt, speed_at_start, substeps, max_cfl, max_substeps)
        tau_of = float(dt) / count
        rounds = unfinished = 0
        for substep in range(int(count.max())):  # a bounded number of substeps
            moving = np.flatnonzero((wall < 0) & (count > substep))
            t, x, tau = tri[moving], position[moving], tau_of[moving]
            if integrator == "per_triangle":
                x, t, hit, r, left = self._walk_per_triangle(x, t, tau, velocity, max_rounds)
            else:
                if substep == 0 and start_velocity is not None:
                    d = -start_velocity[moving]
                else:
                    d = -velocity(t, x)
                if integrator == "midpoint":
                    # x + τ d2 = x_m + τ (d2 − d1 / 2): continue from the midpoint (d1 unfolded there)
                    xm, tm, hit, d1, r1, _ = self.walk(x, t, d, 0.5 * tau, max_rounds)
                    d = -velocity(tm, xm) - 0.5 * d1
                    d[hit >= 0] = 0.0  # clamped during the half step: stays at the wall
                    x, t = xm, tm
                    rounds += r1
                else:
                    hit = np.full(x.shape[0], -1, dtype=np.int64)
                x, t, hit2, _, r, left = self.walk(x, t, d, tau, max_rounds)
                hit = np.where(hit >= 0, hit, hit2)
            position[moving], tri[moving], wall[moving] = x, t, hit
            rounds += r
            unfinished = max(unfinished, left)
        return BacktrackResult(position, tri, wall, rounds, unfinished, int(count.max()))

    def _walk_per_triangle(self, x, t, tau, velocity, max_rounds):
        """Fig. 7.9: Euler with the velocity evaluated again in every triangle entered."""
        position, tri = x.copy(), t.copy()
        P = position.shape[0]
        remaining = np.array(np.broadcast_to(np.asarray(tau, dtype=np.float64), (P,)))
        entry = np.full(P, -1, dtype=np.int64)
        wall = np.full(P, -1, dtype=np.int64)
        direction = np.zeros((P, 3))
        active = np.arange(P)
        rounds = 0
        while active.size and rounds < max_rounds:
            rounds += 1
            fresh = -velocity(tri[active], position[active])
            previous = direction[active]
            # a fresh velocity leaving at once through the entry edge: keep the unfolded one
            lam = np.clip(self.barycentric(tri[active], position[active]), 0.0, None)
            rate = dot3(self.gradient[tri[active]], fresh[:, None, :])
            came = entry[active]
            rows = np.arange(active.size)
            back = (came >= 0) & (rate[rows, np.maximum(came, 0)] < 0) & (lam[rows, np.maximum(came, 0)] <= 1e-12)
            direction[active] = np.where(back[:, None], previous, fresh)
            self._advance(position, tri, direction, remaining, entry, wall, active)
            active = active[remaining[active] > 0]
        return position, tri, wall, rounds, int(active.size)
