"""``app=vector_field``: design a tangential vector field from a few constraints (§6.4).

Sources/sinks (divergence at vertices), vortices (curl on faces) and strokes (directions
on the faces a polyline crosses) become the least-squares problem eq. 6.5–6.6 with
L = diag(⋆2, ⋆0, W), solved for a 1-form (see :mod:`decrun.methods.vector_design` for the
mathematics and the sign conventions, :mod:`decrun.methods.singularities` for the indices).

``operator.boundary``:

* ``none`` — the unadapted δ_1: border dual cells are open, so δ w = 0 forbids flow
  through the border and the field comes out **tangential to the border**; d and δ stay
  adjoint (Hodge decomposition valid; metric ``adjointness_defect`` ≈ 1e-17).
* ``flux`` — the §6.4.4 adaptation (eq. 6.10 and the two matrices after it): the flux
  through border edges is estimated assuming zero curl on border triangles and added to
  the border vertices' divergence, so the field may **cross the border**. The price: δ is
  no longer the adjoint of d (``adjointness_defect`` > 0) and the Hodge decomposition
  fails with these matrices — as the thesis warns.

On closed meshes both modes are identical.

``app.sources: null`` (the CLI's default) takes the sources from the mesh: a source (+1) and a
sink (−1) at the two vertices farthest apart along the principal axis of the vertices (largest
variance; :func:`decrun.methods.vector_design.principal_extremes`), off the border when the
mesh has one. The vertex ids and points are logged and recorded (metrics ``source_vertex``,
``sink_vertex``, ``source_point``, ``sink_point``, ``sources_from_mesh``). Net outflow: with the
unadapted δ, Σ_v ⋆0 δw = 0 for every 1-form w (no flow through any border: the divergence
theorem of the discrete complex), so the prescribed outflows must sum to 0 to be met exactly —
the pair does (residual ~1e-16). With ``flux`` the net is free (it leaves through the border),
but a border vertex's divergence then counts its estimated border flow, so a source on the
border may be absorbed by it: hence the interior vertices. Given sources (a list, ``[]`` for
none) are used as they are.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, List, Optional

import numpy as np

from decrun.apps.base import App, Context, FieldOnEdges, Figure, Output, Result
from decrun.apps.surface_points import check_points_on_surface
from decrun.core.forms import whitney_sharp
from decrun.core.geometry import embed3
from decrun.errors import ConfigError, format_point
from decrun.methods.singularities import cluster_singularities, find_singularities
from decrun.methods.vector_design import (
    DesignConstraints,
    StrokeMagnitude,
    adjointness_defect,
    border_normal_flux,
    design_residuals,
    divergence_target,
    face_normals,
    field_change_relative,
    nearest_faces,
    nearest_vertices,
    principal_extremes,
    smoothness_energy,
    solve_design,
    stroke_edge_targets,
    stroke_face_directions,
)

if TYPE_CHECKING:  # types of the parameters only
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC

@dataclass
class Source:
    """A source (divergence > 0) or sink (< 0): ``point`` (snapped to the nearest vertex; it
    must lie within ``app.point_tolerance`` mean edge lengths of the surface) or ``vertex``
    id. ``divergence`` is the net outflow through the vertex's dual cell."""

    point: Optional[List[float]] = None
    vertex: Optional[int] = None
    divergence: float = 1.0


@dataclass
class Vortex:
    """A vortex: ``point`` (nearest face, within ``app.point_tolerance``) or ``face`` id.
    ``curl`` is the circulation around the face (> 0: counter-clockwise about the outward
    normal)."""

    point: Optional[List[float]] = None
    face: Optional[int] = None
    curl: float = 1.0


@dataclass
class Stroke:
    """A painted stroke: polyline ``points`` (projected to the surface), optionally ``closed``."""

    points: List[List[float]] = field(default_factory=list)
    closed: bool = False


@dataclass
class VectorField(App):
    """Options of ``app=vector_field`` (conf/app/vector_field.yaml)."""

    name = "vector_field"
    one_piece = ("with boundary=none the outflows must sum to 0 on every piece, and the default source and sink "
                 "are the two ends of the whole mesh")
    headline_metrics = ("singularity_cluster_indices", "poincare_hopf_holds", "smoothness_energy",
                        "adjointness_defect")
    boundaries = ("none", "flux")
    form_degrees = (0, 1, 2)
    diagonal_stars = "the least squares of eq. 6.5 weighs with ⋆0, ⋆2 and divides the divergence targets by ⋆0"
    #: None: a source and a sink from the mesh (module docstring); the CLI's default
    sources: Optional[List[Source]] = field(default_factory=list)
    vortices: List[Vortex] = field(default_factory=list)
    strokes: List[Stroke] = field(default_factory=list)
    #: fixed: |v| = stroke_length (eq. 6.8) | precomputed: |v| = |ν_pre| of a solve without strokes (eq. 6.9)
    stroke_magnitude: StrokeMagnitude = StrokeMagnitude.precomputed
    stroke_length: float = 1.0  # λ of eq. 6.8 (field units)
    #: κ of the stroke penalty κ ∫_stroke |u − v|² ds (units 1/length); the diagonal of W is
    #: κ / h̄ (h̄ the mean edge length), so the strokes pull equally hard on coarse and fine meshes
    stroke_weight: float = 100.0
    #: faces whose unit normal n satisfies n·region_normal ≥ region_min_cos form the
    #: "region" of the metric field_change_region_relative (empty list: no region)
    region_normal: List[float] = field(default_factory=list)
    region_min_cos: float = 0.9
    figure_arrows: int = 700  # at most this many arrows in the figure
    #: a source, vortex or stroke point farther than this × the mean edge length h̄ from
    #: the surface is an error (it would otherwise be silently snapped to a far vertex/face)
    point_tolerance: float = 2.0
    #: singular sites closer than this (in mean edge lengths) form one cluster whose index is
    #: their sum (metrics singularity_clusters, singularity_cluster_indices)
    cluster_radius: float = 3.0

    def __post_init__(self):
        self.stroke_magnitude = StrokeMagnitude.of(self.stroke_magnitude, "app.stroke_magnitude")
        if not self.stroke_weight > 0:
            raise ConfigError(f"app.stroke_weight: the weight W must be > 0, got {self.stroke_weight}")
        if not self.stroke_length > 0:
            raise ConfigError(f"app.stroke_length: λ must be > 0, got {self.stroke_length}")
        for i, s in enumerate(_as_list(self.sources)):
            if (s.point is None) == (s.vertex is None):
                raise ConfigError(f"app.sources[{i}]: give exactly one of `point` or `vertex`")
        for i, v in enumerate(self.vortices):
            if (v.point is None) == (v.face is None):
                raise ConfigError(f"app.vortices[{i}]: give exactly one of `point` or `face`")
        for i, s in enumerate(self.strokes):
            if len(s.points) < 2:
                raise ConfigError(f"app.strokes[{i}].points: a stroke needs at least two points, got {len(s.points)}")
        no_sources = self.sources is not None and not self.sources  # (None: a pair from the mesh)
        if self.strokes and self.stroke_magnitude == "precomputed" and no_sources and not self.vortices:
            raise ConfigError(
                "app.stroke_magnitude=precomputed takes |v| from a solve without the strokes (eq. 6.9), but "
                "there are no sources, sinks or vortices, so that field is zero and so would be the result: "
                "use `app.stroke_magnitude=fixed` (eq. 6.8) or add a constraint"
            )
        if not self.point_tolerance >= 0:
            raise ConfigError(f"app.point_tolerance: must be >= 0 (in mean edge lengths), got {self.point_tolerance}")
        if not self.cluster_radius >= 0:
            raise ConfigError(f"app.cluster_radius: must be >= 0 (mean edge lengths), got {self.cluster_radius}")
        if self.region_normal and len(self.region_normal) != 3:
            raise ConfigError(f"app.region_normal: must be empty or three numbers, got {list(self.region_normal)}")


# ----------------------------------------------------------------------------------
# configuration helpers
# ----------------------------------------------------------------------------------

    def outputs(self) -> dict[str, Output]:
        """The circulation 1-form, its vectors per face, the indices, and the places the design
        used: singular vertices and faces, sources (with their divergences), vortices, strokes
        (with their vectors), the region; singularity clusters are points off the vertices."""
        return {"omega": Output("1"), "omega_without_strokes": Output("1"), "face_vectors": Output("dual0", 3),
                "vertex_index": Output("0"), "face_index": Output("dual0"),
                "singular_vertices": Output("vertex_set"), "singular_faces": Output("top_set"),
                "cluster_positions": Output("global", 3), "cluster_indices": Output("global"),
                "source_vertices": Output("vertex_set"), "source_divergences": Output("along:source_vertices"),
                "vortex_faces": Output("top_set"), "stroke_faces": Output("top_set"),
                "stroke_vectors": Output("along:stroke_faces", 3), "region_faces": Output("top_set")}

    def run(self, ctx: Context) -> Result:
        """Design the field (see :func:`_design` for fields and metrics)."""
        return _design(self, ctx)


def _as_list(value) -> list:
    return [] if value is None else list(value)


def _vertex_ids(K: SimplicialComplex, items, key: str, tolerance: float = float("inf")) -> tuple[np.ndarray, np.ndarray]:
    ids, values = [], []
    for i, item in enumerate(items):
        if getattr(item, "vertex", None) is not None:
            v = int(item.vertex)
            if not 0 <= v < K.num_simplices(0):
                raise ConfigError(f"app.{key}[{i}].vertex: {v} is not a vertex id of this mesh (0..{K.num_simplices(0) - 1})")
        else:
            check_points_on_surface(K, [list(item.point)], f"app.{key}[{i}].point", tolerance)
            v = int(nearest_vertices(K, [list(item.point)])[0])
        ids.append(v)
        values.append(float(item.divergence))
    return np.asarray(ids, dtype=np.int64), np.asarray(values)


def _face_ids(K: SimplicialComplex, items, key: str, tolerance: float = float("inf")) -> tuple[np.ndarray, np.ndarray]:
    ids, values = [], []
    for i, item in enumerate(items):
        if getattr(item, "face", None) is not None:
            t = int(item.face)
            if not 0 <= t < K.num_simplices(2):
                raise ConfigError(f"app.{key}[{i}].face: {t} is not a face id of this mesh (0..{K.num_simplices(2) - 1})")
        else:
            check_points_on_surface(K, [list(item.point)], f"app.{key}[{i}].point", tolerance)
            t = int(nearest_faces(K, [list(item.point)])[0][0])
        ids.append(t)
        values.append(float(item.curl))
    return np.asarray(ids, dtype=np.int64), np.asarray(values)


def sources_from_mesh(K: SimplicialComplex, log=None) -> tuple[list[Source], dict]:
    """The default source/sink pair (module docstring) as ``Source`` items by vertex id, and
    the metrics that record it; ``log`` (a callable) is told which vertices were chosen."""
    pair = principal_extremes(K)
    points = embed3(K.vertices)[[pair.source, pair.sink]]
    fmt = format_point
    metrics = {"sources_from_mesh": True, "source_vertex": pair.source, "sink_vertex": pair.sink,
               "source_point": fmt(points[0]), "sink_point": fmt(points[1]), "source_axis": fmt(pair.axis),
               "source_axis_unique": pair.axis_unique}
    if log is not None:
        where = " off the border" if pair.interior_only else ""
        note = "" if pair.axis_unique else (" (the two largest variances are equal: the axis is one of a plane of "
                                            "equally good ones)")
        log(f"vector_field: app.sources=null: source +1 at vertex {pair.source} {metrics['source_point']}, sink -1 "
            f"at vertex {pair.sink} {metrics['sink_point']}: the extreme vertices{where} along the principal axis "
            f"{metrics['source_axis']}{note}; give app.sources to choose others")
    return [Source(vertex=pair.source, divergence=1.0), Source(vertex=pair.sink, divergence=-1.0)], metrics


def build_constraints(K: SimplicialComplex, dec: DEC, cfg, log=None) -> tuple[DesignConstraints, dict]:
    """Curl and divergence targets of eq. 6.5 from ``cfg.sources`` (None: a pair from the mesh,
    :func:`sources_from_mesh`) / ``cfg.vortices`` and the stroke geometry (faces, unit
    directions) from ``cfg.strokes``. ``geometry["source_metrics"]`` records the sources' origin."""
    constraints = DesignConstraints.empty(K)
    tolerance = float(getattr(cfg, "point_tolerance", float("inf")))
    if cfg.sources is None:
        sources, source_metrics = sources_from_mesh(K, log)
    else:
        sources, source_metrics = list(cfg.sources), {"sources_from_mesh": False}
    src_ids, src_values = _vertex_ids(K, sources, "sources", tolerance)
    if src_ids.size:
        constraints.codifferential = divergence_target(dec, src_ids, src_values)
    vort_ids, vort_values = _face_ids(K, _as_list(cfg.vortices), "vortices", tolerance)
    if vort_ids.size:
        np.add.at(constraints.curl, vort_ids, vort_values)  # r_t: circulation = ∫_t curl
    stroke_faces, stroke_dirs = [], []
    for i, stroke in enumerate(_as_list(cfg.strokes)):
        check_points_on_surface(K, stroke.points, f"app.strokes[{i}].points", tolerance)
        faces, dirs = stroke_face_directions(K, np.asarray(stroke.points, dtype=np.float64), closed=bool(stroke.closed))
        stroke_faces.append(faces)
        stroke_dirs.append(dirs)
    geometry = {
        "source_vertices": src_ids,
        "source_divergences": src_values,
        "source_metrics": source_metrics,
        "vortex_faces": vort_ids,
        "stroke_faces": np.concatenate(stroke_faces) if stroke_faces else np.zeros(0, dtype=np.int64),
        "stroke_directions": np.concatenate(stroke_dirs) if stroke_dirs else np.zeros((0, 3)),
    }
    return constraints, geometry


# ----------------------------------------------------------------------------------
# the application
# ----------------------------------------------------------------------------------


def _design(self, ctx: Context) -> Result:
    """Design the field; see the module docstring.

    Fields: ``omega`` (n1,) the 1-form; ``face_vectors`` (n2, 3) Whitney ♯ (eq. 6.7) at the
    barycenters; ``vertex_index`` (n0,) and ``face_index`` (n2,) singularity indices;
    ``singular_vertices`` / ``singular_faces`` (ids); ``source_vertices`` (ids) and
    ``source_divergences`` (their outflows); ``stroke_faces`` (ids) and
    ``stroke_vectors`` (their target vectors v_t); ``omega_without_strokes`` (when strokes
    are given).

    Metrics: ``curl_residual``, ``divergence_residual``, ``direction_residual`` (⋆2, ⋆0 and
    W norms; each also ``*_relative`` to its target when that is non-zero), ``smoothness_energy``
    (⟨dω,dω⟩ + ⟨δω,δω⟩), ``index_sum``, ``euler_characteristic``, ``poincare_hopf_holds``
    (closed meshes), ``singularities`` (count of singular vertices and faces) with
    ``singularities_positive`` / ``_negative``, ``singularity_clusters`` (sites within
    ``cluster_radius`` mean edge lengths merged, index-0 clusters left out) and
    ``singularity_cluster_indices`` (their indices, e.g. ``"+1,+1"``), ``border_normal_flux_mean`` and ``border_normal_fraction``,
    ``adjointness_defect``, ``field_change_relative`` / ``field_change_region_relative``
    (strokes: change of the face vectors caused by the strokes, area-weighted L2, whole
    mesh / region), ``normal_equation_residual``, ``solve_seconds``; ``sources_from_mesh`` and,
    when true, ``source_vertex`` / ``sink_vertex`` / ``source_point`` / ``sink_point`` /
    ``source_axis`` / ``source_axis_unique`` (:func:`sources_from_mesh`).
    """
    K, dec, cfg = ctx.complex, ctx.dec, self
    delta = dec.codifferential(1)
    constraints, geometry = build_constraints(K, dec, cfg, ctx.log)
    pre, solution, constraints, stroke_vectors, seconds = _solve(cfg, ctx, delta, constraints, geometry)
    omega = solution.omega
    face_vectors = embed3(whitney_sharp(K, omega))
    singular = find_singularities(K, omega)
    clusters = cluster_singularities(K, singular, cfg.cluster_radius * K.mean_edge_length)
    closed = K.border_faces()[0].size == 0
    metrics = _design_metrics(dec, delta, constraints, solution, singular, clusters, geometry, seconds)
    fields = {
        "omega": FieldOnEdges(omega),
        "face_vectors": face_vectors,
        "vertex_index": singular.vertex_index,
        "face_index": singular.face_index,
        "singular_vertices": singular.vertices,
        "singular_faces": singular.faces,
        "cluster_positions": clusters.positions,
        "cluster_indices": clusters.indices,
        "source_vertices": geometry["source_vertices"],
        "source_divergences": geometry["source_divergences"],
        "vortex_faces": geometry["vortex_faces"],
        "stroke_faces": geometry["stroke_faces"],
        "stroke_vectors": stroke_vectors,
    }
    if geometry["stroke_faces"].size:
        _stroke_change(cfg, dec, pre.omega, face_vectors, metrics, fields)
    title = f"with border, boundary={dec.boundary.name}" if not closed else "closed surface"
    figures = {"field": Figure.of_kind(
        "vector_field", face_vectors=face_vectors, vertex_index=singular.vertex_index,
        face_index=singular.face_index, stroke_faces=geometry["stroke_faces"], title=f"designed field ({title})",
        max_arrows=int(cfg.figure_arrows), cluster_positions=clusters.positions[clusters.nonzero],
        cluster_indices=clusters.indices[clusters.nonzero], source_vertices=geometry["source_vertices"],
        source_divergences=geometry["source_divergences"], vortex_faces=geometry["vortex_faces"])}
    return Result(fields=fields, metrics=metrics, figures=figures)


def _solve(cfg, ctx: Context, delta, constraints, geometry):
    """(pre, solution, constraints, stroke_vectors, seconds): the least squares of eq. 6.5-6.6
    without the strokes (``pre``) and, with strokes, again with their edge targets — the stroke
    vectors v_t (n_s, 3) of |v| = ``stroke_length`` (eq. 6.8, ``fixed``) or |ν_pre| (eq. 6.9) —
    weighted ``stroke_weight`` / h̄; the solves' wall time (s)."""
    K, dec = ctx.complex, ctx.dec
    start = time.perf_counter()
    with ctx.task("vector field: least squares (eq. 6.5-6.6)"):
        pre = solve_design(dec, ctx.new_solver(), constraints, delta)
    seconds = time.perf_counter() - start
    solution = pre
    stroke_vectors = np.zeros((0, 3))
    if geometry["stroke_faces"].size:
        faces = geometry["stroke_faces"]
        if cfg.stroke_magnitude == "fixed":  # eq. 6.8: |v| = λ
            magnitude = np.full(faces.size, float(cfg.stroke_length))
        else:  # eq. 6.9: |v| = |ν_pre|
            magnitude = np.linalg.norm(whitney_sharp(K, pre.omega, faces=faces), axis=1)
        stroke_vectors = geometry["stroke_directions"] * magnitude[:, None]
        edges, targets = stroke_edge_targets(K, faces, stroke_vectors)
        constraints = constraints.with_strokes(edges, targets,
                                               np.full(edges.size, float(cfg.stroke_weight) / K.mean_edge_length))
        start = time.perf_counter()
        with ctx.task("vector field: least squares with the strokes"):
            solution = solve_design(dec, ctx.new_solver(), constraints, delta)
        seconds += time.perf_counter() - start
    return pre, solution, constraints, stroke_vectors, seconds


def _design_metrics(dec, delta, constraints, solution, singular, clusters, geometry, seconds: float) -> dict:
    """The residuals, energy, singularity counts and border flux of the designed 1-form (the
    metrics listed in :func:`_design`, less the strokes' field change)."""
    K, omega = dec.K, solution.omega
    chi = int(K.euler_characteristic)
    closed = K.border_faces()[0].size == 0
    metrics = design_residuals(dec, delta, constraints, omega)
    metrics.update(
        smoothness_energy=smoothness_energy(dec, delta, omega),
        index_sum=int(singular.index_sum),
        euler_characteristic=chi,
        closed=bool(closed),
        singularities=singular.count,
        singularities_positive=int((singular.vertex_index > 0).sum() + (singular.face_index > 0).sum()),
        singularities_negative=int((singular.vertex_index < 0).sum() + (singular.face_index < 0).sum()),
        index_max_rounding=singular.max_rounding,
        singularity_clusters=int(clusters.nonzero.sum()),
        singularity_cluster_indices=clusters.summary(),
        adjointness_defect=adjointness_defect(dec, delta),
        boundary=dec.boundary.name,
        sources=int(geometry["source_vertices"].size),
        **geometry["source_metrics"],
        vortices=int(geometry["vortex_faces"].size),
        stroke_faces=int(geometry["stroke_faces"].size),
        stroke_edges=int(constraints.stroke_edges.size),
        normal_equation_residual=solution.normal_equation_residual,
        refinement_steps=solution.refinement_steps,
        solve_seconds=seconds,
    )
    if closed:  # Poincaré–Hopf applies to closed surfaces only
        metrics["poincare_hopf_holds"] = bool(singular.index_sum == chi)
    metrics.update(border_normal_flux(K, omega))
    return metrics


def _stroke_change(cfg, dec, omega_pre: np.ndarray, face_vectors: np.ndarray, metrics: dict, fields: dict) -> None:
    """What the strokes changed: ``field_change_relative`` (area-weighted L2 of the face vectors'
    change over the mesh) and, with ``region_normal``, over the faces whose normal is within
    ``region_min_cos`` of it (``field_change_region_relative``, absent over no face); the
    field without strokes and the region's faces."""
    K = dec.K
    before = embed3(whitney_sharp(K, omega_pre))
    area = dec.primal_volumes(2)
    metrics["field_change_relative"] = field_change_relative(before, face_vectors, area, np.ones(area.size, bool))
    fields["omega_without_strokes"] = FieldOnEdges(omega_pre)
    if cfg.region_normal:
        n = np.asarray(cfg.region_normal, dtype=np.float64)
        region = face_normals(K) @ (n / np.linalg.norm(n)) >= float(cfg.region_min_cos)
        metrics["region_faces"] = int(region.sum())
        if region.any():  # over no face there is no change to measure: absent
            metrics["field_change_region_relative"] = field_change_relative(before, face_vectors, area, region)
        fields["region_faces"] = np.flatnonzero(region)
