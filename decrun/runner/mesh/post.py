"""Post-processing steps of the mesh sources (``mesh.post``): one function per step.

Each step is ``step(mesh, cfg) -> Mesh``, reads its options from the typed source ``cfg`` (a
:class:`decrun.runner.mesh.source.MeshSource`: every option there, with its one default, already
validated) and returns the mesh unchanged (the same
object) unless its option enables it. ``mesh.post`` lists the names of these functions in
the order they run; adding a step is adding a function here (and its option field to
``MeshSource``).
"""

from __future__ import annotations

import logging

import numpy as np

from decrun.core.connectivity import component_labels, drop_unreferenced
from decrun.core.geometry import mean_edge_length, triangle_areas, vertex_normals
from decrun.errors import ConfigError, MeshError
from decrun.runner.mesh.base import (
    MAX_TRIANGLES,
    HoleCut,
    HolePieces,
    Mesh,
    Refine,
    UpAxis,
    bounding_diagonal,
    from_meshset,
    require,
    require_surface,
    require_triangles,
    to_meshset,
)
from decrun.runner.mesh.cache import cached_mesh, content_hash
from decrun.runner.mesh.cut import ON_TOLERANCE, parse_regions, signed_distance
from decrun.runner.mesh.cut import cut_holes as split_along_holes
from decrun.runner.mesh.holes import cut_holes as remove_triangles_in_holes
from decrun.runner.mesh.repair import cached_repair, up_axis_to_z

__all__ = ["repair", "up_axis", "clean", "largest_component", "holes", "refine", "normalize", "noise", "lloyd"]


def repair(mesh: Mesh, cfg) -> Mesh:
    """``repair``: pymeshlab's cleaning filters (:func:`decrun.runner.mesh.repair.repair_mesh`,
    through the mesh cache: :func:`decrun.runner.mesh.repair.cached_repair`):
    duplicate vertices and faces, zero-area and degenerate faces, non-manifold edges and
    vertices (bowties split), unreferenced vertices, coherent orientation. Every count goes
    to ``meta['repair']`` and the run log; triangle meshes only."""
    if not cfg.repair:
        return mesh
    require(mesh.simplices.shape[1] == 3, "repair", "repairs triangle meshes only; this mesh has tetrahedra: "
            "use `mesh.repair=false`")
    if "clean_vertices" in mesh.meta:  # repair runs before noise in the default order
        raise MeshError("mesh.repair: runs on the noise-free mesh; list repair before noise in mesh.post")
    vertices, faces, report = cached_repair(mesh.vertices, mesh.simplices)
    changed = {k: v for k, v in report.items() if isinstance(v, (int, np.integer)) and not isinstance(v, bool)
               and v and k not in ("vertices_in", "faces_in", "vertices_out", "faces_out", "rounds")}
    import logging

    logging.getLogger("decrun").info("mesh.repair: %s", ", ".join(f"{k}={v}" for k, v in changed.items())
                                     or "nothing to repair")
    return Mesh(vertices, faces, dict(mesh.meta, repair=report))


def up_axis(mesh: Mesh, cfg) -> Mesh:
    """``up_axis``: rotate the model so that its up axis (``x, y, z, -x, -y, -z``; ``auto``:
    the sample's own, :data:`decrun.runner.mesh.repair.UP_AXIS`, else ``z``) points along +z,
    the axis the figures draw upwards. A proper rotation: lengths, angles, orientation kept."""
    axis = resolved_up_axis(mesh, cfg)
    if axis == "z":
        return mesh
    require(mesh.vertices.shape[1] == 3, "up_axis", "a planar mesh has no up axis; use `mesh.up_axis=z`")
    meta = dict(mesh.meta, up_axis=axis)
    if "clean_vertices" in meta:
        meta["clean_vertices"] = up_axis_to_z(meta["clean_vertices"], axis)
    return Mesh(up_axis_to_z(mesh.vertices, axis), mesh.simplices, meta)


def resolved_up_axis(mesh: Mesh, cfg) -> str:
    """``cfg.up_axis`` (an :class:`~decrun.runner.mesh.base.UpAxis`) as a key of
    :data:`~decrun.runner.mesh.repair.ROTATION_TO_Z_UP`, ``auto`` resolved by the source
    (:meth:`~decrun.runner.mesh.source.MeshSource.auto_up_axis`: a sample's own, else ``z``)."""
    axis = UpAxis.of(cfg.up_axis, "mesh.up_axis").value
    return cfg.auto_up_axis() if axis == UpAxis.auto.value else axis


def holes(mesh: Mesh, cfg) -> Mesh:
    """``holes``: cut ``cfg.hole_balls`` and ``cfg.hole_boxes`` (no-op when both are empty).

    ``hole_cut: split`` (default) splits the triangles along the balls' spheres and the
    boxes' faces (:func:`decrun.runner.mesh.cut.cut_holes`: smooth borders, new vertices on
    the surfaces, ``hole_snap`` against slivers); ``hole_cut: whole_triangles`` removes the
    triangles whose centroid lies inside (:func:`decrun.runner.mesh.holes.cut_holes`: the
    sawtooth borders of the earlier experiments). Records ``meta['holes']`` (the cut's counts)
    and carries ``meta['clean_vertices']`` onto the cut mesh.
    """
    balls, boxes = list(cfg.hole_balls), list(cfg.hole_boxes)
    if not balls and not boxes:
        return mesh
    method = cfg.hole_cut
    require_each_region_cuts(mesh, balls, boxes, method)
    meta = dict(mesh.meta)
    if method == HoleCut.whole_triangles:
        vertices, faces, kept = remove_triangles_in_holes(mesh.vertices, mesh.simplices, balls, boxes,
                                                          keep_all_pieces=True)
        if "clean_vertices" in meta:
            meta["clean_vertices"] = np.asarray(meta["clean_vertices"])[kept]
        meta["holes"] = {"removed_faces": int(len(mesh.simplices) - len(faces))}
    else:
        vertices, faces, info = split_along_holes(mesh.vertices, mesh.simplices, balls, boxes,
                                                  snap=float(cfg.hole_snap), keep_all_pieces=True)
        if "clean_vertices" in meta:
            meta["clean_vertices"] = info["interpolation"] @ np.asarray(meta["clean_vertices"])
        meta["holes"] = {k: v for k, v in info.items() if np.isscalar(v)}
        meta["hole_border_vertices"] = int(np.sum(info["on_border"]))
    meta["holes_removed_faces"] = int(meta["holes"]["removed_faces"])
    cut = type(mesh)(vertices, faces, meta)
    if cfg.hole_pieces == HolePieces.all:
        return cut
    kept = keep_largest_piece(cut, "holes", "edges", "mesh.hole_balls/hole_boxes: the cut",
                              "`mesh.hole_pieces=all` keeps every piece")
    used = kept.meta.pop("_used")
    if method == HoleCut.split:  # counted again on what is kept
        kept.meta["hole_border_vertices"] = int(np.sum(info["on_border"][used]))
    kept.meta["holes"]["dropped_piece_faces"] = kept.meta["holes_dropped_faces"]
    return kept


def _compact(values) -> str:
    """``[a,b,c]`` without spaces (an override in a hint is typed as one word), 6 digits."""
    return "[" + ",".join(f"{float(v):.6g}" for v in values) + "]"


def require_each_region_cuts(mesh: Mesh, balls: list, boxes: list, method: str) -> None:
    """ConfigError naming ``mesh.hole_balls[k]`` / ``mesh.hole_boxes[k]`` for the first region
    that would remove nothing from ``mesh`` on its own — no vertex strictly inside it (the
    ``split`` cut keeps every triangle whose corners are outside or on its border) or, for
    ``whole_triangles``, no triangle centroid inside — instead of a hole that silently is not
    there. The hint is the same list with that region grown to reach the nearest vertex by
    one mean edge length h̄ (the radius; a box's corners), so the region cuts at least it."""
    V = np.asarray(mesh.vertices, dtype=np.float64)
    dim = V.shape[1]
    ball_rows, box_rows = parse_regions(balls, boxes, dim)
    points = V[mesh.simplices].mean(axis=1) if method == HoleCut.whole_triangles else V
    h = float(mean_edge_length(V, mesh.simplices))
    tau = ON_TOLERANCE * h
    empty = np.zeros((0, 2 * dim))
    for k, ball in enumerate(ball_rows):
        phi, _ = signed_distance(points, ball[None], empty)
        if np.any(phi < -tau if method == HoleCut.split else phi <= 0):
            continue
        nearest = int(np.argmin(phi))
        reach = float(np.linalg.norm(points[nearest] - ball[:dim])) + h
        radius = float(f"{reach:.2g}") if float(f"{reach:.2g}") >= reach else float(f"{reach * 1.05:.2g}")
        fixed = [list(map(float, b)) for b in ball_rows]
        fixed[k][dim] = radius
        what = "triangle centroid" if method == HoleCut.whole_triangles else "vertex"
        raise ConfigError(f"mesh.hole_balls[{k}]: {_compact(ball)} removes nothing: no {what} of the mesh lies inside "
                          f"it (the nearest is {phi[nearest] + ball[dim]:.3g} from its centre, radius "
                          f"{ball[dim]:.3g}); move its centre onto the surface or grow it, e.g. "
                          f"`mesh.hole_balls=[{','.join(_compact(b) for b in fixed)}]`")
    for k, box in enumerate(box_rows):
        phi, _ = signed_distance(points, np.zeros((0, dim + 1)), box[None])
        if np.any(phi < -tau if method == HoleCut.split else phi <= 0):
            continue
        nearest = points[int(np.argmin(phi))]
        lo, hi = np.minimum(box[:dim], nearest - h), np.maximum(box[dim:], nearest + h)
        fixed = [list(map(float, b)) for b in box_rows]
        fixed[k] = [float(v) for v in np.concatenate([lo, hi])]
        raise ConfigError(f"mesh.hole_boxes[{k}]: {_compact(box)} removes nothing: nothing of the mesh lies inside it "
                          f"(the nearest point is {float(phi.min()):.3g} outside); move it onto the surface or grow "
                          f"it, e.g. `mesh.hole_boxes=[{','.join(_compact(b) for b in fixed)}]`")


def keep_largest_piece(mesh: Mesh, step: str, through: str, what: str, fix: str) -> Mesh:
    """``mesh`` reduced to its largest piece — the most top simplices, the first on a tie;
    pieces joined across shared ``"edges"`` (triangles) or ``"vertices"``
    (:func:`decrun.core.connectivity.component_labels`) — and the vertices it uses.

    Nothing is dropped unreported: ``meta`` gets ``<step>_components``,
    ``<step>_dropped_vertices`` and ``<step>_dropped_faces`` (the run's metrics,
    :func:`decrun.runner.job.run.execute`), and when anything was dropped one log line says
    ``<what> left N pieces; kept …, dropped …; <fix>``. ``meta['clean_vertices']`` follows
    the kept vertices; ``meta['_used']`` is the (n,) bool mask of the kept input vertices."""
    S = np.asarray(mesh.simplices, dtype=np.int64)
    label = component_labels(S, len(mesh.vertices), through=through)
    counts = np.bincount(label)
    keep_faces = label == np.argmax(counts)
    V, F, used = drop_unreferenced(mesh.vertices, S[keep_faces])
    dropped_v, dropped_f = int((~used).sum()), int((~keep_faces).sum())
    if dropped_v or dropped_f:
        logging.getLogger("decrun").info("%s left %d piece%s; kept the largest: %d of %d vertices and %d of %d "
                                         "simplices (dropped %d vertices, %d simplices); %s", what, len(counts),
                                         "" if len(counts) == 1 else "s", len(V), len(mesh.vertices), len(F), len(S),
                                         dropped_v, dropped_f, fix)
    meta = dict(mesh.meta, _used=used, **{f"{step}_components": len(counts), f"{step}_dropped_vertices": dropped_v,
                                          f"{step}_dropped_faces": dropped_f})
    if "clean_vertices" in meta:
        meta["clean_vertices"] = np.asarray(meta["clean_vertices"])[used]
    return type(mesh)(V, F, meta)


def clean(mesh: Mesh, cfg) -> Mesh:
    """``clean``: keep the largest connected component (by triangle count, components
    joined through shared vertices) and drop unreferenced vertices
    (:func:`keep_largest_piece`: logged and recorded as ``clean_*``; also
    ``dropped_vertices`` / ``dropped_faces``)."""
    if not cfg.clean:
        return mesh
    kept = keep_largest_piece(mesh, "clean", "vertices", "mesh.clean", "`mesh.clean=false` keeps every piece")
    kept.meta.pop("_used")
    kept.meta.update(dropped_vertices=kept.meta["clean_dropped_vertices"], dropped_faces=kept.meta["clean_dropped_faces"])
    return Mesh(kept.vertices, kept.simplices, kept.meta)


def largest_component(mesh: Mesh, cfg) -> Mesh:
    """``largest_component``: keep the connected component with the most top simplices
    (triangles or tetrahedra joined through shared vertices, as
    :meth:`decrun.core.complex.SimplicialComplex.connected_components` counts them; the first
    on a tie) and the vertices it uses. The numbers of components, dropped vertices and dropped
    top simplices go to the run log and to ``meta`` (``largest_component_components``,
    ``largest_component_dropped_vertices``, ``largest_component_dropped_faces``;
    :func:`keep_largest_piece`)."""
    if not cfg.largest_component:
        return mesh
    kept = keep_largest_piece(mesh, "largest_component", "vertices", "mesh.largest_component: the mesh",
                              "`mesh.largest_component=false` keeps every piece")
    kept.meta.pop("_used")
    return kept


def refine(mesh: Mesh, cfg) -> Mesh:
    """``refine``: ``loop`` / ``midpoint`` subdivision or ``isotropic`` remeshing (pymeshlab),
    ``refine_iterations`` times. Drops ``clean_vertices`` (the connectivity changed). The refined
    mesh is kept in the mesh cache (:func:`decrun.runner.mesh.cache.cached_mesh`, keyed by the
    input mesh, the method, the iterations and the target edge)."""
    if cfg.refine == Refine.none:
        return mesh
    require(1 <= cfg.refine_iterations <= 10, "refine_iterations", f"must be in 1..10, got {cfg.refine_iterations}")
    require_surface(mesh, f"mesh.refine={cfg.refine}", "mesh.refine=none")
    dim = mesh.vertices.shape[1]
    m, iterations = len(mesh.simplices), int(cfg.refine_iterations)
    target = 0.0  # isotropic only: the target edge length
    if cfg.refine in ("loop", "midpoint"):  # each iteration splits a triangle into 4
        fits = max(0, int(np.floor(np.log(MAX_TRIANGLES / m) / np.log(4))))
        require_triangles(m * 4.0 ** iterations, "mesh.refine_iterations",
                          f"mesh.refine_iterations={fits}" if fits else "a coarser mesh")
    else:
        require(cfg.refine_target_edge >= 0, "refine_target_edge", "must be >= 0")
        target = cfg.refine_target_edge or mean_edge_length(mesh.vertices, mesh.simplices)
        area = float(triangle_areas(mesh.vertices, mesh.simplices).sum())
        equilateral = np.sqrt(3) / 4 * target**2
        shortest = np.sqrt(area / (MAX_TRIANGLES * np.sqrt(3) / 4))  # the target that makes MAX_TRIANGLES
        require_triangles(area / equilateral, "mesh.refine_target_edge", f"mesh.refine_target_edge={1.1 * shortest:.2g}")

    def build() -> tuple[np.ndarray, np.ndarray, dict]:
        import pymeshlab

        ms = to_meshset(mesh.vertices, mesh.simplices)
        try:
            if cfg.refine == "loop":
                ms.meshing_surface_subdivision_loop(iterations=iterations, threshold=pymeshlab.PercentageValue(0.0))
            elif cfg.refine == "midpoint":
                ms.meshing_surface_subdivision_midpoint(iterations=iterations, threshold=pymeshlab.PercentageValue(0.0))
            else:
                ms.meshing_isotropic_explicit_remeshing(iterations=iterations,
                                                        targetlen=pymeshlab.PureValue(float(target)))
        except pymeshlab.PyMeshLabException as exc:
            reason = " ".join(line.strip() for line in str(exc).splitlines() if line.strip())
            raise MeshError(f"mesh.refine={cfg.refine}: pymeshlab refused the mesh ({reason}); repair the mesh "
                            f"or use mesh.refine=none") from None
        return (*from_meshset(ms, f"mesh.refine={cfg.refine}"), {})

    params = {"input": content_hash(mesh.vertices, mesh.simplices), "refine": str(cfg.refine),
              "iterations": iterations, "target": float(target)}
    vertices, faces, _ = cached_mesh("refine", params, __file__, build)
    meta = {k: v for k, v in mesh.meta.items() if k != "clean_vertices"}
    return Mesh(vertices[:, :dim], faces, meta)


def normalize(mesh: Mesh, cfg) -> Mesh:
    """``normalize``: translate the bounding-box centre to the origin, scale to unit diagonal."""
    if not cfg.normalize:
        return mesh
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    center, diagonal = lo / 2 + hi / 2, bounding_diagonal(mesh.vertices)  # halves first: no overflow at 1e308
    if diagonal == 0:
        raise MeshError("mesh.normalize: all vertices coincide")
    meta = dict(mesh.meta)
    if "clean_vertices" in meta:
        meta["clean_vertices"] = (meta["clean_vertices"] - center) / diagonal
    return Mesh((mesh.vertices - center) / diagonal, mesh.simplices, meta)


def noise(mesh: Mesh, cfg) -> Mesh:
    """``noise``: displace every vertex by ``noise · h · ξ_i`` along its unit normal, where
    ``h`` is the mean edge length and ``ξ_i ~ N(0, 1)`` (generator seeded by ``seed``).
    For planar (2-D) meshes, which have no normal, the direction is a random in-plane unit
    vector. Keeps the noise-free positions in ``meta['clean_vertices']``."""
    require(cfg.noise >= 0, "noise", f"must be >= 0, got {cfg.noise}")
    if cfg.noise == 0:
        return mesh
    require_surface(mesh, "mesh.noise", "mesh.noise=0")
    rng = np.random.default_rng(int(cfg.seed))
    V, F = mesh.vertices, mesh.simplices
    h = mean_edge_length(V, F)
    if V.shape[1] == 3:
        direction = vertex_normals(V, F)
    else:
        angle = rng.uniform(0, 2 * np.pi, len(V))
        direction = np.column_stack([np.cos(angle), np.sin(angle)])
    amplitude = float(cfg.noise) * h
    displaced = V + amplitude * rng.standard_normal(len(V))[:, None] * direction
    meta = dict(mesh.meta, clean_vertices=V.copy(), noise_amplitude=amplitude)
    return Mesh(displaced, F, meta)


def lloyd(mesh: Mesh, cfg) -> Mesh:
    """``lloyd``: at most ``lloyd`` steps of Lloyd's iteration towards the spherical centroidal Voronoi
    tessellation (Du, Gunzburger & Ju 2003; the grid MPAS runs TRiSK on): every vertex moved to the radial
    projection of its Voronoi cell's centroid, the triangles kept (:func:`decrun.core.sphere_lloyd.lloyd_sphere`),
    stopping early once no vertex moves by ``lloyd_tolerance`` times the radius. Only for a triangulated sphere
    centred at the origin (refused in one line otherwise). The result is kept in the mesh cache; the steps done
    and the last move are in ``meta['lloyd']``."""
    if cfg.lloyd == 0:
        return mesh
    require(cfg.lloyd > 0, "lloyd", f"must be >= 0 (Lloyd iterations), got {cfg.lloyd}")
    require(cfg.lloyd_tolerance >= 0, "lloyd_tolerance", f"must be >= 0, got {cfg.lloyd_tolerance}")
    require_surface(mesh, "mesh.lloyd", "mesh.lloyd=0")
    from decrun.core.sphere_lloyd import lloyd_sphere
    from decrun.core.trisk import sphere_radius

    if mesh.vertices.shape[1] != 3:
        raise MeshError("mesh.lloyd: Lloyd's iteration here is on a sphere in R³; use mesh.lloyd=0")
    try:
        sphere_radius(mesh.vertices)
    except MeshError as exc:
        raise MeshError(f"mesh.lloyd: needs a sphere centred at the origin ({exc.args[0].split(': ', 2)[-1]}); "
                        "use mesh.lloyd=0 or mesh=icosphere_earth") from None

    def build() -> tuple[np.ndarray, np.ndarray, dict]:
        vertices, info = lloyd_sphere(mesh.vertices, mesh.simplices, int(cfg.lloyd), float(cfg.lloyd_tolerance))
        return vertices, mesh.simplices, {"iterations": int(info["iterations"]), "last_move": float(info["last_move"])}

    params = {"input": content_hash(mesh.vertices, mesh.simplices), "iterations": int(cfg.lloyd),
              "tolerance": float(cfg.lloyd_tolerance)}
    vertices, faces, info = cached_mesh("lloyd", params, __file__, build)
    logging.getLogger("decrun").info("mesh.lloyd: %d Lloyd steps, the last moving a vertex by %.3g of the radius",
                                     info["iterations"], info["last_move"])
    meta = {k: v for k, v in mesh.meta.items() if k != "clean_vertices"}
    meta["lloyd"] = dict(info)
    return Mesh(vertices, faces, meta)
