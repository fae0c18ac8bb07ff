"""Conformal mesh parametrization with DEC (thesis ch. 5), as pure functions on (K, DEC).

We look for texture coordinates ``uv = (x, y)``, two 0-forms, with ``⋆dx = dy`` (eq. 5.1).
Both are then harmonic, and on a disk a harmonic function is fixed by its border values,
so the work splits into

* interior rows: ``⋆0⁻¹ d1^dual ⋆1 d0 x = 0`` (eq. 5.3) or another matrix whose rows satisfy
  Tutte's conditions 5.5–5.7 (:func:`harmonic_matrix`: ``dec`` | ``uniform`` | ``mean_value``);
* border rows (:func:`parametrize`): a circle (§5.2.2), the conformal border of eq. 5.8–5.9,
  or a free border from the least-squares conformal energy written with DEC operators
  (:func:`least_squares_conformal_map`, beyond the thesis); several borders as in §5.2.3.

Orientation convention: ``K.border_loops()`` runs every border with the surface on its
left (the exterior counter-clockwise, holes clockwise for a counter-clockwise mesh), and
every border construction here produces a uv map that keeps the complex's orientation
(consistently oriented triangles come out counter-clockwise). Final uv are translated and
uniformly scaled into [0, 1]² (thesis §5.2.2).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from decrun.core.choices import Choice
from decrun.core.complex import SimplicialComplex
from decrun.core.geometry import corner_angles
from decrun.core.solvers import solve_with_fixed
from decrun.errors import ConfigError, SolverError, TopologyError

__all__ = [
    "WEIGHTS",
    "BORDERS",
    "check_disk_topology",
    "ordered_border_loops",
    "harmonic_matrix",
    "convex_combination_rows",
    "vertex_angle_sums",
    "target_border_angles",
    "circle_border",
    "conformal_border_rows",
    "conformal_border",
    "least_squares_conformal_map",
    "normalize_to_unit_square",
    "Parametrization",
    "parametrize",
]


class Weights(Choice):
    """``app.weights``: the interior rows (eq. 5.3 / 5.5–5.7)."""

    dec = "dec"
    uniform = "uniform"
    mean_value = "mean_value"


class Border(Choice):
    """``app.border``: pinned to a circle (Tutte), by arc length, conformal (eq. 5.8–5.9) or free."""

    circle = "circle"
    circle_arclength = "circle_arclength"
    conformal = "conformal"
    free = "free"


class Holes(Choice):
    """``app.holes``: how inner borders are treated — ``fill`` closes each with a virtual
    vertex (a disk for Tutte/Floater), ``conformal`` gives them eq. 5.9 rows (§5.2.3);
    ``auto`` = fill under a circle border, conformal under ``border=conformal``."""

    auto = "auto"
    fill = "fill"
    conformal = "conformal"


WEIGHTS = tuple(Weights.names())
BORDERS = tuple(Border.names())
HOLES = tuple(Holes.names())


# ---------------------------------------------------------------------------- topology
def check_disk_topology(K: SimplicialComplex) -> int:
    """Raise :class:`TopologyError` unless ``K`` is a connected genus-0 surface with borders.

    Thesis §5.1/Theorem 2 condition 1: a disk, possibly with holes. With b border loops,
    χ = 2 − 2g − b gives the genus g. Checked before any solve.

    Returns the number of border loops.
    """
    if K.dim != 2:
        raise TopologyError(
            f"mesh: parametrization needs a triangle mesh (a 2-complex), got a {K.dim}-complex"
        )
    count, _ = K.connected_components()
    if count != 1:
        raise TopologyError(
            f"mesh: parametrization needs one connected surface, this mesh has {count} connected "
            "components; keep the largest with `mesh.largest_component=true`"
        )
    loops = K.border_loops()
    if not loops:
        raise TopologyError(
            "mesh: parametrization needs a disk-like surface with a border, this mesh is closed "
            f"(χ = {K.euler_characteristic}, no border edges); cut it open first"
        )
    genus2 = 2 - len(loops) - K.euler_characteristic
    if genus2 != 0:
        raise TopologyError(
            f"mesh: parametrization needs genus 0 (a disk with holes), this surface has {len(loops)} "
            f"border loop(s) and χ = {K.euler_characteristic}, so genus {genus2 / 2:g}: no global "
            "planar map exists without cutting it further"
        )
    return len(loops)


def ordered_border_loops(K: SimplicialComplex, exterior: int | None = None) -> list[np.ndarray]:
    """Border loops with the exterior one first.

    ``exterior``: index into ``K.border_loops()`` (sorted longest first, by length);
    ``None`` picks the longest. Each loop keeps the orientation induced by the complex.
    """
    loops = K.border_loops()
    if exterior is None:
        return loops
    if not -len(loops) <= exterior < len(loops):
        raise ConfigError(
            f"app.exterior_border: index {exterior} out of range, the mesh has {len(loops)} border loop(s)"
        )
    exterior %= len(loops)
    return [loops[exterior]] + [loop for i, loop in enumerate(loops) if i != exterior]


def fill_holes(K: SimplicialComplex, holes: list[np.ndarray]) -> SimplicialComplex:
    """``K`` with every inner border loop closed by a virtual vertex (the loop's centroid)
    joined to the loop's vertices by a fan of triangles.

    A genus-0 surface with b borders becomes a disk whose only border is the exterior loop, so
    Tutte's theorem (convex weights, convex pinned border) gives an embedding of the filled
    disk and hence of ``K`` (Floater 2003, §5.1 Theorem 2). Vertices ``n0 .. n0 + len(holes) − 1``
    are the virtual ones; the original vertices and triangles keep their indices. The fan
    triangles (loop[i+1], loop[i], c) run against the loop, whose direction is the one the
    surface induces (:meth:`SimplicialComplex.border_loops`), so the orientation stays consistent.
    """
    n0 = K.num_simplices(0)
    centres = np.array([K.vertices[loop].mean(axis=0) for loop in holes])
    fans = [np.column_stack([np.roll(loop, -1), loop, np.full(loop.size, n0 + h)]) for h, loop in enumerate(holes)]
    return SimplicialComplex(np.vstack([K.vertices, centres]), np.vstack([K.oriented_simplices(), *fans]),
                             degenerate_tol=0.0)


# ---------------------------------------------------------------------------- interior rows
def _mean_value_weights(K: SimplicialComplex) -> sp.csr_matrix:
    """Floater's mean value weights w_ij = (tan(δ_ij/2) + tan(γ_ij/2)) / |v_i − v_j| (Floater 2003).

    δ_ij, γ_ij are the angles at v_i of the (one or two) triangles containing edge ij.
    Returns the (n0, n0) off-diagonal weight matrix (not symmetric).
    """
    faces = K.oriented_simplices()
    angle = corner_angles(K.vertices, faces)  # (m, 3) angle at local corner l
    half_tan = np.tan(0.5 * angle)
    rows, cols, vals = [], [], []
    for l in range(3):
        i, j, k = faces[:, l], faces[:, (l + 1) % 3], faces[:, (l + 2) % 3]
        for other in (j, k):
            length = np.linalg.norm(K.vertices[other] - K.vertices[i], axis=1)
            rows.append(i)
            cols.append(other)
            vals.append(half_tan[:, l] / length)
    n0 = K.num_simplices(0)
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n0, n0))


def harmonic_matrix(dec, weights: str = "dec") -> sp.csr_matrix:
    """The matrix A of the interior rows ``A x = 0`` (eq. 5.3 / 5.4), (n0, n0) CSR.

    ``dec``
        ``⋆0⁻¹ d1^dual ⋆1 d0`` exactly as eq. 5.3. With d1^dual = −δ1 = −d0ᵀ (eq. 4.13) this is
        the Laplace–Beltrami operator = −Δ0 (the negative of the PSD Laplace–de Rham operator).
        Meets 5.5 and 5.6 always and 5.7 only when every cot weight ⋆1 is ≥ 0.
    ``uniform``
        Tutte's weights: a_ij = 1 for neighbours, a_ii = −degree; written as −d0ᵀd0.
    ``mean_value``
        a_ij = Floater's mean value weight (> 0 for every neighbour), a_ii = −Σ_j a_ij.

    All three satisfy eq. 5.5 (neighbours only) and 5.6 (zero row sums).
    """
    weights = str(Weights.of(weights, "app.weights"))
    d0 = dec.d(0)
    if weights == "dec":  # d1^dual ⋆1 d0 = −d0ᵀ ⋆1 d0 = −(the variant's stiffness)
        # a Galerkin ⋆0 is lumped (row sums) here: the rows' scale does not change the map
        lumped = dec.star_diagonal_or_none(0)
        if lumped is None:
            lumped = np.asarray(dec.star(0).sum(axis=1)).ravel()
        return (-(sp.diags(1.0 / lumped) @ dec.laplacian_symmetric(0))).tocsr()
    if weights == "uniform":
        return (-(d0.T @ d0)).tocsr()
    W = _mean_value_weights(dec.K)  # mean_value
    return (W - sp.diags(np.asarray(W.sum(axis=1)).ravel())).tocsr()


#: interior weights whose harmonic matrix is symmetric (−stiffness): their systems are SPD
SYMMETRIC_WEIGHTS = ("dec", "uniform")


def harmonic_numerator(dec, weights: str = "dec") -> sp.csr_matrix:
    """The harmonic rows without their ⋆0⁻¹ (the right side is 0, so the scale cancels):
    −(the operator's stiffness) for ``dec``, −d0ᵀd0 for ``uniform`` (both symmetric, negative
    semi-definite), the unsymmetric mean-value rows otherwise."""
    if weights == "dec":
        return (-dec.laplacian_symmetric(0)).tocsr()
    return harmonic_matrix(dec, weights)


def convex_combination_rows(dec, weights: str = "dec") -> sp.csr_matrix:
    """Rows of :func:`harmonic_matrix` divided by −a_ii: −1 on the diagonal, w_ij = −a_ij/a_ii off it.

    This is the thesis' normalization after eq. 5.7 (``v_i = Σ w_j v_j``). It is the same
    equation (right-hand side 0), so the solution does not change; for ``dec`` the factor
    ⋆0⁻¹ cancels, which is why the ⋆0 variant (``operator.star``) does not change the map.
    Computed from ``d1^dual ⋆1 d0`` directly so a zero ⋆0 cannot produce ∞/∞.
    """
    A = harmonic_numerator(dec, weights)  # d1^dual ⋆1 d0 = −(stiffness) for dec
    diagonal = A.diagonal()
    bad = np.flatnonzero(~(np.abs(diagonal) > 1e-300))
    if bad.size:
        raise SolverError(
            f"app.weights={weights}: the harmonic row of vertex {bad[:5].tolist()} has a zero diagonal "
            "(the cot weights around it cancel); use `app.weights=mean_value` (or `app.weights=uniform`)"
        )
    return (sp.diags(-1.0 / diagonal) @ A).tocsr()


# ---------------------------------------------------------------------------- border angles
def vertex_angle_sums(K: SimplicialComplex) -> np.ndarray:
    """Σ of the corner angles of the triangles around each vertex on the mesh, (n0,), radians.

    At a border vertex this is the angle α_v between its two border edges measured across the
    surface (thesis Fig. 5.4); at an interior vertex 2π minus the angle defect.
    """
    faces = K.oriented_simplices()
    return np.bincount(faces.ravel(), weights=corner_angles(K.vertices, faces).ravel(),
                       minlength=K.num_simplices(0))


def target_border_angles(K: SimplicialComplex, loop: np.ndarray, exterior: bool = True) -> np.ndarray:
    """Target angles of eq. 5.8 for one border loop, (L,) radians.

    α_v^mapped = α_v · S / Σ_loop α_v with S = (L − 2)π for the exterior border (interior angles
    of a simple planar L-gon) and S = (L + 2)π for a hole (the surface-side angles of a planar
    L-gon hole; the thesis only says "as with the exterior border" — this is the sum that makes a
    flat mesh with a hole keep its angles). A vertex is reflex when α^mapped > π.
    """
    alpha = vertex_angle_sums(K)[loop]
    length = len(loop)
    total = (length - 2) * np.pi if exterior else (length + 2) * np.pi
    return alpha * total / alpha.sum()


def _loop_edge_lengths(K: SimplicialComplex, loop: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mesh lengths |prev − v| and |next − v| for every vertex v of a loop, (L,) each."""
    points = K.vertices[loop]
    to_prev = np.linalg.norm(np.roll(points, 1, axis=0) - points, axis=1)
    to_next = np.linalg.norm(np.roll(points, -1, axis=0) - points, axis=1)
    return to_prev, to_next


def circle_border(K: SimplicialComplex, loop: np.ndarray, arclength: bool = False) -> np.ndarray:
    """Border positions on the unit circle (§5.2.2), (L, 2).

    k-th vertex at angle 2πk/L, or 2π·borderDist(v_k, v_0)/length(border) with ``arclength``.
    The thesis writes (sin, cos), which runs clockwise; we use (cos, sin) so the map keeps the
    orientation of the complex (the loop runs with the surface on its left).
    """
    if arclength:
        _, to_next = _loop_edge_lengths(K, loop)
        fraction = np.concatenate([[0.0], np.cumsum(to_next)[:-1]]) / to_next.sum()
    else:
        fraction = np.arange(len(loop)) / len(loop)
    angle = 2 * np.pi * fraction
    return np.column_stack([np.cos(angle), np.sin(angle)])


def conformal_border_rows(
    K: SimplicialComplex, loop: np.ndarray, alpha: np.ndarray, rows_of: np.ndarray | None = None
) -> sp.csr_matrix:
    """The 2×6 blocks of eq. 5.9 for the vertices of one loop, as rows of the (2 n0, 2 n0) system.

    For border vertex v with predecessor p and successor q along the loop (surface on the
    left; the thesis' v⁺ = p, v⁻ = q), ρ = |p − v| / |q − v| measured on the mesh and
    R(α) the counter-clockwise rotation by the target angle α = α_v^mapped:

        (p − v) − ρ R(α) (q − v) = 0,       i.e. (v⁺ − v) + ρ R(α)(v − v⁻) = 0   (eq. 5.9)

    Unknowns and rows are ordered [x (n0); y (n0)]: the x equation of v is row v, its y
    equation row n0 + v; all other rows are empty. ``rows_of`` (L,) bool selects the loop
    vertices that get their block (default: all).
    """
    n0 = K.num_simplices(0)
    to_prev, to_next = _loop_edge_lengths(K, loop)
    rho = to_prev / to_next
    c, s = rho * np.cos(alpha), rho * np.sin(alpha)
    v, p, q = loop, np.roll(loop, 1), np.roll(loop, -1)
    keep = np.ones(len(loop), dtype=bool) if rows_of is None else np.asarray(rows_of, dtype=bool)
    v, p, q, c, s = v[keep], p[keep], q[keep], c[keep], s[keep]
    ones = np.ones(len(v))
    # x: (x_p − x_v) − [c (x_q − x_v) − s (y_q − y_v)] = 0
    # y: (y_p − y_v) − [s (x_q − x_v) + c (y_q − y_v)] = 0
    rows = np.concatenate([v] * 5 + [n0 + v] * 5)
    cols = np.concatenate([p, v, q, n0 + q, n0 + v, n0 + p, n0 + v, q, v, n0 + q])
    vals = np.concatenate([ones, -ones + c, -c, s, -s, ones, -ones + c, -s, s, -c])
    return sp.csr_matrix((vals, (rows, cols)), shape=(2 * n0, 2 * n0))


def _far_apart(points: np.ndarray) -> tuple[int, int]:
    """Two indices of roughly maximal distance (two farthest-point sweeps)."""
    a = int(np.argmax(np.linalg.norm(points - points[0], axis=1)))
    b = int(np.argmax(np.linalg.norm(points - points[a], axis=1)))
    return (a, b) if a != b else (0, len(points) - 1)


def normalize_to_unit_square(uv: np.ndarray) -> np.ndarray:
    """Translate and uniformly scale (n, 2) points so their bounding box fits [0, 1]² (§5.2.2)."""
    low = uv.min(axis=0)
    extent = float(np.max(uv.max(axis=0) - low))
    if not np.isfinite(extent) or extent <= 0:
        raise SolverError("app: the parametrization collapsed to a point (zero extent)")
    return (uv - low) / extent


def conformal_border(K: SimplicialComplex, loop: np.ndarray, solver) -> np.ndarray:
    """Border positions of eq. 5.8–5.9 for the exterior loop, (L, 2), inside [0, 1]².

    Eq. 5.9 is written for every loop vertex (2L real equations); its solutions are invariant
    under translation, rotation and scale, so two vertices far apart on the border are pinned to
    (0, 0) and (1, 0) (thesis: "fix two arbitrary boundary vertices"). When the target angles and
    lengths do not close up into a polygon the remaining 2L equations in 2L − 4 unknowns are
    inconsistent; we solve them in the least-squares sense (normal equations through ``solver``),
    which is the exact solution whenever one exists. The result is rescaled into [0, 1]².
    """
    n0 = K.num_simplices(0)
    L = len(loop)
    alpha = target_border_angles(K, loop, exterior=True)
    rows = conformal_border_rows(K, loop, alpha)
    own = np.concatenate([loop, n0 + loop])  # x of the loop vertices, then their y
    local = rows[own][:, own].tocsc()  # (2L, 2L): the loop's equations on its own unknowns
    a, b = _far_apart(K.vertices[loop])
    pinned = np.array([a, b, L + a, L + b])
    pinned_values = np.array([0.0, 1.0, 0.0, 0.0])
    solution = solve_with_fixed(local, np.zeros(2 * L), pinned, pinned_values, solver, least_squares=True)
    return normalize_to_unit_square(np.column_stack([solution[:L], solution[L:]]))


# ---------------------------------------------------------------------------- free border
def conformal_energy_matrix(dec) -> sp.csr_matrix:
    """H (2 n0, 2 n0) with E_C(x, y) = ½ zᵀ H z, z = [x; y]: the DEC conformal energy.

    E_C = E_D − A with E_D = ½ xᵀ(d0ᵀ⋆1 d0)x + ½ yᵀ(d0ᵀ⋆1 d0)y (cot stiffness,
    ``dec.laplacian_symmetric(0)``) and the uv area A = ∫_M dx∧dy = ∮_∂M x dy (Stokes)
    = xᵀ Pᵀ diag(c) d0 y, where c = δ2·1 is the border 1-chain (``K.border_faces``) and
    P = |d0|/2 averages a 0-form onto edges. Symmetric PSD; its kernel holds the similarities.

    Row v of −H z at a border vertex v with border neighbours p → v → q is
    ``(d1^dual ⋆1 d0 x)_v + ½(y_q − y_p)``: the harmonic row of eq. 5.3 whose dual cell is
    closed along the border with ⋆dx = dy (eq. 5.1) — the Cauchy–Riemann border row.
    """
    K = dec.K
    d0 = dec.d(0)
    stiffness = dec.laplacian_symmetric(0)
    index, sign = K.border_faces()
    chain = np.zeros(K.num_simplices(1))
    chain[index] = sign
    average = 0.5 * abs(d0)
    area_form = (average.T @ sp.diags(chain) @ d0).tocsr()  # A(x, y) = xᵀ area_form y
    return sp.bmat([[stiffness, -area_form], [-area_form.T, stiffness]]).tocsr()


def least_squares_conformal_map(dec, solver, pins: tuple[int, int] | None = None) -> np.ndarray:
    """Free-border conformal map minimizing E_C = E_D − A (least-squares conformal map), (n0, 2).

    E_C is written with DEC operators in :func:`conformal_energy_matrix`.
    E_C = ½ ∫ |⋆dx − dy|² ≥ 0 vanishes exactly for conformal maps (eq. 5.1), so on a flat or
    developable mesh the minimizer is the isometric layout up to similarity. Its kernel are
    the similarities; the two ``pins`` (border vertices, default: two far apart) fix them at
    their mesh distance. The reduced system is symmetric positive definite. Interior rows of
    the normal equations are d0ᵀ⋆1 d0 x = 0: the interior is harmonic with the ``dec`` weights.
    """
    K = dec.K
    n0 = K.num_simplices(0)
    H = conformal_energy_matrix(dec)
    if pins is None:
        border = np.flatnonzero(K.border_vertices())
        a, b = _far_apart(K.vertices[border])
        pins = (int(border[a]), int(border[b]))
    a, b = pins
    distance = float(np.linalg.norm(K.vertices[a] - K.vertices[b]))
    pinned = np.array([a, b, n0 + a, n0 + b])
    pinned_values = np.array([0.0, distance, 0.0, 0.0])
    z = solve_with_fixed(H, np.zeros(2 * n0), pinned, pinned_values, solver)
    return np.column_stack([z[:n0], z[n0:]])


# ---------------------------------------------------------------------------- the overall system
@dataclass
class Parametrization:
    """Result of :func:`parametrize`.

    uv : (n0, 2) texture coordinates in [0, 1]².
    loops : border loops, exterior first, each with the surface on its left.
    row_kind : (n0,) int8 — which equation each vertex got: 0 harmonic row (eq. 5.3),
        1 pinned (x = b_x, y = b_y), 2 conformal border row (eq. 5.9), 3 Cauchy–Riemann
        border row (:func:`conformal_energy_matrix`).
    reflex_predicted : border vertices reflex under the target angles α^mapped (0 for
        circle/free borders, which place every exterior vertex).
    predicted_reflex_mask : (n0,) bool, those vertices.
    solve_seconds : wall time of the factorizations and solves.
    """

    uv: np.ndarray
    loops: list[np.ndarray]
    row_kind: np.ndarray
    reflex_predicted: int = 0
    predicted_reflex_mask: np.ndarray | None = None
    solve_seconds: float = 0.0


HARMONIC, PINNED, CONFORMAL, CAUCHY_RIEMANN = 0, 1, 2, 3


class ReflexRows(Choice):
    """``app.reflex_rows``: the row of border vertices reflex under eq. 5.8 — the thesis'
    harmonic row, or the DEC row closed by ⋆dx = dy (:func:`conformal_energy_matrix`)."""

    harmonic = "harmonic"
    cauchy_riemann = "cauchy_riemann"


REFLEX_ROWS = tuple(ReflexRows.names())


def parametrize(
    dec,
    new_solver,
    border: str = "conformal",
    weights: str = "dec",
    exterior: int | None = None,
    reflex_rows: str = "harmonic",
    holes: str = "auto",
) -> Parametrization:
    """Parametrize a disk with holes: thesis §5.2.3 "overall linear equation".

    Per vertex (one row per x and y coordinate):

    * interior vertices: the harmonic rows of ``weights`` (eq. 5.3 / 5.5–5.7);
    * exterior border, ``circle``/``circle_arclength``: every vertex pinned to the circle (Tutte);
    * exterior border, ``conformal``: positions b from eq. 5.8–5.9 (:func:`conformal_border`),
      pinned on the vertices convex under α^mapped;
    * inner borders (every border but ``free``): eq. 5.9 on the vertices convex under
      α^mapped (hole normalization of :func:`target_border_angles`);
    * border vertices reflex under α^mapped: ``reflex_rows="harmonic"`` gives them the
      harmonic row of ``weights`` (the thesis); ``"cauchy_riemann"`` the DEC harmonic row with
      the dual cell closed along the border by ⋆dx = dy (:func:`conformal_energy_matrix`),
      which a similarity satisfies exactly — so a flat mesh with a conformal border is
      reproduced exactly — and which the thesis' one-sided harmonic row is not;
    * ``free``: every border vertex pinned where the least-squares conformal map puts it
      (:func:`least_squares_conformal_map`); with ``weights=dec`` that already is the answer.

    ``holes``: ``fill`` closes every inner border with a virtual vertex (:func:`fill_holes`) and
    solves the disk, so the hole vertices get harmonic rows — with convex weights (uniform,
    mean_value) and a circle border the map is an embedding (Tutte/Floater); ``conformal``
    gives them the eq. 5.9 rows above; ``auto`` (default) fills under circle borders.

    ``new_solver()`` returns a fresh decrun Solver for each linear system
    (:func:`decrun.core.solvers.solver_factory`).

    Returns a :class:`Parametrization` with uv in [0, 1]². Raises :class:`TopologyError` for a
    mesh that is not a connected genus-0 surface with border, before any solve.
    """
    K = dec.K
    border, weights = str(Border.of(border, "app.border")), str(Weights.of(weights, "app.weights"))
    reflex_rows, holes = str(ReflexRows.of(reflex_rows, "app.reflex_rows")), str(Holes.of(holes, "app.holes"))
    if holes == "fill" and border == "free":
        raise ConfigError("app.holes=fill: with app.border=free every border is pinned where the least-squares "
                          "conformal map puts it; use `app.holes=auto`")
    check_disk_topology(K)
    loops = ordered_border_loops(K, exterior)
    n0 = K.num_simplices(0)
    if len(loops) > 1 and (holes == "fill" or (holes == "auto" and border in ("circle", "circle_arclength"))):
        filled = type(dec)(fill_holes(K, loops[1:]), star=dec.star_variant, boundary="none")
        disk = parametrize(filled, new_solver, border=border, weights=weights, reflex_rows=reflex_rows,
                           holes="conformal")
        return Parametrization(disk.uv[:n0], loops, disk.row_kind[:n0], disk.reflex_predicted,
                               disk.predicted_reflex_mask[:n0], disk.solve_seconds)
    kind = np.full(n0, HARMONIC, dtype=np.int8)
    reflex_mask = np.zeros(n0, dtype=bool)
    pinned_uv = np.zeros((n0, 2))
    coupling = sp.csr_matrix((2 * n0, 2 * n0))  # rows that couple x and y (eq. 5.9, Cauchy–Riemann)
    start = time.perf_counter()

    if border == "free":
        lscm = least_squares_conformal_map(dec, new_solver())
        if weights == "dec":
            # the minimizer's border rows are the Cauchy–Riemann rows (two of them pins)
            kind[K.border_vertices()] = CAUCHY_RIEMANN
            return Parametrization(normalize_to_unit_square(lscm), loops, kind, 0, reflex_mask,
                                   time.perf_counter() - start)
        kind[K.border_vertices()] = PINNED
        pinned_uv[:] = lscm
    else:
        exterior_loop = loops[0]
        if border == "conformal":
            alpha = target_border_angles(K, exterior_loop, exterior=True)
            reflex = alpha > np.pi + 1e-9
            reflex_mask[exterior_loop[reflex]] = True
            kind[exterior_loop[~reflex]] = PINNED
            pinned_uv[exterior_loop] = conformal_border(K, exterior_loop, new_solver())
        else:
            kind[exterior_loop] = PINNED
            pinned_uv[exterior_loop] = circle_border(K, exterior_loop, arclength=border == "circle_arclength")
        for hole in loops[1:]:
            alpha = target_border_angles(K, hole, exterior=False)
            reflex = alpha > np.pi + 1e-9
            reflex_mask[hole[reflex]] = True
            kind[hole[~reflex]] = CONFORMAL
            if np.any(~reflex):
                coupling = coupling + conformal_border_rows(K, hole, alpha, rows_of=~reflex)
        if reflex_rows == "cauchy_riemann" and reflex_mask.any():
            kind[reflex_mask] = CAUCHY_RIEMANN
            selected = np.concatenate([reflex_mask, reflex_mask]).astype(float)
            coupling = coupling + sp.diags(selected) @ (-conformal_energy_matrix(dec))

    pinned_rhs = pinned_uv * (kind == PINNED)[:, None]
    if coupling.nnz == 0 and weights in SYMMETRIC_WEIGHTS:
        # Symmetric weights, every border vertex pinned: eliminate the pinned values and solve
        # the interior rows S_II x_I = −S_IB x_B with the SPD stiffness (condensation), so
        # cg and amg apply; both coordinates share one factorization.
        stiffness = -harmonic_numerator(dec, weights)
        pinned = np.flatnonzero(kind == PINNED)
        free = np.flatnonzero(kind != PINNED)
        system = stiffness[free][:, free].tocsc()
        rhs = -(stiffness[free][:, pinned] @ pinned_uv[pinned])
        uv = pinned_uv.copy()
        uv[free] = new_solver().factorize(system).solve(rhs)
        seconds = time.perf_counter() - start
        if not np.all(np.isfinite(uv)):
            raise SolverError(f"app: the parametrization system (border={border}, weights={weights}) gave non-finite uv")
        return Parametrization(normalize_to_unit_square(uv), loops, kind, int(reflex_mask.sum()), reflex_mask, seconds)
    A = convex_combination_rows(dec, weights)
    block = (sp.diags((kind == HARMONIC).astype(float)) @ A + sp.diags((kind == PINNED).astype(float))).tocsr()
    if coupling.nnz == 0:
        # x and y decouple (eq. 5.4): factorize once, solve both right-hand sides.
        uv = new_solver().factorize(block.tocsc()).solve(pinned_rhs)
    else:
        # Eq. 5.9 / Cauchy–Riemann rows couple x and y: one (2 n0)² system, their rows replace
        # both rows of their vertex (the block rows of those vertices are empty).
        M = (sp.block_diag([block, block]) + coupling).tocsc()
        z = new_solver().factorize(M).solve(pinned_rhs.T.ravel())
        uv = np.column_stack([z[:n0], z[n0:]])
    seconds = time.perf_counter() - start
    if not np.all(np.isfinite(uv)):
        raise SolverError(f"app: the parametrization system (border={border}, weights={weights}) gave non-finite uv")
    return Parametrization(normalize_to_unit_square(uv), loops, kind, int(reflex_mask.sum()), reflex_mask, seconds)
