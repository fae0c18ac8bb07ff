"""Cut holes with smooth borders: split the triangles along the zero level set of balls/boxes.

The holes are the union of the regions ``balls`` (``[cx, cy, cz, r]``, 2-D ``[cx, cy, r]``)
and ``boxes`` (``[xmin, ymin, zmin, xmax, ymax, zmax]``, 2-D ``[xmin, ymin, xmax, ymax]``),
described by the signed distance

    φ(x) = min_k φ_k(x),   φ_ball(x) = |x − c| − r,   φ_box(x) = |max(q, 0)| + min(max_i q_i, 0),
    q = |x − (lo + hi)/2| − (hi − lo)/2                 (negative inside, zero on the border).

:func:`cut_holes` keeps the part of the surface where φ ≥ 0 (marching triangles):

1. **classify** the vertices: outside (φ > τ), inside (φ < −τ), on the level set (|φ| ≤ τ),
   τ = 1e-12 × the mean edge length;
2. **cross** every edge from an outside to an inside vertex at the point where the segment
   first enters the union of the regions — computed exactly per region (the smaller root of
   |a + t(b − a) − c|² = r² for a ball, the slab entry for a box, whose crossed plane
   coordinate is then set exactly), not by interpolating φ, so the new vertices lie on the
   ball's sphere / the box's face to round-off. The crossing is computed once per unique
   edge, so the two triangles sharing a cut edge share its one new vertex;
3. **snap** (no slivers): where the crossing lies within ``snap`` × the edge length of an
   end point, that end point is moved along the edge onto the crossing instead (a vertex
   with several such edges takes the nearest) and counts as on the level set. A snap that
   would turn any incident triangle over (its normal reversed; signed area in 2-D) is
   undone for that triangle's vertices (``snap_undone``). After snapping every remaining
   cut has a parameter in (snap, 1 − snap): every new vertex is at least ``snap`` × its
   edge's length away from both ends of that edge, so the pieces of a split triangle have at
   least ``snap``² of its area (measured on the Fig. 5.7 half sphere, subdiv 4: smallest
   corner angle 1.5° without snapping, 6.0° at 0.1, 9.7° at 0.2, 15.4° at the default 0.25;
   the largest move was 0.019, a quarter of the mean edge length 0.075);
4. **split** each triangle by the signs of its corners, keeping the input orientation:
   no inside corner → kept whole; no outside corner → removed; one outside corner →
   the triangle at it; two → the quadrilateral, split along its shorter diagonal; one on the
   level set, one outside, one inside → the triangle on the outside. A triangle with all
   three corners on the level set is kept when φ(centroid) > τ, removed when < −τ, and by
   the sign of its corners before snapping otherwise (``ambiguous_faces``);
5. **clean up**: a vertex where kept triangles meet in more than one fan (the level set
   touches it twice: two holes meeting at a point) is split into one copy per fan
   (``pinched_vertices_split``); unless ``keep_all_pieces``, only the largest piece
   (triangles joined across edges) is kept (``dropped_piece_faces``); unused vertices go.

Limits: the cut sees φ only through the vertices — a region that crosses an edge without
containing either end point (a feature thinner than the mesh) is missed on that edge.
Everything is vectorized over the vertices, edges and faces.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import scipy.sparse as sp

from decrun.core.connectivity import drop_unreferenced, edge_table, graph_components, largest_component
from decrun.core.geometry import area_normals
from decrun.errors import ConfigError, MeshError

__all__ = ["cut_holes", "signed_distance", "parse_regions"]

ON_TOLERANCE = 1e-12  # |φ| ≤ ON_TOLERANCE × mean edge length counts as on the level set


def parse_regions(balls: Sequence, boxes: Sequence, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Validate the hole regions for ``dim``-dimensional vertices (2 or 3).

    Returns balls (nb, dim+1) ``[centre, radius]`` and boxes (nx, 2·dim) ``[lo, hi]``, float64.
    Raises :class:`ConfigError` naming ``mesh.hole_balls[k]`` / ``mesh.hole_boxes[k]``.
    """
    ball_rows, box_rows = [], []
    for k, ball in enumerate(balls):
        ball = np.asarray(list(ball), dtype=np.float64)
        if ball.shape != (dim + 1,) or not np.isfinite(ball).all() or ball[-1] <= 0:
            raise ConfigError(f"mesh.hole_balls[{k}]: need [centre ({dim} numbers), radius > 0], got {ball.tolist()}")
        ball_rows.append(ball)
    for k, box in enumerate(boxes):
        box = np.asarray(list(box), dtype=np.float64)
        if box.shape != (2 * dim,) or not np.isfinite(box).all() or np.any(box[:dim] >= box[dim:]):
            raise ConfigError(f"mesh.hole_boxes[{k}]: need [min corner ({dim}), max corner ({dim})] with "
                              f"min < max, got {box.tolist()}")
        box_rows.append(box)
    return (np.array(ball_rows).reshape(-1, dim + 1), np.array(box_rows).reshape(-1, 2 * dim))


def _ball_distance(points: np.ndarray, ball: np.ndarray) -> np.ndarray:
    d = points.shape[1]
    return np.linalg.norm(points - ball[:d], axis=1) - ball[d]


def _box_distance(points: np.ndarray, box: np.ndarray) -> np.ndarray:
    d = points.shape[1]
    lo, hi = box[:d], box[d:]
    q = np.abs(points - (lo + hi) / 2) - (hi - lo) / 2
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def signed_distance(points: np.ndarray, balls: np.ndarray, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """φ of the union of the regions at ``points`` (n, d), model units; negative inside.

    Returns φ (n,) and the region attaining the minimum (n,) int: balls are regions
    0..nb−1, boxes nb..nb+nx−1 (the arrays of :func:`parse_regions`).
    """
    columns = [_ball_distance(points, b) for b in balls] + [_box_distance(points, b) for b in boxes]
    phi = np.column_stack(columns)
    region = np.argmin(phi, axis=1)
    return phi[np.arange(len(points)), region], region


def _ball_entry(a: np.ndarray, direction: np.ndarray, ball: np.ndarray) -> np.ndarray:
    """Parameter t ∈ [0, 1] where a + t·direction first enters the ball (inf if it does not).

    The smaller root of |f + t·direction|² = r², f = a − c, in the cancellation-free form
    t = C / (−B + √(B² − A C)) (A = |direction|², B = f·direction, C = |f|² − r² > 0): it
    enters only when B < 0.
    """
    d = a.shape[1]
    f = a - ball[:d]
    A = np.einsum("ij,ij->i", direction, direction)
    B = np.einsum("ij,ij->i", f, direction)
    C = np.einsum("ij,ij->i", f, f) - ball[d] ** 2
    disc = B * B - A * C
    hits = (B < 0) & (disc >= 0) & (C >= 0)
    t = np.full(len(a), np.inf)
    t[hits] = C[hits] / (-B[hits] + np.sqrt(disc[hits]))
    t[t > 1] = np.inf
    return t


def _box_entry(a: np.ndarray, direction: np.ndarray, box: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slab entry of a + t·direction into the box: t (inf if none in [0, 1]), the axis of the
    entry plane and that plane's coordinate (to set the crossing's coordinate exactly)."""
    d = a.shape[1]
    lo, hi = box[:d], box[d:]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_lo = (lo - a) / direction
        t_hi = (hi - a) / direction
    parallel = direction == 0
    inside_slab = (a >= lo) & (a <= hi)
    t_near = np.where(parallel, np.where(inside_slab, -np.inf, np.inf), np.minimum(t_lo, t_hi))
    t_far = np.where(parallel, np.where(inside_slab, np.inf, -np.inf), np.maximum(t_lo, t_hi))
    axis = np.argmax(t_near, axis=1)
    rows = np.arange(len(a))
    t_enter, t_exit = t_near[rows, axis], t_far.min(axis=1)
    plane = np.where(direction[rows, axis] > 0, lo[axis], hi[axis])
    t = np.where((t_enter <= t_exit) & (t_enter >= 0) & (t_enter <= 1), t_enter, np.inf)
    return t, axis, plane


def _crossings(a: np.ndarray, b: np.ndarray, balls: np.ndarray, boxes: np.ndarray):
    """First entry of the segments a→b (a outside, b inside) into the union of the regions.

    Returns t (k,) in (0, 1), the points (k, d) and the entered region (k,).
    """
    direction = b - a
    k = len(a)
    entries, planes = [], []
    for ball in balls:
        entries.append(_ball_entry(a, direction, ball))
        planes.append(None)
    for box in boxes:
        t, axis, plane = _box_entry(a, direction, box)
        entries.append(t)
        planes.append((axis, plane))
    entries = np.column_stack(entries) if entries else np.zeros((k, 0))
    region = np.argmin(entries, axis=1)
    t = entries[np.arange(k), region]
    if not np.isfinite(t).all():  # cannot happen for a strictly outside a and inside b
        raise MeshError("mesh holes: an edge from outside to inside the holes did not enter any of them")
    points = a + t[:, None] * direction
    for r in range(len(balls), len(balls) + len(boxes)):
        chosen = np.flatnonzero(region == r)
        axis, plane = planes[r]
        points[chosen, axis[chosen]] = plane[chosen]  # exactly on the crossed face plane
    return t, points, region


def _rotate_to(faces: np.ndarray, position: np.ndarray) -> np.ndarray:
    """Cyclically rotate each face row so that local ``position`` comes first (orientation kept)."""
    order = (position[:, None] + np.arange(3)[None, :]) % 3
    return np.take_along_axis(faces, order, axis=1)


def _fans(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Fan label of every face corner (3m,) and the number of fans per vertex (n,).

    Two corners of the same vertex are in one fan when their triangles share an edge at it.
    """
    m = len(faces)
    _, edge_of = edge_table(faces, n_vertices)
    slots = edge_of.ravel()  # half-edge 3f + l runs from corner l to corner l+1
    order = np.argsort(slots, kind="stable")
    same = slots[order][1:] == slots[order][:-1]
    first, second = order[:-1][same], order[1:][same]
    corner = np.arange(3 * m)
    vertex = faces.ravel()
    rows, cols = [], []
    f0, l0 = first // 3, first % 3
    f1, l1 = second // 3, second % 3
    for end in (0, 1):  # the two vertices of the shared edge
        c0 = 3 * f0 + (l0 + end) % 3
        v = vertex[c0]
        in_second_start = vertex[3 * f1 + l1] == v
        c1 = np.where(in_second_start, 3 * f1 + l1, 3 * f1 + (l1 + 1) % 3)
        rows.append(c0)
        cols.append(c1)
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    graph = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(3 * m, 3 * m))
    _, label = graph_components(graph)
    pairs = np.unique(np.column_stack([vertex, label[corner]]), axis=0)
    return label, np.bincount(pairs[:, 0], minlength=n_vertices)


def _split_pinched(vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray):
    """One vertex copy per fan at vertices with several fans. Returns vertices, faces, origin, count."""
    label, fans = _fans(faces, len(vertices))
    if not np.any(fans > 1):
        return vertices, faces, origin, 0
    vertex = faces.ravel()
    pairs, inverse = np.unique(np.column_stack([vertex, label]), axis=0, return_inverse=True)
    inverse = inverse.ravel()
    first_of_vertex = np.r_[True, pairs[1:, 0] != pairs[:-1, 0]]
    extra = np.flatnonzero(~first_of_vertex)
    new_id = pairs[:, 0].copy()
    new_id[extra] = len(vertices) + np.arange(extra.size)
    faces = new_id[inverse].reshape(-1, 3)
    copies = pairs[extra, 0]
    return (np.concatenate([vertices, vertices[copies]]), faces,
            np.concatenate([origin, origin[copies]]), int(extra.size))


#: the snap distance (× edge length) of ``mesh.hole_snap`` (module doc, step 3)
SNAP = 0.25


def cut_holes(vertices, faces, balls: Sequence = (), boxes: Sequence = (), *, snap: float = SNAP,
              keep_all_pieces: bool = False) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Cut the union of ``balls`` and ``boxes`` out of a triangle mesh along their border.

    Parameters
    ----------
    vertices : (n, d) float, d = 2 (planar) or 3, model units
    faces : (m, 3) int, oriented triangles (the orientation of every kept piece is kept)
    balls : rows ``[centre (d), radius]``; boxes : rows ``[min corner (d), max corner (d)]``
    snap : in [0, 0.5): a crossing within ``snap`` × edge length of an end point moves that
        end point onto the level set instead of making a new vertex (module doc, step 3)
    keep_all_pieces : keep every piece the holes leave, not only the largest

    Returns
    -------
    vertices (n', d) float64, faces (m', 3) int64 and ``info``:

    - ``new_vertices``: edge crossings added; ``snapped_vertices``: vertices moved onto the
      level set; ``snap_undone``: snaps undone to keep a triangle from turning over;
      ``max_snap_distance``: longest snap move (model units)
    - ``removed_faces``: input triangles removed entirely; ``split_faces``: input triangles
      cut into a kept part; ``ambiguous_faces``: all corners on the level set (step 4)
    - ``pinched_vertices_split``: vertex copies added at pinches; ``dropped_piece_faces``:
      triangles of the smaller pieces dropped
    - ``on_border`` (n',) bool: vertex on the level set (new, snapped, or within τ already);
      ``region`` (n',) int: the ball (0..nb−1) or box (nb..) it lies on, −1 elsewhere
    - ``interpolation``: (n', n) CSR matrix P with ``P @ input_vertices == vertices`` (to
      round-off): every vertex is an input vertex or a point on an input edge, so P carries
      any per-vertex field (e.g. noise-free positions) onto the cut mesh
    - ``source_vertex`` (n',) int: the input vertex a kept vertex is (or a copy of), −1 for
      new ones

    Raises :class:`ConfigError` for a bad region, :class:`MeshError` when nothing is left.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    n, dim = vertices.shape
    if dim not in (2, 3) or faces.ndim != 2 or faces.shape[1] != 3:
        raise MeshError(f"cut_holes needs (n, 2|3) vertices and (m, 3) triangles, got {vertices.shape}, {faces.shape}")
    if not 0 <= snap < 0.5:
        raise ConfigError(f"mesh.hole_snap: must be in [0, 0.5), got {snap}")
    ball_rows, box_rows = parse_regions(balls, boxes, dim)
    info: dict[str, Any] = dict(new_vertices=0, snapped_vertices=0, snap_undone=0, max_snap_distance=0.0,
                                removed_faces=0, split_faces=0, ambiguous_faces=0, pinched_vertices_split=0,
                                dropped_piece_faces=0)
    if len(ball_rows) + len(box_rows) == 0:
        info.update(on_border=np.zeros(n, dtype=bool), region=np.full(n, -1), source_vertex=np.arange(n),
                    interpolation=sp.identity(n, format="csr"))
        return vertices.copy(), faces.copy(), info

    # 1. classify
    edges, edge_of = edge_table(faces, n)
    length = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    tau = ON_TOLERANCE * length.mean()
    phi, vertex_region = signed_distance(vertices, ball_rows, box_rows)
    sign0 = np.where(phi > tau, 1, np.where(phi < -tau, -1, 0))

    # 2. cross every outside→inside edge once
    e_sign = sign0[edges]
    cut = np.flatnonzero(e_sign[:, 0] * e_sign[:, 1] < 0)
    outer = np.where(e_sign[cut, 0] > 0, edges[cut, 0], edges[cut, 1])
    inner = np.where(e_sign[cut, 0] > 0, edges[cut, 1], edges[cut, 0])
    t, point, cross_region = _crossings(vertices[outer], vertices[inner], ball_rows, box_rows)

    # 3. snap end points within snap × edge length of the crossing
    near_outer, near_inner = t <= snap, t >= 1 - snap
    cand_vertex = np.concatenate([outer[near_outer], inner[near_inner]])
    cand_edge = np.concatenate([np.flatnonzero(near_outer), np.flatnonzero(near_inner)])
    cand_move = np.concatenate([t[near_outer], 1 - t[near_inner]]) * length[cut[cand_edge]]
    pick = np.lexsort([cand_move, cand_vertex])
    first = np.r_[True, cand_vertex[pick][1:] != cand_vertex[pick][:-1]] if pick.size else np.zeros(0, bool)
    snap_vertex, snap_edge = cand_vertex[pick][first], cand_edge[pick][first]
    normal_before = area_normals(vertices, faces)
    undone = 0
    while True:  # undo the snaps of every triangle the snaps would turn over (each round undoes ≥ 1)
        moved = vertices.copy()
        moved[snap_vertex] = point[snap_edge]
        turned = np.einsum("ij,ij->i", area_normals(moved, faces), normal_before) <= 0
        undo = np.isin(snap_vertex, faces[turned])
        if not undo.any():
            break
        undone += int(undo.sum())
        snap_vertex, snap_edge = snap_vertex[~undo], snap_edge[~undo]
    sign = sign0.copy()
    sign[snap_vertex] = 0
    info["snapped_vertices"], info["snap_undone"] = int(snap_vertex.size), undone
    if snap_vertex.size:
        info["max_snap_distance"] = float(np.linalg.norm(moved[snap_vertex] - vertices[snap_vertex], axis=1).max())

    # the cuts left: both end points unmoved, so their crossings stand; one new vertex each
    still_cut = np.ones(len(cut), dtype=bool)
    still_cut[np.isin(outer, snap_vertex) | np.isin(inner, snap_vertex)] = False
    new_of_edge = np.full(len(edges), -1, dtype=np.int64)
    live = np.flatnonzero(still_cut)
    new_of_edge[cut[live]] = n + np.arange(live.size)
    info["new_vertices"] = int(live.size)
    all_vertices = np.concatenate([moved, point[live]])

    # interpolation rows: unmoved vertices are themselves, snapped/new ones points on an edge
    rows = [np.arange(n)]
    cols = [np.arange(n)]
    vals = [np.ones(n)]
    weights_of = lambda e: (outer[e], inner[e], t[e])  # noqa: E731  point = (1−t)·outer + t·inner
    for target, e in ((snap_vertex, snap_edge), (n + np.arange(live.size), live)):
        o, i, te = weights_of(e)
        rows += [target, target]
        cols += [o, i]
        vals += [1 - te, te]
    keep_identity = np.ones(n, dtype=bool)
    keep_identity[snap_vertex] = False
    rows[0], cols[0], vals[0] = rows[0][keep_identity], cols[0][keep_identity], vals[0][keep_identity]
    interpolation = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                  shape=(len(all_vertices), n))

    on_border = np.concatenate([sign == 0, np.ones(live.size, dtype=bool)])
    region = np.concatenate([np.where(sign0 == 0, vertex_region, -1), cross_region[live]])
    region[snap_vertex] = cross_region[snap_edge]

    # 4. split the triangles by the signs of their corners
    s = sign[faces]
    plus, minus, zero = (s > 0).sum(1), (s < 0).sum(1), (s == 0).sum(1)
    whole = (minus == 0) & (zero < 3)
    pieces = [faces[whole]]
    # all corners on the level set
    all_zero = np.flatnonzero(zero == 3)
    keep_zero = np.zeros(0, dtype=bool)
    if all_zero.size:
        centroid_phi, _ = signed_distance(all_vertices[faces[all_zero]].mean(axis=1), ball_rows, box_rows)
        vote = sign0[faces[all_zero]].sum(axis=1)
        keep_zero = np.where(centroid_phi > tau, True, np.where(centroid_phi < -tau, False, vote > 0))
        info["ambiguous_faces"] = int((np.abs(centroid_phi) <= tau).sum())
        pieces.append(faces[all_zero[keep_zero]])
    new_at = lambda f, a: new_of_edge[edge_of[f, a]]  # noqa: E731  new vertex on the edge from corner a to a+1

    # one outside, two inside: the triangle at the outside corner
    one = np.flatnonzero((plus == 1) & (minus == 2))
    k = np.argmax(s[one] > 0, axis=1)
    rf = _rotate_to(faces[one], k)
    pieces.append(np.column_stack([rf[:, 0], new_at(one, k), new_at(one, (k + 2) % 3)]))
    # two outside, one inside: the quadrilateral, split along its shorter diagonal
    two = np.flatnonzero((plus == 2) & (minus == 1))
    k = np.argmax(s[two] < 0, axis=1)
    rf = _rotate_to(faces[two], k)
    p01, p20 = new_at(two, k), new_at(two, (k + 2) % 3)
    quad = np.column_stack([p01, rf[:, 1], rf[:, 2], p20])  # in the face's orientation
    diag_02 = np.linalg.norm(all_vertices[quad[:, 0]] - all_vertices[quad[:, 2]], axis=1)
    diag_13 = np.linalg.norm(all_vertices[quad[:, 1]] - all_vertices[quad[:, 3]], axis=1)
    use_02 = diag_02 <= diag_13
    pieces.append(np.where(use_02[:, None], quad[:, [0, 1, 2]], quad[:, [0, 1, 3]]))
    pieces.append(np.where(use_02[:, None], quad[:, [0, 2, 3]], quad[:, [1, 2, 3]]))
    # one on the level set, one outside, one inside: the triangle on the outside
    mixed = np.flatnonzero((zero == 1) & (plus == 1) & (minus == 1))
    k = np.argmax(s[mixed] == 0, axis=1)
    rf = _rotate_to(faces[mixed], k)
    p12 = new_at(mixed, (k + 1) % 3)
    next_outside = sign[rf[:, 1]] > 0
    pieces.append(np.where(next_outside[:, None], np.column_stack([rf[:, 0], rf[:, 1], p12]),
                           np.column_stack([rf[:, 0], p12, rf[:, 2]])))
    info["split_faces"] = int(one.size + two.size + mixed.size)
    new_faces = np.concatenate(pieces).astype(np.int64)
    info["removed_faces"] = int(len(faces) - info["split_faces"] - whole.sum() - keep_zero.sum())
    if len(new_faces) == 0:
        raise MeshError("mesh.hole_balls/hole_boxes: the holes remove every face of the mesh")

    # 5. pinches, pieces, unused vertices
    source = np.concatenate([np.arange(n), np.full(live.size, -1)])  # a snapped vertex stays itself, moved
    index = np.arange(len(all_vertices))
    all_vertices, new_faces, index, info["pinched_vertices_split"] = _split_pinched(all_vertices, new_faces, index)
    if not keep_all_pieces:
        largest = largest_component(new_faces, len(all_vertices))
        info["dropped_piece_faces"] = int((~largest).sum())
        new_faces = new_faces[largest]
    all_vertices, new_faces, used = drop_unreferenced(all_vertices, new_faces)
    index = index[used]
    info.update(on_border=on_border[index], region=region[index], source_vertex=source[index],
                interpolation=interpolation[index])
    return all_vertices, new_faces, info
