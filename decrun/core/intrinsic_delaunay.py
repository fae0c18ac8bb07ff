"""The intrinsic Delaunay triangulation of a triangle surface and its Laplacian.

Bobenko & Springborn 2007 (*A discrete Laplace–Beltrami operator for simplicial
surfaces*): keep the surface's metric (its edge lengths) and flip edges until every edge
is intrinsically Delaunay, i.e. its cotangent weight ½(cot α + cot β) is ≥ 0 (α, β the
angles opposite the edge). The cotangent Laplacian of that triangulation has non-negative
weights — an M-matrix, so the maximum principle holds — on any surface, whatever its
embedded triangles look like. Sharp & Crane 2020 (*A Laplacian for nonmanifold triangle
meshes*) add two things, both implemented here:

* **intrinsic mollification**: with δ = ``mollify`` × mean edge length, every edge length
  grows by ε = max(0, max over triangle corners of l_c − l_a − l_b + δ), so each
  triangle satisfies the triangle inequality with margin δ (degenerate input stays usable);
* **the tufted cover** (``border="tufted"``): two copies of every triangle (front and
  back, opposite orientations) glued so the result is closed — along a border edge the
  front is glued to its own back. A border edge then has two opposite angles (both equal
  to the one it had) and can be flipped when that angle is obtuse, so border weights become
  non-negative too. The operators of the cover are halved back onto the original vertices.
  ``border="fixed"`` instead keeps border edges (the classical intrinsic Delaunay
  triangulation of a surface with boundary), where ½ cot α < 0 can remain on a border.

Flips happen in **rounds** (the compiled ``flip_rounds`` of :mod:`decrun.core.extension`, beside its
numpy twin :func:`flip_rounds_numpy`): every round computes the weights of the edges that
may have changed, picks non-Delaunay edges of which no two share a triangle (each one is a
local minimum of the weight among the non-Delaunay edges of its two triangles), and flips
all of them at once. The triangulation is a Δ-complex (intrinsic triangulations may have
loops and multiple edges), stored with edge ids, not vertex pairs.

The Laplacian convention is decrun's: ``stiffness`` is the positive semi-definite
d0ᵀ ⋆1 d0 (``DEC.laplacian_symmetric(0)``), ``star0`` the positive lumped area
(a third of each intrinsic triangle's area per corner).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from decrun.core import extension
from decrun.errors import DegenerateSimplexError, MeshError, NonManifoldError, OrientationError, UnreferencedVertexError

__all__ = ["IntrinsicTriangulation", "IntrinsicOperators", "intrinsic_delaunay", "intrinsic_delaunay_operators"]

_ROUND_OFF = 1e-12  # cot weights in [-_ROUND_OFF, 0) after flipping are round-off of a zero weight
_NEXT = np.array([1, 2, 0])
_PREV = np.array([2, 0, 1])


@dataclass
class IntrinsicTriangulation:
    """An intrinsic triangulation (a Δ-complex with edge lengths) after Delaunay flips.

    Attributes
    ----------
    n_vertices : number of vertices of the input mesh (vertex ids are shared by both
        sheets of a tufted cover)
    faces : (f, 3) int64 vertex ids of each triangle's corners, counter-clockwise in the
        triangulation's orientation; a vertex may repeat (loops)
    face_edges : (f, 3) int64 id of the edge opposite each corner
    edge_lengths : (e,) float64 intrinsic lengths (after mollification), length units
    edge_sides : (e, 2) int64 the two sides of each edge as ``3·face + corner`` of the
        opposite corner; -1 in column 1 for a border edge
    flips, rounds : edge flips performed and vectorized rounds used
    mollify_epsilon : ε added to every input edge length (0 without mollification)
    cover : True when the triangulation is the tufted double cover (operators are halved)
    """

    n_vertices: int
    faces: np.ndarray
    face_edges: np.ndarray
    edge_lengths: np.ndarray
    edge_sides: np.ndarray
    flips: int
    rounds: int
    mollify_epsilon: float
    cover: bool

    def face_areas(self) -> np.ndarray:
        """(f,) intrinsic triangle areas from the edge lengths (stable Heron formula)."""
        return _heron(self.edge_lengths[self.face_edges])

    def corner_cotangents(self) -> np.ndarray:
        """(f, 3) cot of the angle at each corner: (l_b² + l_c² − l_a²) / (4 area)."""
        return _corner_cot(self.edge_lengths[self.face_edges])

    def cotan_weights(self) -> np.ndarray:
        """(e,) edge weights ⋆1 = ½ Σ_sides cot(opposite angle) — dual/primal length ratio."""
        half_cot = 0.5 * self.corner_cotangents().ravel()
        weights = half_cot[self.edge_sides[:, 0]]
        interior = self.edge_sides[:, 1] >= 0
        weights[interior] += half_cot[self.edge_sides[interior, 1]]
        weights[(weights < 0) & (weights >= -_ROUND_OFF)] = 0.0
        return weights

    def edge_endpoints(self) -> np.ndarray:
        """(e, 2) vertex ids at the ends of each edge (equal for a loop)."""
        side = self.edge_sides[:, 0]
        face, corner = side // 3, side % 3
        return np.stack([self.faces[face, _NEXT[corner]], self.faces[face, _PREV[corner]]], axis=1)

    def stiffness(self) -> sp.csr_matrix:
        """(n0, n0) cotangent stiffness Σ_e w_e (δ_a − δ_b)(δ_a − δ_b)ᵀ, positive semi-definite.

        Off-diagonal entries are −(sum of the weights of the edges joining the two vertices),
        ≤ 0 once every edge is Delaunay; halved on a tufted cover.
        """
        w = self.cotan_weights()
        if self.cover:
            w = 0.5 * w
        ends = self.edge_endpoints()
        a, b = ends[:, 0], ends[:, 1]
        rows = np.concatenate([a, b, a, b])
        cols = np.concatenate([b, a, a, b])
        data = np.concatenate([-w, -w, w, w])
        n = self.n_vertices
        return sp.csr_matrix((data, (rows, cols)), shape=(n, n))

    def star0(self) -> np.ndarray:
        """(n0,) lumped vertex areas: a third of each incident intrinsic triangle's area
        (halved on a tufted cover), area units; Σ = the (mollified) surface area."""
        share = self.face_areas() / 3.0
        if self.cover:
            share *= 0.5
        return np.bincount(self.faces.ravel(), weights=np.repeat(share, 3), minlength=self.n_vertices)


class IntrinsicOperators(NamedTuple):
    """``stiffness`` (n0, n0) CSR, ``star0`` (n0,), and the flip statistics."""

    stiffness: sp.csr_matrix
    star0: np.ndarray
    flips: int
    rounds: int


# ---------------------------------------------------------------- triangle geometry from lengths
def _heron(lengths: np.ndarray) -> np.ndarray:
    """Areas from (…, 3) edge lengths, Kahan's stable Heron formula (a ≥ b ≥ c)."""
    x, y, z = lengths[..., 0], lengths[..., 1], lengths[..., 2]
    low_xy, high_xy = np.minimum(x, y), np.maximum(x, y)
    a = np.maximum(high_xy, z)
    c = np.minimum(low_xy, z)
    b = np.maximum(low_xy, np.minimum(high_xy, z))  # the median, selected exactly
    product = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c))
    return 0.25 * np.sqrt(np.maximum(product, 0.0))


def _corner_cot(lengths: np.ndarray) -> np.ndarray:
    """(…, 3) cot of the angle at each corner from the (…, 3) opposite edge lengths:
    cot θ_c = (l_a² + l_b² − l_c²) / (4 area)."""
    area = _heron(lengths)
    sq = lengths * lengths
    total = sq.sum(axis=-1, keepdims=True)
    return (total - 2.0 * sq) / (4.0 * area[..., None])


# ---------------------------------------------------------------- connectivity
def _half_edges(faces: np.ndarray, n_vertices: int):
    """Group the 3m sides by undirected edge: (side ids sorted by edge, group starts, tail, head)."""
    tail = faces[:, [1, 2, 0]].ravel()  # side 3f + c runs from corner c+1 to corner c+2
    head = faces[:, [2, 0, 1]].ravel()
    key = np.minimum(tail, head) * np.int64(n_vertices) + np.maximum(tail, head)
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    new = np.empty(key.size, dtype=bool)
    new[0] = True
    np.not_equal(sorted_key[1:], sorted_key[:-1], out=new[1:])
    starts = np.append(np.flatnonzero(new), key.size)
    return order, starts, tail, head


def _build(vertices: np.ndarray, faces: np.ndarray, mollify: float, border: str):
    """Validated connectivity and (mollified) lengths of the mesh or of its tufted cover."""
    m = faces.shape[0]
    n0 = vertices.shape[0]
    order, starts, tail, head = _half_edges(faces, n0)
    counts = np.diff(starts)
    if (counts > 2).any():
        bad = np.flatnonzero(counts > 2)
        sides = order[starts[bad[:3]]]
        pairs = np.stack([tail[sides], head[sides]], axis=1).tolist()
        raise NonManifoldError(
            f"non-manifold: {bad.size} edge(s) lie in more than two triangles, e.g. vertex pairs {pairs}")
    first = order[starts[:-1]]
    second = np.where(counts == 2, order[np.minimum(starts[:-1] + 1, order.size - 1)], -1)
    interior = counts == 2
    same_direction = np.zeros(first.size, dtype=bool)
    same_direction[interior] = tail[first[interior]] == tail[second[interior]]

    # lengths of the unique input edges, then mollification (Sharp & Crane 2020, §4.5)
    diff = vertices[head[first]] - vertices[tail[first]]
    lengths = np.sqrt(np.einsum("ij,ij->i", diff, diff))
    epsilon = 0.0
    if mollify > 0:
        edge_of_side = np.empty(3 * m, dtype=np.int64)
        edge_of_side[order] = np.repeat(np.arange(first.size), counts)
        face_lengths = lengths[edge_of_side.reshape(m, 3)]
        slack = face_lengths.max(axis=1) * 2.0 - face_lengths.sum(axis=1)  # l_c − l_a − l_b, longest c
        epsilon = max(0.0, float(slack.max()) + mollify * float(lengths.mean()))
        lengths = lengths + epsilon

    closed = not (~interior).any()
    consistent = not same_direction.any()
    if border == "fixed" and not consistent:
        bad = np.flatnonzero(same_direction)[:5]
        pairs = np.stack([tail[first[bad]], head[first[bad]]], axis=1).tolist()
        raise OrientationError(
            f"inconsistent orientation: {int(same_direction.sum())} edge(s) are traversed in the same direction by "
            f"both triangles, e.g. vertex pairs {pairs} (border='tufted' accepts unoriented input)")
    if border == "fixed" or (closed and consistent):
        # the mesh itself (a closed oriented mesh's tufted cover is two identical copies of it)
        sides = np.stack([first, second], axis=1)
        return faces.copy(), sides, lengths, epsilon, False

    # Tufted cover: back face m + f has corners (f0, f2, f1); its corner c is front corner swap[c].
    swap = np.array([0, 2, 1])
    cover_faces = np.concatenate([faces, faces[:, swap]])

    def back(side):
        return 3 * (side // 3 + m) + swap[side % 3]

    # interior edge: front↔front + back↔back when oriented consistently, else front↔back twice
    partner = np.where(same_direction, back(np.maximum(second, 0)), second)
    other = np.where(same_direction, np.maximum(second, 0), back(np.maximum(second, 0)))
    sides_a = np.stack([first[interior], partner[interior]], axis=1)
    sides_b = np.stack([back(first[interior]), other[interior]], axis=1)
    border_first = first[~interior]
    sides_c = np.stack([border_first, back(border_first)], axis=1)
    sides = np.concatenate([sides_a, sides_b, sides_c])
    cover_lengths = np.concatenate([lengths[interior], lengths[interior], lengths[~interior]])
    return cover_faces, sides, cover_lengths, epsilon, True


def _face_edges(n_faces: int, sides: np.ndarray) -> np.ndarray:
    face_edges = np.empty(3 * n_faces, dtype=np.int64)
    ids = np.arange(sides.shape[0])
    face_edges[sides[:, 0]] = ids
    interior = sides[:, 1] >= 0
    face_edges[sides[interior, 1]] = ids[interior]
    return face_edges.reshape(n_faces, 3)


# ---------------------------------------------------------------- flipping
def _edge_weights(edges, sides, face_edges, lengths) -> np.ndarray:
    """(len(edges),) cot weights ½(cot α + cot β) of interior edges."""
    total = np.zeros(edges.size)
    rows = np.arange(edges.size)
    for column in (0, 1):
        side = sides[edges, column]
        face, corner = side // 3, side % 3
        local = lengths[face_edges[face]]  # (k, 3), column c opposite corner c
        sq = local * local
        opposite = sq[rows, corner]
        total += (sq.sum(axis=1) - 2.0 * opposite) / (8.0 * _heron(local))
    return total


def _independent(edges, weights, sides, n_faces) -> np.ndarray:
    """Mask of ``edges`` (all non-Delaunay) such that no two selected share a triangle:
    each selected edge has the smallest (weight, id) rank among the candidates of both its
    triangles. The globally most negative edge is always selected."""
    order = np.lexsort((edges, weights))
    rank = np.empty(edges.size, dtype=np.int64)
    rank[order] = np.arange(edges.size)
    f0, f1 = sides[edges, 0] // 3, sides[edges, 1] // 3
    best = np.full(n_faces, edges.size, dtype=np.int64)
    np.minimum.at(best, f0, rank)
    np.minimum.at(best, f1, rank)
    return (best[f0] == rank) & (best[f1] == rank) & (f0 != f1)


def _flip(edges, faces, face_edges, sides, lengths) -> np.ndarray:
    """Flip the given edges (no two sharing a triangle) in place; returns the touched edges.

    Edge e between faces f = (x, p, q) (e opposite corner x) and g = (y, q, p): the quad
    x, p, y, q becomes f' = (x, p, y), g' = (y, q, x) with the new edge x–y of length
    |xy|² = l_xp² + l_py² − 2 l_xp l_py cos(θ_f + θ_g), θ the angles at p (Euclidean flip).
    """
    h1, h2 = sides[edges, 0], sides[edges, 1]
    f, a = h1 // 3, h1 % 3
    g, b = h2 // 3, h2 % 3
    x, p, q = faces[f, a], faces[f, _NEXT[a]], faces[f, _PREV[a]]
    y = faces[g, b]
    e_xq, e_xp = face_edges[f, _NEXT[a]], face_edges[f, _PREV[a]]  # opposite p, opposite q
    e_py, e_yq = face_edges[g, _NEXT[b]], face_edges[g, _PREV[b]]  # opposite q, opposite p (in g)
    l_pq, l_xp, l_xq, l_py, l_yq = lengths[edges], lengths[e_xp], lengths[e_xq], lengths[e_py], lengths[e_yq]
    area_f = _heron(np.stack([l_pq, l_xq, l_xp], axis=1))
    area_g = _heron(np.stack([l_pq, l_yq, l_py], axis=1))
    cos_f = (l_xp**2 + l_pq**2 - l_xq**2) / (2 * l_xp * l_pq)
    cos_g = (l_py**2 + l_pq**2 - l_yq**2) / (2 * l_py * l_pq)
    sin_f = 2 * area_f / (l_xp * l_pq)
    sin_g = 2 * area_g / (l_py * l_pq)
    cos_sum = cos_f * cos_g - sin_f * sin_g
    new_length = np.sqrt(np.maximum(l_xp**2 + l_py**2 - 2 * l_xp * l_py * cos_sum, 0.0))

    # which column of edge_sides holds each moved side (read everything before writing)
    old = [(e_py, 3 * g + _NEXT[b], 3 * f + 0), (e_xp, 3 * f + _PREV[a], 3 * f + 2),
           (e_xq, 3 * f + _NEXT[a], 3 * g + 0), (e_yq, 3 * g + _PREV[b], 3 * g + 2)]
    columns = [np.where(sides[edge, 0] == side, 0, 1) for edge, side, _ in old]
    faces[f] = np.stack([x, p, y], axis=1)
    faces[g] = np.stack([y, q, x], axis=1)
    face_edges[f] = np.stack([e_py, edges, e_xp], axis=1)
    face_edges[g] = np.stack([e_xq, edges, e_yq], axis=1)
    for (edge, _, new_side), column in zip(old, columns, strict=True):
        sides[edge, column] = new_side
    sides[edges, 0] = 3 * f + 1
    sides[edges, 1] = 3 * g + 1
    lengths[edges] = new_length
    return np.concatenate([edges, e_xp, e_xq, e_py, e_yq])


def flip_rounds_numpy(faces, face_edges, sides, lengths, delaunay_tol: float, max_rounds: int):
    """Flip rounds until every interior edge has weight ≥ −``delaunay_tol`` (in place): the
    numpy twin of the compiled ``flip_rounds``. Returns (flips, rounds, finished)."""
    check = np.flatnonzero(sides[:, 1] >= 0)
    flips = rounds = 0
    while check.size:
        if rounds >= max_rounds:
            return flips, rounds, False
        weights = _edge_weights(check, sides, face_edges, lengths)
        bad = weights < -delaunay_tol
        if not bad.any():
            break
        rounds += 1
        candidates, candidate_weights = check[bad], weights[bad]
        chosen = _independent(candidates, candidate_weights, sides, faces.shape[0])
        touched = _flip(candidates[chosen], faces, face_edges, sides, lengths)
        flips += int(chosen.sum())
        touched = touched[sides[touched, 1] >= 0]
        mark = np.zeros(sides.shape[0], dtype=bool)
        mark[touched] = True
        mark[candidates[~chosen]] = True
        check = np.flatnonzero(mark)
    return flips, rounds, True


def intrinsic_delaunay(vertices, faces, mollify: float = 0.0, border: str = "tufted", delaunay_tol: float = _ROUND_OFF,
                       max_rounds: int = 10_000) -> IntrinsicTriangulation:
    """Flip a triangle mesh's intrinsic triangulation to Delaunay (Bobenko–Springborn 2007).

    Parameters
    ----------
    vertices : (n0, 2 or 3) float positions (only edge lengths are used)
    faces : (m, 3) int triangles; every vertex must be used; edges manifold (≤ 2 triangles);
        any orientation with ``border="tufted"``, consistent with ``border="fixed"``
    mollify : Sharp & Crane's relative mollification factor (δ = mollify × mean edge length);
        0 disables it
    border : ``"tufted"`` (default; Sharp & Crane 2020: flip on the tufted cover, so border
        weights are ≥ 0 too) or ``"fixed"`` (border edges never flip)
    delaunay_tol : an interior edge is flipped when its weight ½(cot α + cot β) < −delaunay_tol.
        The default 1e-12 is round-off (with 0, the two diagonals of a cocircular quad can
        flip back and forth forever); weights left in [−1e-12, 0) are reported as 0.
        geometry-central and robust_laplacian use 1e-6.
    max_rounds : safety limit on the number of rounds

    Returns
    -------
    IntrinsicTriangulation (see its ``stiffness()`` and ``star0()``)

    Raises
    ------
    MeshError subclasses for bad input; DegenerateSimplexError when a triangle violates the
    triangle inequality strictly (use ``mollify`` > 0).
    """
    if border not in ("tufted", "fixed"):
        raise ValueError(f"border must be 'tufted' or 'fixed', not {border!r}")
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces)
    if vertices.ndim != 2 or faces.ndim != 2 or faces.shape[1] != 3 or faces.shape[0] == 0:
        raise MeshError(f"expected vertices (n, d) and triangles (m, 3), got {vertices.shape} and {faces.shape}")
    faces = faces.astype(np.int64)
    n0 = vertices.shape[0]
    if faces.min() < 0 or faces.max() >= n0:
        raise MeshError(f"triangles reference vertex indices outside 0..{n0 - 1}")
    if ((faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])).any():
        raise MeshError("a triangle lists the same vertex twice")
    used = np.zeros(n0, dtype=bool)
    used[faces.ravel()] = True
    if not used.all():
        raise UnreferencedVertexError(f"vertices {np.flatnonzero(~used)[:8].tolist()} are used by no triangle")

    faces, sides, lengths, epsilon, cover = _build(vertices, faces, mollify, border)
    face_edges = _face_edges(faces.shape[0], sides)
    areas = _heron(lengths[face_edges])
    scale = lengths.mean() ** 2
    if (areas <= 1e-14 * scale).any():
        bad = np.flatnonzero(areas <= 1e-14 * scale)
        raise DegenerateSimplexError(
            f"triangles {bad[:8].tolist()} have zero area in their edge lengths (pass mollify > 0, e.g. 1e-5)")

    compiled = extension.kernels()
    flip_rounds = compiled.flip_rounds if compiled is not None else flip_rounds_numpy
    flips, rounds, finished = flip_rounds(faces, face_edges, sides, lengths, float(delaunay_tol), int(max_rounds))
    if not finished:
        raise RuntimeError(f"intrinsic Delaunay flipping did not finish in {max_rounds} rounds")
    return IntrinsicTriangulation(n0, faces, face_edges, lengths, sides, flips, rounds, epsilon, cover)


def intrinsic_delaunay_operators(vertices, faces, mollify: float = 0.0, border: str = "tufted",
                                 delaunay_tol: float = _ROUND_OFF) -> IntrinsicOperators:
    """The intrinsic Delaunay Laplacian: (stiffness, star0, flips, rounds).

    ``stiffness`` (n0, n0) CSR is d0ᵀ ⋆1 d0 of the intrinsic Delaunay triangulation —
    positive semi-definite, rows summing to zero, off-diagonal entries ≤ 0 (for
    ``border="tufted"``, and for ``"fixed"`` away from obtuse border angles);
    ``star0`` (n0,) > 0 the lumped barycentric areas. The Laplace–Beltrami operator on
    functions is −star0⁻¹ stiffness. See :func:`intrinsic_delaunay` for the parameters.
    """
    T = intrinsic_delaunay(vertices, faces, mollify=mollify, border=border, delaunay_tol=delaunay_tol)
    return IntrinsicOperators(T.stiffness(), T.star0(), T.flips, T.rounds)
