"""Backtracking of the dual vertices along −u (thesis §7.2.3, Fig. 7.9; ETK07 §4.2).

All points walk at once; each *round* moves every still-active point in a straight line
inside its current triangle, with the interpolated velocity at its current position,
until the remaining time is used up or it reaches an edge. At an edge it crosses into
the neighbour and the direction is unfolded into the neighbour's plane (rotation about
the shared edge). Unlike the printed pseudocode, a point always advances (a step equal
to the distance to the edge moves it onto the edge). If the velocity evaluated in the
new triangle points straight back out through the edge just crossed, the unfolded
previous direction is used instead, so no point can ping-pong on an edge.

At a border edge the point stops (clamped to the wall; the rest of the time step is
dropped) and the border edge is recorded: the caller gives such points the wall's
velocity. That applies to the outer (inflow / outflow) border too: a point whose past
lies upstream of the inflow border is placed on it, where the fluid arrives with the
prescribed inflow velocity and no vorticity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from decrun.dec import DEC
from decrun.methods.fluid.dual_cells import _embed3

__all__ = ["TriangleWalker", "BacktrackResult"]


@dataclass
class BacktrackResult:
    """Where the points were ``dt`` earlier.

    position : (P, 3); triangle : (P,) the triangle holding each position
    wall_edge : (P,) border edge id where a point was clamped, -1 otherwise
    rounds : walking rounds used; unfinished : points still walking after ``max_rounds``
    """

    position: np.ndarray
    triangle: np.ndarray
    wall_edge: np.ndarray
    rounds: int
    unfinished: int


class TriangleWalker:
    """Triangle adjacency and barycentric tables for walking on a triangle mesh.

    Local vertex order is that of ``dec.K.simplices(2)``; ``neighbor[t, l]`` is the
    triangle across the edge opposite local vertex l (-1 on the border), ``edge[t, l]``
    that edge's id.
    """

    def __init__(self, dec: DEC, face_normal: np.ndarray):
        K = dec.K
        self.x = _embed3(K.vertices)
        self.top = K.simplices(2)
        m = self.top.shape[0]
        self.face_normal = face_normal
        self.edge = K.face_indices(2)  # (m, 3) edge opposite local vertex l
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
        self.centroid = p.mean(axis=1)

    def barycentric(self, triangle: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(P, 3) barycentric coordinates of x (P, 3) in the plane of ``triangle`` (P,)."""
        return 1.0 / 3.0 + np.einsum("pcd,pd->pc", self.gradient[triangle], x - self.centroid[triangle])

    def unfold(self, direction: np.ndarray, triangle: np.ndarray, slot: np.ndarray, neighbor: np.ndarray) -> np.ndarray:
        """Rotate ``direction`` (P, 3) about the edge (opposite ``slot`` of ``triangle``) into the
        plane of ``neighbor``: d' = <d, ê> ê + <d, N×ê> (N'×ê)."""
        a = self.top[triangle, (slot + 1) % 3]
        b = self.top[triangle, (slot + 2) % 3]
        e = self.x[b] - self.x[a]
        e /= np.linalg.norm(e, axis=1, keepdims=True)
        old = np.cross(self.face_normal[triangle], e)
        new = np.cross(self.face_normal[neighbor], e)
        return (np.einsum("pd,pd->p", direction, e)[:, None] * e
                + np.einsum("pd,pd->p", direction, old)[:, None] * new)

    def _direction_checked(self, d, t, lam, came, fallback):
        """Replace directions that leave at once through the entry edge by ``fallback``."""
        rate = np.einsum("pcd,pd->pc", self.gradient[t], d)
        rows = np.arange(t.size)
        slot = np.maximum(came, 0)
        back = (came >= 0) & (rate[rows, slot] < 0) & (lam[rows, slot] <= 1e-12)
        if back.any():
            d = d.copy()
            d[back] = fallback[back]
            rate[back] = np.einsum("pcd,pd->pc", self.gradient[t[back]], d[back])
        return d, rate

    @staticmethod
    def _exit(lam, rate):
        with np.errstate(divide="ignore", invalid="ignore"):
            exit_time = np.where(rate < 0, lam / -rate, np.inf)
        slot = np.argmin(exit_time, axis=1)
        return exit_time[np.arange(slot.size), slot], slot

    def backtrack(self, start: np.ndarray, triangle: np.ndarray, dt: float, velocity,
                  max_rounds: int = 500, max_segment_time: float | None = None,
                  integrator: str = "midpoint") -> BacktrackResult:
        """Follow −u for time ``dt`` from every start point.

        Parameters
        ----------
        start : (P, 3) positions; triangle : (P,) their triangles
        dt : time step (s)
        velocity : callable (triangles (Q,), positions (Q, 3)) -> (Q, 3) the interpolated
            velocity (mesh units / s) tangent to the given triangles
        max_rounds : safety bound on walking rounds (unfinished points are reported)
        max_segment_time : longest straight segment (s), the stepSize of Fig. 7.9; default:
            a segment ends only at the remaining time or at the triangle's edge
        integrator : "euler" — each segment follows the velocity at its start (Fig. 7.9);
            "midpoint" — each segment follows the velocity at the midpoint of the Euler
            segment (explicit midpoint rule; the trial midpoint lies in the same triangle).
            Euler inflates rotating cells by a factor 1 + (Ω τ)² per segment of length τ,
            which shows as vorticity growth in vortex cores; the midpoint rule by 1 + (Ω τ)⁴/4.
        """
        if integrator not in ("euler", "midpoint"):
            raise ValueError(f"integrator must be 'euler' or 'midpoint', not {integrator!r}")
        position = np.array(start, dtype=np.float64)
        tri = np.array(triangle, dtype=np.int64)
        P = position.shape[0]
        remaining = np.full(P, float(dt))
        wall = np.full(P, -1, dtype=np.int64)
        entry = np.full(P, -1, dtype=np.int64)
        previous = np.zeros((P, 3))
        active = np.flatnonzero(remaining > 0)
        rounds = 0
        while active.size and rounds < max_rounds:
            rounds += 1
            t, x, r = tri[active], position[active], remaining[active]
            came = entry[active]
            lam = np.clip(self.barycentric(t, x), 0.0, None)
            d, rate = self._direction_checked(-velocity(t, x), t, lam, came, previous[active])
            limit = r if max_segment_time is None else np.minimum(r, max_segment_time)
            if integrator == "midpoint":
                s, _ = self._exit(lam, rate)
                tau = np.minimum(limit, s)
                middle = x + 0.5 * tau[:, None] * d
                d, rate = self._direction_checked(-velocity(t, middle), t, lam, came, d)
            s, slot = self._exit(lam, rate)
            inside = s >= limit
            # points that stay inside their triangle: move the full (segment) time
            position[active[inside]] = x[inside] + limit[inside, None] * d[inside]
            remaining[active[inside]] = r[inside] - limit[inside]
            entry[active[inside]] = -1
            # points reaching an edge: move onto it exactly, then cross or stop at the wall
            cross = np.flatnonzero(~inside)
            if cross.size:
                idx = active[cross]
                tc, sc, lc = t[cross], s[cross], slot[cross]
                lam_new = lam[cross] + sc[:, None] * rate[cross]
                lam_new[np.arange(cross.size), lc] = 0.0
                lam_new = np.clip(lam_new, 0.0, None)
                lam_new /= lam_new.sum(axis=1, keepdims=True)
                position[idx] = np.einsum("pc,pcd->pd", lam_new, self.x[self.top[tc]])
                remaining[idx] = r[cross] - sc
                nb = self.neighbor[tc, lc]
                at_wall = nb < 0
                wall[idx[at_wall]] = self.edge[tc[at_wall], lc[at_wall]]
                remaining[idx[at_wall]] = 0.0
                go = ~at_wall
                previous[idx[go]] = self.unfold(d[cross][go], tc[go], lc[go], nb[go])
                entry[idx[go]] = self.neighbor_slot[tc[go], lc[go]]
                tri[idx[go]] = nb[go]
            active = np.flatnonzero(remaining > 0)
        return BacktrackResult(position, tri, wall, rounds, int(active.size))
